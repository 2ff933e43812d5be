// The ray marcher's dispatch: the compute pipelines of raymarch.comp, their descriptor set, the
// offscreen image and its readback, recording and timing the march (raymarcher.hpp). What the
// march reads lives in field_residency.cpp; its push constants in march_params.cpp.
#include "voxfield/vk/raymarcher.hpp"

#include <algorithm>
#include <cstddef>
#include <cstring>
#include <stdexcept>
#include <utility>

#include "compute_pipeline.hpp"
#include "field_residency.hpp"
#include "march_params.hpp"
#include "raymarch_spv.h"
#include "voxfield/layout.h"

namespace voxfield::vk {
namespace {

constexpr std::uint32_t kBindings = VF_RAYMARCH_BINDING_MATERIAL + VF_RAYMARCH_MAX_SLABS;
static_assert(VF_RAYMARCH_BINDING_FIELD + VF_RAYMARCH_MAX_SLABS <= VF_RAYMARCH_BINDING_MATERIAL);
// The shader reads the distance of both formats with the packed32 constants.
static_assert(VF_COMPACT_DISTANCE_SHIFT == VF_PACKED_DISTANCE_SHIFT);
static_assert(VF_COMPACT_DISTANCE_MAX == VF_PACKED_DISTANCE_MAX);
// The per-pixel counters of RenderOptions::count (raymarch.comp's buffer C): the binding after
// the material slabs.
constexpr std::uint32_t kCounterBinding = kBindings;
static_assert(VF_RAYMARCH_BINDING_BLOCK_MIN == kCounterBinding + 1);
// The implicit surface's bindings (trace_layout.h) follow the block minima.
static_assert(VF_TRACE_BINDING_TILES == VF_RAYMARCH_BINDING_BLOCK_MIN + 1);

// raymarch.comp's specialization constants: constant_id 0 the metric (kManhattan,
// kChebyshev, kEuclidean = 0, 1, 2), constant_id 1 whether rays count, constant_id 2 whether
// lit shading marches shadow rays, constant_id 3 whether the field lies in one binding,
// constant_id 4 whether it is compact, constant_id 5 whether an implicit surface is traced,
// constant_id 6 whether rays record their hits (VkBool32s).
struct Specialization {
    std::uint32_t metric;
    VkBool32 count;
    VkBool32 shadows;
    VkBool32 one_slab;
    VkBool32 compact;
    VkBool32 implicit;
    VkBool32 surface;
};
// Pipelines per metric: one per combination of the six flags.
constexpr std::size_t kVariants = 64;
constexpr std::size_t kMetrics = 3;
// Timestamp pairs used in turn by recorded ray marches (more than the frames that can be in
// flight, so that a finished frame's pair is read before it is reused).
constexpr std::uint32_t kQueryPairs = 4;

std::uint32_t metric_code(Metric m) {
    switch (m) {
        case Metric::manhattan:
            return 0;
        case Metric::chebyshev:
            return 1;
        case Metric::euclidean:
            return 2;
    }
    throw std::logic_error("ray marcher: unknown metric");
}

// The most bytes one storage-buffer binding of `ctx` holds, lowered to `limit` (0: none), in
// whole words.
VkDeviceSize binding_limit(const Context& ctx, std::uint64_t limit) {
    VkDeviceSize bytes = ctx.info().max_storage_buffer_range;
    if (limit != 0) {
        bytes = std::min<VkDeviceSize>(bytes, limit);
    }
    return bytes / 4 * 4;
}

}  // namespace

struct Raymarcher::Impl {
    Context& ctx;
    // What the march reads (field, materials, palette, block minima, metric).
    FieldResidency field;
    Owned<VkDescriptorSetLayout> set_layout;
    Owned<VkPipelineLayout> pipeline_layout;
    Owned<VkShaderModule> shader;
    // One pipeline per metric and combination of the specialization flags (bits 0..5 of its
    // index among the metric's kVariants: counting, shadow rays, one binding, compact, implicit
    // surface, hit records), built on first use.
    std::array<Owned<VkPipeline>, kMetrics * kVariants> pipelines;
    // The descriptor set, in a pool of its own: when the bindings change while work that uses
    // the set may be in flight, the pool is retired and a fresh set written.
    Owned<VkDescriptorPool> pool;
    VkDescriptorSet set = VK_NULL_HANDLE;
    bool set_recorded = false;  // bound in a command buffer since it was made
    // The field residency's generation() the set was written for.
    std::uint64_t set_generation = 0;
    Owned<VkQueryPool> queries;  // kQueryPairs pairs (dispatch start, end)
    std::array<std::uint64_t, kQueryPairs> pair_serial{};  // the submission that wrote each
    std::uint32_t next_pair = 0;
    std::uint64_t reported_serial = 0;  // finished_raymarch_ms(): the latest pair read
    double reported_ms = -1;
    // RenderOptions::count: one uvec2 (fetches, steps) per pixel; a single one otherwise.
    Buffer counters;
    // RenderOptions::surface: one SurfaceHit per pixel; a single one otherwise.
    Buffer surface;
    // The offscreen image and its readback buffer, kept while the image size stays (a frame
    // loop would otherwise allocate both, megabytes of pinned memory, every frame).
    OffscreenTarget target;
    // render_to's buffer over the caller's exportable memory (rebound when that changes).
    Buffer frame;
    VkDeviceMemory frame_memory = VK_NULL_HANDLE;

