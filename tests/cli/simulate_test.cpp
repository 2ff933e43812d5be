// End-to-end tests of `voxfield simulate` (DESIGN §4): the world and field it writes against
// the CPU reference automaton and the exact reference field, --verify, the --json record,
// and bad input rejected with exit 2 and no file left behind.
#include <gtest/gtest.h>
#include <nlohmann/json.hpp>
#include "cli_test_util.hpp"
#include "far_grid_util.hpp"

#include <algorithm>
#include <cstdint>
#include <filesystem>
#include <set>
#include <string>
#include <vector>

#include "voxfield/core/format.hpp"
#include "voxfield/core/npy.hpp"
#include "voxfield/core/palette.hpp"
#include "voxfield/core/reference.hpp"
#include "voxfield/core/sand.hpp"
#include "voxfield/core/world.hpp"

namespace voxfield {
namespace {

using namespace voxfield::test;  // the spawn and file helpers of cli_test_util.hpp

namespace fs = std::filesystem;
using nlohmann::json;

const Dims kDims{32, 24, 28};

class SimulateTest : public TempDirsTest {
  protected:
    SimulateTest() : TempDirsTest("voxfield_simulate") {}
    void SetUp() override {
        TempDirsTest::SetUp();
        world_path_ = dir_ / "world.npy";
        const NpyArray a = npy_from_world(start());
        write_npy(world_path_, a.type, a.dims, a.data);
    }
    RunResult run(std::vector<std::string> args) {
        args.insert(args.begin(), {"simulate", world_path_.string()});
        return run_voxfield(args, io_);
    }
    static World start() { return scene_sand(kDims, 11); }

    // The starting world after `steps` reference steps with `seed`, and each step's changes.
    static World reference(std::uint64_t steps, std::uint64_t seed, const SandRules& rules,
                           std::vector<std::size_t>* changed = nullptr) {
        World w = start();
        for (std::uint64_t step = 0; step < steps; ++step) {
            const std::size_t n = sand_step(w, rules, seed, step).size();
            if (changed != nullptr) {
                changed->push_back(n);
            }
        }
        return w;
    }

    // A run that must be rejected with exit 2 and a one-line message before writing anything
    // (with every output unless `outputs` is false).
    void expect_rejected(const std::vector<std::string>& args, const std::string& message,
                         bool outputs = true) {
        std::vector<std::string> all;
        if (outputs) {
            all = {"--world-output", (dir_ / "w.npy").string(), "-o", (dir_ / "f.npy").string(),
                   "--json",         (dir_ / "s.json").string()};
        }
        all.insert(all.end(), args.begin(), args.end());
        const RunResult r = run(all);
        EXPECT_EQ(r.code, 2) << describe(r);
        EXPECT_TRUE(r.out.empty()) << describe(r);
        EXPECT_EQ(split_lines(r.err).size(), 1u) << describe(r);
        EXPECT_NE(r.err.find(message), std::string::npos) << describe(r);
        EXPECT_EQ(list_dir(dir_), (std::set<std::string>{"world.npy"}));
    }

