// End-to-end tests of `voxfield replay` (DESIGN §4): runs the binary on random edit files and
// checks the edited world and the final field against the CPU (apply_brush, the exact
// references), the --json keys, --verify, and the rejection of bad edit files.
#include <fcntl.h>
#include <spawn.h>
#include <stdlib.h>
#include <sys/wait.h>
#include <unistd.h>

#include <gtest/gtest.h>
#include <nlohmann/json.hpp>
#include "cli_test_util.hpp"

#include <algorithm>
#include <cerrno>
#include <cstdint>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <functional>
#include <iterator>
#include <random>
#include <set>
#include <sstream>
#include <string>
#include <vector>

#include "voxfield/core/brush.hpp"
#include "voxfield/core/format.hpp"
#include "voxfield/core/npy.hpp"
#include "voxfield/core/palette.hpp"
#include "voxfield/core/reference.hpp"
#include "voxfield/core/scenes.hpp"
#include "voxfield/core/world.hpp"

namespace voxfield {
namespace {

using namespace voxfield::test;  // the spawn and file helpers of cli_test_util.hpp

namespace fs = std::filesystem;
using nlohmann::json;

const Dims kDims{48, 48, 48};

// Index of the first differing element (element size `es`), or -1.
long long first_difference(const std::vector<std::uint8_t>& a, const std::vector<std::uint8_t>& b,
                           std::size_t es) {
    const std::size_t n = std::min(a.size(), b.size());
    for (std::size_t i = 0; i < n; ++i) {
        if (a[i] != b[i]) {
            return static_cast<long long>(i / es);
        }
    }
    return a.size() == b.size() ? -1 : static_cast<long long>(n / es);
}

// An edit file, the line number of each edit in it, and the world the edits make on the CPU.
struct EditScript {
    std::string text;
    std::vector<std::size_t> lines;
    std::vector<Brush> brushes;
};

std::string edit_line(const Brush& b, bool with_material) {
    std::string s = to_string(b.op) + " " + to_string(b.shape) + " " + std::to_string(b.centre.x) +
                    " " + std::to_string(b.centre.y) + " " + std::to_string(b.centre.z) + " " +
                    std::to_string(b.radius);
    if (with_material) {
        s += " " + std::to_string(b.material);
    }
    return s;
}

// `count` random edits: every op, both shapes, radii 0..12, centres inside the world, on its
// faces and outside it (some still reaching in), with comments, blank lines, tabs, trailing
// comments and CRLF line endings mixed in.
EditScript random_script(std::uint64_t seed, std::size_t count) {
    std::mt19937_64 rng(seed);
    auto uniform = [&](std::int64_t lo, std::int64_t hi) {
        return std::uniform_int_distribution<std::int64_t>(lo, hi)(rng);
    };
    EditScript s;
    std::size_t line = 0;
    auto add_line = [&](const std::string& l) {
        s.text += l + (uniform(0, 9) == 0 ? "\r\n" : "\n");
        ++line;
    };
    add_line("# random replay script, seed " + std::to_string(seed));
    add_line("");
    for (std::size_t i = 0; i < count; ++i) {
        while (uniform(0, 5) == 0) {
            add_line(uniform(0, 1) == 0 ? "" : "   # a comment line");
        }
        Brush b;
        b.op = static_cast<BrushOp>(uniform(0, 2));
        b.shape = static_cast<BrushShape>(uniform(0, 1));
        b.radius = uniform(0, 12);
        const std::int64_t n = kDims.x;
        Int3 c;
        for (std::int64_t* v : {&c.x, &c.y, &c.z}) {
            switch (uniform(0, 5)) {
                case 0:  // on a face
                    *v = uniform(0, 1) == 0 ? 0 : n - 1;
                    break;
                case 1:  // outside, possibly reaching in
                    *v = uniform(0, 1) == 0 ? -uniform(1, 14) : n - 1 + uniform(1, 14);
                    break;
                default:
                    *v = uniform(0, n - 1);
            }
        }
        b.centre = c;
        bool with_material = false;
        if (b.op != BrushOp::erase && uniform(0, 2) != 0) {
            b.material = static_cast<std::uint8_t>(uniform(1, 255));
            with_material = true;
        }
        std::string l = edit_line(b, with_material);
        if (uniform(0, 7) == 0) {
            std::replace(l.begin(), l.end(), ' ', '\t');
        }
        if (uniform(0, 7) == 0) {
            l = "  " + l + "  # trailing comment";
        }
        add_line(l);
        s.lines.push_back(line);
        s.brushes.push_back(b);
    }
    add_line("# end");
    return s;
}

class ReplayTest : public TempDirsTest {
  protected:
    ReplayTest() : TempDirsTest("voxfield_replay") {}
    void SetUp() override {
        TempDirsTest::SetUp();
        world_path_ = dir_ / "world.npy";
        const NpyArray a = npy_from_world(initial_world());
        write_npy(world_path_, a.type, a.dims, a.data);
    }

