#pragma once
// The falling-sand loop that `simulate` and `bench --suite sand` share: each step of the
// automaton in place on the scene's device voxels, then the field updated there from the
// step's change list (pipeline::Scene::step_sand): nothing of a step crosses to the host.
#include <cstddef>
#include <cstdint>
#include <functional>
#include <utility>
#include <vector>

#include <nlohmann/json.hpp>

#include "voxfield/cl/sparse_sand.hpp"
#include "voxfield/core/sand.hpp"
#include "voxfield/core/stats.hpp"
#include "voxfield/pipeline/scene.hpp"

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
// `Field`: an ocl::IncrementalField or a pipeline::Scene.
template <class Field>
void warm_up_updates(Field& field) {
    const std::uint8_t v0 = field.world().voxels()[0];
    const std::uint8_t other = v0 != 0 ? std::uint8_t{0} : std::uint8_t{1};
    field.apply_changes({{0, v0, other}});
    field.apply_changes({{0, other, v0}});
}

// Runs steps [0, steps) with `seed`; after each, `after` (if set) sees its record and returns
// false to stop the run there. Returns the records of the steps run.
std::vector<SandStepRecord> run_sand_steps(
    pipeline::Scene& scene, const SandRules& rules, std::uint64_t seed, std::uint64_t steps,
    const std::function<bool(const SandStepRecord&)>& after = {});

// The same loop on a sparse world (ocl::SparseSand, `simulate --sparse` and `bench --suite
// sparse-sand`): steps [0, steps); a record's voxels_recomputed is the volume of the field's
// recomputed hull. `tiles` (if set) receives each step's tiles run and tiles changed.
std::vector<SandStepRecord> run_sparse_sand_steps(
    ocl::SparseSand& sim, std::uint64_t seed, std::uint64_t steps,
    const std::function<bool(const SandStepRecord&)>& after = {},
    std::vector<std::pair<std::uint32_t, std::uint32_t>>* tiles = nullptr);

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
