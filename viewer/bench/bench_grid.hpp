#pragma once
// `voxfield bench` without --suite: every generator asked for on every world size asked for,
// timed by profiling events and checked against the CPU reference, as DESIGN §4 bench JSON.
// Never prints: its log, progress and rows go to a BenchObserver (bench_suites.hpp).
#include <nlohmann/json.hpp>

#include <cstdint>
#include <string>
#include <vector>

#include "bench_suites.hpp"
#include "cli_util.hpp"
#include "voxfield/cl/runtime.hpp"
#include "voxfield/core/world.hpp"

namespace voxfield::cli {

struct GridOptions {
    std::vector<std::string> algorithms = {"exact"};
    std::vector<Dims> sizes;
    std::string scene = "spheres";
    std::uint64_t seed = 6683787;
    GeneratorFlags field;  // metric, spacing, bound, sign; algorithm and chunk are per row
    Format format = Format::u16;
    std::uint32_t chunk = 0;  // the dissertation's algorithms' chunk (exact stays global)
    std::uint32_t repeat = 10, warmup = 2;
};

// Returns {"device", "commit", "date", "results"}: one row per (algorithm, size) in that order,
// a size an algorithm refuses (brute force on a large grid, a chunk larger than the world) a
// row with "skipped": why. Options no size can take are the caller's to refuse first.
nlohmann::json run_grid(ocl::Context& ctx, const GridOptions& o, BenchObserver& observer);

}  // namespace voxfield::cli
