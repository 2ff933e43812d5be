#pragma once
// `voxfield bench --suite implicit`: discretisation of the gallery's bracket into the tile grid
// of contrees (cl/implicit.hpp) at effective resolutions 256^3, 1024^3 and 4096^3 for several tile
// sizes / contree depths, the reference blog's two among them; and the ray march of the part
// (as committed) traced on its trilinear surface at 1920x1080.
#include <nlohmann/json.hpp>

#include <cstdint>
#include <filesystem>

#include "bench_suites.hpp"
#include "voxfield/cl/runtime.hpp"

namespace voxfield::cli {

// `part` (the gallery's bracket, data/parts/bracket.sdf.json) discretised: one row per
// (resolution, tile depth): wall-clock times of `repeat` runs after `warmup`
// (stopping early past `budget_s` per row), device kernel time, and the structure's counts
// and bytes; each run's progress and each row go to `observer`. Then two rows of table
// "implicit_trace" (lit and flat): the ray march's GPU time at 1920x1080 (a log line each via
// observer.stage, not observer.row).
nlohmann::json run_implicit(ocl::Context& ctx, const std::filesystem::path& part,
                            std::uint32_t repeat, std::uint32_t warmup, double budget_s, bool quick,
                            BenchObserver& observer);

}  // namespace voxfield::cli
