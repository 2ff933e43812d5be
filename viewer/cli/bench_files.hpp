#pragma once
// The files `voxfield bench` finds beside its binary, in <prefix>/share/voxfield/ (the build
// tree mirrors it in build/share/voxfield/), so that an installed binary needs no source tree:
// bench/plot.py for --plot, run on the JSON the command wrote, and the implicit suite's part.
#include <filesystem>
#include <string>
#include <vector>

namespace voxfield::cli {

// --suite implicit's part: data/parts/bracket.sdf.json of the working directory, else
// share/voxfield/parts/bracket.sdf.json beside the binary; throws InputError naming both.
std::filesystem::path require_implicit_part();

// The Python interpreter that has matplotlib (VOXFIELD_PYTHON, /usr/bin/python3, python3),
// and share/voxfield/plot.py beside the binary; throws InputError (exit 2) naming
// `apt-get install python3-matplotlib` when there is none. Called before any long run starts.
struct Plotter {
    std::string python, script;
};
Plotter require_plotter();
// Runs plot.py on the JSON files, writing PNGs into `dir` (the command line on stderr);
// throws InputError if it fails.
void run_plotter(const Plotter& p, const std::string& dir, const std::vector<std::string>& files);

}  // namespace voxfield::cli
