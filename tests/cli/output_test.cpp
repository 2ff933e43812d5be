// What the commands do with their output paths (README "Output files"): every path checked
// before any work, nothing left behind by a failed run, special files written directly or
// refused, never replaced. Special files are made in a temporary folder (mkfifo, mknod c 1 7
// for a /dev/full-like device); device nodes need root, else those tests are skipped.
#include <signal.h>
#include <sys/stat.h>
#include <sys/sysmacros.h>

#include <chrono>
#include <csignal>
#include <future>
#include <thread>

#include "cli_test_util.hpp"
#include "voxfield/core/npy.hpp"

namespace voxfield::test {
namespace {

class OutputCli : public ::testing::Test {
  protected:
    void SetUp() override {
        dir = make_temp_dir("voxfield_output");
        io = make_temp_dir("voxfield_output_io");
        std::vector<std::uint8_t> voxels(6 * 5 * 4, 0);
        voxels[7] = 1;
        voxels[60] = 3;
        write_npy(dir / "w.npy", NpyType::u8, Dims{6, 5, 4}, voxels);
    }
    void TearDown() override {
        fs::remove_all(dir);
        fs::remove_all(io);
    }
    RunResult run(const std::vector<std::string>& args) { return run_voxfield(args, io); }
    std::string in(const std::string& name) const { return (dir / name).string(); }
    // A character device node in the folder; false (the test skips) without root.
    bool char_device(const std::string& name, unsigned major, unsigned minor) {
        return ::mknod(in(name).c_str(), S_IFCHR | 0666, makedev(major, minor)) == 0;
    }
    bool is_char_device(const std::string& name) const {
        struct stat st {};
        return ::lstat(in(name).c_str(), &st) == 0 && S_ISCHR(st.st_mode);
    }

