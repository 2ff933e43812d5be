// `voxfield bench --plot` (bench_plot.hpp).
#include "bench_plot.hpp"

#include <unistd.h>

#include <cstdlib>
#include <filesystem>
#include <iostream>

#include "voxfield/core/error.hpp"

namespace voxfield::cli {
namespace {

namespace fs = std::filesystem;

bool python_has_matplotlib(const std::string& python) {
    const std::string cmd = python + " -c 'import matplotlib' >/dev/null 2>&1";
    return std::system(cmd.c_str()) == 0;
}

}  // namespace

Plotter require_plotter() {
    // The script is installed beside the binary's tree: <prefix>/share/voxfield/plot.py,
    // which the build tree mirrors (build/share/voxfield/plot.py beside build/viewer/).
    Plotter p;
    std::error_code ec;
    const fs::path exe = fs::read_symlink("/proc/self/exe", ec);
    if (!ec) {
        const fs::path candidate =
            exe.parent_path().parent_path() / "share" / "voxfield" / "plot.py";
        if (fs::is_regular_file(candidate))
            p.script = candidate.string();
    }
    if (p.script.empty()) {
        throw InputError("--plot needs plot.py in share/voxfield/ beside the voxfield binary (" +
                         (ec ? std::string("its path is unknown") : exe.string()) +
                         "); reinstall voxfield");
    }
    std::vector<std::string> pythons;
    if (const char* env = std::getenv("VOXFIELD_PYTHON"); env != nullptr && *env != '\0') {
        pythons.emplace_back(env);
    }
    pythons.emplace_back("/usr/bin/python3");
    pythons.emplace_back("python3");
    for (const std::string& py : pythons) {
        if ((py.find('/') == std::string::npos || ::access(py.c_str(), X_OK) == 0) &&
            python_has_matplotlib(py)) {
            p.python = py;
            return p;
        }
    }
    throw InputError(
        "--plot needs python3 with matplotlib, found none (tried VOXFIELD_PYTHON, "
        "/usr/bin/python3, python3): apt-get install python3-matplotlib");
}

void run_plotter(const Plotter& p, const std::string& dir, const std::vector<std::string>& files) {
    const auto quote = [](const std::string& s) {
        std::string out = "'";
        for (char c : s) {
            out += c == '\'' ? std::string("'\\''") : std::string(1, c);
        }
        out += '\'';
        return out;
    };
    // Appended piece by piece: GCC 12's -Wrestrict misreads the chain of `+` here.
    std::string cmd = quote(p.python);
    cmd += ' ';
    cmd += quote(p.script);
    cmd += " --out ";
    cmd += quote(dir);
    for (const auto& f : files) {
        cmd += ' ';
        cmd += quote(f);
    }
    std::cerr << "bench: plotting: " << cmd << '\n';
    if (std::system(cmd.c_str()) != 0) {
        throw InputError("plotting failed: " + cmd);
    }
}

}  // namespace voxfield::cli
