// `voxfield view` on sparse worlds end to end (the executable, PoCL and lavapipe, every run with
// the Vulkan validation layer): the first frame equals `render --sparse`'s image; after edits
// the window's screenshot equals `render --sparse` of the world edited the same way (the tracer
// updated tile by tile shows what a fresh upload shows); the headless benchmark on the
// generated city records frames, edits and tiles updated; a huge grid goes sparse without
// --sparse; what sparse worlds refuse exits 2 with one line. Without xvfb-run the window test
// skips.
#include <gtest/gtest.h>

#include <nlohmann/json.hpp>

#include <algorithm>
#include <cstdlib>
#include <optional>
#include <string>
#include <vector>

#include "../cli/cli_test_util.hpp"
#include "../cli/far_grid_util.hpp"
#include "../scoped_env.hpp"
#include "voxfield/core/brush.hpp"
#include "voxfield/core/npy.hpp"
#include "voxfield/core/palette.hpp"
#include "voxfield/core/sand.hpp"
#include "voxfield/core/vdb.hpp"
#include "voxfield/core/vox.hpp"
#include "voxfield/core/world.hpp"

namespace voxfield::test {
namespace {

class ViewSparse : public TempDirsTest {
  protected:
    ViewSparse() : TempDirsTest("voxfield_view_sparse") {}
    HeadlessViewerEnv env_;
};

// A 150 x 40 x 140 world (three tiles along x and z): a floor, a wall and a tower.
World test_world() {
    World w(Dims{150, 40, 140});
    for (std::uint32_t z = 0; z < 140; ++z) {
        for (std::uint32_t x = 0; x < 150; ++x) {
            w.set(x, 0, z, static_cast<std::uint8_t>(1 + (x / 16 + z / 16) % 5));
        }
    }
    for (std::uint32_t y = 1; y < 30; ++y) {
        for (std::uint32_t x = 20; x < 130; ++x) {
            w.set(x, y, 70, 6);
        }
        for (std::uint32_t x = 100; x < 110; ++x) {
            for (std::uint32_t z = 20; z < 30; ++z) {
                w.set(x, y + 8, z, 9);
            }
        }
    }
    return w;
}

// The material grid of `vdb` read back equals `w` voxel for voxel. A .vdb is read from its
// solids' box, which starts at the origin for the worlds here (their floors hold voxel 0, 0, 0).
void expect_vdb_world(const fs::path& vdb, const World& w) {
    const SparseWorld s = read_vdb_sparse(vdb, "");
    const Dims d = s.dims(), wd = w.dims();
    ASSERT_LE(d.x, wd.x);
    ASSERT_LE(d.y, wd.y);
    ASSERT_LE(d.z, wd.z);
    std::size_t differing = 0;
    for (std::uint32_t z = 0; z < wd.z; ++z) {
        for (std::uint32_t y = 0; y < wd.y; ++y) {
            for (std::uint32_t x = 0; x < wd.x; ++x) {
                const bool inside = x < d.x && y < d.y && z < d.z;
                differing += w.at(x, y, z) != (inside ? s.at(x, y, z) : 0);
            }
        }
    }
    EXPECT_EQ(differing, 0u) << vdb;
}

fs::path write_world(const World& w, const fs::path& path) {
    const NpyArray a = npy_from_world(w);
    write_npy(path, a.type, a.dims, a.data);
    return path;
}

TEST_F(ViewSparse, FirstFrameEqualsRenderSparse) {
    const fs::path model = fs::path(VOXFIELD_DATA_DIR) / "vox" / "chr_army1.vox";
    const fs::path viewed = dir_ / "viewed.png", rendered = dir_ / "rendered.png";
    RunResult r = run_voxfield({"view", model.string(), "--sparse", "--width", "120", "--height",
                                "90", "--fallback-png", viewed.string()},
                               io_);
    ASSERT_EQ(r.code, 0) << describe(r);
    EXPECT_NE(r.out.find("(sparse)"), std::string::npos) << r.out;
    EXPECT_NE(r.out.find("field:   exact, bounded at 16, u8"), std::string::npos) << r.out;
    r = run_voxfield({"render", model.string(), "--sparse", "-o", rendered.string(), "--width",
                      "120", "--height", "90", "--shading", "lit"},
                     io_);
    ASSERT_EQ(r.code, 0) << describe(r);
    EXPECT_EQ(read_text(viewed), read_text(rendered)) << "the PNGs differ";
}

TEST_F(ViewSparse, EditedWindowEqualsRenderOfTheEditedWorld) {
    if (!have_xvfb()) {
        GTEST_SKIP() << "xvfb-run is not installed (setup.sh installs it)";
    }
    World w = test_world();
    const fs::path world = write_world(w, dir_ / "world.npy");
    // Inside the solids' box (the default camera stays the same): tiles repainted, the tower
    // mostly erased, voxels placed in the air; each edit rewrites the tiles it touches.
    const std::string edit_text =
        "paint sphere 60 10 70 12 3\n"
        "erase cube 104 24 24 12\n"
        "place sphere 40 30 30 5 8\n"
        "place cube 140 34 130 3 11\n";
    const fs::path edits = dir_ / "edits.txt";
    write_file(edits, edit_text);
    // The tracer reading OpenCL's trees in place (path 2 here), and its own copy updated from
    // the host world ($VOXFIELD_TRACER_COPY).
    const fs::path shot = dir_ / "viewed.png", copied = dir_ / "viewed_copy.png";
    const fs::path saved = dir_ / "saved.vdb";
    for (const bool copy : {false, true}) {
        std::optional<ScopedEnv> env;
        if (copy) {
            env.emplace("VOXFIELD_TRACER_COPY", "1");
        }
        std::vector<std::string> args = {"view",
                                         world.string(),
                                         "--sparse",
                                         "--frames",
                                         "6",
                                         "--edits",
                                         edits.string(),
                                         "--shading",
                                         "flat",
                                         "--width",
                                         "160",
                                         "--height",
                                         "120",
                                         "--screenshot",
                                         (copy ? copied : shot).string()};
        if (!copy) {
            args.insert(args.end(), {"--world-output", saved.string()});
        }
        const int code = run_under_xvfb(args, io_ / "xvfb.log");
        const std::string log = read_text(io_ / "xvfb.log");
        ASSERT_EQ(code, 0) << log;
        EXPECT_NE(log.find("window:"), std::string::npos) << log;
        EXPECT_NE(log.find("edits 4"), std::string::npos) << log;
        EXPECT_NE(log.find(copy ? "sharing: path 3" : "sharing: path 2"), std::string::npos) << log;
    }
    EXPECT_EQ(read_text(shot), read_text(copied)) << "the shared and copied trees' frames differ";

    for (const Brush& b : {Brush{BrushOp::paint, BrushShape::sphere, {60, 10, 70}, 12, 3},
                           Brush{BrushOp::erase, BrushShape::cube, {104, 24, 24}, 12, 0},
                           Brush{BrushOp::place, BrushShape::sphere, {40, 30, 30}, 5, 8},
                           Brush{BrushOp::place, BrushShape::cube, {140, 34, 130}, 3, 11}}) {
        apply_brush(w, b);
    }
    // --world-output wrote the edited world (and its field) as .vdb grids.
    expect_vdb_world(saved, w);
    const fs::path edited = write_world(w, dir_ / "edited.npy");
    const fs::path rendered = dir_ / "rendered.png";
    // The edits keep the solids' box, so render's default camera is the viewer's.
    const RunResult r =
        run_voxfield({"render", edited.string(), "--sparse", "-o", rendered.string(), "--width",
                      "160", "--height", "120", "--shading", "flat"},
                     io_);
    ASSERT_EQ(r.code, 0) << describe(r);
    EXPECT_EQ(read_text(shot), read_text(rendered)) << "the window's frame differs from render's";
}

// --simulate on a sparse world: after 9 frames (9 steps of the automaton with --seed) the
// window's screenshot equals `render --sparse` of the world stepped 9 times by the CPU
// reference. A .vox keeps its palette in both; a floor and a pillar fix the solids' box, so
// that both default cameras agree.
TEST_F(ViewSparse, SimulatedWindowEqualsRenderOfTheSteppedWorld) {
    if (!have_xvfb()) {
        GTEST_SKIP() << "xvfb-run is not installed (setup.sh installs it)";
    }
    const SandRules rules;
    World w(Dims{90, 70, 80});
    for (std::uint32_t z = 0; z < 80; ++z) {
        for (std::uint32_t x = 0; x < 90; ++x) {
            w.set(x, 0, z, 1);
        }
    }
    for (std::uint32_t y = 0; y < 70; ++y) {
        w.set(89, y, 79, 1);
    }
    for (std::uint32_t z = 20; z < 40; ++z) {
        for (std::uint32_t y = 30; y < 50; ++y) {
            for (std::uint32_t x = 10; x < 30; ++x) {
                w.set(x, y, z, rules.sand);
                w.set(x + 40, y - 20, z + 20, rules.water);
            }
        }
    }
    const Palette palette = Palette::magicavoxel_default();
    const fs::path world = dir_ / "world.vox";
    write_vox(world, w, palette);
    const fs::path shot = dir_ / "viewed.png";
    const int code = run_under_xvfb(
        {"view", world.string(), "--sparse", "--simulate", "--seed", "5", "--frames", "9",
         "--shading", "flat", "--width", "160", "--height", "120", "--screenshot", shot.string()},
        io_ / "xvfb.log");
    const std::string log = read_text(io_ / "xvfb.log");
    ASSERT_EQ(code, 0) << log;
    EXPECT_NE(log.find("sand steps 9"), std::string::npos) << log;
    for (std::uint64_t step = 0; step < 9; ++step) {
        sand_step(w, rules, 5, step);
    }
    const fs::path stepped = dir_ / "stepped.vox", rendered = dir_ / "rendered.png";
    write_vox(stepped, w, palette);
    const RunResult r =
        run_voxfield({"render", stepped.string(), "--sparse", "-o", rendered.string(), "--width",
                      "160", "--height", "120", "--shading", "flat"},
                     io_);
    ASSERT_EQ(r.code, 0) << describe(r);
    EXPECT_EQ(read_text(shot), read_text(rendered)) << "the window's frame differs from render's";
}

// The script's click at the crosshair places the brush aimed at on the sparse world (picking
// through SparseWorld::at), a right click erases; the script's shading select applies.
TEST_F(ViewSparse, ScriptedClicksEditTheSparseWorld) {
    if (!have_xvfb()) {
        GTEST_SKIP() << "xvfb-run is not installed (setup.sh installs it)";
    }
    const fs::path world = write_world(test_world(), dir_ / "world.npy");
    const fs::path script = dir_ / "script.txt";
    // The script saves after its edits (STEM.vdb), as --world-output does at exit.
    const fs::path stem = dir_ / "scripted";
    write_file(script, "1 select shading flat\n2 click left\n4 click right\n6 key F2\n7 save " +
                           stem.string() + "\n7 quit\n");
    const fs::path shot = dir_ / "shot.png", at_exit = dir_ / "at_exit.vdb";
    const int code = run_under_xvfb(
        {"view", world.string(), "--sparse", "--script", script.string(), "--width", "200",
         "--height", "150", "--screenshot", shot.string(), "--world-output", at_exit.string()},
        io_ / "xvfb.log");
    const std::string log = read_text(io_ / "xvfb.log");
    ASSERT_EQ(code, 0) << log;
    EXPECT_NE(log.find("frames:  8, edits 2"), std::string::npos) << log;
    EXPECT_NE(log.find("saved " + stem.string() + ".vdb"), std::string::npos) << log;
    EXPECT_EQ(read_text(shot).substr(1, 3), "PNG");
    const SparseWorld scripted = read_vdb_sparse(stem.string() + ".vdb", "");
    const SparseWorld exited = read_vdb_sparse(at_exit, "");
    ASSERT_EQ(scripted.dims(), exited.dims());
    EXPECT_EQ(scripted.to_dense().voxels(), exited.to_dense().voxels());
    World original = test_world();
    EXPECT_NE(scripted.to_dense().voxels(), original.voxels()) << "the clicks changed nothing";

    // What a sparse world does not take from a script: one line, exit 2.
    write_file(script, "1 click left\n3 select algorithm fim\n");
    EXPECT_EQ(run_under_xvfb({"view", world.string(), "--sparse", "--script", script.string()},
                             io_ / "refused.log"),
              2);
    EXPECT_NE(read_text(io_ / "refused.log").find("--script line 2"), std::string::npos)
        << read_text(io_ / "refused.log");
}

TEST_F(ViewSparse, HeadlessBenchmarkOnTheCityRecordsEditsAndTiles) {
    const fs::path json = dir_ / "bench.json";
    const RunResult r =
        run_voxfield({"view", "--scene", "city", "--dims", "200,96,200", "--sparse", "--benchmark",
                      "--duration-s", "1.5", "--interval-ms", "40", "--width", "64", "--height",
                      "48", "--max-distance", "6", "--json", json.string()},
                     io_);
    ASSERT_EQ(r.code, 0) << describe(r);
    EXPECT_NE(r.out.find("benchmark runs headless"), std::string::npos) << r.out;
    EXPECT_NE(r.out.find("benchmark: sparse"), std::string::npos) << r.out;
    const nlohmann::json j = nlohmann::json::parse(read_text(json));
    EXPECT_EQ(j.at("world"), nlohmann::json({200, 96, 200}));
    EXPECT_EQ(j.at("present"), "headless");
    EXPECT_EQ(j.at("source"), "scene city");
    const nlohmann::json& s = j.at("sparse");
    EXPECT_GT(s.at("tiles").get<int>(), 0);
    EXPECT_EQ(s.at("max_distance").get<double>(), 6.0);
    EXPECT_EQ(s.at("format"), "u8");
    EXPECT_GT(s.at("field_tiles").get<int>(), 0);
    // PoCL and lavapipe share host memory (path 2): the tracer reads OpenCL's trees in place.
    EXPECT_EQ(s.at("tracer_sharing").get<std::string>().rfind("path 2", 0), 0u)
        << s.at("tracer_sharing");
    EXPECT_GE(s.at("tracer_shared_bytes").get<std::uint64_t>(),
              s.at("world_bytes").get<std::uint64_t>() / 2);
    EXPECT_LT(s.at("tracer_bytes").get<std::uint64_t>(),
              s.at("world_bytes").get<std::uint64_t>() / 4);
    ASSERT_GE(j.at("edits").size(), 1u);
    std::uint64_t written = 0;
    for (const nlohmann::json& e : j.at("edits")) {
        EXPECT_TRUE(e.at("benchmark").get<bool>());
        EXPECT_GE(e.at("wall_ms").get<double>(), e.at("tracer_ms").get<double>());
        EXPECT_FALSE(e.at("tracer_whole").get<bool>());
        written += e.at("tiles_written").get<std::uint64_t>();
    }
    EXPECT_GT(written, 0u);
    EXPECT_EQ(j.at("tiles_written").get<std::uint64_t>(), written);
    EXPECT_EQ(j.at("frames").size(), j.at("summary").at("frame").at("n").get<std::size_t>());
    for (const char* key : {"edit", "edit_frame", "readback", "tracer_update", "raymarch"}) {
        EXPECT_TRUE(j.at("summary").contains(key)) << key;
    }
}

// Ctrl+Z and Ctrl+Y on a sparse world (the history kept on the OpenCL device): two clicks undone
// give back the world as it was, pixel for pixel and voxel for voxel; redone, the world of the
// clicks; nothing left to undo says so.
TEST_F(ViewSparse, UndoAndRedoOnTheDevice) {
    if (!have_xvfb()) {
        GTEST_SKIP() << "xvfb-run is not installed (setup.sh installs it)";
    }
    const World original = test_world();
    const fs::path world = write_world(original, dir_ / "world.npy");
    const fs::path script = dir_ / "script.txt";
    const auto view = [&](const std::string& text, const fs::path& shot, const fs::path& out) {
        write_file(script, text);
        const int code = run_under_xvfb(
            {"view", world.string(), "--sparse", "--script", script.string(), "--width", "200",
             "--height", "150", "--screenshot", shot.string(), "--world-output", out.string()},
            io_ / "xvfb.log");
        const std::string log = read_text(io_ / "xvfb.log");
        EXPECT_EQ(code, 0) << log;
        return log;
    };
    const std::string clicks = "1 select shading flat\n2 click left\n4 click right\n";
    // The clicks, undone twice (and once more, with nothing left).
    const fs::path undone_shot = dir_ / "undone.png", undone = dir_ / "undone.vdb";
    const std::string log =
        view(clicks + "6 key ctrl+z\n8 key ctrl+z\n10 key ctrl+z\n12 quit\n", undone_shot, undone);
    EXPECT_NE(log.find("nothing to undo"), std::string::npos) << log;
    expect_vdb_world(undone, original);
    // The same view without clicks.
    const fs::path plain_shot = dir_ / "plain.png", plain = dir_ / "plain.vdb";
    view("1 select shading flat\n12 quit\n", plain_shot, plain);
    EXPECT_EQ(read_text(undone_shot), read_text(plain_shot)) << "the undone frame differs";
    // Undone and redone: the clicks' world.
    const fs::path clicked_shot = dir_ / "clicked.png", clicked = dir_ / "clicked.vdb";
    view(clicks + "12 quit\n", clicked_shot, clicked);
    const fs::path redone_shot = dir_ / "redone.png", redone = dir_ / "redone.vdb";
    // (Keys a frame apart: a key held over consecutive frames is pressed once.)
    view(clicks + "6 key ctrl+z\n8 key ctrl+z\n10 key ctrl+y\n12 key ctrl+y\n14 quit\n",
         redone_shot, redone);
    const SparseWorld a = read_vdb_sparse(clicked, ""), b = read_vdb_sparse(redone, "");
    ASSERT_EQ(a.dims(), b.dims());
    EXPECT_EQ(a.to_dense().voxels(), b.to_dense().voxels());
    EXPECT_NE(a.to_dense().voxels(), SparseWorld::from_dense(original).to_dense().voxels());
    EXPECT_EQ(read_text(clicked_shot), read_text(redone_shot)) << "the redone frame differs";
}

// Two 4^3 cubes 600000 voxels apart in a .vdb grid: 1.2e12 voxels, viewed sparse unasked.
TEST_F(ViewSparse, HugeGridGoesSparseWithoutTheFlag) {
    const fs::path grid = io_ / "far.vdb";
    write_far_cubes_vdb(grid);
    const fs::path out = dir_ / "far.png";
    const RunResult r = run_voxfield({"view", grid.string(), "--width", "64", "--height", "48",
                                      "--max-distance", "4", "--fallback-png", out.string()},
                                     io_);
    ASSERT_EQ(r.code, 0) << describe(r);
    EXPECT_NE(r.out.find("600004x4x500004 (sparse): 2 tiles of 64^3, 128 solid"), std::string::npos)
        << r.out;
    EXPECT_EQ(read_text(out).substr(1, 3), "PNG");
}

TEST_F(ViewSparse, WhatSparseWorldsRefuseExitsTwo) {
    const std::vector<std::vector<std::string>> refused = {
        {"view", "--scene", "city", "--world", "64", "--sparse", "--benchmark", "--world-output",
         (dir_ / "w.npy").string()},
        {"view", "--scene", "city", "--world", "64", "--sparse", "--benchmark", "--field-output",
         (dir_ / "f.npy").string()},
        {"view", "--scene", "city", "--world", "64", "--sparse", "--benchmark", "--present", "gpu"},
        {"view", "--scene", "spheres", "--dims", "70000,8,70000", "--benchmark"},
        {"view", "--scene", "city", "--dims", "2000000,8,8", "--benchmark"}};
    for (const auto& args : refused) {
        const RunResult r = run_voxfield(args, io_);
        EXPECT_EQ(r.code, 2) << describe(r);
        EXPECT_EQ(std::count(r.err.begin(), r.err.end(), '\n'), 1) << describe(r);
    }
    EXPECT_TRUE(list_dir(dir_).empty());
}

}  // namespace
}  // namespace voxfield::test
