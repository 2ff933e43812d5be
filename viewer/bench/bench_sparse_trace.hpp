#pragma once
// `bench --suite sparse`'s trace of the world (vk::SparseTracer): 1920x1080 flat and lit
// images from render's default camera, timed by GPU timestamps, for each row (after its peak
// memory was read: the tracer's copy of the world is not counted there).
#include <nlohmann/json.hpp>

#include <cstdint>
#include <string>

#include "voxfield/core/palette.hpp"
#include "voxfield/core/sparse.hpp"

namespace voxfield::cli {

// The row's trace keys: trace_width, trace_height, trace_vulkan_device, trace_device_bytes,
// trace_node_chunks and trace_material_chunks (the buffers nodes and materials were cut into),
// trace_flat_ms and trace_lit_ms (medians of `runs` dispatches, the suite's --repeat, after one
// untimed each), their samples, trace_node_visits_per_ray and trace_node_exits_per_ray (flat,
// primary rays); trace_skipped (why) alone when no Vulkan device serves, or the world does not
// fit its limits or its memory.
nlohmann::json sparse_trace_keys(const SparseWorld& world, const Palette& palette,
                                 std::uint32_t runs);
// One line for the run's log: "traced 1920x1080 on DEVICE: flat F ms, lit L ms (GPU timestamps),
// V node visits per ray, N node and M material chunks", or why it was skipped.
std::string describe_sparse_trace(const nlohmann::json& keys);

}  // namespace voxfield::cli
