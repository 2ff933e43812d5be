// `voxfield bench --suite implicit` (bench_implicit.hpp).
#include "bench_implicit.hpp"

#include <sys/resource.h>

#include <chrono>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <iostream>
#include <sstream>
#include <string>
#include <vector>

#include "cli_util.hpp"
#include "voxfield/cl/implicit.hpp"
#include "voxfield/core/error.hpp"
#include "voxfield/core/sdf.hpp"
#include "voxfield/core/stats.hpp"

namespace voxfield::cli {
namespace {

namespace fs = std::filesystem;
using nlohmann::json;

// The gallery's bracket: data/parts of the working directory, else of the source tree the
// binary was built in (build/viewer/voxfield -> build/.. ).
fs::path bracket_path() {
    std::error_code ec;
    const fs::path exe = fs::read_symlink("/proc/self/exe", ec);
    std::vector<fs::path> candidates = {fs::current_path() / "data" / "parts" / "bracket.sdf.json"};
    if (!ec) {
        candidates.push_back(exe.parent_path().parent_path().parent_path() / "data" / "parts" /
                             "bracket.sdf.json");
    }
    for (const fs::path& p : candidates) {
        if (fs::is_regular_file(p)) {
            return p;
        }
    }
    throw InputError(
        "--suite implicit needs data/parts/bracket.sdf.json of the voxfield sources (run from "
        "the repository root)");
}

// The part with its voxel size set so that its longest side spans `resolution` voxels.
sdf::Part at_resolution(const fs::path& path, std::uint32_t resolution) {
    std::ifstream in(path);
    json doc = json::parse(in);
    const auto& b = doc["bounds"];
    double extent = 0;
    for (int a = 0; a < 3; ++a) {
        extent = std::max(extent, b[1][a].get<double>() - b[0][a].get<double>());
    }
    doc["voxel_size"] = extent / resolution;
    return sdf::parse_part(doc.dump(), path.string());
}

// CPU time of this process (every thread, the OpenCL runtime's included), in ms.
double process_cpu_ms() {
    rusage u{};
    getrusage(RUSAGE_SELF, &u);
    return (double(u.ru_utime.tv_sec + u.ru_stime.tv_sec) * 1e3) +
           double(u.ru_utime.tv_usec + u.ru_stime.tv_usec) * 1e-3;
}

}  // namespace

json run_implicit(ocl::Context& ctx, std::uint32_t repeat, std::uint32_t warmup, double budget_s,
                  bool quick) {
    const fs::path path = bracket_path();
    json rows = json::array();
    const std::vector<std::uint32_t> resolutions =
        quick ? std::vector<std::uint32_t>{256} : std::vector<std::uint32_t>{256, 1024};
    for (std::uint32_t resolution : resolutions) {
        const sdf::Part part = at_resolution(path, resolution);
        for (std::uint32_t depth = 1; depth <= 4; ++depth) {
            const std::uint32_t edge = 1u << (2 * (depth + 1));
            if (edge > 4 * resolution) {
                continue;  // a single tile mostly outside the grid
            }
            ocl::ImplicitDiscretiser job(ctx, part, {depth, ocl::Layout::automatic});
            std::vector<double> wall, kernel, cpu;
            double first_ms = 0;
            // One grid reused by every run, as a caller discretising again would.
            ocl::ImplicitGrid grid;
            const auto start = std::chrono::steady_clock::now();
            for (std::uint32_t i = 0; i < warmup + repeat; ++i) {
                const double cpu0 = process_cpu_ms();
                job.run(grid);
                if (i == 0) {
                    first_ms = job.timing().total_ms;
                }
                if (i >= warmup) {
                    wall.push_back(job.timing().total_ms);
                    kernel.push_back(job.timing().kernel_ms);
                    cpu.push_back(process_cpu_ms() - cpu0);
                }
                const double spent =
                    std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
                if (i >= warmup && spent > budget_s) {
                    break;
                }
            }
            const Summary s = summarize(wall);
            const Summary k = summarize(kernel);
            const std::uint64_t solid = grid.solid_count();
            const double effective = double(part.dims.count());
            std::cerr << "bench: implicit " << resolution << "^3 " << part.dims.to_string()
                      << " depth " << depth << " (" << grid.tiles.to_string() << " tiles of "
                      << edge << "^3): " << fixed(s.median, 2) << " ms, " << grid.leaves
                      << " leaves, " << grid.crossed_count() << " crossed voxels, "
                      << fixed(double(grid.bytes()) / 1048576.0, 1) << " MiB\n";
            rows.push_back({{"table", "implicit"},
                            {"group", std::to_string(resolution) + "^3"},
                            {"algorithm", "implicit depth " + std::to_string(depth)},
                            {"part", path.filename().string()},
                            {"effective_resolution", resolution},
                            {"voxel_size", part.voxel_size},
                            {"size", {part.dims.x, part.dims.y, part.dims.z}},
                            {"chunk", edge},
                            {"metric", nullptr},
                            {"tile_depth", depth},
                            {"tile_edge", edge},
                            {"tiles", {grid.tiles.x, grid.tiles.y, grid.tiles.z}},
                            {"layout", job.gpu_layout() ? "gpu" : "cpu"},
                            {"median_ms", s.median},
                            {"mean_ms", s.mean},
                            {"std_ms", s.std},
                            {"ci95_ms", {s.ci95_lo, s.ci95_hi}},
                            {"min_ms", s.min},
                            {"max_ms", s.max},
                            {"kernel_median_ms", k.median},
                            {"first_ms", first_ms},
                            {"cpu_median_ms", summarize(cpu).median},
                            {"gvox_per_s", effective / (s.median * 1e-3) / 1e9},
                            {"iterations", s.n},
                            {"passes", job.timing().passes},
                            {"nodes", grid.node_count()},
                            {"leaves", grid.leaves},
                            {"crossed_voxels", grid.crossed_count()},
                            {"vertices", grid.vertex_count()},
                            {"solid_voxels", solid},
                            {"bytes", grid.bytes()},
                            {"max_error", nullptr},
                            {"mean_error", nullptr}});
        }
    }
    return rows;
}

}  // namespace voxfield::cli