    static World initial_world() { return scene_floor_spheres(kDims, 7, 16); }

    // Replays `script` with --verify and every output, then checks the world against
    // apply_brush on the CPU, the field against `reference` of that world, and the JSON.
    void check_replay(const EditScript& script, const std::vector<std::string>& extra,
                      const std::function<std::vector<std::uint32_t>(const World&)>& reference,
                      const std::string& format = "u16") {
        const fs::path edits = dir_ / "edits.txt";
        write_file(edits, script.text);
        const fs::path world_out = dir_ / "world_out.npy";
        const fs::path field_out = dir_ / "field_out.npy";
        const fs::path json_out = dir_ / "replay.json";
        std::vector<std::string> args = {"replay",
                                         edits.string(),
                                         "--input",
                                         world_path_.string(),
                                         "--world-output",
                                         world_out.string(),
                                         "-o",
                                         field_out.string(),
                                         "--json",
                                         json_out.string(),
                                         "--verify",
                                         "--format",
                                         format};
        args.insert(args.end(), extra.begin(), extra.end());
        const RunResult r = run(args);
        ASSERT_EQ(r.code, 0) << describe(r);
        EXPECT_NE(r.out.find("full"), std::string::npos) << r.out;

        World expected = initial_world();
        for (const Brush& b : script.brushes) {
            apply_brush(expected, b);
        }
        const NpyArray w = read_npy(world_out);
        ASSERT_EQ(w.dims, kDims);
        ASSERT_EQ(w.type, NpyType::u8);
        EXPECT_EQ(first_difference(w.data, expected.voxels(), 1), -1)
            << "world differs from apply_brush on the CPU";

        const World edited = world_from_npy(w);
        const Format f = parse_format(format);
        const auto want =
            encode_field(reference(edited), edited, Palette::magicavoxel_default(), f);
        const NpyArray field = read_npy(field_out);
        ASSERT_EQ(field.dims, kDims);
        EXPECT_EQ(first_difference(field.data, want, element_size(f)), -1)
            << "final field differs from the CPU reference";

        const json j = json::parse(read_text(json_out));
        ASSERT_TRUE(j.contains("device") && j["device"].is_object()) << j.dump(1);
        ASSERT_TRUE(j.contains("full_regeneration_ms") && j["full_regeneration_ms"].is_number());
        EXPECT_GT(j["full_regeneration_ms"].get<double>(), 0.0);
        ASSERT_TRUE(j.contains("edits") && j["edits"].is_array());
        ASSERT_EQ(j["edits"].size(), script.brushes.size());
        for (std::size_t i = 0; i < script.brushes.size(); ++i) {
            const json& e = j["edits"][i];
            SCOPED_TRACE("edit " + std::to_string(i) + ": " + e.dump());
            ASSERT_TRUE(e.contains("line") && e.contains("op") && e.contains("update_ms") &&
                        e.contains("voxels_recomputed"));
            EXPECT_EQ(e["line"].get<std::size_t>(), script.lines[i]);
            EXPECT_EQ(e["op"].get<std::string>(), to_string(script.brushes[i].op));
            ASSERT_TRUE(e["update_ms"].is_number());
            EXPECT_GE(e["update_ms"].get<double>(), 0.0);
            ASSERT_TRUE(e["voxels_recomputed"].is_number_unsigned());
        }
        // Every output named, nothing else left behind (no temporary files).
        EXPECT_EQ(list_dir(dir_), (std::set<std::string>{"world.npy", "edits.txt", "world_out.npy",
                                                         "field_out.npy", "replay.json"}));
    }

