#pragma once
// `voxfield bench --suite sparse`: sparse worlds at scale (issue 24). Per size, core's
// terrain-and-city scene (CityScene) built tile by tile into a SparseWorld (no dense array),
// its whole exact bounded field (cl/sparse_field.hpp) timed, radius-8 sphere edits applied on
// the device and timed, the edited regions checked against the dense bounded field of the same
// voxels, peak memory and bytes per stored voxel recorded.
#include <nlohmann/json.hpp>

#include <cstddef>
#include <cstdint>
#include <string>
#include <utility>
#include <vector>

#include "bench_suites.hpp"
#include "voxfield/cl/generator.hpp"
#include "voxfield/cl/runtime.hpp"
#include "voxfield/core/sparse.hpp"

namespace voxfield::cli {

// One row per size in `o.sizes` (default 1024x256x1024, --quick 256x128x256): `o.field`'s
// metric, spacing, sign and --max-distance (default 16), `o.format` (default u8); `o.edits`
// timed edits (default 30, --quick 6) after `warmup` untimed ones; `repeat` whole-field runs.
// The options of a sparse row: the bench flags' metric, spacing, sign and bound (default 16),
// the format given; InputError for a bad combination.
ocl::GeneratorOptions sparse_options(const SuiteOptions& o);
// Core's city scene of `dims` (seed `seed`) built tile by tile into a SparseWorld, announced to
// `observer` as `label`'s build stage; `build_ms` gets the time it took.
SparseWorld build_city(Dims dims, std::uint64_t seed, const std::string& label,
                       BenchObserver& observer, double& build_ms);
// The machine's load averages (1, 5, 15 minutes; /proc/loadavg), null where unreadable: other
// work on the machine slows a CPU device's run.
nlohmann::json load_average();
// Per-name sample columns of a run's stages: `named` (one run's stage times) appended as
// sample number `samples` - 1 of every column, a stage absent from a run counting 0 there.
using StageSamples = std::vector<std::pair<std::string, std::vector<double>>>;
void append_stage_samples(StageSamples& columns, std::size_t samples,
                          const std::vector<std::pair<std::string, double>>& named);

nlohmann::json run_sparse(ocl::Context& ctx, const SuiteOptions& o, std::uint32_t repeat,
                          std::uint32_t warmup, BenchObserver& observer);

}  // namespace voxfield::cli
