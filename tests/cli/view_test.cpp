// `voxfield view` end to end: the no-display path, the headless benchmark, and a smoke test
// of the window under Xvfb + lavapipe (skipped, with CTest's skip, only without xvfb-run).
#include <gtest/gtest.h>

#include <nlohmann/json.hpp>

#include <algorithm>
#include <cstdlib>
#include <filesystem>
#include <regex>
#include <string>
#include <utility>
#include <vector>

#include "cli_test_util.hpp"
#include "voxfield/core/brush.hpp"
#include "voxfield/core/npy.hpp"
#include "voxfield/core/scenes.hpp"
#include "voxfield/core/undo.hpp"
#include "voxfield/core/world.hpp"

#define STB_IMAGE_IMPLEMENTATION
#define STB_IMAGE_STATIC
#include <stb/stb_image.h>

namespace voxfield::test {
namespace {

// The pixels of the PNG at `path` that are not black; 0 (with a failure) when it cannot be read
// or is not width x height.
std::size_t non_black_pixels(const fs::path& path, int width, int height) {
    int iw = 0, ih = 0, channels = 0;
    unsigned char* px = stbi_load(path.c_str(), &iw, &ih, &channels, 4);
    if (px == nullptr || iw != width || ih != height) {
        ADD_FAILURE() << path << ": not a " << width << "x" << height << " PNG (" << iw << "x" << ih
                      << ")";
        stbi_image_free(px);
        return 0;
    }
    std::size_t n = 0;
    for (int i = 0; i < iw * ih; ++i) {
        n += (px[4 * i] != 0 || px[4 * i + 1] != 0 || px[4 * i + 2] != 0) ? 1 : 0;
    }
    stbi_image_free(px);
    return n;
}

class ViewTest : public TempDirsTest {
  protected:
    ViewTest() : TempDirsTest("voxfield_view_test") {}
    void check_shot_and_field(const fs::path& world, const fs::path& edits,
                              const std::string& format, const fs::path& shot,
                              const fs::path& field);
    HeadlessViewerEnv env_;
};

TEST_F(ViewTest, NoDisplaySaysSoInOneLineAndSuggestsRender) {
    const RunResult r = run_voxfield({"view", "--world", "16"}, io_);
    EXPECT_EQ(r.code, 2) << describe(r);
    const auto lines = split_lines(r.err);
    ASSERT_EQ(lines.size(), 1u) << describe(r);
    EXPECT_NE(lines[0].find("no display"), std::string::npos) << lines[0];
    EXPECT_NE(lines[0].find("voxfield render"), std::string::npos) << lines[0];
    EXPECT_TRUE(r.out.empty()) << describe(r);
}

TEST_F(ViewTest, UnreachableDisplayIsNoDisplayToo) {
    ::setenv("DISPLAY", ":4711", 1);  // no X server there
    const RunResult r = run_voxfield({"view", "--world", "16"}, io_);
    ::unsetenv("DISPLAY");
    EXPECT_EQ(r.code, 2) << describe(r);
    const auto lines = split_lines(r.err);
    ASSERT_EQ(lines.size(), 1u) << describe(r);
    EXPECT_NE(lines[0].find("no display"), std::string::npos) << lines[0];
    EXPECT_NE(lines[0].find("voxfield render"), std::string::npos) << lines[0];
}

TEST_F(ViewTest, FallbackPngRendersOneFrameHeadless) {
    const fs::path shot = dir_ / "fallback.png";
    const RunResult r =
        run_voxfield({"view", "--world", "24", "--scene", "terrain", "--shading", "flat", "--width",
                      "80", "--height", "60", "--fallback-png", shot.string()},
                     io_);
    ASSERT_EQ(r.code, 0) << describe(r);
    EXPECT_NE(r.out.find("no display"), std::string::npos) << r.out;
    EXPECT_NE(r.out.find("screenshot " + shot.string()), std::string::npos) << r.out;
    // Flat shading, black sky: lit pixels are voxels.
    EXPECT_GT(non_black_pixels(shot, 80, 60), 80u * 60 / 20) << "the fallback image is all sky";
}

TEST_F(ViewTest, FirstFrameEqualsRender) {
    // The viewer's pipeline (IncrementalField, the render field written in place) and
    // `render`'s (the exact generator) show a model identically from the same default camera.
    const fs::path model = fs::path(VOXFIELD_DATA_DIR) / "vox" / "chr_army1.vox";
    const fs::path viewed = dir_ / "viewed.png", rendered = dir_ / "rendered.png";
    RunResult r = run_voxfield({"view", model.string(), "--width", "120", "--height", "90",
                                "--fallback-png", viewed.string()},
                               io_);
    ASSERT_EQ(r.code, 0) << describe(r);
    r = run_voxfield({"render", model.string(), "-o", rendered.string(), "--width", "120",
                      "--height", "90", "--shading", "lit"},
                     io_);
    ASSERT_EQ(r.code, 0) << describe(r);
    EXPECT_EQ(read_text(viewed), read_text(rendered)) << "the PNGs differ";
}

TEST_F(ViewTest, BadUsageIsCheckedFirst) {
    RunResult r = run_voxfield({"view", "--world", "16", "--dims", "4,4,4"}, io_);
    EXPECT_EQ(r.code, 2) << describe(r);
    EXPECT_NE(r.err.find("not both"), std::string::npos) << describe(r);
    r = run_voxfield({"view", "--algorithm", "nope"}, io_);
    EXPECT_EQ(r.code, 2) << describe(r);
    r = run_voxfield({"view", "--edits", (dir_ / "missing.txt").string()}, io_);
    EXPECT_EQ(r.code, 2) << describe(r);
    // A scaled field is drawn through voxel steps (its distances divided by the largest
    // spacing, rounded down): the same first frame as the unit field's.
    const fs::path spaced = dir_ / "s.png", unit = dir_ / "u.png";
    for (const auto& [png, spacing] : {std::pair{spaced, "2,1,0.5"}, std::pair{unit, "1,1,1"}}) {
        r = run_voxfield({"view", "--world", "16", "--spacing", spacing, "--shading", "flat",
                          "--width", "48", "--height", "32", "--fallback-png", png.string()},
                         io_);
        EXPECT_EQ(r.code, 0) << describe(r);
    }
    EXPECT_EQ(read_text(spaced), read_text(unit));
}

TEST_F(ViewTest, HeadlessBenchmarkIsReproducibleAndRecorded) {
    const fs::path json = dir_ / "b.json", csv = dir_ / "b.csv";
    const RunResult r =
        run_voxfield({"view", "--world", "32", "--benchmark", "--seed", "7", "--interval-ms", "50",
                      "--duration-s", "1", "--width", "96", "--height", "64", "--json",
                      json.string(), "--csv", csv.string()},
                     io_);
    ASSERT_EQ(r.code, 0) << describe(r);
    EXPECT_NE(r.out.find("headless"), std::string::npos) << r.out;
    EXPECT_NE(r.out.find("95% CI"), std::string::npos) << r.out;
    const auto j = nlohmann::json::parse(read_text(json));
    EXPECT_EQ(j["seed"], 7);
    EXPECT_EQ(j["present"], "headless");
    const auto& frames = j["frames"];
    ASSERT_GT(frames.size(), 2u);
    std::size_t edits = 0;
    for (const auto& f : frames) {
        EXPECT_GE(f["frame_ms"].get<double>(), f["update_ms"].get<double>());
        edits += f["edit"].get<bool>() ? 1 : 0;
    }
    EXPECT_GE(edits, 1u);
    EXPECT_EQ(j["summary"]["field_update"]["n"], edits);
    EXPECT_EQ(j["summary"]["frame"]["n"], frames.size());
    EXPECT_EQ(split_lines(read_text(csv)).size(), frames.size() + 1);
    // The editing protocol's harness (shared with bench --suite edits): each edit is core's
    // RandomEdits for this seed, recorded with bench's per-edit keys.
    ASSERT_EQ(j["edits"].size(), edits);
    RandomEdits protocol(Dims{32, 32, 32}, 16, 7);
    for (const auto& e : j["edits"]) {
        const Brush b = protocol.next();
        EXPECT_EQ(e["op"], to_string(b.op));
        EXPECT_EQ(e["centre"], nlohmann::json({b.centre.x, b.centre.y, b.centre.z}));
        EXPECT_EQ(e["radius"], b.radius);
        EXPECT_EQ(e["size"], protocol.last_size());
        for (const char* key : {"material", "update_ms", "voxels_recomputed", "voxels_changed",
                                "full_regeneration"}) {
            EXPECT_TRUE(e.contains(key)) << key;
        }
    }
}

TEST_F(ViewTest, BenchmarkEditsLeaveTheFieldAFreshGenerationWouldGive) {
    // The viewer's loop (random spheres through IncrementalField, the render field written in
    // place) ends with the field `generate` computes from the final world.
    for (const std::vector<std::string>& algorithm :
         {std::vector<std::string>{"--algorithm", "exact"},
          std::vector<std::string>{"--algorithm", "lod", "--chunk", "8"}}) {
        SCOPED_TRACE(algorithm[1]);
        const fs::path world = dir_ / "w.npy", field = dir_ / "f.npy", fresh = dir_ / "g.npy";
        std::vector<std::string> args = {"view",
                                         "--world",
                                         "32",
                                         "--benchmark",
                                         "--seed",
                                         "3",
                                         "--interval-ms",
                                         "10",
                                         "--duration-s",
                                         "1.5",
                                         "--width",
                                         "32",
                                         "--height",
                                         "24",
                                         "--world-output",
                                         world.string(),
                                         "--field-output",
                                         field.string()};
        args.insert(args.end(), algorithm.begin(), algorithm.end());
        RunResult r = run_voxfield(args, io_);
        ASSERT_EQ(r.code, 0) << describe(r);
        std::smatch m;
        ASSERT_TRUE(std::regex_search(r.out, m, std::regex(" (\\d+) edits,"))) << r.out;
        EXPECT_GE(std::stoi(m[1]), 1) << r.out;
        std::vector<std::string> gen = {"generate", world.string(), "-o", fresh.string()};
        gen.insert(gen.end(), algorithm.begin(), algorithm.end());
        r = run_voxfield(gen, io_);
        ASSERT_EQ(r.code, 0) << describe(r);
        const auto got = read_npy(field), want = read_npy(fresh);
        EXPECT_EQ(got.dims, want.dims);
        EXPECT_TRUE(got.data == want.data) << "the viewer's field differs from a fresh one";
    }
}

TEST_F(ViewTest, SimulateStepsTheSandEveryFrameAndKeepsTheFieldExact) {
    // `--simulate` on the sand scene, no edits (an interval past the run), six frames (not a
    // duration: a loaded machine may not reach three frames in a second): every frame steps
    // the automaton; the final world conserves sand and water, and the final field is the one
    // `generate` computes from it.
    const fs::path json = dir_ / "s.json", world = dir_ / "w.npy", field = dir_ / "f.npy",
                   fresh = dir_ / "g.npy";
    RunResult r = run_voxfield({"view",
                                "--world",
                                "32",
                                "--scene",
                                "sand",
                                "--simulate",
                                "--benchmark",
                                "--seed",
                                "5",
                                "--interval-ms",
                                "100000",
                                "--duration-s",
                                "60",
                                "--frames",
                                "6",
                                "--width",
                                "48",
                                "--height",
                                "32",
                                "--json",
                                json.string(),
                                "--world-output",
                                world.string(),
                                "--field-output",
                                field.string()},
                               io_);
    ASSERT_EQ(r.code, 0) << describe(r);
    EXPECT_NE(r.out.find("sand simulation (device)"), std::string::npos) << r.out;
    const auto j = nlohmann::json::parse(read_text(json));
    EXPECT_TRUE(j["simulate"].get<bool>());
    const auto& frames = j["frames"];
    ASSERT_GT(frames.size(), 2u);
    std::size_t moved = 0;
    for (const auto& f : frames) {
        ASSERT_FALSE(f["simulate_ms"].is_null());
        moved += f["sand_voxels_changed"].get<std::size_t>();
    }
    EXPECT_GT(moved, 0u);
    EXPECT_EQ(j["summary"]["simulate"]["n"], frames.size());
    const World start = make_scene("sand", Dims{32, 32, 32}, 6683787);
    const NpyArray end = read_npy(world);
    for (const std::uint8_t material : {std::uint8_t{2}, std::uint8_t{3}}) {
        EXPECT_EQ(std::count(end.data.begin(), end.data.end(), material),
                  std::count(start.voxels().begin(), start.voxels().end(), material))
            << "material " << int{material};
    }
    r = run_voxfield({"generate", world.string(), "-o", fresh.string()}, io_);
    ASSERT_EQ(r.code, 0) << describe(r);
    EXPECT_TRUE(read_npy(field).data == read_npy(fresh).data)
        << "the viewer's field differs from a fresh one";
}

TEST_F(ViewTest, SmokeUnderXvfbShowsTheWorldAndFollowsEdits) {
    if (!have_xvfb()) {
        GTEST_SKIP() << "xvfb-run is not installed (setup.sh installs it)";
    }
    // A 40x24x40 world: a floor and a pillar, palette index 1 (white in MagicaVoxel's).
    World w(Dims{40, 24, 40});
    for (std::uint32_t z = 0; z < 40; ++z) {
        for (std::uint32_t x = 0; x < 40; ++x) {
            w.set(x, 0, z, 1);
        }
    }
    for (std::uint32_t y = 0; y < 12; ++y) {
        w.set(20, y, 20, 2);
    }
    const fs::path world = dir_ / "world.npy";
    const NpyArray a = npy_from_world(w);
    write_npy(world, a.type, a.dims, a.data);
    const fs::path edits = dir_ / "edits.txt";
    write_file(edits, "place sphere 10 6 10 4 3\nerase cube 30 0 30 3\npaint sphere 20 5 20 3 7\n");

    // The field kept on the OpenCL device in u16 (the default) and in packed32: both are
    // converted into the render field the ray marcher reads in place (sharing path 2 here).
    for (const std::string format : {"u16", "packed32"}) {
        SCOPED_TRACE(format);
        const fs::path shot = dir_ / ("shot_" + format + ".png");
        const fs::path field = dir_ / ("view_field_" + format + ".npy");
        const int code = run_under_xvfb(
            {"view", world.string(), "--frames", "6", "--edits", edits.string(), "--shading",
             "flat", "--width", "160", "--height", "120", "--format", format, "--screenshot",
             shot.string(), "--field-output", field.string()},
            io_ / "xvfb.log");
        const std::string log = read_text(io_ / "xvfb.log");
        ASSERT_EQ(code, 0) << log;
        EXPECT_NE(log.find("window:"), std::string::npos) << log;
        EXPECT_NE(log.find("sharing: path 2"), std::string::npos) << log;
        check_shot_and_field(world, edits, format, shot, field);
    }
}

// `view --script` drives the real window under Xvfb: a click places, Ctrl+Z / Ctrl+Y undo and
// redo it, a palette colour paints, the overlay's algorithm and metric switches rebuild the
// field (a refused one changes nothing and says why), F2 opens the full panel, the wheel sizes
// the brush, `save` writes the world. After each step the world, the field (equal to what
// `generate` gives for that world and those options) and the overlay's state are checked.
TEST_F(ViewTest, ScriptDrivesEditsUndoSwitchesPaletteAndSaving) {
    if (!have_xvfb()) {
        GTEST_SKIP() << "xvfb-run is not installed (setup.sh installs it)";
    }
    const std::string d = dir_.string() + "/";
    const fs::path script = dir_ / "script.txt";
    write_file(script,
               "# a scripted session\n"
               "0 check " +
                   d +
                   "a\n"
                   "1 key F2\n"
                   "2 click left\n"
                   "3 check " +
                   d +
                   "b\n"
                   "4 key ctrl+z\n"
                   "5 check " +
                   d +
                   "c\n"
                   "6 key ctrl+y\n"
                   "7 check " +
                   d +
                   "d\n"
                   "8 select colour 7\n"
                   "8 key P\n"
                   "9 click left\n"
                   "10 check " +
                   d +
                   "e\n"
                   "11 select algorithm fim\n"
                   "12 check " +
                   d +
                   "f\n"
                   "13 select metric euclidean   # fim is manhattan only: refused\n"
                   "14 check " +
                   d +
                   "g\n"
                   "15 select algorithm exact\n"
                   "15 select metric euclidean\n"
                   "15 scroll 3\n"
                   "16 check " +
                   d +
                   "h\n"
                   "17 save " +
                   d +
                   "saved\n"
                   "18 quit\n"
                   "40 check " +
                   d + "never\n");
    const int code = run_under_xvfb({"view", "--world", "48", "--scene", "terrain", "--width",
                                     "160", "--height", "120", "--script", script.string()},
                                    io_ / "xvfb.log");
    const std::string log = read_text(io_ / "xvfb.log");
    ASSERT_EQ(code, 0) << log;
    EXPECT_NE(log.find("frames:  19"), std::string::npos) << log;
    EXPECT_FALSE(fs::exists(dir_ / "never-state.json"));

    const auto state = [&](const std::string& stem) {
        return nlohmann::json::parse(read_text(dir_ / (stem + "-state.json")));
    };
    const auto world = [&](const std::string& stem) {
        return read_npy(dir_ / (stem + "-world.npy")).data;
    };
    const auto solids = [](const std::vector<std::uint8_t>& w) {
        return static_cast<std::size_t>(
            std::count_if(w.begin(), w.end(), [](std::uint8_t v) { return v != 0; }));
    };
    // The field of each check equals generate's for that world and the state's options.
    const auto check_field = [&](const std::string& stem, const std::vector<std::string>& opts) {
        SCOPED_TRACE(stem);
        const fs::path field = dir_ / (stem + "-generated.npy");
        std::vector<std::string> args = {"generate", (dir_ / (stem + "-world.npy")).string(),
                                         "-o",       field.string(),
                                         "--format", "u16",
                                         "--device", "cpu"};
        args.insert(args.end(), opts.begin(), opts.end());
        const RunResult r = run_voxfield(args, io_);
        ASSERT_EQ(r.code, 0) << describe(r);
        EXPECT_EQ(read_npy(dir_ / (stem + "-field.npy")).data, read_npy(field).data);
    };

    const auto a = state("a");
    EXPECT_EQ(a["frame"], 0);
    EXPECT_EQ(a["panel"], "compact");
    EXPECT_EQ(a["algorithm"], "exact");
    EXPECT_EQ(a["metric"], "manhattan");
    check_field("a", {});

    const auto b = state("b");  // placed at the crosshair
    EXPECT_EQ(b["panel"], "full");
    EXPECT_EQ(b["undo"], 1);
    EXPECT_GT(solids(world("b")), solids(world("a")));
    EXPECT_EQ(b["solid_voxels"], solids(world("b")));
    check_field("b", {});

    const auto c = state("c");  // undone
    EXPECT_EQ(c["undo"], 0);
    EXPECT_EQ(c["redo"], 1);
    EXPECT_EQ(world("c"), world("a"));
    EXPECT_EQ(read_npy(dir_ / "c-field.npy").data, read_npy(dir_ / "a-field.npy").data);

    EXPECT_EQ(world("d"), world("b"));  // redone
    EXPECT_EQ(read_npy(dir_ / "d-field.npy").data, read_npy(dir_ / "b-field.npy").data);

    const auto e = state("e");  // colour 7 painted: same solids, some of them now 7
    EXPECT_TRUE(e["paint_mode"].get<bool>());
    EXPECT_EQ(e["brush"]["material"], 7);
    const std::vector<std::uint8_t> we = world("e"), wd = world("d");
    EXPECT_EQ(solids(we), solids(wd));
    EXPECT_GT(std::count(we.begin(), we.end(), 7), std::count(wd.begin(), wd.end(), 7));
    check_field("e", {});

    const auto f = state("f");
    EXPECT_EQ(f["algorithm"], "fim");
    EXPECT_EQ(f["field_algorithm"], "fim");
    EXPECT_EQ(f["chunk"], 16);
    EXPECT_EQ(f["undo"], 0);  // a new field starts a new history
    check_field("f", {"--algorithm", "fim", "--chunk", "16"});

    const auto g = state("g");  // refused: nothing changed, the overlay says why
    EXPECT_NE(g["switch_error"].get<std::string>().find("euclidean"), std::string::npos) << g;
    EXPECT_EQ(g["field_algorithm"], "fim");
    EXPECT_EQ(g["metric"], "manhattan");
    EXPECT_EQ(read_npy(dir_ / "g-field.npy").data, read_npy(dir_ / "f-field.npy").data);

    const auto h = state("h");
    EXPECT_EQ(h["field_algorithm"], "exact");
    EXPECT_EQ(h["field_metric"], "euclidean");
    EXPECT_EQ(h["switch_error"], "");
    EXPECT_EQ(h["brush"]["size"], 8);  // 5 + 3 notches
    check_field("h", {"--metric", "euclidean"});

    EXPECT_EQ(read_npy(dir_ / "saved.npy").data, world("h"));
    EXPECT_TRUE(fs::exists(dir_ / "saved.vox"));
}

// A script that cannot be read or parsed is refused before any window opens (exit 2, the
// line named).
TEST_F(ViewTest, BadScriptIsAnInputError) {
    const fs::path script = dir_ / "bad.txt";
    for (const std::string bad : {"0 key NOSUCHKEY\n", "x key A\n", "0 select algorithm magic\n",
                                  "0 mouse 1\n", "0 jump\n", "0 select colour 300\n"}) {
        write_file(script, "# fine\n" + bad);
        const RunResult r =
            run_voxfield({"view", "--world", "16", "--script", script.string()}, io_);
        EXPECT_EQ(r.code, 2) << bad << describe(r);
        EXPECT_NE(r.err.find("script line 2"), std::string::npos) << bad << describe(r);
    }
    const RunResult missing =
        run_voxfield({"view", "--world", "16", "--script", (dir_ / "none.txt").string()}, io_);
    EXPECT_EQ(missing.code, 2) << describe(missing);
    EXPECT_NE(missing.err.find("cannot read script"), std::string::npos) << describe(missing);
}

TEST_F(ViewTest, WindowShowsTheRayMarchedImage) {
    if (!have_xvfb()) {
        GTEST_SKIP() << "xvfb-run is not installed (setup.sh installs it)";
    }
    // What the swapchain showed (ray-marched on the one device that also presents, which
    // lavapipe under Xvfb can: auto and gpu; or through the host) equals the ray-marched
    // image, away from the overlay (its panel is at the top left, the crosshair and brush
    // preview at the centre). Lit shading: the sky gradient and shaded voxels have R != B, so
    // a byte-order slip shows.
    for (const std::string present : {"auto", "gpu", "host"}) {
        SCOPED_TRACE(present);
        const fs::path shot = dir_ / "marched.png", window = dir_ / "window.png";
        const int code =
            run_under_xvfb({"view", "--world", "48", "--scene", "terrain", "--frames", "1",
                            "--width", "1024", "--height", "768", "--screenshot", shot.string(),
                            "--window-screenshot", window.string(), "--present", present},
                           io_ / "xvfb.log", "1024x768x24");
        const std::string log = read_text(io_ / "xvfb.log");
        ASSERT_EQ(code, 0) << log;
        EXPECT_NE(log.find(present == "host" ? "through the host" : "window:  "), std::string::npos)
            << log;
        if (present != "host") {
            EXPECT_NE(log.find("one device: frames stay on the GPU"), std::string::npos) << log;
        }
        int w1 = 0, h1 = 0, w2 = 0, h2 = 0, c = 0;
        unsigned char* a = stbi_load(shot.c_str(), &w1, &h1, &c, 4);
        unsigned char* b = stbi_load(window.c_str(), &w2, &h2, &c, 4);
        ASSERT_NE(a, nullptr);
        ASSERT_NE(b, nullptr);
        EXPECT_EQ(w1, 1024);
        EXPECT_EQ(h1, 768);
        EXPECT_EQ(w2, w1);
        EXPECT_EQ(h2, h1);
        std::size_t compared = 0, differ = 0, coloured = 0;
        // Right of the overlay (top left; even the full panel, F2, is about 640 pixels wide and
        // 440 high) and below the centre.
        for (int y = h1 * 5 / 8; y < h1 && w2 == w1 && h2 == h1; ++y) {
            for (int x = w1 * 11 / 16; x < w1; ++x) {
                const int i = 4 * (y * w1 + x);
                ++compared;
                differ += (a[i] != b[i] || a[i + 1] != b[i + 1] || a[i + 2] != b[i + 2]) ? 1 : 0;
                coloured += a[i] != a[i + 2] ? 1 : 0;
            }
        }
        stbi_image_free(a);
        stbi_image_free(b);
        EXPECT_GT(compared, 0u);
        EXPECT_EQ(differ, 0u) << "of " << compared << " pixels";
        EXPECT_GT(coloured, compared / 2)
            << "the compared region is grey: it cannot catch R/B swaps";
    }
}

TEST_F(ViewTest, OverlayShowsTheAlgorithmGiven) {
    if (!have_xvfb()) {
        GTEST_SKIP() << "xvfb-run is not installed (setup.sh installs it)";
    }
    // The overlay's algorithm list is in DESIGN §4 order, not the enum's: `--algorithm fim`
    // once showed (and "regenerate" switched to) fim-host. Every algorithm, under one server.
    const std::vector<std::string> algorithms = {
        "exact", "brute",    "brute-chunked", "fim", "fim-host",
        "jfa",   "jfa-host", "jfa-fim",       "lod", "monolithic"};
    std::string script;
    for (const std::string& a : algorithms) {
        script.append("'").append(kExe.string()).append("' view --world 16 --algorithm ");
        script.append(a).append(a == "exact" ? "" : " --chunk 8");
        script.append(" --frames 1 --width 64 --height 48 || exit 1; ");
    }
    const fs::path log = io_ / "xvfb.log";
    const std::string cmd =
        xvfb_run("640x480x24") + " sh -c \"" + script + "\" >'" + log.string() + "' 2>&1";
    const int status = std::system(cmd.c_str());
    const std::string out = read_text(log);
    ASSERT_TRUE(WIFEXITED(status) && WEXITSTATUS(status) == 0) << out;
    std::size_t at = 0;
    for (const std::string& a : algorithms) {
        const std::string want = "overlay: algorithm " + a + ", compact\n";
        const std::size_t found = out.find(want, at);
        EXPECT_NE(found, std::string::npos) << want << out;
        at = found == std::string::npos ? at : found + want.size();
    }
}

TEST_F(ViewTest, CompactOverlayCoversAtMost15PercentOfTheWindow) {
    if (!have_xvfb()) {
        GTEST_SKIP() << "xvfb-run is not installed (setup.sh installs it)";
    }
    // 1280x720: what the window showed differs from the ray-marched image only in the overlay
    // (the crosshair and brush preview aside, at the centre), whose bounding box must stay
    // within 15% of the window.
    const int w = 1280, h = 720;
    const fs::path shot = dir_ / "marched.png", window = dir_ / "window.png";
    const int code =
        run_under_xvfb({"view", "--world", "48", "--scene", "terrain", "--frames", "2", "--width",
                        std::to_string(w), "--height", std::to_string(h), "--screenshot",
                        shot.string(), "--window-screenshot", window.string()},
                       io_ / "xvfb.log", "1280x720x24");
    const std::string log = read_text(io_ / "xvfb.log");
    ASSERT_EQ(code, 0) << log;
    EXPECT_NE(log.find("overlay: algorithm exact, compact"), std::string::npos) << log;
    int w1 = 0, h1 = 0, w2 = 0, h2 = 0, c = 0;
    unsigned char* a = stbi_load(shot.c_str(), &w1, &h1, &c, 4);
    unsigned char* b = stbi_load(window.c_str(), &w2, &h2, &c, 4);
    ASSERT_NE(a, nullptr);
    ASSERT_NE(b, nullptr);
    ASSERT_TRUE(w1 == w && h1 == h && w2 == w && h2 == h)
        << w1 << "x" << h1 << ", " << w2 << "x" << h2;
    int x0 = w, y0 = h, x1 = -1, y1 = -1;
    for (int y = 0; y < h; ++y) {
        for (int x = 0; x < w; ++x) {
            if (std::abs(x - w / 2) < w / 8 && std::abs(y - h / 2) < h / 8) {
                continue;  // crosshair and brush preview
            }
            const int i = 4 * (y * w + x);
            if (a[i] != b[i] || a[i + 1] != b[i + 1] || a[i + 2] != b[i + 2]) {
                x0 = std::min(x0, x);
                y0 = std::min(y0, y);
                x1 = std::max(x1, x);
                y1 = std::max(y1, y);
            }
        }
    }
    stbi_image_free(a);
    stbi_image_free(b);
    ASSERT_GE(x1, 0) << "no overlay in the window";
    const double covered = double(x1 - x0 + 1) * double(y1 - y0 + 1) / (double(w) * h);
    EXPECT_LE(covered, 0.15) << "the overlay spans (" << x0 << ", " << y0 << ") - (" << x1 << ", "
                             << y1 << ")";
}

TEST_F(ViewTest, HelpListsValidateAndTheKeys) {
    const RunResult r = run_voxfield({"view", "--help"}, io_);
    ASSERT_EQ(r.code, 0) << describe(r);
    for (const char* text : {"--validate", "VOXFIELD_VALIDATE", "F1", "F2", "compact overlay"}) {
        EXPECT_NE(r.out.find(text), std::string::npos) << text << '\n' << r.out;
    }
}

// The smoke test's checks for one format: the screenshot shows the world, the final field
// equals replay's for the same edits and differs from the unedited world's.
void ViewTest::check_shot_and_field(const fs::path& world, const fs::path& edits,
                                    const std::string& format, const fs::path& shot,
                                    const fs::path& field) {
    // The screenshot shows the world: flat shading, black sky, so lit pixels are voxels.
    EXPECT_GT(non_black_pixels(shot, 160, 120), 160u * 120 / 20) << "the screenshot is all sky";

    // The field after the edits equals `replay`'s and differs from the unedited world's.
    const fs::path replayed = dir_ / "replay_field.npy", before = dir_ / "before.npy";
    RunResult r = run_voxfield({"replay", edits.string(), "--input", world.string(), "--format",
                                format, "-o", replayed.string()},
                               io_);
    ASSERT_EQ(r.code, 0) << describe(r);
    r = run_voxfield({"generate", world.string(), "--format", format, "-o", before.string()}, io_);
    ASSERT_EQ(r.code, 0) << describe(r);
    const auto got = read_npy(field), want = read_npy(replayed), old = read_npy(before);
    EXPECT_EQ(got.dims, want.dims);
    EXPECT_TRUE(got.data == want.data) << "view's field differs from replay's";
    EXPECT_FALSE(got.data == old.data) << "the edits did not change the field";
}

}  // namespace
}  // namespace voxfield::test
