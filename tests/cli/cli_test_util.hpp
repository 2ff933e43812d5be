#pragma once
// Shared by the end-to-end tests of the `voxfield` executable: spawning it with captured
// stdout/stderr and exit code, and small file helpers.
#include <fcntl.h>
#include <spawn.h>
#include <sys/wait.h>
#include <unistd.h>

#include <gtest/gtest.h>

#include <cerrno>
#include <cstdint>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <optional>
#include <set>
#include <sstream>
#include <stdexcept>
#include <string>
#include <utility>
#include <vector>

#include "../xvfb_run.hpp"

extern char** environ;

namespace voxfield::test {

namespace fs = std::filesystem;

inline const fs::path kExe = VOXFIELD_EXE;

struct RunResult {
    int code = -1;
    std::string out, err;
};

inline std::string read_text(const fs::path& p) {
    std::ifstream in(p, std::ios::binary);
    return {std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>()};
}

inline std::vector<std::uint8_t> read_bytes(const fs::path& p) {
    std::ifstream in(p, std::ios::binary);
    return {std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>()};
}

inline void write_file(const fs::path& p, const std::string& bytes) {
    std::ofstream out(p, std::ios::binary);
    out.write(bytes.data(), static_cast<std::streamsize>(bytes.size()));
    ASSERT_TRUE(out.good()) << p;
}

inline fs::path make_temp_dir(const std::string& stem) {
    std::string tmpl = (fs::temp_directory_path() / (stem + "_XXXXXX")).string();
    if (::mkdtemp(tmpl.data()) == nullptr) {
        throw std::runtime_error("mkdtemp failed for " + tmpl);
    }
    return tmpl;
}

inline std::set<std::string> list_dir(const fs::path& dir) {
    std::set<std::string> names;
    for (const auto& e : fs::directory_iterator(dir)) {
        names.insert(e.path().filename().string());
    }
    return names;
}

inline std::vector<std::string> split_lines(const std::string& text) {
    std::vector<std::string> lines;
    std::istringstream in(text);
    for (std::string line; std::getline(in, line);) {
        lines.push_back(line);
    }
    return lines;
}

// Runs the binary with `args`; stdout/stderr go to files in `io_dir` (never the work folder,
// so that the folder listing checks see only what voxfield wrote).
// Starts voxfield with `args`, stdin from /dev/null and stdout and stderr into the files
// given; its pid, or 0 with `error` set.
inline pid_t spawn_voxfield(const std::vector<std::string>& args, const fs::path& out_path,
                            const fs::path& err_path, std::string& error) {
    std::vector<std::string> argv_s = {kExe.string()};
    argv_s.insert(argv_s.end(), args.begin(), args.end());
    std::vector<char*> argv;
    for (auto& a : argv_s) {
        argv.push_back(a.data());
    }
    argv.push_back(nullptr);

    posix_spawn_file_actions_t fa;
    posix_spawn_file_actions_init(&fa);
    posix_spawn_file_actions_addopen(&fa, 1, out_path.c_str(), O_WRONLY | O_CREAT | O_TRUNC, 0644);
    posix_spawn_file_actions_addopen(&fa, 2, err_path.c_str(), O_WRONLY | O_CREAT | O_TRUNC, 0644);
    posix_spawn_file_actions_addopen(&fa, 0, "/dev/null", O_RDONLY, 0);
    pid_t pid = 0;
    const int rc = posix_spawn(&pid, argv[0], &fa, nullptr, argv.data(), environ);
    posix_spawn_file_actions_destroy(&fa);
    if (rc != 0) {
        error = std::string("posix_spawn failed: ") + std::strerror(rc);
        return 0;
    }
    return pid;
}

inline RunResult run_voxfield(const std::vector<std::string>& args, const fs::path& io_dir) {
    static int counter = 0;
    ++counter;
    const fs::path out_path = io_dir / ("stdout_" + std::to_string(counter));
    const fs::path err_path = io_dir / ("stderr_" + std::to_string(counter));
    RunResult r;
    const pid_t pid = spawn_voxfield(args, out_path, err_path, r.err);
    if (pid == 0) {
        return r;
    }
    int status = 0;
    while (::waitpid(pid, &status, 0) < 0 && errno == EINTR) {
    }
    if (WIFEXITED(status)) {
        r.code = WEXITSTATUS(status);
    } else if (WIFSIGNALED(status)) {
        r.code = 128 + WTERMSIG(status);
    }
    r.out = read_text(out_path);
    r.err = read_text(err_path);
    fs::remove(out_path);
    fs::remove(err_path);
    return r;
}

// A fixture's two temporary folders, made before each test and removed after it: dir_ for its
// files, io_ for run_voxfield's captured output (stem and stem + "_io").
class TempDirsTest : public ::testing::Test {
  protected:
    explicit TempDirsTest(std::string stem) : stem_(std::move(stem)) {}
    void SetUp() override {
        dir_ = make_temp_dir(stem_);
        io_ = make_temp_dir(stem_ + "_io");
    }
    void TearDown() override {
        std::error_code ec;
        fs::remove_all(dir_, ec);
        fs::remove_all(io_, ec);
    }
    RunResult run(const std::vector<std::string>& args) { return run_voxfield(args, io_); }

    fs::path dir_, io_;

  private:
    std::string stem_;
};

inline std::string describe(const RunResult& r) {
    return "exit " + std::to_string(r.code) + "\n--- stdout ---\n" + r.out + "--- stderr ---\n" +
           r.err;
}

// For the viewer's end-to-end tests, while alive: no display (DISPLAY and WAYLAND_DISPLAY
// unset, restored afterwards), the CPU Vulkan device and `--validate` for every run (the
// validation layer's messages, synchronisation validation included, are printed and any
// makes the viewer exit 1).
class HeadlessViewerEnv {
  public:
    HeadlessViewerEnv() {
        for (const char* v : kDisplays) {
            const char* old = std::getenv(v);
            saved_.push_back(old ? std::optional<std::string>(old) : std::nullopt);
        }
        for (const char* v : kDisplays) {
            ::unsetenv(v);
        }
        ::setenv("VOXFIELD_DEVICE", "cpu", 1);
        ::setenv("VOXFIELD_VALIDATE", "1", 1);
    }
    ~HeadlessViewerEnv() {
        for (std::size_t i = 0; i < 2; ++i) {
            if (saved_[i]) {
                ::setenv(kDisplays[i], saved_[i]->c_str(), 1);
            }
        }
    }
    HeadlessViewerEnv(const HeadlessViewerEnv&) = delete;
    HeadlessViewerEnv& operator=(const HeadlessViewerEnv&) = delete;

  private:
    static constexpr const char* kDisplays[2] = {"DISPLAY", "WAYLAND_DISPLAY"};
    std::vector<std::optional<std::string>> saved_;
};

inline bool have_xvfb() {
    return std::system("command -v xvfb-run >/dev/null 2>&1") == 0;
}

// Runs `voxfield ARGS` under a fresh Xvfb server; returns the exit code, output in `log`.
inline int run_under_xvfb(const std::vector<std::string>& args, const fs::path& log,
                          const std::string& screen = "640x480x24") {
    std::string cmd = xvfb_run(screen) + " '" + kExe.string() + "'";
    for (const auto& a : args) {
        cmd += " '" + a + "'";
    }
    cmd += " >'" + log.string() + "' 2>&1";
    const int status = std::system(cmd.c_str());
    return WIFEXITED(status) ? WEXITSTATUS(status) : 128;
}

}  // namespace voxfield::test
