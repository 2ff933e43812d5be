// The Vulkan steps that the compute passes (raymarcher.cpp, sparse_tracer.cpp) share: a
// descriptor-set layout of compute bindings, a pipeline layout with one push-constant range, a
// shader module, a pool of one set, a timestamp query pool and its read-out, a compute pipeline,
// descriptor writes, colour-image barriers (present.cpp uses those too) and the offscreen r32ui
// image read back through a buffer. Internal to vk/.
#pragma once

#include <cstddef>
#include <cstdint>
#include <string>
#include <vector>

#include "voxfield/vk/context.hpp"

namespace voxfield::vk {

// One compute-stage binding of `type`.
VkDescriptorSetLayoutBinding compute_binding(std::uint32_t binding, VkDescriptorType type);

// A set layout of `bindings`; `what` names the owner in errors.
Owned<VkDescriptorSetLayout> make_set_layout(
    VkDevice dev, const std::vector<VkDescriptorSetLayoutBinding>& bindings,
    const std::string& what);

// A pipeline layout of `set_layout` and one compute push-constant range of `push_bytes`.
Owned<VkPipelineLayout> make_pipeline_layout(VkDevice dev, VkDescriptorSetLayout set_layout,
                                             std::uint32_t push_bytes, const std::string& what);

// A shader module of the SPIR-V `code` (`bytes` long); `what` names the shader.
Owned<VkShaderModule> make_shader(VkDevice dev, const std::uint32_t* code, std::size_t bytes,
                                  const std::string& what);

// A pool for one set of one storage image and `buffers` storage buffers.
Owned<VkDescriptorPool> make_set_pool(VkDevice dev, std::uint32_t buffers, const std::string& what);

// Allocates the one set of `layout` from `pool`.
VkDescriptorSet allocate_set(VkDevice dev, VkDescriptorPool pool, VkDescriptorSetLayout layout,
                             const std::string& what);

// A pool of `count` timestamp queries.
Owned<VkQueryPool> make_timestamp_pool(VkDevice dev, std::uint32_t count, const std::string& what);

// The compute pipeline of `shader`'s "main" with `spec` under `layout`; `what` names it.
Owned<VkPipeline> make_compute_pipeline(VkDevice dev, VkShaderModule shader,
                                        VkPipelineLayout layout, const VkSpecializationInfo& spec,
                                        const std::string& what);

// A write of one descriptor of `type` at `binding` of `set` (the caller points it at its info).
VkWriteDescriptorSet descriptor_write(VkDescriptorSet set, std::uint32_t binding,
                                      VkDescriptorType type);

// A barrier over the whole colour image `image` from layout `from` to `to`, queue families
// ignored.
VkImageMemoryBarrier color_barrier(VkImage image, VkAccessFlags src, VkAccessFlags dst,
                                   VkImageLayout from, VkImageLayout to);

// The milliseconds between timestamps `first` and `first + 1` of `pool`; wait: until they are
// available, else -1 when they are not yet. `what` names them in errors.
double timestamp_pair_ms(Context& ctx, VkQueryPool pool, std::uint32_t first, bool wait,
                         const std::string& what);

// An offscreen image of one r32ui texel per RGBA8 pixel, storage and copy source, with its view
// and a readback buffer of the same bytes.
struct OffscreenTarget {
    std::uint32_t width = 0, height = 0;
    Owned<VkDeviceMemory> memory;  // declared first: freed after the image is destroyed
    Owned<VkImage> image;
    Owned<VkImageView> view;
    Buffer readback;
};

// Makes an OffscreenTarget of width x height: `what` names the image, `memory_what` its memory
// and `readback_what` the readback buffer in errors.
OffscreenTarget make_offscreen_target(Context& ctx, std::uint32_t width, std::uint32_t height,
                                      const std::string& what, const std::string& memory_what,
                                      const std::string& readback_what);

}  // namespace voxfield::vk
