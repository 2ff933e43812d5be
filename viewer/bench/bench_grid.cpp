// `voxfield bench` without --suite (bench_grid.hpp).
#include "bench_grid.hpp"

#include <memory>
#include <optional>

#include "voxfield/cl/generator.hpp"
#include "voxfield/core/accuracy.hpp"
#include "voxfield/core/error.hpp"
#include "voxfield/core/palette.hpp"
#include "voxfield/core/scenes.hpp"
#include "voxfield/core/stats.hpp"

namespace voxfield::cli {

using nlohmann::json;

json run_grid(ocl::Context& ctx, const GridOptions& o, BenchObserver& observer) {
    json results = json::array();
    for (const auto& algorithm : o.algorithms) {
        for (const Dims& dims : o.sizes) {
            const std::string label = algorithm + " " + dims.to_string();
            observer.stage(label + ": building scene '" + o.scene + "'");
            const World world = make_scene(o.scene, dims, o.seed);
            GeneratorFlags flags = o.field;
            flags.algorithm = algorithm;
            flags.chunk = algorithm == "exact" ? 0 : o.chunk;
            std::unique_ptr<ocl::Generator> generator;
            ocl::GeneratorOptions options;
            try {
                options = generator_options(flags, o.format, dims);
                generator =
                    ocl::make_generator(ctx, world, Palette::magicavoxel_default(), options);
            } catch (const InputError& e) {
                // Sizes an algorithm cannot do (brute force on large grids, chunks larger than
                // the world) are reported, not silently dropped.
                observer.stage(label + ": skipped: " + e.what());
                results.push_back({{"algorithm", algorithm},
                                   {"size", {dims.x, dims.y, dims.z}},
                                   {"chunk", flags.chunk == 0 ? json() : json(flags.chunk)},
                                   {"skipped", e.what()}});
                observer.row(results.back());
                continue;
            }
            ocl::Generator& job = *generator;
            std::vector<double> ms;
            StageTimes stage_times;
            for (std::uint32_t i = 0; i < o.warmup + o.repeat; ++i) {
                observer.progress(label + ": " + (i < o.warmup ? "warm-up " : "run ") +
                                  std::to_string(i < o.warmup ? i + 1 : i + 1 - o.warmup) + "/" +
                                  std::to_string(i < o.warmup ? o.warmup : o.repeat));
                const double t = job.run();
                if (i >= o.warmup) {
                    ms.push_back(t);
                    stage_times.add(job);
                }
            }
            double download_ms = 0;
            const auto field = job.read(&download_ms);
            observer.progress(label + ": checking against the CPU reference");
            const Accuracy a = accuracy_of(world, Palette::magicavoxel_default(), options, field);
            const Summary s = summarize(ms);
            const double gvox = static_cast<double>(dims.count()) / (s.median * 1e-3) / 1e9;
            results.push_back(
                {{"algorithm", algorithm},
                 {"size", {dims.x, dims.y, dims.z}},
                 {"chunk", options.chunk == 0 ? json() : json(options.chunk)},
                 {"metric", to_string(options.metric)},
                 {"spacing", {options.spacing.x, options.spacing.y, options.spacing.z}},
                 {"signed", options.signed_field},
                 {"format", to_string(o.format)},
                 {"scene", o.scene},
                 {"seed", o.seed},
                 {"variant", job.variant()},
                 {"repeat", o.repeat},
                 {"warmup", o.warmup},
                 {"median_ms", s.median},
                 {"mean_ms", s.mean},
                 {"std_ms", s.std},
                 {"ci95_ms", {s.ci95_lo, s.ci95_hi}},
                 {"min_ms", s.min},
                 {"max_ms", s.max},
                 {"gvox_per_s", gvox},
                 {"iterations", job.iterations()},
                 {"max_error", a.max_error},
                 {"mean_error", a.mean_error},
                 {"over_fraction", a.over_fraction},
                 {"under_fraction", a.under_fraction},
                 {"upload_ms", job.upload_ms()},
                 {"download_ms", download_ms},
                 {"stages", stage_times.json()},
                 {"samples_ms", ms}});
            observer.row(results.back());
        }
    }
    return {{"device", device_json(ctx.info())},
            {"commit", commit()},
            {"date", utc_now()},
            {"results", results}};
}

}  // namespace voxfield::cli