    fs::path world_path_;
};

TEST_F(SimulateTest, VerifiedRunWritesTheReferenceWorldAndItsExactField) {
    const fs::path world_out = dir_ / "world_out.npy", field_out = dir_ / "field_out.npy";
    const RunResult r = run({"--steps", "30", "--seed", "5", "--verify", "--world-output",
                             world_out.string(), "-o", field_out.string()});
    ASSERT_EQ(r.code, 0) << describe(r);
    EXPECT_NE(r.out.find("verify:   the field matched a full regeneration after every step"),
              std::string::npos)
        << r.out;
    EXPECT_NE(r.out.find("steps/s"), std::string::npos) << r.out;
    EXPECT_NE(r.out.find("simulate: median"), std::string::npos) << r.out;
    EXPECT_NE(r.out.find("update:   median"), std::string::npos) << r.out;

    const World want = reference(30, 5, SandRules{});
    const NpyArray w = read_npy(world_out);
    ASSERT_EQ(w.dims, kDims);
    ASSERT_EQ(w.type, NpyType::u8);
    EXPECT_EQ(w.data, want.voxels()) << "world differs from the CPU reference automaton";
    EXPECT_NE(w.data, start().voxels());

    const NpyArray field = read_npy(field_out);
    ASSERT_EQ(field.type, NpyType::u16);
    EXPECT_EQ(field.data, encode_field(reference_manhattan(want), want,
                                       Palette::magicavoxel_default(), Format::u16))
        << "field differs from the exact reference of the final world";
    EXPECT_EQ(list_dir(dir_),
              (std::set<std::string>{"world.npy", "world_out.npy", "field_out.npy"}));
}

// A bounded field after a run equals the exact field of the reference world capped at D,
// whether the steps updated it incrementally or regenerated it (saturating sweeps).
TEST_F(SimulateTest, BoundedRunEndsWithTheCappedExactField) {
    const fs::path world_out = dir_ / "world_out.npy", field_out = dir_ / "field_out.npy";
    const RunResult r = run({"--steps", "12", "--seed", "3", "--max-distance", "3.5",
                             "--world-output", world_out.string(), "-o", field_out.string()});
    ASSERT_EQ(r.code, 0) << describe(r);
    const World want = reference(12, 3, SandRules{});
    EXPECT_EQ(read_npy(world_out).data, want.voxels());
    std::vector<double> capped = reference_distance(want, Metric::manhattan, Spacing{});
    for (double& v : capped) {
        v = std::min(v, 3.5);
    }
    EXPECT_EQ(read_npy(field_out).data,
              encode_real_field(capped, want, Palette::magicavoxel_default(), Format::u16))
        << "bounded field differs from min(exact, D) of the final world";
}

TEST_F(SimulateTest, JsonRecordsEveryStepAndTheFullRegeneration) {
    const fs::path json_out = dir_ / "sim.json";
    const RunResult r =
        run({"--steps", "12", "--seed", "8", "--format", "packed32", "--json", json_out.string()});
    ASSERT_EQ(r.code, 0) << describe(r);
    std::vector<std::size_t> changed;
    reference(12, 8, SandRules{}, &changed);
    const json j = json::parse(read_text(json_out));
    ASSERT_TRUE(j.contains("device") && j["device"].is_object()) << j.dump(1);
    EXPECT_TRUE(j["device"].contains("name"));
    ASSERT_TRUE(j.contains("full_regeneration_ms") && j["full_regeneration_ms"].is_number());
    EXPECT_GT(j["full_regeneration_ms"].get<double>(), 0.0);
    EXPECT_EQ(j["format"], "packed32");
    ASSERT_TRUE(j.contains("steps") && j["steps"].is_array());
    ASSERT_EQ(j["steps"].size(), 12u);
    for (std::size_t i = 0; i < 12; ++i) {
        const json& s = j["steps"][i];
        SCOPED_TRACE("step " + std::to_string(i) + ": " + s.dump());
        ASSERT_TRUE(s.contains("step") && s.contains("simulate_ms") && s.contains("update_ms") &&
                    s.contains("voxels_changed"));
        EXPECT_EQ(s["step"].get<std::size_t>(), i);
        ASSERT_TRUE(s["simulate_ms"].is_number() && s["update_ms"].is_number());
        EXPECT_GT(s["simulate_ms"].get<double>(), 0.0);
        EXPECT_GE(s["update_ms"].get<double>(), 0.0);
        EXPECT_EQ(s["voxels_changed"].get<std::size_t>(), changed[i]);
    }
    EXPECT_EQ(list_dir(dir_), (std::set<std::string>{"world.npy", "sim.json"}));
}

TEST_F(SimulateTest, MaterialsAndSeedsAreTheOnesAsked) {
    // Water as sand and sand as water: the basin's water falls like sand, the grains flow.
    const SandRules swapped{3, 2};
    const fs::path a = dir_ / "a.npy", b = dir_ / "b.npy";
    RunResult r = run({"--steps", "16", "--sand-material", "3", "--water-material", "2", "--seed",
                       "1", "--world-output", a.string()});
    ASSERT_EQ(r.code, 0) << describe(r);
    EXPECT_EQ(read_npy(a).data, reference(16, 1, swapped).voxels());
    r = run({"--steps", "16", "--seed", "2", "--world-output", b.string()});
    ASSERT_EQ(r.code, 0) << describe(r);
    EXPECT_EQ(read_npy(b).data, reference(16, 2, SandRules{}).voxels());
    EXPECT_NE(reference(16, 2, SandRules{}).voxels(), reference(16, 1, SandRules{}).voxels());
}

TEST_F(SimulateTest, ZeroStepsWritesTheStartingWorld) {
    const fs::path w = dir_ / "w0.npy";
    const RunResult r = run({"--steps", "0", "--verify", "--world-output", w.string()});
    ASSERT_EQ(r.code, 0) << describe(r);
    EXPECT_EQ(read_npy(w).data, start().voxels());
}

TEST_F(SimulateTest, BadInputExitsTwoAndWritesNothing) {
    expect_rejected({"--steps", "-1"}, "--steps");
    expect_rejected({}, "--steps");
    expect_rejected({"--steps", "many"}, "--steps");
    expect_rejected({"--steps", "3", "--sand-material", "0"}, "--sand-material");
    expect_rejected({"--steps", "3", "--sand-material", "256"}, "--sand-material");
    expect_rejected({"--steps", "3", "--water-material", "0"}, "--water-material");
    expect_rejected({"--steps", "3", "--water-material", "-4"}, "--water-material");
    expect_rejected({"--steps", "3", "--sand-material", "3"}, "different materials");
    expect_rejected({"--steps", "3", "--sand-material", "7", "--water-material", "7"},
                    "different materials");
    expect_rejected({"--steps", "3", "--seed", "-1"}, "--seed");
    expect_rejected({"--steps", "3", "--seed", "18446744073709551616"}, "--seed");
    expect_rejected({"--steps", "3", "--metric", "cosine"}, "--metric");
    expect_rejected({"--steps", "3", "--spacing", "1,0,1"}, "spacing");
    expect_rejected({"--steps", "3", "-o", (dir_ / "f.npy").string(), "--world-output",
                     (dir_ / "none" / "w.npy").string()},
                    "does not exist", false);
    expect_rejected(
        {"--steps", "3", "-o", (dir_ / "w.npy").string(), "--json", (dir_ / "w.npy").string()},
        "same file", false);
    expect_rejected({"--steps", "3", "-o", world_path_.string()}, "is the input", false);
    const RunResult r = run_voxfield({"simulate", (dir_ / "missing.npy").string(), "--steps", "2",
                                      "-o", (dir_ / "f.npy").string()},
                                     io_);
    EXPECT_EQ(r.code, 2) << describe(r);
    EXPECT_EQ(split_lines(r.err).size(), 1u) << describe(r);
    EXPECT_EQ(list_dir(dir_), (std::set<std::string>{"world.npy"}));
}

// --sparse: the world as 64-trees stepped by SparseSand; --verify compares every step with the
// dense automaton and the dense bounded field; the outputs equal the CPU reference world and
// min(exact, D) of it. A world of several tiles (cut by the world's edge) as well as the
// one-tile fixture.
TEST_F(SimulateTest, SparseRunVerifiesAndEndsWithTheReferenceWorldAndCappedField) {
    const fs::path world_out = dir_ / "world_out.npy", field_out = dir_ / "field_out.npy";
    const fs::path json_out = dir_ / "sim.json";
    RunResult r = run({"--steps", "12", "--seed", "3", "--sparse", "--verify", "--max-distance",
                       "3.5", "--world-output", world_out.string(), "-o", field_out.string(),
                       "--json", json_out.string()});
    ASSERT_EQ(r.code, 0) << describe(r);
    EXPECT_NE(r.out.find("verify:   world and field matched the dense automaton and the dense "
                         "bounded field after every step"),
              std::string::npos)
        << r.out;
    const World want = reference(12, 3, SandRules{});
    EXPECT_EQ(read_npy(world_out).data, want.voxels());
    std::vector<double> capped = reference_distance(want, Metric::manhattan, Spacing{});
    for (double& v : capped) {
        v = std::min(v, 3.5);
    }
    EXPECT_EQ(read_npy(field_out).data,
              encode_real_field(capped, want, Palette::magicavoxel_default(), Format::u16));
    const json j = json::parse(read_text(json_out));
    EXPECT_EQ(j["sparse"], true);
    EXPECT_EQ(j["max_distance"], 3.5);
    ASSERT_EQ(j["steps"].size(), 12u);
    EXPECT_TRUE(j["steps"][0].contains("tiles_run")) << j["steps"][0].dump();
    // DESIGN §4's simulate record, as dense runs write it.
    ASSERT_TRUE(j.contains("device") && j["device"].is_object()) << j.dump(1);
    ASSERT_TRUE(j.contains("full_regeneration_ms") && j["full_regeneration_ms"].is_number());
    for (const json& s : j["steps"]) {
        EXPECT_TRUE(s.contains("step") && s.contains("simulate_ms") && s.contains("update_ms") &&
                    s.contains("voxels_changed"))
            << s.dump();
    }
    EXPECT_GT(j["summary"]["voxels_changed"].get<std::size_t>(), 0u);

    const fs::path big = dir_ / "big.npy";
    const NpyArray a = npy_from_world(scene_sand(Dims{130, 70, 66}, 4));
    write_npy(big, a.type, a.dims, a.data);
    r = run_voxfield({"simulate", big.string(), "--steps", "10", "--sparse", "--verify",
                      "--max-distance", "6", "--sand-material", "3", "--water-material", "2"},
                     io_);
    ASSERT_EQ(r.code, 0) << describe(r);
    EXPECT_NE(r.out.find("verify:"), std::string::npos) << r.out;
}

// What a sparse run cannot do on a world too large for one dense array is refused with one
// line, before any work: --verify, -o and --world-output.
TEST_F(SimulateTest, SparseRefusesDenseOutputsOfHugeWorlds) {
    const fs::path grid = io_ / "far.vdb";
    write_far_cubes_vdb(grid);
    for (const std::vector<std::string>& extra : {std::vector<std::string>{"--verify"},
                                                  {"-o", (dir_ / "f.npy").string()},
                                                  {"--world-output", (dir_ / "w.npy").string()}}) {
        std::vector<std::string> args = {"simulate", grid.string(), "--steps", "2", "--sparse"};
        args.insert(args.end(), extra.begin(), extra.end());
        const RunResult r = run_voxfield(args, io_);
        EXPECT_EQ(r.code, 2) << describe(r);
        EXPECT_EQ(split_lines(r.err).size(), 1u) << describe(r);
        EXPECT_NE(r.err.find("one dense array"), std::string::npos) << describe(r);
    }
    EXPECT_EQ(list_dir(dir_), (std::set<std::string>{"world.npy"}));
}

TEST_F(SimulateTest, HelpDescribesEveryOption) {
    const RunResult r = run_voxfield({"simulate", "--help"}, io_);
    ASSERT_EQ(r.code, 0) << describe(r);
    for (const char* option :
         {"--steps", "--sand-material", "--water-material", "--seed", "--world-output", "--output",
          "--metric", "--spacing", "--format", "--device", "--verify", "--json", "--sparse"}) {
        EXPECT_NE(r.out.find(option), std::string::npos) << option << "\n" << r.out;
    }
}

}  // namespace
}  // namespace voxfield
