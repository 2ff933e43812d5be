// Values checked against what the kernels represent before any work (README "Errors and exit
// codes"), readable messages for bad option values, rates that never read 0.00, and the
// progress line on a terminal (through script(1)'s pseudo-terminal) but not on a file.
#include <regex>

#include "cli_test_util.hpp"
#include "voxfield/core/npy.hpp"

namespace voxfield::test {
namespace {

class ValuesCli : public ::testing::Test {
  protected:
    void SetUp() override {
        dir = make_temp_dir("voxfield_values");
        io = make_temp_dir("voxfield_values_io");
        // The issue's 20x16x24 world: a few solids far apart.
        std::vector<std::uint8_t> voxels(20 * 16 * 24, 0);
        for (std::size_t i = 0; i < voxels.size(); i += 97) {
            voxels[i] = 1;
        }
        write_npy(dir / "w.npy", NpyType::u8, Dims{20, 16, 24}, voxels);
    }
    void TearDown() override {
        fs::remove_all(dir);
        fs::remove_all(io);
    }
    RunResult run(const std::vector<std::string>& args) { return run_voxfield(args, io); }
    std::string in(const std::string& name) const { return (dir / name).string(); }
    // generate w.npy -o o.npy on the CPU with `extra`; expects exit 2, no output and `message`.
    void expect_refused(const std::vector<std::string>& extra, const std::string& message) {
        std::vector<std::string> args = {"generate",  in("w.npy"), "-o",
                                         in("o.npy"), "--device",  "cpu"};
        args.insert(args.end(), extra.begin(), extra.end());
        const RunResult r = run(args);
        EXPECT_EQ(r.code, 2) << describe(r);
        EXPECT_NE(r.err.find(message), std::string::npos) << r.err;
        EXPECT_LT(r.err.size(), 600u) << r.err;
        EXPECT_FALSE(fs::exists(dir / "o.npy"));
    }