    fs::path dir, io;
};

TEST_F(OutputCli, AFullDeviceFailsWithExit1NamingThePathAndStaysADevice) {
    if (!char_device("full", 1, 7)) {
        GTEST_SKIP() << "mknod c 1 7 needs root: " << std::strerror(errno);
    }
    const RunResult r = run({"generate", in("w.npy"), "-o", in("full"), "--device", "cpu"});
    EXPECT_EQ(r.code, 1) << describe(r);
    EXPECT_NE(r.err.find("cannot write '" + in("full") + "'"), std::string::npos) << r.err;
    EXPECT_NE(r.err.find("No space left on device"), std::string::npos) << r.err;
    EXPECT_TRUE(is_char_device("full"));
    EXPECT_EQ(list_dir(dir), (std::set<std::string>{"full", "w.npy"}));
}

TEST_F(OutputCli, AFailingJsonLeavesNoFieldBehind) {
    if (!char_device("full", 1, 7)) {
        GTEST_SKIP() << "mknod c 1 7 needs root: " << std::strerror(errno);
    }
    const RunResult r = run({"generate", in("w.npy"), "-o", in("o.npy"), "--indices", in("i.npy"),
                             "--json", in("full"), "--device", "cpu"});
    EXPECT_EQ(r.code, 1) << describe(r);
    EXPECT_EQ(list_dir(dir), (std::set<std::string>{"full", "w.npy"}));
}

TEST_F(OutputCli, ANullDeviceTakesTheOutputAndStaysADevice) {
    if (!char_device("null", 1, 3)) {
        GTEST_SKIP() << "mknod c 1 3 needs root: " << std::strerror(errno);
    }
    const RunResult r = run(
        {"generate", in("w.npy"), "-o", in("null"), "--indices", in("null"), "--device", "cpu"});
    EXPECT_EQ(r.code, 0) << describe(r);
    EXPECT_TRUE(is_char_device("null"));
    EXPECT_EQ(list_dir(dir), (std::set<std::string>{"null", "w.npy"}));
}

TEST_F(OutputCli, AFifoGetsTheFieldAndStaysAFifo) {
    ASSERT_EQ(::mkfifo(in("pipe").c_str(), 0600), 0) << std::strerror(errno);
    auto reader = std::async(std::launch::async, [&] { return read_bytes(in("pipe")); });
    const RunResult r = run({"generate", in("w.npy"), "-o", in("pipe"), "--device", "cpu"});
    EXPECT_EQ(r.code, 0) << describe(r);
    const std::vector<std::uint8_t> bytes = reader.get();
    ASSERT_GE(bytes.size(), 10u);
    EXPECT_EQ(std::string(bytes.begin() + 1, bytes.begin() + 6), "NUMPY");
    EXPECT_EQ(bytes.size(), 128u + 6 * 5 * 4 * 2);  // header + u16 field
    struct stat st {};
    ASSERT_EQ(::lstat(in("pipe").c_str(), &st), 0);
    EXPECT_TRUE(S_ISFIFO(st.st_mode));
}

// Ctrl-C or SIGTERM while a generate's outputs are reserved (their temporaries made while the
// device is set up, before the kernels' many repeats): the signal still ends the process, and
// its handler removes the temporaries, which no destructor would.
TEST_F(OutputCli, ASignalLeavesNoTemporaryBehind) {
    write_npy(dir / "big.npy", NpyType::u8, Dims{64, 64, 64}, std::vector<std::uint8_t>(1 << 18));
    for (const int sig : {SIGINT, SIGTERM}) {
        SCOPED_TRACE(sig);
        std::string error;
        const pid_t pid = spawn_voxfield({"generate", in("big.npy"), "-o", in("f.npy"), "--indices",
                                          in("i.npy"), "--repeat", "100000", "--device", "cpu"},
                                         "/dev/null", "/dev/null", error);
        ASSERT_NE(pid, 0) << error;
        // Both temporaries exist once the kernels repeat (at most a minute on PoCL).
        auto temporaries = [&] {
            std::size_t n = 0;
            for (const auto& name : list_dir(dir)) {
                n += name.find(".tmp-") != std::string::npos;
            }
            return n;
        };
        for (int i = 0; i < 600 && temporaries() < 2; ++i) {
            std::this_thread::sleep_for(std::chrono::milliseconds(100));
        }
        EXPECT_EQ(temporaries(), 2u);
        ::kill(pid, sig);
        int status = 0;
        while (::waitpid(pid, &status, 0) < 0 && errno == EINTR) {
        }
        ASSERT_TRUE(WIFSIGNALED(status));
        EXPECT_EQ(WTERMSIG(status), sig);
        EXPECT_EQ(list_dir(dir), (std::set<std::string>{"big.npy", "w.npy"}));
    }
}

// A signal its caller ignores (nohup's SIGHUP) stays ignored: the handler that removes the
// temporaries is installed only where the signal would have ended the process.
TEST_F(OutputCli, AnIgnoredSignalStaysIgnored) {
    write_npy(dir / "big.npy", NpyType::u8, Dims{64, 64, 64}, std::vector<std::uint8_t>(1 << 18));
    struct sigaction ignore {};
    struct sigaction old {};
    ignore.sa_handler = SIG_IGN;
    ASSERT_EQ(::sigaction(SIGHUP, &ignore, &old), 0);
    std::string error;
    const pid_t pid = spawn_voxfield(
        {"generate", in("big.npy"), "-o", in("f.npy"), "--repeat", "100000", "--device", "cpu"},
        "/dev/null", "/dev/null", error);
    ::sigaction(SIGHUP, &old, nullptr);
    ASSERT_NE(pid, 0) << error;
    for (int i = 0; i < 600 && list_dir(dir).size() < 3; ++i) {
        std::this_thread::sleep_for(std::chrono::milliseconds(100));
    }
    EXPECT_EQ(list_dir(dir).size(), 3u);  // w.npy, big.npy and f.npy's temporary
    ::kill(pid, SIGHUP);
    std::this_thread::sleep_for(std::chrono::milliseconds(500));
    int status = 0;
    EXPECT_EQ(::waitpid(pid, &status, WNOHANG), 0) << "ended by an ignored SIGHUP";
    ::kill(pid, SIGTERM);
    while (::waitpid(pid, &status, 0) < 0 && errno == EINTR) {
    }
    ASSERT_TRUE(WIFSIGNALED(status));
    EXPECT_EQ(WTERMSIG(status), SIGTERM);
    EXPECT_EQ(list_dir(dir), (std::set<std::string>{"big.npy", "w.npy"}));
}

// The indices are streamed from the device a slab at a time: a target that fails part-way
// still leaves no field, and a FIFO gets the same bytes as a file.
TEST_F(OutputCli, StreamedIndicesFailingLeaveNoFieldBehind) {
    if (!char_device("full", 1, 7)) {
        GTEST_SKIP() << "mknod c 1 7 needs root: " << std::strerror(errno);
    }
    const RunResult r = run({"generate", in("w.npy"), "-o", in("o.npy"), "--indices", in("full"),
                             "--metric", "euclidean", "--device", "cpu"});
    EXPECT_EQ(r.code, 1) << describe(r);
    EXPECT_NE(r.err.find("cannot write '" + in("full") + "'"), std::string::npos) << r.err;
    EXPECT_EQ(list_dir(dir), (std::set<std::string>{"full", "w.npy"}));
}

TEST_F(OutputCli, AFifoGetsTheIndicesAFileGets) {
    const RunResult f = run({"generate", in("w.npy"), "-o", in("o.npy"), "--indices", in("i.npy"),
                             "--metric", "euclidean", "--device", "cpu"});
    ASSERT_EQ(f.code, 0) << describe(f);
    ASSERT_EQ(::mkfifo(in("pipe").c_str(), 0600), 0) << std::strerror(errno);
    auto reader = std::async(std::launch::async, [&] { return read_bytes(in("pipe")); });
    const RunResult r = run({"generate", in("w.npy"), "-o", in("p.npy"), "--indices", in("pipe"),
                             "--metric", "euclidean", "--device", "cpu"});
    EXPECT_EQ(r.code, 0) << describe(r);
    EXPECT_EQ(reader.get(), read_bytes(in("i.npy")));
}

TEST_F(OutputCli, BadOutputPathsAreRefusedBeforeAnyWork) {
    fs::create_directory(dir / "adir");
    write_file(dir / "g.json.tmp", "a user's file");
    struct Case {
        std::vector<std::string> args;
        std::string message;
    };
    const std::vector<Case> cases = {
        {{"generate", in("w.npy"), "-o", in("o.npy"), "--json", in("adir")}, "is a directory"},
        {{"generate", in("w.npy"), "-o", in("o.npy"), "--indices", in("adir")}, "is a directory"},
        {{"generate", in("w.npy"), "-o", in("adir")}, "is a directory"},
        {{"generate", in("w.npy"), "-o", in("o.npy"), "--json", in("o.npy")},
         "-o and --json name the same file"},
        {{"generate", in("w.npy"), "-o", in("o.npy"), "--indices", in("./o.npy")},
         "-o and --indices name the same file"},
        {{"generate", in("w.npy"), "-o", in("w.npy")}, "is the input INPUT"},
        {{"generate", in("w.npy"), "-o", in("o.npy"), "--json", in("w.npy/g.json")},
         "is not a folder"},
        {{"replay", in("edits.txt"), "--input", in("w.npy"), "-o", in("o.npy"), "--json",
          in("adir")},
         "no such file"},
        {{"bench", "--sizes", "8", "--json", in("adir")}, "is a directory"},
        {{"view", in("w.npy"), "--fallback-png", in("x.jpg")}, "must be a .png file"},
        {{"view", in("w.npy"), "--screenshot", in("adir")}, "must be a .png file"},
    };
    for (const Case& c : cases) {
        const RunResult r = run(c.args);
        EXPECT_EQ(r.code, 2) << describe(r);
        EXPECT_NE(r.err.find(c.message), std::string::npos) << r.err;
        EXPECT_EQ(r.err.find("bench: device"), std::string::npos) << r.err;
        EXPECT_EQ(list_dir(dir), (std::set<std::string>{"adir", "g.json.tmp", "w.npy"}))
            << describe(r);
    }
    EXPECT_EQ(read_text(dir / "g.json.tmp"), "a user's file");
}

TEST_F(OutputCli, ReplayNamesAMissingFileBeforeSayingItWouldProduceNothing) {
    const RunResult r = run({"replay", in("missing.txt"), "--input", in("w.npy")});
    EXPECT_EQ(r.code, 2) << describe(r);
    EXPECT_NE(r.err.find("missing.txt': no such file"), std::string::npos) << r.err;
}

TEST_F(OutputCli, TwoRunsWritingOneOutputDoNotCollide) {
    write_file(dir / "g.json.tmp", "a user's file");
    const RunResult a = run(
        {"generate", in("w.npy"), "-o", in("o.npy"), "--json", in("g.json"), "--device", "cpu"});
    ASSERT_EQ(a.code, 0) << describe(a);
    EXPECT_EQ(read_text(dir / "g.json.tmp"), "a user's file");
    EXPECT_EQ(list_dir(dir), (std::set<std::string>{"g.json", "g.json.tmp", "o.npy", "w.npy"}));
}

}  // namespace
}  // namespace voxfield::test
