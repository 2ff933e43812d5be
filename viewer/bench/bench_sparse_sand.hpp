#pragma once
// `voxfield bench --suite sparse-sand`: falling sand and water on sparse worlds (issue 24). Per
// size, core's terrain-and-city scene (CityScene) built tile by tile into a SparseWorld, its
// snow (material 2) falling as sand and its lakes (material 7) flowing as water, with balls of
// both dropped from above the surface first (at rest, the city does not move), stepped by
// ocl::SparseSand with the bounded field updated within D of each step's changes: steps per
// second, the simulation's and the field update's device times, tiles run and changed per step;
// on worlds small enough to be dense, the world and field after the last step compared with the
// CPU automaton and the dense bounded field.
#include <nlohmann/json.hpp>

#include <cstdint>

#include "bench_suites.hpp"
#include "voxfield/cl/runtime.hpp"

namespace voxfield::cli {

// One row per size in `o.sizes` (default 512x128x512, --quick 256x128x256): `o.field`'s
// metric, spacing, sign and --max-distance (default 16), `o.format` (default u8); `warmup`
// untimed steps, then `steps` timed ones, a row stopping after the step that passes `budget_s`.
nlohmann::json run_sparse_sand(ocl::Context& ctx, const SuiteOptions& o, std::uint32_t steps,
                               std::uint32_t warmup, double budget_s, BenchObserver& observer);

}  // namespace voxfield::cli
