#pragma once
// `voxfield bench --suite NAME`: the dissertation's generation-time experiments, its editing
// protocol headless, and the renderer's frame times, each as one reproducible run that writes
// DESIGN §4 bench JSON (plus the suite's own fields) and optionally plots it.
#include <cstdint>
#include <optional>
#include <string>
#include <vector>

namespace voxfield::cli {

struct SuiteOptions {
    std::string suite, device, json, csv, plot;
    bool quick = false;
    std::uint32_t repeat = 0;             // 0: the suite's default (full or --quick)
    std::optional<std::uint32_t> warmup;  // none: the suite's default
    double budget_s = 0;                  // per-row wall-clock budget; 0: the suite's default
    std::uint64_t seed = 6683787;
    std::uint32_t chunk = 16;    // edits: the chunk-local algorithms' chunk size
    std::uint32_t edits = 0;     // edits: how many; 0: the suite's default
    std::uint32_t world = 0;     // edits, sand: the world's edge; 0: the suite's default
    std::string format = "u16";  // edits: the field format
};

// "dissertation", "edits", "render", "sand", "implicit".
const std::vector<std::string>& suite_names();

// The Python interpreter that has matplotlib (VOXFIELD_PYTHON, /usr/bin/python3, python3),
// and bench/plot.py; throws InputError (exit 2) naming `apt-get install python3-matplotlib`
// when there is none. Called before any long run starts.
struct Plotter {
    std::string python, script;
};
Plotter require_plotter();
// Runs plot.py on the JSON files, writing PNGs into `dir`; throws InputError if it fails.
void run_plotter(const Plotter& p, const std::string& dir, const std::vector<std::string>& files);

int run_suite(const SuiteOptions& o);

}  // namespace voxfield::cli