    fs::path dir, io;
};

TEST_F(ValuesCli, SpacingBeyondWhatTheFloatScansResolveIsRefusedWithTheLimit) {
    expect_refused({"--metric", "chebyshev", "--spacing", "3e8,1,1"}, "(2^31 - 1)");
    expect_refused({"--metric", "chebyshev", "--spacing", "1,1,1e10"}, "(2^31 - 1)");
    expect_refused({"--metric", "euclidean", "--spacing", "1e39,1,1"}, "float range");
    expect_refused({"--metric", "euclidean", "--spacing", "1e-39,1,1"}, "float range");
    expect_refused({"--spacing", "1,1,1,1"}, "expected three values X,Y,Z, got 4");
    // Within the limit: computed, and exact against the CPU reference; the other metrics'
    // separators have no such limit.
    for (const char* metric : {"chebyshev", "manhattan", "euclidean"}) {
        const RunResult r = run(
            {"generate", in("w.npy"), "-o", in("o.npy"), "--device", "cpu", "--metric", metric,
             "--spacing", std::string(metric) == "chebyshev" ? "1e8,1,1" : "3e8,1,1", "--stats"});
        EXPECT_EQ(r.code, 0) << describe(r);
        EXPECT_NE(r.out.find("max error 0,"), std::string::npos) << r.out;
    }
}

TEST_F(ValuesCli, ABoundThatRoundsToZeroAndIndicesWithABoundAreRefused) {
    expect_refused({"--max-distance", "0.5"}, "every voxel would be 0");
    expect_refused({"--max-distance", "0.5", "--format", "u8"}, "every voxel would be 0");
    expect_refused({"--max-distance", "3", "--indices", in("i.npy")},
                   "--indices with --max-distance");
    const RunResult r = run({"generate", in("w.npy"), "-o", in("o.npy"), "--device", "cpu",
                             "--max-distance", "0.5", "--format", "f32"});
    EXPECT_EQ(r.code, 0) << describe(r);
}

TEST_F(ValuesCli, EmptyValuesAndABoundBeyondFloatRangeAreRefused) {
    // An empty value is not the option left out.
    expect_refused({"--max-distance", ""}, "--max-distance: an empty value");
    expect_refused({"--spacing", ""}, "--spacing: an empty value");
    // A .vdb's background and the kernels hold the bound as a float.
    expect_refused({"--max-distance", "1e40", "--format", "f64"}, "beyond float range");
}

TEST_F(ValuesCli, ADeviceIndexBeyondTheIntegersDoesNotWrapAround) {
    for (const char* index : {"18446744073709551616", "18446744073709551617", "99"}) {
        const RunResult r = run({"generate", in("w.npy"), "-o", in("o.npy"), "--device", index});
        EXPECT_EQ(r.code, 2) << describe(r);
        EXPECT_NE(r.err.find("the indices are 0.."), std::string::npos) << r.err;
        // Every device is rejected as not the index given, never as not a wrapped one (1).
        EXPECT_NE(r.err.find(std::string("not index ") + index + ";"), std::string::npos) << r.err;
        EXPECT_EQ(r.err.find("not index 1;"), std::string::npos) << r.err;
        EXPECT_FALSE(fs::exists(dir / "o.npy"));
    }
}

TEST_F(ValuesCli, OptionValueMessagesAreReadable) {
    for (const std::vector<std::string>& args :
         {std::vector<std::string>{"generate", in("w.npy"), "-o", in("o.npy"), "--repeat", "0"},
          std::vector<std::string>{"bench", "--repeat", "0"}}) {
        const RunResult r = run(args);
        EXPECT_EQ(r.code, 2) << describe(r);
        EXPECT_NE(r.err.find("must be a positive number, got '0'"), std::string::npos) << r.err;
        EXPECT_LT(r.err.size(), 200u) << r.err;
    }
}

TEST_F(ValuesCli, BenchRefusesWhatGenerateRefusesBeforeAnyWork) {
    for (const std::vector<std::string>& args :
         {std::vector<std::string>{"bench", "--algorithms", "fim", "--chunk", "3", "--sizes", "16"},
          std::vector<std::string>{"bench", "--algorithms", "exact,fim", "--metric", "euclidean",
                                   "--sizes", "16"},
          std::vector<std::string>{"bench", "--sizes", "100000"}}) {
        const RunResult r = run(args);
        EXPECT_EQ(r.code, 2) << describe(r);
        EXPECT_EQ(r.err.find("bench: device"), std::string::npos) << r.err;
        EXPECT_TRUE(r.out.empty()) << r.out;
    }
    const RunResult r = run({"bench", "--sizes", "100000"});
    EXPECT_NE(r.err.find("GiB of host memory"), std::string::npos) << r.err;
}

TEST_F(ValuesCli, BruteCountsTheWholeWorldLoadsOfAnAllSolidWorld) {
    // 256^3 all solid: no voxel pair to compare, yet each of its 65536 work-groups loads the
    // whole world; minutes on a CPU, refused up front rather than run.
    write_npy(dir / "solid.npy", NpyType::u8, Dims{256, 256, 256},
              std::vector<std::uint8_t>(std::size_t{256} * 256 * 256, 1));
    const RunResult r = run({"generate", in("solid.npy"), "-o", in("o.npy"), "--device", "cpu",
                             "--algorithm", "brute"});
    EXPECT_EQ(r.code, 2) << describe(r);
    EXPECT_NE(r.err.find("would scan"), std::string::npos) << r.err;
    EXPECT_FALSE(fs::exists(dir / "o.npy"));
}

TEST_F(ValuesCli, EveryAlgorithmShowsItsRate) {
    const RunResult r =
        run({"generate", in("w.npy"), "-o", in("o.npy"), "--device", "cpu", "--algorithm", "fim"});
    ASSERT_EQ(r.code, 0) << describe(r);
    std::smatch m;
    ASSERT_TRUE(std::regex_search(r.out, m, std::regex(R"(\(([0-9.e+-]+) Gvox/s\))"))) << r.out;
    EXPECT_GT(std::stod(m[1].str()), 0.0) << r.out;
    EXPECT_NE(m[1].str(), "0.00") << r.out;
}

TEST_F(ValuesCli, GenerateTimeAndPhasesLinesAgreeOnUploadAndDownload) {
    const RunResult r = run({"generate", in("w.npy"), "-o", in("o.npy"), "--device", "cpu",
                             "--metric", "euclidean", "--stats"});
    ASSERT_EQ(r.code, 0) << describe(r);
    std::smatch t, p;
    ASSERT_TRUE(std::regex_search(
        r.out, t,
        std::regex(
            R"(upload (?:\(incl\. kernel build\) )?([0-9.]+) \+ first run [0-9.]+ \+ download ([0-9.]+) ms)")))
        << r.out;
    ASSERT_TRUE(std::regex_search(
        r.out, p, std::regex(R"(upload ([0-9.]+) ms.*download ([0-9.]+) ms, write)")))
        << r.out;
    EXPECT_EQ(t[1].str(), p[1].str()) << r.out;
    EXPECT_EQ(t[2].str(), p[2].str()) << r.out;
}

// The progress line: on a terminal (script(1) gives the command one) work over a second shows
// "\rgenerate: ...", erased at the end; with stderr a file, nothing.
TEST_F(ValuesCli, ProgressShowsOnATerminalOnly) {
    if (!fs::exists("/usr/bin/script")) {
        GTEST_SKIP() << "/usr/bin/script (bsdutils) is not installed";
    }
    // brute on 40^3 takes a few seconds on a 2-core CPU (all empty but one voxel).
    std::vector<std::uint8_t> voxels(40 * 40 * 40, 0);
    voxels[0] = 1;
    write_npy(dir / "b.npy", NpyType::u8, Dims{40, 40, 40}, voxels);
    const std::string command = kExe.string() + " generate " + in("b.npy") + " -o " + in("o.npy") +
                                " --device cpu --algorithm brute --repeat 3";
    const RunResult file = run({"generate", in("b.npy"), "-o", in("o2.npy"), "--device", "cpu",
                                "--algorithm", "brute", "--repeat", "3"});
    ASSERT_EQ(file.code, 0) << describe(file);
    EXPECT_EQ(file.err.find('\r'), std::string::npos) << file.err;
    // Through a pseudo-terminal: script -qec COMMAND /dev/null copies what the terminal saw.
    const fs::path log = io / "script.out";
    const std::string shell =
        "/usr/bin/script -qec '" + command + "' /dev/null > " + log.string() + " 2>&1";
    ASSERT_EQ(std::system(shell.c_str()), 0) << read_text(log);
    const std::string seen = read_text(log);
    EXPECT_NE(seen.find("\rgenerate: run"), std::string::npos) << seen;
    EXPECT_NE(seen.find("\r\033[K"), std::string::npos) << seen;
}

}  // namespace
}  // namespace voxfield::test