    Impl(Context& c, VkDeviceSize max_binding) : ctx(c), field(c, max_binding) {}

    // Records the ray march of `o` into `cmd` (Raymarcher::record); returns the timestamp pair
    // it writes.
    std::uint32_t record(VkCommandBuffer cmd, const RenderOptions& o);
    // Renders `o` and copies the image into `dst` (width * height * 4 bytes), then waits.
    // external: dst lies in memory another VkDevice imports; it is released to
    // VK_QUEUE_FAMILY_EXTERNAL instead of being made visible to the host. Returns the pair.
    std::uint32_t march(const RenderOptions& o, VkBuffer dst, bool external);
    // A set that no work in flight uses (the current one, or a fresh one when it may be in
    // use), with every binding written.
    void write_set();
    // The pipeline of `metric`, with or without counting (built when first asked for).
    VkPipeline pipeline_for(Metric metric, bool count, bool shadows, bool one_slab, bool compact,
                            bool implicit, bool surface);
    // Makes `counters` hold at least `pixels` counters and points its binding at it.
    void prepare_counters(std::size_t pixels);
    // Makes `surface` hold at least `pixels` hits and points its binding at it.
    void prepare_surface(std::size_t pixels);
    // The dispatch time recorded in timestamp pair `pair` (-1 without timestamp queries);
    // wait: until it is available, else -1 when it is not yet.
    double pair_ms(std::uint32_t pair, bool wait);
    // Makes `target` an image of width x height (no-op when it already is).
    void prepare_target(std::uint32_t width, std::uint32_t height, const std::string& what);
};

Raymarcher::Raymarcher(Context& ctx, std::uint64_t max_binding_bytes)
    : impl_(std::make_unique<Impl>(ctx, binding_limit(ctx, max_binding_bytes))) {
    Impl& m = *impl_;
    const VkDevice dev = ctx.device();

    std::vector<VkDescriptorSetLayoutBinding> bindings;
    for (std::uint32_t b = 0; b <= VF_TRACE_LAST_BINDING; ++b) {
        if (b >= VF_RAYMARCH_BINDING_FIELD + VF_RAYMARCH_MAX_SLABS &&
            b < VF_RAYMARCH_BINDING_MATERIAL) {
            continue;
        }
        bindings.push_back(compute_binding(b, b == VF_RAYMARCH_BINDING_IMAGE
                                                  ? VK_DESCRIPTOR_TYPE_STORAGE_IMAGE
                                                  : VK_DESCRIPTOR_TYPE_STORAGE_BUFFER));
    }
    m.set_layout = make_set_layout(dev, bindings, "ray marcher");
    m.pipeline_layout =
        make_pipeline_layout(dev, m.set_layout.get(), sizeof(PushConstants), "ray marcher");
    m.shader = make_shader(dev, vf_raymarch_spv, sizeof(vf_raymarch_spv), "raymarch.comp");

    m.write_set();

    if (ctx.info().timestamps) {
        m.queries = make_timestamp_pool(dev, 2 * kQueryPairs, "ray marcher");
    }
    m.prepare_counters(1);
    m.prepare_surface(1);
}

Raymarcher::~Raymarcher() {
    // Recorded frames may still use the pipelines, the set and the buffers.
    impl_->ctx.wait_frames_in_flight();
}

void Raymarcher::Impl::write_set() {
    const VkDevice dev = ctx.device();
    if (!pool || (set_recorded && ctx.busy())) {
        if (pool) {
            ctx.retire(std::move(pool));  // frees the set once the frames using it finished
        }
        pool = make_set_pool(dev, VF_TRACE_LAST_BINDING + 1, "ray marcher");
        set = allocate_set(dev, pool.get(), set_layout.get(), "ray marcher");
        set_recorded = false;
    }
    std::vector<VkDescriptorBufferInfo> infos;
    infos.reserve(VF_TRACE_LAST_BINDING + 1);
    std::vector<VkWriteDescriptorSet> writes;
    auto add = [&](std::uint32_t binding, const Buffer& b, VkDeviceSize range) {
        if (b.get() == VK_NULL_HANDLE) {
            return;
        }
        infos.push_back(VkDescriptorBufferInfo{b.get(), 0, range});
        VkWriteDescriptorSet w = descriptor_write(set, binding, VK_DESCRIPTOR_TYPE_STORAGE_BUFFER);
        w.pBufferInfo = &infos.back();
        writes.push_back(w);
    };
    add(VF_RAYMARCH_BINDING_PALETTE, field.palette(), VK_WHOLE_SIZE);
    add(kCounterBinding, counters, VK_WHOLE_SIZE);
    add(VF_RAYMARCH_BINDING_BLOCK_MIN, field.block_min(), VK_WHOLE_SIZE);
    add(VF_TRACE_BINDING_SURFACE, surface, VK_WHOLE_SIZE);
    for (std::uint32_t i = 0; i < 4; ++i) {
        add(VF_TRACE_BINDING_TILES + i, field.implicit_buffers()[i], VK_WHOLE_SIZE);
    }
    const FieldLayout& layout = field.layout();
    const std::vector<Buffer>& slabs = field.field();
    const std::vector<Buffer>& material = field.material();
    for (std::uint32_t s = 0; s < VF_RAYMARCH_MAX_SLABS && !slabs.empty(); ++s) {
        // Unused bindings alias slab 0 and are never read; compact fields have no material
        // buffers, so those bindings alias field slab 0 too.
        const std::uint32_t k = s < layout.slabs ? s : 0;
        add(VF_RAYMARCH_BINDING_FIELD + s, slabs[k], layout.slab_bytes(k));
        if (material.empty()) {
            add(VF_RAYMARCH_BINDING_MATERIAL + s, slabs[0], layout.slab_bytes(0));
        } else {
            add(VF_RAYMARCH_BINDING_MATERIAL + s, material[k], VK_WHOLE_SIZE);
        }
    }
    set_generation = field.generation();
    const VkDescriptorImageInfo image_info{VK_NULL_HANDLE, target.view.get(),
                                           VK_IMAGE_LAYOUT_GENERAL};
    if (target.view) {
        VkWriteDescriptorSet w =
            descriptor_write(set, VF_RAYMARCH_BINDING_IMAGE, VK_DESCRIPTOR_TYPE_STORAGE_IMAGE);
        w.pImageInfo = &image_info;
        writes.push_back(w);
    }
    vkUpdateDescriptorSets(dev, static_cast<std::uint32_t>(writes.size()), writes.data(), 0,
                           nullptr);
}

VkPipeline Raymarcher::Impl::pipeline_for(Metric which, bool count, bool shadows, bool one_slab,
                                          bool compact, bool implicit, bool surface_hits) {
    const std::uint32_t code = metric_code(which);
    const std::size_t flags = (count ? 1u : 0u) | (shadows ? 2u : 0u) | (one_slab ? 4u : 0u) |
                              (compact ? 8u : 0u) | (implicit ? 16u : 0u) |
                              (surface_hits ? 32u : 0u);
    Owned<VkPipeline>& slot = pipelines[code * kVariants + flags];
    if (slot) {
        return slot.get();
    }
    const auto flag = [](bool b) { return b ? VkBool32{VK_TRUE} : VkBool32{VK_FALSE}; };
    const Specialization data{code,          flag(count),    flag(shadows),     flag(one_slab),
                              flag(compact), flag(implicit), flag(surface_hits)};
    const std::array<VkSpecializationMapEntry, 7> entries = {
        VkSpecializationMapEntry{0, offsetof(Specialization, metric), sizeof data.metric},
        VkSpecializationMapEntry{1, offsetof(Specialization, count), sizeof data.count},
        VkSpecializationMapEntry{2, offsetof(Specialization, shadows), sizeof data.shadows},
        VkSpecializationMapEntry{3, offsetof(Specialization, one_slab), sizeof data.one_slab},
        VkSpecializationMapEntry{4, offsetof(Specialization, compact), sizeof data.compact},
        VkSpecializationMapEntry{5, offsetof(Specialization, implicit), sizeof data.implicit},
        VkSpecializationMapEntry{6, offsetof(Specialization, surface), sizeof data.surface}};
    VkSpecializationInfo spec{};
    spec.mapEntryCount = static_cast<std::uint32_t>(entries.size());
    spec.pMapEntries = entries.data();
    spec.dataSize = sizeof data;
    spec.pData = &data;
    slot = make_compute_pipeline(
        ctx.device(), shader.get(), pipeline_layout.get(), spec,
        "raymarch.comp, " + to_string(which) + (count ? ", counting" : "") +
            (shadows ? ", shadows" : "") + (one_slab ? ", one binding" : "") +
            (compact ? ", compact" : ", packed32") + (implicit ? ", implicit surface" : "") +
            (surface_hits ? ", hit records" : ""));
    return slot.get();
}

void Raymarcher::Impl::prepare_counters(std::size_t pixels) {
    const VkDeviceSize bytes = VkDeviceSize{8} * pixels;
    if (counters.get() != VK_NULL_HANDLE && counters.size() >= bytes) {
        return;
    }
    ctx.retire(std::move(counters));
    counters = ctx.make_buffer(bytes, VK_BUFFER_USAGE_STORAGE_BUFFER_BIT, MemoryIntent::readback,
                               "ray counters");
    write_set();
}

void Raymarcher::Impl::prepare_surface(std::size_t pixels) {
    const VkDeviceSize bytes = VkDeviceSize{sizeof(SurfaceHit)} * pixels;
    if (surface.get() != VK_NULL_HANDLE && surface.size() >= bytes) {
        return;
    }
    ctx.retire(std::move(surface));
    surface = ctx.make_buffer(bytes, VK_BUFFER_USAGE_STORAGE_BUFFER_BIT, MemoryIntent::readback,
                              "surface hits");
    write_set();
}

void Raymarcher::Impl::prepare_target(std::uint32_t width, std::uint32_t height,
                                      const std::string& what) {
    if (target.width == width && target.height == height) {
        return;
    }
    // Frames in flight may still use the old target (view, image, then its memory go).
    ctx.retire(std::move(target));
    target = OffscreenTarget{};
    // Offscreen target: one r32ui texel per RGBA8 pixel, read back through a buffer.
    target = make_offscreen_target(ctx, width, height, what, "offscreen image", "image readback");
    write_set();
}

Image Raymarcher::render(const RenderOptions& o) {
    Image out;
    render(o, out);
    return out;
}

std::uint32_t Raymarcher::Impl::record(VkCommandBuffer cmd, const RenderOptions& o) {
    Impl& m = *this;
    if (m.field.empty()) {
        throw std::logic_error("Raymarcher::render before upload");
    }
    const FieldLayout& layout = m.field.layout();
    const bool implicit = m.field.implicit_active();
    const PushConstants pc =
        push_constants(o, layout, m.field.coarse(),
                       implicit ? m.field.implicit_grid() : std::array<std::uint32_t, 4>{});
    const std::string what = "ray march " + std::to_string(o.width) + "x" +
                             std::to_string(o.height) + " of " + layout.dims.to_string();
    m.prepare_target(o.width, o.height, what);
    if (o.count) {
        m.prepare_counters(std::size_t{o.width} * o.height);
    }
    if (o.surface) {
        m.prepare_surface(std::size_t{o.width} * o.height);
    }
    if (m.set_generation != m.field.generation()) {
        m.write_set();  // the field residency replaced a buffer
    }
    const VkPipeline pipeline =
        m.pipeline_for(m.field.metric(), o.count, o.shading == Shading::lit, layout.slabs <= 1,
                       layout.format == FieldFormat::compact, implicit, o.surface);
    const VkImage image_handle = m.target.image.get();

    const std::uint32_t pair = m.next_pair;
    m.next_pair = (m.next_pair + 1) % kQueryPairs;
    m.pair_serial[pair] = m.ctx.next_serial();
    m.field.note_reader(m.ctx.next_serial());

    // The previous march's writes and the copy out of the image (an earlier frame, maybe
    // still running) come before the image is written again.
    const VkImageMemoryBarrier to_general =
        color_barrier(image_handle, VK_ACCESS_SHADER_WRITE_BIT, VK_ACCESS_SHADER_WRITE_BIT,
                      VK_IMAGE_LAYOUT_UNDEFINED, VK_IMAGE_LAYOUT_GENERAL);
    // Host writes to mapped buffers are visible to the device at submission; staged uploads
    // finished (and were waited for) before it.
    vkCmdPipelineBarrier(cmd, VK_PIPELINE_STAGE_COMPUTE_SHADER_BIT | VK_PIPELINE_STAGE_TRANSFER_BIT,
                         VK_PIPELINE_STAGE_COMPUTE_SHADER_BIT, 0, 0, nullptr, 0, nullptr, 1,
                         &to_general);
    // Path 1: OpenCL wrote the field through its fd, so the field is acquired from
    // VK_QUEUE_FAMILY_EXTERNAL before the dispatch reads it and released back after.
    const bool external = m.field.sharing() == SharingPath::opaque_fd;
    std::vector<VkBufferMemoryBarrier> ownership;
    if (external) {
        std::vector<VkBuffer> shared;
        for (const Buffer& b : m.field.field()) {
            shared.push_back(b.get());
        }
        if (m.field.block_min_shared()) {
            shared.push_back(m.field.block_min().get());  // written by OpenCL in the same memory
        }
        for (const VkBuffer b : shared) {
            VkBufferMemoryBarrier acquire{};
            acquire.sType = VK_STRUCTURE_TYPE_BUFFER_MEMORY_BARRIER;
            acquire.srcAccessMask = 0;
            acquire.dstAccessMask = VK_ACCESS_SHADER_READ_BIT;
            acquire.srcQueueFamilyIndex = VK_QUEUE_FAMILY_EXTERNAL;
            acquire.dstQueueFamilyIndex = m.ctx.queue_family();
            acquire.buffer = b;
            acquire.offset = 0;
            acquire.size = VK_WHOLE_SIZE;
            ownership.push_back(acquire);
        }
        vkCmdPipelineBarrier(
            cmd, VK_PIPELINE_STAGE_TOP_OF_PIPE_BIT, VK_PIPELINE_STAGE_COMPUTE_SHADER_BIT, 0, 0,
            nullptr, static_cast<std::uint32_t>(ownership.size()), ownership.data(), 0, nullptr);
    }
    const VkQueryPool timer = m.queries.get();
    if (timer != VK_NULL_HANDLE) {
        vkCmdResetQueryPool(cmd, timer, 2 * pair, 2);
        // Both timestamps at the compute stage, so that they bracket the dispatch on every
        // driver: TOP_OF_PIPE/BOTTOM_OF_PIPE let lavapipe under a window write the pair before
        // the dispatch ran (0.019 ms for a 37 ms ray march).
        vkCmdWriteTimestamp(cmd, VK_PIPELINE_STAGE_COMPUTE_SHADER_BIT, timer, 2 * pair);
    }
    vkCmdBindPipeline(cmd, VK_PIPELINE_BIND_POINT_COMPUTE, pipeline);
    vkCmdBindDescriptorSets(cmd, VK_PIPELINE_BIND_POINT_COMPUTE, m.pipeline_layout.get(), 0, 1,
                            &m.set, 0, nullptr);
    m.set_recorded = true;
    vkCmdPushConstants(cmd, m.pipeline_layout.get(), VK_SHADER_STAGE_COMPUTE_BIT, 0, sizeof pc,
                       &pc);
    const std::uint32_t g = VF_RAYMARCH_LOCAL_SIZE;
    vkCmdDispatch(cmd, (o.width + g - 1) / g, (o.height + g - 1) / g, 1);
    if (timer != VK_NULL_HANDLE) {
        vkCmdWriteTimestamp(cmd, VK_PIPELINE_STAGE_COMPUTE_SHADER_BIT, timer, 2 * pair + 1);
    }
    if (external) {
        for (VkBufferMemoryBarrier& b : ownership) {
            b.srcAccessMask = 0;
            b.dstAccessMask = 0;
            std::swap(b.srcQueueFamilyIndex, b.dstQueueFamilyIndex);
        }
        vkCmdPipelineBarrier(
            cmd, VK_PIPELINE_STAGE_COMPUTE_SHADER_BIT, VK_PIPELINE_STAGE_BOTTOM_OF_PIPE_BIT, 0, 0,
            nullptr, static_cast<std::uint32_t>(ownership.size()), ownership.data(), 0, nullptr);
    }
    if (o.count || o.surface) {
        VkMemoryBarrier counted{};
        counted.sType = VK_STRUCTURE_TYPE_MEMORY_BARRIER;
        counted.srcAccessMask = VK_ACCESS_SHADER_WRITE_BIT;
        counted.dstAccessMask = VK_ACCESS_HOST_READ_BIT;
        vkCmdPipelineBarrier(cmd, VK_PIPELINE_STAGE_COMPUTE_SHADER_BIT, VK_PIPELINE_STAGE_HOST_BIT,
                             0, 1, &counted, 0, nullptr, 0, nullptr);
    }
    const VkImageMemoryBarrier to_copy =
        color_barrier(image_handle, VK_ACCESS_SHADER_WRITE_BIT, VK_ACCESS_TRANSFER_READ_BIT,
                      VK_IMAGE_LAYOUT_GENERAL, VK_IMAGE_LAYOUT_TRANSFER_SRC_OPTIMAL);
    vkCmdPipelineBarrier(cmd, VK_PIPELINE_STAGE_COMPUTE_SHADER_BIT, VK_PIPELINE_STAGE_TRANSFER_BIT,
                         0, 0, nullptr, 0, nullptr, 1, &to_copy);
    return pair;
}

std::uint32_t Raymarcher::Impl::march(const RenderOptions& o, VkBuffer dst, bool external) {
    Impl& m = *this;
    std::uint32_t pair = 0;
    m.ctx.submit_and_wait(
        [&](VkCommandBuffer cmd) {
            pair = m.record(cmd, o);
            if (dst == VK_NULL_HANDLE) {
                dst = m.target.readback.get();
            }
            VkBufferImageCopy region{};
            region.imageSubresource = {VK_IMAGE_ASPECT_COLOR_BIT, 0, 0, 1};
            region.imageExtent = {o.width, o.height, 1};
            vkCmdCopyImageToBuffer(cmd, m.target.image.get(), VK_IMAGE_LAYOUT_TRANSFER_SRC_OPTIMAL,
                                   dst, 1, &region);
            if (external) {
                // Release the buffer to the device that imports it (another VkDevice).
                VkBufferMemoryBarrier release{};
                release.sType = VK_STRUCTURE_TYPE_BUFFER_MEMORY_BARRIER;
                release.srcAccessMask = VK_ACCESS_TRANSFER_WRITE_BIT;
                release.dstAccessMask = 0;
                release.srcQueueFamilyIndex = m.ctx.queue_family();
                release.dstQueueFamilyIndex = VK_QUEUE_FAMILY_EXTERNAL;
                release.buffer = dst;
                release.offset = 0;
                release.size = VkDeviceSize{o.width} * o.height * 4;
                vkCmdPipelineBarrier(cmd, VK_PIPELINE_STAGE_TRANSFER_BIT,
                                     VK_PIPELINE_STAGE_BOTTOM_OF_PIPE_BIT, 0, 0, nullptr, 1,
                                     &release, 0, nullptr);
            } else {
                VkMemoryBarrier to_host{};
                to_host.sType = VK_STRUCTURE_TYPE_MEMORY_BARRIER;
                to_host.srcAccessMask = VK_ACCESS_TRANSFER_WRITE_BIT;
                to_host.dstAccessMask = VK_ACCESS_HOST_READ_BIT;
                vkCmdPipelineBarrier(cmd, VK_PIPELINE_STAGE_TRANSFER_BIT,
                                     VK_PIPELINE_STAGE_HOST_BIT, 0, 1, &to_host, 0, nullptr, 0,
                                     nullptr);
            }
        },
        "ray march " + std::to_string(o.width) + "x" + std::to_string(o.height));
    return pair;
}

double Raymarcher::Impl::pair_ms(std::uint32_t pair, bool wait) {
    if (!queries) {
        return -1;
    }
    return timestamp_pair_ms(ctx, queries.get(), 2 * pair, wait, "ray march timestamps");
}

void Raymarcher::render(const RenderOptions& o, Image& out) {
    Impl& m = *impl_;
    const std::uint32_t pair = m.march(o, VK_NULL_HANDLE, false);
    const VkDeviceSize bytes = VkDeviceSize{o.width} * o.height * 4;
    out.width = o.width;
    out.height = o.height;
    out.rgba.resize(bytes);
    std::memcpy(out.rgba.data(), m.target.readback.data(), bytes);
    out.raymarch_ms = m.pair_ms(pair, true);
    out.fetches = out.steps = 0;
    if (o.count) {
        const auto* c = static_cast<const std::uint32_t*>(m.counters.data());
        for (std::size_t i = 0; i < std::size_t{o.width} * o.height; ++i) {
            out.fetches += c[2 * i];
            out.steps += c[2 * i + 1];
        }
    }
    out.surface.clear();
    if (o.surface) {
        const auto* hits = static_cast<const SurfaceHit*>(m.surface.data());
        out.surface.assign(hits, hits + std::size_t{o.width} * o.height);
    }
}

double Raymarcher::render_to(const RenderOptions& o, const ExternalMemory& frame) {
    Impl& m = *impl_;
    const VkDeviceSize bytes = VkDeviceSize{o.width} * o.height * 4;
    if (o.count || o.surface) {
        throw std::logic_error("Raymarcher::render_to does not count or record hits; use render()");
    }
    if (frame.path() != SharingPath::opaque_fd || frame.size() < bytes) {
        throw std::logic_error("Raymarcher::render_to needs exportable memory of " +
                               std::to_string(bytes) + " bytes");
    }
    if (m.frame_memory != frame.memory() || m.frame.size() < bytes) {
        m.ctx.retire(std::move(m.frame));
        m.frame = m.ctx.make_external_buffer(frame.size(), VK_BUFFER_USAGE_TRANSFER_DST_BIT,
                                             frame.handle_type(), "shared frame");
        m.ctx.bind(m.frame, frame.memory(), 0, "shared frame");
        m.frame_memory = frame.memory();
    }
    return m.pair_ms(m.march(o, m.frame.get(), true), true);
}

VkImage Raymarcher::record(VkCommandBuffer cmd, const RenderOptions& o) {
    if (o.count || o.surface) {
        throw std::logic_error("Raymarcher::record does not count or record hits; use render()");
    }
    impl_->record(cmd, o);
    return impl_->target.image.get();
}

double Raymarcher::finished_raymarch_ms() {
    Impl& m = *impl_;
    std::uint32_t latest = kQueryPairs;
    for (std::uint32_t p = 0; p < kQueryPairs; ++p) {
        const std::uint64_t serial = m.pair_serial[p];
        if (serial > m.reported_serial && m.ctx.finished(serial) &&
            (latest == kQueryPairs || serial > m.pair_serial[latest])) {
            latest = p;
        }
    }
    if (latest != kQueryPairs) {
        m.reported_serial = m.pair_serial[latest];
        m.reported_ms = m.pair_ms(latest, false);
    }
    return m.reported_ms;
}

void Raymarcher::upload(const World& world, const Palette& palette,
                        std::span<const std::uint32_t> packed32) {
    impl_->field.upload(world, palette, packed32);
}

FieldLayout Raymarcher::plan(Dims dims, FieldFormat format) const {
    return impl_->field.plan(dims, format);
}

void Raymarcher::upload_compact(Dims dims, const Palette& palette,
                                std::span<const std::uint16_t> compact) {
    impl_->field.upload_compact(dims, palette, compact);
}

void Raymarcher::bind_shared(const ExternalMemory& memory, const FieldLayout& layout,
                             const Palette& palette) {
    impl_->field.bind_shared(memory, layout, palette);
}

void Raymarcher::update_compact(std::span<const Box> boxes, std::span<const std::uint16_t> values) {
    impl_->field.update_compact(boxes, values);
}

void Raymarcher::update_compact(std::span<const std::uint16_t> compact) {
    impl_->field.update_compact(compact);
}

void Raymarcher::update_packed32(std::span<const Box> boxes,
                                 std::span<const std::uint32_t> packed32,
                                 std::span<const std::uint8_t> materials) {
    impl_->field.update_packed32(boxes, packed32, materials);
}

std::vector<std::uint16_t> Raymarcher::read_compact() {
    return impl_->field.read_compact();
}

void Raymarcher::wait_for_readers() {
    impl_->field.wait_for_readers();
}

void Raymarcher::set_block_min(std::span<const std::uint32_t> block_min) {
    impl_->field.set_block_min(block_min);
}

void Raymarcher::update_block_min(std::span<const Box> blocks,
                                  std::span<const std::uint32_t> minima) {
    impl_->field.update_block_min(blocks, minima);
}

void Raymarcher::bind_shared_block_min(const ExternalMemory& memory, std::uint64_t offset) {
    impl_->field.bind_shared_block_min(memory, offset);
}

std::uint64_t Raymarcher::block_min_bytes_copied() const {
    return impl_->field.block_min_bytes_copied();
}

void Raymarcher::set_implicit(const ImplicitSurface& surface) {
    impl_->field.set_implicit(surface);
}

void Raymarcher::clear_implicit() {
    impl_->field.clear_implicit();
}

bool Raymarcher::has_implicit() const {
    return impl_->field.has_implicit();
}

std::uint64_t Raymarcher::implicit_bytes() const {
    return impl_->field.implicit_bytes();
}

void Raymarcher::set_metric(Metric metric) {
    impl_->field.set_metric(metric);
}

Metric Raymarcher::metric() const {
    return impl_->field.metric();
}

std::uint32_t Raymarcher::field_bindings() const {
    return static_cast<std::uint32_t>(impl_->field.field().size());
}

std::uint32_t Raymarcher::slab_depth() const {
    return impl_->field.layout().slab_depth;
}

const FieldLayout& Raymarcher::layout() const {
    return impl_->field.layout();
}

std::uint64_t Raymarcher::bytes_copied() const {
    return impl_->field.bytes_copied();
}

SharingPath Raymarcher::sharing() const {
    return impl_->field.sharing();
}

std::string Raymarcher::sharing_path() const {
    return describe(impl_->field.sharing());
}

}  // namespace voxfield::vk
