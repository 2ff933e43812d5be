#pragma once
// `voxfield bench --suite NAME`: the dissertation's generation-time experiments, its editing
// protocol headless, the renderer's frame times, the falling sand and the implicit parts, each
// as one reproducible run that returns DESIGN §4 bench JSON (plus the suite's own fields).
// The harness never prints: what happens while it runs goes to a BenchObserver, which the
// command line turns into its log, progress line and table (cli/bench_print.hpp).
#include <nlohmann/json.hpp>

#include <cstdint>
#include <optional>
#include <string>
#include <vector>

#include "cli_util.hpp"
#include "voxfield/cl/runtime.hpp"
#include "voxfield/core/world.hpp"

namespace voxfield::cli {

struct SuiteOptions {
    std::string suite;
    bool quick = false;
    std::uint32_t repeat = 0;             // 0: the suite's default (full or --quick)
    std::optional<std::uint32_t> warmup;  // none: the suite's default
    double budget_s = 0;                  // per-row wall-clock budget; 0: the suite's default
    std::uint64_t seed = 6683787;
    std::uint32_t chunk = 16;     // edits: the chunk-local algorithms' chunk size
    std::uint32_t edits = 0;      // edits: how many; 0: the suite's default
    std::uint32_t world = 0;      // edits, sand: the world's edge; 0: the suite's default
    std::string format = "u16";   // edits: the field format
    std::string implicit_part;    // implicit: the part's .sdf.json (data/parts/bracket.sdf.json)
    std::vector<Dims> sizes;      // sparse, sparse-sand: the worlds (empty: the suite's default)
    GeneratorFlags field;         // sparse, sparse-sand: metric, spacing, sign, --max-distance
    bool compare_blocks = false;  // sparse: also time the whole field by blocks (--compare-blocks)
    bool peer = false;            // sparse: then OpenVDB's fast sweeping on the same world (--peer)
};

// What a suite reports while it runs, in order; every call is optional to act on.
class BenchObserver {
  public:
    virtual ~BenchObserver() = default;
    // A line of the run's log: the plan, a row being set up, a row skipped and why, a row cut
    // short by its time budget, the suite done ("[3/40] Table 4.2 brute 8x8x8: setting up").
    virtual void stage(const std::string& /*text*/) {}
    // What is being done now, replacing the previous one ("[3/40] Table 4.2 brute 8x8x8: run
    // 2/3"); a suite sends many of these, some per kernel launch.
    virtual void progress(const std::string& /*what*/) {}
    // One measurement inside a row that is not complete yet: the render suite's metric at one
    // resolution (its "metrics" entry plus "size", "width" and "height").
    virtual void measured(const nlohmann::json& /*measurement*/) {}
    // A row of "results", measured or skipped (with "skipped": why), as soon as it is done.
    virtual void row(const nlohmann::json& /*row*/) {}
};

// "dissertation", "edits", "render", "sand", "implicit", "sparse", "sparse-sand".
const std::vector<std::string>& suite_names();

// Throws InputError for the options of a sparse suite (sparse, sparse-sand) that it cannot take
// (sizes over kMaxSparseAxis, a bad metric, bound or format), before any device is opened.
void check_sparse_suite_options(const SuiteOptions& o);

// Runs suite `o.suite` on `ctx` (the render suite also opens a Vulkan context of its own) and
// returns its document: {"device", "commit", "date", "suite", "quick", "scene", "seed",
// "repeat", "warmup", "time_budget_s", the suite's own keys, "results": the rows}. Throws
// InputError for options the suite cannot take, before its first row.
nlohmann::json run_suite(ocl::Context& ctx, const SuiteOptions& o, BenchObserver& observer);

}  // namespace voxfield::cli
