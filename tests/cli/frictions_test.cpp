// Frictions a user meets: what --help offers works, devices --json names the sharing path,
// simulate is quiet when stderr is no terminal, every .npy dtype refusal reads the same.
#include <nlohmann/json.hpp>

#include <chrono>

#include "cli_test_util.hpp"
#include "voxfield/core/npy.hpp"
#include "voxfield/core/sand.hpp"

namespace voxfield::test {
namespace {

class FrictionsCli : public ::testing::Test {
  protected:
    void SetUp() override { io = make_temp_dir("voxfield_frictions_io"); }
    void TearDown() override { fs::remove_all(io); }
    RunResult run(const std::vector<std::string>& args) { return run_voxfield(args, io); }
    fs::path io;
};

// The help text of `option` (its line and the wrapped lines under it).
std::string option_help(const std::string& help, const std::string& option) {
    const std::size_t at = help.find("  " + option + " ");
    if (at == std::string::npos) {
        return {};
    }
    const std::size_t end = help.find("\n  -", at + 1);
    return help.substr(at, end == std::string::npos ? std::string::npos : end - at);
}

TEST_F(FrictionsCli, DevicesJsonNamesEachDevicesSharingPath) {
    const RunResult r = run({"devices", "--json"});
    ASSERT_EQ(r.code, 0) << describe(r);
    const nlohmann::json j = nlohmann::json::parse(r.out);
    ASSERT_TRUE(j.is_array());
    ASSERT_FALSE(j.empty());
    for (const auto& d : j) {
        ASSERT_TRUE(d.contains("sharing")) << d.dump();
        EXPECT_FALSE(d["sharing"]["path"].get<std::string>().empty()) << d.dump();
        EXPECT_TRUE(d["sharing"].contains("vulkan_device")) << d.dump();
        EXPECT_TRUE(d["sharing"].contains("why_not")) << d.dump();
    }
}

TEST_F(FrictionsCli, ViewOffersOnlyTheFormatsItRenders) {
    const RunResult r = run({"view", "--help"});
    ASSERT_EQ(r.code, 0) << describe(r);
    const std::string format = option_help(r.out, "--format");
    ASSERT_FALSE(format.empty()) << r.out;
    for (const char* works : {"u8", "u16", "u32", "packed32"}) {
        EXPECT_NE(format.find(works), std::string::npos) << format;
    }
    for (const char* not_rendered : {"i8", "i16", "i32", "f32", "f64"}) {
        EXPECT_EQ(format.find(not_rendered), std::string::npos) << format;
    }
    const RunResult f = run({"view", "--world", "8", "--format", "f32"});
    EXPECT_EQ(f.code, 2) << describe(f);
}

TEST_F(FrictionsCli, RenderAndViewHelpNameEachOthersDefaultShading) {
    // render draws flat by default (its images are compared pixel for pixel) and view opens
    // lit; changing either default would change a valid command's output, so each --help says
    // what the other does.
    const RunResult r = run({"render", "--help"});
    ASSERT_EQ(r.code, 0) << describe(r);
    const std::string render = option_help(r.out, "--shading");
    EXPECT_NE(render.find("render defaults to flat"), std::string::npos) << render;
    EXPECT_NE(render.find("view opens lit"), std::string::npos) << render;
    const RunResult v = run({"view", "--help"});
    ASSERT_EQ(v.code, 0) << describe(v);
    const std::string view = option_help(v.out, "--shading");
    EXPECT_NE(view.find("as render draws by default"), std::string::npos) << view;
    EXPECT_NE(view.find("view's default"), std::string::npos) << view;
}

TEST_F(FrictionsCli, SimulateHelpOffersNoAlgorithm) {
    const RunResult r = run({"simulate", "--help"});
    ASSERT_EQ(r.code, 0) << describe(r);
    EXPECT_EQ(r.out.find("--algorithm"), std::string::npos) << r.out;
    const RunResult g = run({"generate", "--help"});
    EXPECT_NE(option_help(g.out, "--metric").find("--algorithm exact"), std::string::npos) << g.out;
}

TEST_F(FrictionsCli, SimulateShowsNoProgressWhenStderrIsNotATerminal) {
    // run_voxfield sends stderr to a file. Steps grow until the run lasts well past the
    // second after which progress shows on a terminal, so the check means something.
    const fs::path world = io / "sand.npy";
    const NpyArray a = npy_from_world(scene_sand(Dims{32, 24, 28}, 11));
    write_npy(world, a.type, a.dims, a.data);
    RunResult r;
    double seconds = 0;
    for (int steps = 100; seconds < 2.5 && steps <= 25600; steps *= 4) {
        const auto t0 = std::chrono::steady_clock::now();
        r = run({"simulate", world.string(), "--steps", std::to_string(steps), "--verify",
                 "--device", "cpu"});
        seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
        ASSERT_EQ(r.code, 0) << describe(r);
    }
    ASSERT_GE(seconds, 2.5) << "no run lasted long enough for progress to show";
    EXPECT_EQ(r.err.find('\r'), std::string::npos) << r.err;
    EXPECT_EQ(r.err.find("simulate:"), std::string::npos) << r.err;
    EXPECT_TRUE(r.err.empty()) << r.err;
}

// A .npy of `descr` (as the header writes it) and shape (2, 2, 2) with `bytes` of data.
void write_raw_npy(const fs::path& path, const std::string& descr, std::size_t bytes) {
    std::string header = "{'descr': " + descr + ", 'fortran_order': False, 'shape': (2, 2, 2), }";
    header.append((64 - (10 + header.size() + 1) % 64) % 64, ' ');
    header += '\n';
    std::string file("\x93NUMPY\x01\x00", 8);
    file += static_cast<char>(header.size() & 0xFF);
    file += static_cast<char>(header.size() >> 8);
    file += header;
    file.append(bytes, '\0');
    write_file(path, file);
}

TEST_F(FrictionsCli, NpyDtypeRefusalsReadTheSame) {
    // Every dtype a world cannot have: "FILE: dtype D (numpy's name) is not supported: " and
    // what a world is; big-endian integers say how to save them instead.
    const std::string world_is =
        "is not supported: a world is a bool or integer array (a label volume: 0 = empty, "
        "nonzero = solid)";
    struct Case {
        std::string file, descr, shown;
        std::size_t bytes;
    };
    const std::vector<Case> cases = {
        {"f32.npy", "'<f4'", "dtype '<f4' (float32) ", 32},
        {"f64.npy", "'<f8'", "dtype '<f8' (float64) ", 64},
        {"f16.npy", "'<f2'", "dtype '<f2' (float16) ", 16},
        {"c8.npy", "'<c8'", "dtype '<c8' (complex64) ", 64},
        {"str.npy", "'<U1'", "dtype '<U1' (str) ", 32},
        {"obj.npy", "'|O'", "dtype '|O' (object) ", 64},
        {"time.npy", "'<M8[s]'", "dtype '<M8[s]' (datetime64) ", 64},
        {"void.npy", "'|V2'", "dtype '|V2' (void) ", 16},
        {"be_f4.npy", "'>f4'", "dtype '>f4' (float32) ", 32},
        {"rec.npy", "[('a', '|u1'), ('b', '|u1')]",
         "dtype [('a', '|u1'), ('b', '|u1')] (a structured array) ", 16},
    };
    for (const char* command : {"generate", "info"}) {
        for (const Case& c : cases) {
            write_raw_npy(io / c.file, c.descr, c.bytes);
            const std::string path = (io / c.file).string();
            const RunResult r =
                std::string(command) == "generate"
                    ? run({"generate", path, "-o", (io / "out.npy").string(), "--device", "cpu"})
                    : run({"info", path});
            EXPECT_EQ(r.code, 2) << describe(r);
            EXPECT_EQ(r.err, "voxfield: " + path + ": " + c.shown + world_is + "\n") << command;
        }
        write_raw_npy(io / "be_u2.npy", "'>u2'", 16);
        const std::string path = (io / "be_u2.npy").string();
        const RunResult r =
            std::string(command) == "generate"
                ? run({"generate", path, "-o", (io / "out.npy").string(), "--device", "cpu"})
                : run({"info", path});
        EXPECT_EQ(r.code, 2) << describe(r);
        EXPECT_NE(r.err.find("dtype '>u2' (uint16, big-endian) is not supported: only "
                             "little-endian arrays are read (save it with a.astype('<u2'))"),
                  std::string::npos)
            << r.err;
    }
}

}  // namespace
}  // namespace voxfield::test
