#pragma once
// The falling-sand loop that `simulate` and `bench --suite sand` share: each step of the
// automaton on the device, then its changed voxels through the incremental field in one batch.
#include <cstddef>
#include <cstdint>
#include <functional>
#include <vector>

#include <nlohmann/json.hpp>

#include "voxfield/cl/incremental.hpp"
#include "voxfield/cl/sand.hpp"
#include "voxfield/core/stats.hpp"

namespace voxfield::cli {

struct SandStepRecord {
    std::uint64_t step = 0;
    double simulate_ms = 0, update_ms = 0;  // device time (profiling events)
    double wall_ms = 0;                     // the step and its update, host included
    std::size_t voxels_changed = 0;
    std::uint64_t voxels_recomputed = 0;
    bool full_regeneration = false;
};

// Toggles voxel 0 and restores it, untimed: the first launch of each update kernel pays its
// build (PoCL compiles per kernel and work-group shape), so that update times measure updates
// (the updates are exact: the field is as before).
void warm_up_updates(ocl::IncrementalField& field);

// Runs steps [0, steps) with `seed`; after each, `after` (if set) sees its record and returns
// false to stop the run there. Returns the records of the steps run.
std::vector<SandStepRecord> run_sand_steps(
    ocl::SandSimulator& sim, ocl::IncrementalField& field, std::uint64_t seed, std::uint64_t steps,
    const std::function<bool(const SandStepRecord&)>& after = {});

// What `simulate` and `bench --suite sand` report of a run: per-step device-time statistics,
// totals, and each step as JSON ({"step", "simulate_ms", "update_ms", "wall_ms",
// "voxels_changed", "voxels_recomputed", "full_regeneration"}).
struct SandRunSummary {
    Summary simulate, update, step;  // device ms per step; step = simulate + update
    double device_ms = 0, wall_ms = 0;
    std::size_t voxels_changed = 0, full_regenerations = 0;
    nlohmann::json per_step = nlohmann::json::array();
};
SandRunSummary summarize_run(const std::vector<SandStepRecord>& records);

}  // namespace voxfield::cli
