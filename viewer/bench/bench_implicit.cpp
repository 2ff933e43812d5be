// `voxfield bench --suite implicit` (bench_implicit.hpp).
#include "bench_implicit.hpp"

#include <sys/resource.h>

#include <chrono>
#include <cmath>
#include <filesystem>
#include <fstream>
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

json run_implicit(ocl::Context& ctx, const fs::path& path, std::uint32_t repeat,
                  std::uint32_t warmup, double budget_s, bool quick, BenchObserver& observer) {
    if (!fs::is_regular_file(path)) {
        throw InputError("--suite implicit: " + path.string() + ": no such file");
    }
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
                observer.progress("implicit " + std::to_string(resolution) + "^3 depth " +
                                  std::to_string(depth) + ": " +
                                  (i < warmup ? "warm-up " : "run ") +
                                  std::to_string(i < warmup ? i + 1 : i + 1 - warmup) + "/" +
                                  std::to_string(i < warmup ? warmup : repeat));
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
            put_summary(rows.back(), s);
            observer.row(rows.back());
        }
    }
    // The trace rows go to the JSON and the log (stage), not to the discretisation table.
    for (json& row : trace_rows(ctx, path, repeat, warmup, budget_s, observer)) {
        rows.push_back(std::move(row));
    }
    return rows;
}

}  // namespace voxfield::cli
