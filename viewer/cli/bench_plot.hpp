#pragma once
// `voxfield bench --plot DIR`: bench/plot.py, installed in <prefix>/share/voxfield/ (the build
// tree mirrors it in build/share/voxfield/), run on the JSON the command wrote.
#include <string>
#include <vector>

namespace voxfield::cli {

// The Python interpreter that has matplotlib (VOXFIELD_PYTHON, /usr/bin/python3, python3),
// and plot.py found through the binary's own path; throws InputError (exit 2) naming
// `apt-get install python3-matplotlib` when there is none. Called before any long run starts.
struct Plotter {
    std::string python, script;
};
Plotter require_plotter();
// Runs plot.py on the JSON files, writing PNGs into `dir` (the command line on stderr);
// throws InputError if it fails.
void run_plotter(const Plotter& p, const std::string& dir, const std::vector<std::string>& files);

}  // namespace voxfield::cli
