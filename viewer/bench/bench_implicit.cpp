// `voxfield bench --suite implicit` (bench_implicit.hpp).
#include "bench_implicit.hpp"

#include <sys/resource.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <optional>
#include <string>
#include <vector>

#include "cli_util.hpp"
#include "edit_log.hpp"
#include "traced_part.hpp"
#include "voxfield/cl/implicit.hpp"
#include "voxfield/core/error.hpp"
#include "voxfield/core/sdf.hpp"
#include "voxfield/core/stats.hpp"
#include "voxfield/pipeline/frame_pipeline.hpp"
#include "voxfield/vk/context.hpp"
#include "voxfield/vk/raymarcher.hpp"

namespace voxfield::cli {
namespace {

namespace fs = std::filesystem;
using nlohmann::json;

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

// The part as committed (its own voxel size), discretised with the default tile depth and traced
// by the ray marcher at 1920x1080 from render's default camera, lit (shadow rays, occlusion)
// and flat, through the frame pipeline that render and view use: one row per shading, each
// frame's dispatch timed by GPU timestamps.
json trace_rows(ocl::Context& ctx, const fs::path& path, std::uint32_t repeat, std::uint32_t warmup,
                double budget_s, BenchObserver& observer) {
    constexpr std::uint32_t kWidth = 1920, kHeight = 1080;
    const sdf::Part source = sdf::load_part(path);
    const TracedPart part = load_traced_part(ctx, source, path.string());
    const Dims dims = part.model.world.dims();
    vk::Context vk_ctx;
    observer.stage("suite implicit: ray march of " + path.filename().string() + " " +
                   dims.to_string() + " at " + std::to_string(kWidth) + "x" +
                   std::to_string(kHeight) + " on " + vk_ctx.info().name);
    pipeline::FramePipeline frames(ctx, vk_ctx, part.model.palette, dims);
    ocl::GeneratorOptions g;
    g.format = Format::u16;
    frames.rebuild(World(part.model.world), g);
    vk::Raymarcher& marcher = frames.marcher();
    marcher.set_implicit(part.surface());
    json rows = json::array();
    for (const vk::Shading shading : {vk::Shading::lit, vk::Shading::flat}) {
        const std::string name = shading == vk::Shading::lit ? "lit" : "flat";
        vk::RenderOptions r;
        r.width = kWidth;
        r.height = kHeight;
        r.camera = vk::default_camera(part.model.world, kWidth, kHeight);
        r.shading = shading;
        r.sky_gradient = shading == vk::Shading::lit;
        std::vector<double> ms;
        const auto start = std::chrono::steady_clock::now();
        vk::Image image;
        for (std::uint32_t i = 0; i < warmup + repeat; ++i) {
            observer.progress("implicit ray march " + name + ": " +
                              (i < warmup ? "warm-up " : "run ") + std::to_string(i + 1));
            marcher.render(r, image);
            if (image.raymarch_ms < 0) {
                throw std::runtime_error(vk_ctx.info().name +
                                         " has no compute timestamps to time the ray march");
            }
            if (i >= warmup) {
                ms.push_back(image.raymarch_ms);
            }
            if (i >= warmup &&
                std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count() >
                    budget_s) {
                break;
            }
        }
        const Summary s = summarize(ms);
        const double rays = double(kWidth) * double(kHeight);
        rows.push_back({{"table", "implicit_trace"},
                        {"group", std::to_string(kWidth) + "x" + std::to_string(kHeight)},
                        {"algorithm", "trace " + name},
                        {"chunk", nullptr},
                        {"metric", "manhattan"},  // the compact field the march steps through
                        {"gvox_per_s", nullptr},  // a frame, not a field: mrays_per_s below
                        {"part", path.filename().string()},
                        {"voxel_size", source.voxel_size},
                        {"size", {dims.x, dims.y, dims.z}},
                        {"width", kWidth},
                        {"height", kHeight},
                        {"shading", name},
                        {"vulkan_device", vk_ctx.info().name},
                        {"tile_depth", part.grid.tile_depth},
                        {"crossed_voxels", part.grid.crossed_count()},
                        {"implicit_bytes", marcher.implicit_bytes()},
                        {"iterations", s.n},
                        {"mrays_per_s", rays / (s.median * 1e-3) / 1e6},
                        {"max_error", nullptr},
                        {"mean_error", nullptr}});
        put_summary(rows.back(), s);
        observer.stage("implicit: ray march " + name + " " + std::to_string(kWidth) + "x" +
                       std::to_string(kHeight) + ": median " + fixed(s.median, 3) +
                       " ms (GPU timestamps, " + std::to_string(s.n) + " runs)");
    }
    return rows;
}

}  // namespace

namespace {

// The value at fraction q of the sorted samples (nearest rank).
double quantile(std::vector<double> v, double q) {
    if (v.empty()) {
        return 0;
    }
    std::sort(v.begin(), v.end());
    return v[static_cast<std::size_t>(q * double(v.size() - 1) + 0.5)];
}

double median_of(const std::vector<double>& v) {
    return quantile(v, 0.5);
}

}  // namespace

json run_implicit(ocl::Context& ctx, const fs::path& path, std::uint32_t repeat,
                  std::uint32_t warmup, double budget_s, bool quick, BenchObserver& observer) {
    if (!fs::is_regular_file(path)) {
        throw InputError("--suite implicit: " + path.string() + ": no such file");
    }
    json rows = json::array();
    const std::vector<std::uint32_t> resolutions =
        quick ? std::vector<std::uint32_t>{256} : std::vector<std::uint32_t>{256, 1024, 4096};
    // One row: `repeat` runs (after `warmup`) of one discretiser into one reused grid, as a
    // caller discretising again would; `pinned` overrides the device's default readback.
    auto measure = [&](const sdf::Part& part, std::uint32_t resolution, std::uint32_t depth,
                       std::optional<bool> pinned) {
        const std::uint32_t edge = 1u << (2 * (depth + 1));
        ocl::ImplicitDiscretiser job(ctx, part, {depth, ocl::Layout::automatic});
        if (pinned) {
            job.set_pinned_readback(*pinned);
        }
        const std::string readback = job.pinned_readback() ? "pinned" : "direct";
        std::vector<double> wall, kernel, cpu, tiles, levels, leaves, reads, host, wait, copy;
        ocl::ImplicitTiming first;
        ocl::ImplicitGrid grid;
        const auto start = std::chrono::steady_clock::now();
        for (std::uint32_t i = 0; i < warmup + repeat; ++i) {
            observer.progress("implicit " + std::to_string(resolution) + "^3 depth " +
                              std::to_string(depth) + " (" + readback +
                              " readback): " + (i < warmup ? "warm-up " : "run ") +
                              std::to_string(i < warmup ? i + 1 : i + 1 - warmup) + "/" +
                              std::to_string(i < warmup ? warmup : repeat));
            const double cpu0 = process_cpu_ms();
            job.run(grid);
            const ocl::ImplicitTiming& t = job.timing();
            if (i == 0) {
                first = t;
            }
            if (i >= warmup) {
                wall.push_back(t.total_ms);
                kernel.push_back(t.kernel_ms);
                cpu.push_back(process_cpu_ms() - cpu0);
                tiles.push_back(t.tiles_ms);
                levels.push_back(t.levels_ms);
                leaves.push_back(t.leaves_ms);
                reads.push_back(t.read_ms);
                host.push_back(t.host_ms);
                wait.push_back(t.wait_ms);
                copy.push_back(t.copy_ms);
            }
            const double spent =
                std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
            if (i >= warmup && spent > budget_s) {
                break;
            }
        }
        const ocl::ImplicitTiming& last = job.timing();
        const Summary s = summarize(wall);
        const double effective = double(part.dims.count());
        json row = {{"table", "implicit"},
                    {"group", std::to_string(resolution) + "^3"},
                    {"algorithm", "implicit depth " + std::to_string(depth) +
                                      (pinned ? " (" + readback + " readback)" : "")},
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
                    {"readback", readback},
                    {"kernel_median_ms", median_of(kernel)},
                    // The wall clock's spread over the runs, beside min_ms / max_ms / std_ms.
                    {"p10_ms", quantile(wall, 0.1)},
                    {"p90_ms", quantile(wall, 0.9)},
                    // Medians per stage: device (profiling) and host (issuing, blocked,
                    // filling the arrays after the last wait).
                    {"tiles_median_ms", median_of(tiles)},
                    {"levels_median_ms", median_of(levels)},
                    {"leaves_median_ms", median_of(leaves)},
                    {"read_median_ms", median_of(reads)},
                    {"host_median_ms", median_of(host)},
                    {"wait_median_ms", median_of(wait)},
                    {"copy_median_ms", median_of(copy)},
                    // Per run: host waits for the device and commands enqueued (the last run;
                    // the first, counted, run apart).
                    {"syncs", last.syncs},
                    {"enqueues", last.enqueues},
                    {"counted", last.counted},
                    {"first_ms", first.total_ms},
                    {"first_syncs", first.syncs},
                    {"first_enqueues", first.enqueues},
                    {"cpu_median_ms", summarize(cpu).median},
                    {"gvox_per_s", effective / (s.median * 1e-3) / 1e9},
                    {"iterations", s.n},
                    {"passes", last.passes},
                    {"nodes", grid.node_count()},
                    {"leaves", grid.leaves},
                    {"crossed_voxels", grid.crossed_count()},
                    {"vertices", grid.vertex_count()},
                    {"solid_voxels", grid.solid_count()},
                    {"bytes", grid.bytes()},
                    {"max_error", nullptr},
                    {"mean_error", nullptr}};
        put_summary(row, s);
        observer.row(row);
        observer.stage(
            "implicit " + std::to_string(resolution) + "^3 depth " + std::to_string(depth) + " (" +
            row["layout"].get<std::string>() + " layout, " + readback + " readback): wall median " +
            fixed(s.median, 3) + " ms (p10 " + fixed(quantile(wall, 0.1), 3) + ", p90 " +
            fixed(quantile(wall, 0.9), 3) + "), kernels " + fixed(median_of(kernel), 3) +
            " ms (tiles " + fixed(median_of(tiles), 3) + ", levels " + fixed(median_of(levels), 3) +
            ", leaves " + fixed(median_of(leaves), 3) + "), reads " + fixed(median_of(reads), 3) +
            " ms; host: issuing " + fixed(median_of(host), 3) + ", waiting " +
            fixed(median_of(wait), 3) + ", copying " + fixed(median_of(copy), 3) + " ms; " +
            std::to_string(last.syncs) + " waits, " + std::to_string(last.enqueues) +
            " enqueues a run (first run " + fixed(first.total_ms, 3) + " ms, " +
            std::to_string(first.syncs) + " waits)");
        return row;
    };
    for (std::uint32_t resolution : resolutions) {
        const sdf::Part part = at_resolution(path, resolution);
        for (std::uint32_t depth = 1; depth <= 4; ++depth) {
            const std::uint32_t edge = 1u << (2 * (depth + 1));
            if (edge > 4 * resolution) {
                continue;  // a single tile mostly outside the grid
            }
            rows.push_back(measure(part, resolution, depth, std::nullopt));
            // The reference blog's configuration (16^3 tiles of depth 2 in its terms: tiles of
            // 16^3 voxels here) again with the other readback, for the device to choose.
            if (resolution == 256 && depth == 1) {
                // (A device computing in host memory reads directly by default.)
                rows.push_back(measure(part, resolution, depth, ctx.computes_in_host_memory()));
            }
        }
    }
    // The trace rows go to the JSON and the log (stage), not to the discretisation table.
    for (json& row : trace_rows(ctx, path, repeat, warmup, budget_s, observer)) {
        rows.push_back(std::move(row));
    }
    return rows;
}

}  // namespace voxfield::cli
