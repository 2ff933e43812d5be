// The sparse suite's trace timing (bench_sparse_trace.hpp).
#include "bench_sparse_trace.hpp"

#include <string>
#include <vector>

#include "cli_util.hpp"
#include "voxfield/core/error.hpp"
#include "voxfield/core/stats.hpp"
#include "voxfield/vk/sparse_tracer.hpp"

namespace voxfield::cli {

nlohmann::json sparse_trace_keys(const SparseWorld& world, const Palette& palette,
                                 std::uint32_t runs) {
    constexpr std::uint32_t kWidth = 1920, kHeight = 1080;
    try {
        vk::Context ctx;
        vk::SparseTracer tracer(ctx);
        tracer.upload(world, palette);
        vk::RenderOptions r;
        r.width = kWidth;
        r.height = kHeight;
        r.camera = vk::default_camera(world, kWidth, kHeight);
        nlohmann::json keys = {{"trace_width", kWidth},
                               {"trace_height", kHeight},
                               {"trace_vulkan_device", ctx.info().name},
                               {"trace_device_bytes", tracer.stats().bytes},
                               {"trace_node_chunks", tracer.stats().node_chunks},
                               {"trace_material_chunks", tracer.stats().material_chunks}};
        for (const vk::Shading shading : {vk::Shading::flat, vk::Shading::lit}) {
            r.shading = shading;
            tracer.render(r);  // untimed: first use of the pipeline
            std::vector<double> ms;
            for (std::uint32_t i = 0; i < runs; ++i) {
                ms.push_back(tracer.render(r).raymarch_ms);
            }
            const std::string name = shading == vk::Shading::flat ? "flat" : "lit";
            keys["trace_" + name + "_ms"] =
                ms.front() < 0 ? nlohmann::json() : nlohmann::json(summarize(ms).median);
            keys["trace_" + name + "_ms_samples"] = ms;
        }
        r.shading = vk::Shading::flat;
        r.count = true;
        const vk::Image counted = tracer.render(r);
        const double rays = double(kWidth) * kHeight;
        keys["trace_node_visits_per_ray"] = double(counted.fetches) / rays;
        keys["trace_node_exits_per_ray"] = double(counted.steps) / rays;
        return keys;
    } catch (const vk::DeviceSelectionError& e) {
        return {{"trace_skipped", std::string("no Vulkan device: ") + e.what()}};
    } catch (const InputError& e) {
        return {{"trace_skipped", e.what()}};
    } catch (const vk::VkError& e) {
        // The device's memory does not hold the tracer's copy (besides OpenCL's world and field
        // when both run on one GPU).
        if (e.result() != VK_ERROR_OUT_OF_DEVICE_MEMORY &&
            e.result() != VK_ERROR_OUT_OF_HOST_MEMORY) {
            throw;
        }
        return {{"trace_skipped", e.what()}};
    }
}

std::string describe_sparse_trace(const nlohmann::json& keys) {
    if (keys.contains("trace_skipped")) {
        return "trace skipped: " + keys["trace_skipped"].get<std::string>();
    }
    auto ms = [&](const char* key) {
        return keys[key].is_null() ? std::string("? (no timestamps)")
                                   : fixed(keys[key].get<double>(), 2) + " ms";
    };
    return "traced 1920x1080 on " + keys["trace_vulkan_device"].get<std::string>() + ": flat " +
           ms("trace_flat_ms") + ", lit " + ms("trace_lit_ms") + " (GPU timestamps), " +
           fixed(keys["trace_node_visits_per_ray"].get<double>(), 2) + " node visits per ray, " +
           std::to_string(keys["trace_node_chunks"].get<std::uint32_t>()) + " node and " +
           std::to_string(keys["trace_material_chunks"].get<std::uint32_t>()) + " material chunks";
}

}  // namespace voxfield::cli