    // Runs a replay that must be rejected with exit 2 before writing anything; returns stderr.
    std::string expect_rejected(const std::string& edit_text,
                                const std::vector<std::string>& extra = {}) {
        const fs::path edits = dir_ / "edits.txt";
        write_file(edits, edit_text);
        std::vector<std::string> args = {"replay",
                                         edits.string(),
                                         "--input",
                                         world_path_.string(),
                                         "--world-output",
                                         (dir_ / "w.npy").string(),
                                         "-o",
                                         (dir_ / "f.npy").string(),
                                         "--json",
                                         (dir_ / "r.json").string(),
                                         "--verify"};
        args.insert(args.end(), extra.begin(), extra.end());
        const RunResult r = run(args);
        EXPECT_EQ(r.code, 2) << describe(r);
        EXPECT_TRUE(r.out.empty()) << describe(r);
        EXPECT_EQ(split_lines(r.err).size(), 1u) << describe(r);
        EXPECT_EQ(list_dir(dir_), (std::set<std::string>{"world.npy", "edits.txt"}));
        return r.err;
    }

    fs::path world_path_;
};

TEST_F(ReplayTest, RandomEditsExactMatchCpuAndVerify) {
    check_replay(random_script(1, 300), {}, reference_manhattan);
}

TEST_F(ReplayTest, RandomEditsExactPacked32) {
    // packed32 carries the colour: paint must reach the field too.
    check_replay(random_script(2, 120), {"--algorithm", "exact"}, reference_manhattan, "packed32");
}

TEST_F(ReplayTest, RandomEditsFimChunked) {
    check_replay(random_script(3, 300), {"--algorithm", "fim", "--chunk", "8"},
                 [](const World& w) { return reference_manhattan_chunked(w, 8); });
}

TEST_F(ReplayTest, RandomEditsMonolithicChunked) {
    check_replay(random_script(4, 300),
                 {"--algorithm", "monolithic", "--chunk", "8", "--focus", "0,0,0,8"},
                 [](const World& w) { return reference_manhattan_chunked(w, 8); });
}

TEST_F(ReplayTest, EraseEverythingThenPlace) {
    EditScript s;
    s.text =
        "# clear the world, then build again\n"
        "erase cube 24 24 24 1000\n"
        "\n"
        "place sphere 10 10 10 3 7\n"
        "erase cube -5 -5 -5 100000\n"
        "erase sphere 0 0 0 0\n"
        "place cube 47 47 47 0 9  # one voxel in a corner\n"
        "paint cube 47 47 47 5 200\n"
        "place cube 0 0 0 2\n";
    s.lines = {2, 4, 5, 6, 7, 8, 9};
    s.brushes = {
        {BrushOp::erase, BrushShape::cube, {24, 24, 24}, 1000, 1},
        {BrushOp::place, BrushShape::sphere, {10, 10, 10}, 3, 7},
        {BrushOp::erase, BrushShape::cube, {-5, -5, -5}, 100000, 1},
        {BrushOp::erase, BrushShape::sphere, {0, 0, 0}, 0, 1},
        {BrushOp::place, BrushShape::cube, {47, 47, 47}, 0, 9},
        {BrushOp::paint, BrushShape::cube, {47, 47, 47}, 5, 200},
        {BrushOp::place, BrushShape::cube, {0, 0, 0}, 2, 1},
    };
    check_replay(s, {}, reference_manhattan);
    check_replay(s, {}, reference_manhattan, "packed32");
    check_replay(s, {"--algorithm", "fim", "--chunk", "8"},
                 [](const World& w) { return reference_manhattan_chunked(w, 8); });
}

TEST_F(ReplayTest, CommentsOnlyFileReplaysNothing) {
    EditScript s;
    s.text = "# nothing to do\n\n   \n";
    check_replay(s, {}, reference_manhattan);
}

TEST_F(ReplayTest, BadEditFilesAreRejectedBeforeAnyWork) {
    struct Case {
        std::string text, where, what;
    };
    const std::vector<Case> cases = {
        {"place sphere 1 2 3 4\nexplode sphere 1 2 3 4\n", ":2:", "explode"},
        {"# comment\n\nplace sphere 1 2\n", ":3:", "missing"},
        {"place sphere 1 2 3 4 5\nerase cube 1 2 3 -4\n", ":2:", "negative"},
        {"paint sphere 1 two 3 4 5\n", ":1:", "two"},
        {"place cube 1 2 3 4\n\n\n\nplace cube 1 2 3 4.5\n", ":5:", "4.5"},
        {"place blob 1 2 3 4\n", ":1:", "blob"},
        {"place sphere 1 2 3 4 0\n", ":1:", "MATERIAL"},
        {"erase sphere 1 2 3 4 5\n", ":1:", "MATERIAL"},
    };
    const std::string edits = (dir_ / "edits.txt").string();
    for (const Case& c : cases) {
        SCOPED_TRACE(c.text);
        const std::string err = expect_rejected(c.text);
        EXPECT_NE(err.find(edits + c.where), std::string::npos) << err;
        EXPECT_NE(err.find(c.what), std::string::npos) << err;
    }
}

TEST_F(ReplayTest, MissingEditFileIsInputError) {
    const RunResult r = run({"replay", (dir_ / "nope.txt").string(), "--input",
                             world_path_.string(), "-o", (dir_ / "f.npy").string()});
    EXPECT_EQ(r.code, 2) << describe(r);
    EXPECT_NE(r.err.find("nope.txt"), std::string::npos) << r.err;
    EXPECT_EQ(list_dir(dir_), (std::set<std::string>{"world.npy"}));
}

TEST_F(ReplayTest, NothingToProduceIsUsageError) {
    const fs::path edits = dir_ / "edits.txt";
    write_file(edits, "place sphere 1 2 3 4\n");
    const RunResult r = run({"replay", edits.string(), "--input", world_path_.string()});
    EXPECT_EQ(r.code, 2) << describe(r);
    EXPECT_NE(r.err.find("nothing"), std::string::npos) << r.err;
    EXPECT_EQ(split_lines(r.err).size(), 1u) << r.err;
}

TEST_F(ReplayTest, SameFileForTwoOutputsIsUsageError) {
    const fs::path edits = dir_ / "edits.txt";
    write_file(edits, "place sphere 1 2 3 4\n");
    const std::string same = (dir_ / "out.npy").string();
    const RunResult r = run({"replay", edits.string(), "--input", world_path_.string(),
                             "--world-output", same, "-o", same});
    EXPECT_EQ(r.code, 2) << describe(r);
    EXPECT_NE(r.err.find("same file"), std::string::npos) << r.err;
    EXPECT_EQ(list_dir(dir_), (std::set<std::string>{"world.npy", "edits.txt"}));
}

TEST_F(ReplayTest, MissingOutputFolderIsRejectedBeforeWork) {
    const fs::path edits = dir_ / "edits.txt";
    write_file(edits, "place sphere 1 2 3 4\n");
    const RunResult r = run({"replay", edits.string(), "--input", world_path_.string(), "-o",
                             (dir_ / "no_such_dir" / "f.npy").string()});
    EXPECT_EQ(r.code, 2) << describe(r);
    EXPECT_NE(r.err.find("no_such_dir"), std::string::npos) << r.err;
}

TEST_F(ReplayTest, HelpDescribesEveryOption) {
    const RunResult r = run({"replay", "--help"});
    ASSERT_EQ(r.code, 0) << describe(r);
    for (const char* opt : {"EDITS", "--input", "--world-output", "--output", "--algorithm",
                            "--chunk", "--focus", "--device", "--format", "--verify", "--json"}) {
        EXPECT_NE(r.out.find(opt), std::string::npos) << opt << "\n" << r.out;
    }
}

}  // namespace
}  // namespace voxfield
