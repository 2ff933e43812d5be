// The files `voxfield bench` finds beside its binary (bench_files.hpp).
#include "bench_files.hpp"

#include <unistd.h>

#include <cstdlib>
#include <filesystem>
#include <iostream>

#include "voxfield/core/error.hpp"

namespace voxfield::cli {
namespace {

namespace fs = std::filesystem;

// <prefix>/share/voxfield for the binary at <prefix>/bin (build/share/voxfield for
// build/viewer), or why it is unknown.
fs::path share_dir(std::string& why) {
    std::error_code ec;
    const fs::path exe = fs::read_symlink("/proc/self/exe", ec);
    if (ec) {
        why = "its path is unknown";
        return {};
    }
    why = exe.string();
    return exe.parent_path().parent_path() / "share" / "voxfield";
}

bool python_has_matplotlib(const std::string& python) {
    const std::string cmd = python + " -c 'import matplotlib' >/dev/null 2>&1";
    return std::system(cmd.c_str()) == 0;
}

}  // namespace

fs::path require_implicit_part() {
    const fs::path here = fs::current_path() / "data" / "parts" / "bracket.sdf.json";
    if (fs::is_regular_file(here)) {
        return here;
    }
    std::string why;
    const fs::path share = share_dir(why);
    if (!share.empty() && fs::is_regular_file(share / "parts" / "bracket.sdf.json")) {
        return share / "parts" / "bracket.sdf.json";
    }
    throw InputError(
        "--suite implicit needs data/parts/bracket.sdf.json in the working directory or "
        "share/voxfield/parts/ beside the voxfield binary (" +
        why + "); reinstall voxfield");
}

Plotter require_plotter() {
    Plotter p;
    std::string why;
    const fs::path share = share_dir(why);
    if (share.empty() || !fs::is_regular_file(share / "plot.py")) {
        throw InputError("--plot needs plot.py in share/voxfield/ beside the voxfield binary (" +
                         why + "); reinstall voxfield");
    }
    p.script = (share / "plot.py").string();
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
