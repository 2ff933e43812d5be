// The sparse tracer (sparse_tracer.hpp): the directory and chunks of a sparse world on the
// device, the compute pipelines of sparse_trace.comp, their descriptor set, the offscreen image
// and its readback.
#include "voxfield/vk/sparse_tracer.hpp"

#include <algorithm>
#include <array>
#include <cstddef>
#include <cstring>
#include <numeric>
#include <stdexcept>
#include <string>
#include <utility>
#include <vector>

#include "compute_pipeline.hpp"
#include "march_params.hpp"
#include "sparse_trace_spv.h"
#include "voxfield/core/camera.hpp"
#include "voxfield/core/error.hpp"
#include "voxfield/layout.h"
#include "voxfield/vk/sparse_trace_layout.h"

namespace voxfield::vk {
namespace {

constexpr std::uint32_t kPageTiles =
    VF_SPARSE_BLOCK_TILES * VF_SPARSE_BLOCK_TILES * VF_SPARSE_BLOCK_TILES;

// Mirrors the push-constant block `Params` of sparse_trace.comp (std430: vec4 / uvec4).
struct SparsePushConstants {
    float origin[4];
    float forward[4];
    float right[4];
    float up[4];
    std::uint32_t dims[4];
    std::uint32_t image[4];
    std::uint32_t blocks[4];
};
static_assert(sizeof(SparsePushConstants) == 112);

// sparse_trace.comp's specialization constants 0..3: shadows, counting, one node chunk, one
// material chunk.
struct Specialization {
    VkBool32 shadows;
    VkBool32 count;
    VkBool32 one_node_chunk;
    VkBool32 one_material_chunk;
};

// A contiguous range [begin, end) of a node or material buffer bound as one chunk.
struct Range {
    std::uint64_t begin = 0, end = 0;
};

// Cuts a buffer into ranges of at most `limit` elements at tile starts: tiles in order of their
// base, each whole in one range. Returns the ranges and each tile's range.
std::vector<Range> cut(const std::vector<std::uint64_t>& bases,
                       const std::vector<std::uint32_t>& counts, std::uint64_t limit,
                       std::vector<std::uint32_t>& chunk_of) {
    std::vector<std::uint32_t> order(bases.size());
    std::iota(order.begin(), order.end(), 0u);
    std::sort(order.begin(), order.end(),
              [&](std::uint32_t a, std::uint32_t b) { return bases[a] < bases[b]; });
    chunk_of.assign(bases.size(), 0);
    std::vector<Range> ranges;
    for (const std::uint32_t t : order) {
        if (counts[t] > limit) {
            throw InputError("sparse tracer: a tile of " + std::to_string(counts[t]) +
                             " elements exceeds one storage-buffer binding (" +
                             std::to_string(limit) + " elements)");
        }
        const std::uint64_t end = bases[t] + counts[t];
        if (ranges.empty() || end - ranges.back().begin > limit) {
            ranges.push_back(Range{bases[t], end});
        }
        ranges.back().end = std::max(ranges.back().end, end);
        chunk_of[t] = static_cast<std::uint32_t>(ranges.size() - 1);
    }
    return ranges;
}

std::string mib(std::uint64_t bytes) {
    return std::to_string(bytes >> 20) + " MiB";
}

}  // namespace

Camera default_camera(const SparseWorld& world, std::uint32_t width, std::uint32_t height,
                      double fov_deg) {
    Box solids{};
    for (std::uint32_t t = 0; t < world.tile_count(); ++t) {
        solids = hull(solids, world.solid_bounds(t));
    }
    Framing f = world_framing(world.dims());
    if (!solids.empty()) {
        const std::array<std::int64_t, 3> lo{solids.min.x, solids.min.y, solids.min.z};
        const std::array<std::int64_t, 3> hi{solids.max.x, solids.max.y, solids.max.z};
        for (std::size_t a = 0; a < 3; ++a) {
            f.centre[a] = double(lo[a] + hi[a]) / 2.0;
            f.half[a] = double(hi[a] - lo[a]) / 2.0;
        }
        f.front = {0, 0, -1};
    }
    Camera c;
    c.position = framing_position(f, fov_deg, double(width) / double(std::max(height, 1u)));
    c.target = f.centre;
    c.fov_deg = fov_deg;
    return c;
}

struct SparseTracer::Impl {
    Context& ctx;
    VkDeviceSize limit;  // bytes per binding, whole words
    Owned<VkDescriptorSetLayout> set_layout;
    Owned<VkPipelineLayout> pipeline_layout;
    Owned<VkShaderModule> shader;
    // By shadows | count << 1 | one node chunk << 2 | one material chunk << 3.
    std::array<Owned<VkPipeline>, 16> pipelines;
    Owned<VkDescriptorPool> pool;
    VkDescriptorSet set = VK_NULL_HANDLE;
    Owned<VkQueryPool> queries;  // one pair: dispatch start, end

    bool loaded = false;
    Dims dims;
    std::array<std::uint32_t, 3> blocks{};
    Buffer palette, block_table, pages, records, counters;
    std::vector<Buffer> masks, offsets, materials;
    SparseDeviceStats stats;

    OffscreenTarget target;

    Impl(Context& c, VkDeviceSize l) : ctx(c), limit(l) {}

    Buffer storage(VkDeviceSize bytes, const void* data, VkDeviceSize data_bytes,
                   const std::string& what) {
        Buffer b =
            ctx.make_buffer(std::max<VkDeviceSize>(bytes, 16),
                            VK_BUFFER_USAGE_STORAGE_BUFFER_BIT | VK_BUFFER_USAGE_TRANSFER_DST_BIT,
                            MemoryIntent::device_local, what);
        ctx.upload(b, data, data_bytes);
        stats.bytes += b.size();
        return b;
    }
    void write_set();
    VkPipeline pipeline_for(bool shadows, bool count, bool one_node_chunk, bool one_material_chunk);
    void prepare_target(std::uint32_t width, std::uint32_t height);
};

SparseTracer::SparseTracer(Context& ctx, std::uint64_t max_binding_bytes) {
    VkDeviceSize limit = ctx.info().max_storage_buffer_range;
    if (max_binding_bytes != 0) {
        limit = std::min<VkDeviceSize>(limit, max_binding_bytes);
    }
    impl_ = std::make_unique<Impl>(ctx, limit / 8 * 8);
    Impl& m = *impl_;
    const VkDevice dev = ctx.device();
    std::vector<VkDescriptorSetLayoutBinding> bindings;
    for (std::uint32_t b = 0; b <= VF_SPARSE_LAST_BINDING; ++b) {
        bindings.push_back(compute_binding(b, b == VF_SPARSE_BINDING_IMAGE
                                                  ? VK_DESCRIPTOR_TYPE_STORAGE_IMAGE
                                                  : VK_DESCRIPTOR_TYPE_STORAGE_BUFFER));
    }
    m.set_layout = make_set_layout(dev, bindings, "sparse tracer");
    m.pipeline_layout =
        make_pipeline_layout(dev, m.set_layout.get(), sizeof(SparsePushConstants), "sparse tracer");
    m.shader =
        make_shader(dev, vf_sparse_trace_spv, sizeof(vf_sparse_trace_spv), "sparse_trace.comp");
    m.pool = make_set_pool(dev, VF_SPARSE_LAST_BINDING, "sparse tracer");
    m.set = allocate_set(dev, m.pool.get(), m.set_layout.get(), "sparse tracer");

    if (ctx.info().timestamps) {
        m.queries = make_timestamp_pool(dev, 2, "sparse tracer");
    }
    m.counters = ctx.make_buffer(8, VK_BUFFER_USAGE_STORAGE_BUFFER_BIT, MemoryIntent::readback,
                                 "sparse ray counters");
}

SparseTracer::~SparseTracer() {
    impl_->ctx.wait_frames_in_flight();
}

const SparseDeviceStats& SparseTracer::stats() const {
    return impl_->stats;
}

void SparseTracer::upload(const SparseWorld& world, const Palette& palette) {
    Impl& m = *impl_;
    m.ctx.wait_frames_in_flight();  // renders wait for their work; nothing reads the buffers
    m.loaded = false;
    m.stats = SparseDeviceStats{};
    const Dims grid = world.tile_grid();
    const std::uint32_t bt = VF_SPARSE_BLOCK_TILES;
    m.blocks = {(grid.x + bt - 1) / bt, (grid.y + bt - 1) / bt, (grid.z + bt - 1) / bt};
    const std::uint64_t block_count = std::uint64_t{m.blocks[0]} * m.blocks[1] * m.blocks[2];
    if (block_count * 4 > m.limit) {
        throw InputError("sparse tracer: the world " + world.dims().to_string() + " needs " +
                         std::to_string(block_count) + " directory blocks of 512^3 voxels (" +
                         mib(block_count * 4) + "), more than one storage-buffer binding holds (" +
                         mib(m.limit) + ")");
    }
    // The directory: a page of tile indices per block that holds a stored tile.
    std::vector<std::uint32_t> block_table(static_cast<std::size_t>(block_count), VF_SPARSE_NONE);
    std::vector<std::uint32_t> pages;
    for (std::uint32_t t = 0; t < world.tile_count(); ++t) {
        const Int3 c = world.tile_coord(t);
        const auto b = static_cast<std::size_t>(
            (std::uint64_t(c.z / bt) * m.blocks[1] + std::uint64_t(c.y / bt)) * m.blocks[0] +
            std::uint64_t(c.x / bt));
        if (block_table[b] == VF_SPARSE_NONE) {
            block_table[b] = static_cast<std::uint32_t>(pages.size() / kPageTiles);
            pages.resize(pages.size() + kPageTiles, VF_SPARSE_NONE);
        }
        const std::uint64_t local =
            (std::uint64_t(c.z % bt) * bt + std::uint64_t(c.y % bt)) * bt + std::uint64_t(c.x % bt);
        pages[std::size_t{block_table[b]} * kPageTiles + local] = t;
        if (pages.size() * 4 > m.limit) {
            throw InputError("sparse tracer: the directory of the world's " +
                             std::to_string(world.tile_count()) +
                             " tiles exceeds one storage-buffer binding (" + mib(m.limit) + ")");
        }
    }
    // Nodes and materials cut at tile starts into chunks of one binding each.
    std::vector<std::uint32_t> node_chunk, material_chunk;
    const std::vector<Range> node_ranges =
        cut(world.node_bases(), world.node_counts(), m.limit / 8, node_chunk);
    const std::vector<Range> material_ranges =
        cut(world.material_bases(), world.material_counts(), m.limit, material_chunk);
    if (node_ranges.size() > VF_SPARSE_MAX_NODE_CHUNKS ||
        material_ranges.size() > VF_SPARSE_MAX_MATERIAL_CHUNKS) {
        throw InputError("sparse tracer: the world's " + std::to_string(world.node_masks().size()) +
                         " nodes and " + std::to_string(world.materials().size()) +
                         " material bytes need " + std::to_string(node_ranges.size()) +
                         " node and " + std::to_string(material_ranges.size()) +
                         " material bindings of at most " + mib(m.limit) +
                         "; the tracer binds at most " + std::to_string(VF_SPARSE_MAX_NODE_CHUNKS) +
                         " and " + std::to_string(VF_SPARSE_MAX_MATERIAL_CHUNKS) + " (" +
                         std::to_string(VF_SPARSE_MAX_NODE_CHUNKS * (m.limit / 8)) + " nodes, " +
                         mib(VF_SPARSE_MAX_MATERIAL_CHUNKS * m.limit) + " of materials)");
    }
    std::vector<std::uint32_t> records(std::size_t{world.tile_count()} * 4);
    for (std::uint32_t t = 0; t < world.tile_count(); ++t) {
        records[4 * std::size_t{t}] =
            static_cast<std::uint32_t>(world.node_bases()[t] - node_ranges[node_chunk[t]].begin);
        records[4 * std::size_t{t} + 1] = static_cast<std::uint32_t>(
            world.material_bases()[t] - material_ranges[material_chunk[t]].begin);
        records[4 * std::size_t{t} + 2] = node_chunk[t];
        records[4 * std::size_t{t} + 3] = material_chunk[t];
    }

    std::array<std::uint32_t, 256> colours{};
    for (std::size_t i = 0; i < colours.size(); ++i) {
        colours[i] = pack_rgba(palette[static_cast<std::uint8_t>(i)]);
    }
    m.palette = m.storage(sizeof colours, colours.data(), sizeof colours, "sparse palette");
    m.block_table = m.storage(block_table.size() * 4, block_table.data(), block_table.size() * 4,
                              "sparse block table");
    m.pages = m.storage(pages.size() * 4, pages.data(), pages.size() * 4, "sparse tile pages");
    m.records =
        m.storage(records.size() * 4, records.data(), records.size() * 4, "sparse tile records");
    m.masks.clear();
    m.offsets.clear();
    m.materials.clear();
    for (const Range& r : node_ranges) {
        const std::uint64_t n = r.end - r.begin;
        m.masks.push_back(
            m.storage(n * 8, world.node_masks().data() + r.begin, n * 8, "sparse node masks"));
        m.offsets.push_back(
            m.storage(n * 4, world.node_offsets().data() + r.begin, n * 4, "sparse node offsets"));
    }
    for (const Range& r : material_ranges) {
        const std::uint64_t n = r.end - r.begin;
        // Whole words: the bytes past the last material are never used.
        m.materials.push_back(
            m.storage((n + 3) / 4 * 4, world.materials().data() + r.begin, n, "sparse materials"));
    }
    m.stats.node_chunks = static_cast<std::uint32_t>(node_ranges.size());
    m.stats.material_chunks = static_cast<std::uint32_t>(material_ranges.size());
    m.stats.blocks = block_count;
    m.stats.pages = pages.size() / kPageTiles;
    m.dims = world.dims();
    m.loaded = true;
    m.write_set();
}

void SparseTracer::Impl::write_set() {
    std::vector<VkDescriptorBufferInfo> infos;
    infos.reserve(VF_SPARSE_LAST_BINDING + 1);
    std::vector<VkWriteDescriptorSet> writes;
    auto add = [&](std::uint32_t binding, const Buffer& b) {
        infos.push_back(VkDescriptorBufferInfo{b.get(), 0, VK_WHOLE_SIZE});
        VkWriteDescriptorSet w = descriptor_write(set, binding, VK_DESCRIPTOR_TYPE_STORAGE_BUFFER);
        w.pBufferInfo = &infos.back();
        writes.push_back(w);
    };
    add(VF_SPARSE_BINDING_PALETTE, palette);
    add(VF_SPARSE_BINDING_BLOCKS, block_table);
    add(VF_SPARSE_BINDING_PAGES, pages);
    add(VF_SPARSE_BINDING_RECORDS, records);
    add(VF_SPARSE_BINDING_COUNTERS, counters);
    // A world without tiles has no chunks: the block table stands in (never read).
    for (std::uint32_t c = 0; c < VF_SPARSE_MAX_NODE_CHUNKS; ++c) {
        add(VF_SPARSE_BINDING_MASKS + c,
            masks.empty() ? block_table : masks[c < masks.size() ? c : 0]);
        add(VF_SPARSE_BINDING_OFFSETS + c,
            offsets.empty() ? block_table : offsets[c < offsets.size() ? c : 0]);
    }
    for (std::uint32_t c = 0; c < VF_SPARSE_MAX_MATERIAL_CHUNKS; ++c) {
        add(VF_SPARSE_BINDING_MATERIALS + c,
            materials.empty() ? block_table : materials[c < materials.size() ? c : 0]);
    }
    const VkDescriptorImageInfo image_info{VK_NULL_HANDLE, target.view.get(),
                                           VK_IMAGE_LAYOUT_GENERAL};
    if (target.view) {
        VkWriteDescriptorSet w =
            descriptor_write(set, VF_SPARSE_BINDING_IMAGE, VK_DESCRIPTOR_TYPE_STORAGE_IMAGE);
        w.pImageInfo = &image_info;
        writes.push_back(w);
    }
    vkUpdateDescriptorSets(ctx.device(), static_cast<std::uint32_t>(writes.size()), writes.data(),
                           0, nullptr);
}

VkPipeline SparseTracer::Impl::pipeline_for(bool shadows, bool count, bool one_node_chunk,
                                            bool one_material_chunk) {
    Owned<VkPipeline>& slot =
        pipelines[(shadows ? 1u : 0u) | (count ? 2u : 0u) | (one_node_chunk ? 4u : 0u) |
                  (one_material_chunk ? 8u : 0u)];
    if (slot) {
        return slot.get();
    }
    const auto flag = [](bool b) { return b ? VkBool32{VK_TRUE} : VkBool32{VK_FALSE}; };
    const Specialization data{flag(shadows), flag(count), flag(one_node_chunk),
                              flag(one_material_chunk)};
    const std::array<VkSpecializationMapEntry, 4> entries = {
        VkSpecializationMapEntry{0, offsetof(Specialization, shadows), sizeof(VkBool32)},
        VkSpecializationMapEntry{1, offsetof(Specialization, count), sizeof(VkBool32)},
        VkSpecializationMapEntry{2, offsetof(Specialization, one_node_chunk), sizeof(VkBool32)},
        VkSpecializationMapEntry{3, offsetof(Specialization, one_material_chunk),
                                 sizeof(VkBool32)}};
    VkSpecializationInfo spec{};
    spec.mapEntryCount = static_cast<std::uint32_t>(entries.size());
    spec.pMapEntries = entries.data();
    spec.dataSize = sizeof data;
    spec.pData = &data;
    slot = make_compute_pipeline(ctx.device(), shader.get(), pipeline_layout.get(), spec,
                                 "sparse_trace.comp");
    return slot.get();
}

void SparseTracer::Impl::prepare_target(std::uint32_t width, std::uint32_t height) {
    if (target.width == width && target.height == height) {
        return;
    }
    target = OffscreenTarget{};
    const std::string what =
        "sparse trace image " + std::to_string(width) + "x" + std::to_string(height);
    target = make_offscreen_target(ctx, width, height, what, what, "sparse trace readback");
    write_set();
}

Image SparseTracer::render(const RenderOptions& o) {
    Image out;
    render(o, out);
    return out;
}

void SparseTracer::render(const RenderOptions& o, Image& out) {
    Impl& m = *impl_;
    if (o.surface) {
        throw std::logic_error("SparseTracer::render does not record surface hits");
    }
    if (!m.loaded) {
        throw std::logic_error("SparseTracer::render before upload");
    }
    validate(o);
    const CameraBasis basis = camera_basis(o.camera, o.width, o.height);
    SparsePushConstants pc{};
    for (std::size_t i = 0; i < 3; ++i) {
        pc.origin[i] = static_cast<float>(o.camera.position[i]);
        pc.forward[i] = static_cast<float>(basis.forward[i]);
        pc.right[i] = static_cast<float>(basis.right[i]);
        pc.up[i] = static_cast<float>(basis.up[i]);
        pc.blocks[i] = m.blocks[i];
    }
    pc.dims[0] = m.dims.x;
    pc.dims[1] = m.dims.y;
    pc.dims[2] = m.dims.z;
    pc.image[0] = o.width;
    pc.image[1] = o.height;
    pc.image[2] =
        (o.shading == Shading::lit ? VF_RAYMARCH_FLAG_LIT : 0u) |
        (o.shading == Shading::lit && o.sky_gradient ? VF_RAYMARCH_FLAG_SKY_GRADIENT : 0u) |
        (o.bgra ? VF_RAYMARCH_FLAG_BGRA : 0u);
    pc.image[3] = pack_rgba(o.sky);
    const std::size_t pixels = std::size_t{o.width} * o.height;
    if (o.count && m.counters.size() < 8 * pixels) {
        m.counters = Buffer{};
        m.counters = m.ctx.make_buffer(8 * pixels, VK_BUFFER_USAGE_STORAGE_BUFFER_BIT,
                                       MemoryIntent::readback, "sparse ray counters");
        m.write_set();
    }
    m.prepare_target(o.width, o.height);
    const VkPipeline pipeline = m.pipeline_for(o.shading == Shading::lit, o.count,
                                               m.masks.size() <= 1, m.materials.size() <= 1);
    const VkImage image = m.target.image.get();
    const VkQueryPool timer = m.queries.get();
    m.ctx.submit_and_wait(
        [&](VkCommandBuffer cmd) {
            const VkImageMemoryBarrier to_general =
                color_barrier(image, 0, VK_ACCESS_SHADER_WRITE_BIT, VK_IMAGE_LAYOUT_UNDEFINED,
                              VK_IMAGE_LAYOUT_GENERAL);
            // After the previous render's copy out of the image and its dispatch.
            vkCmdPipelineBarrier(
                cmd, VK_PIPELINE_STAGE_TRANSFER_BIT | VK_PIPELINE_STAGE_COMPUTE_SHADER_BIT,
                VK_PIPELINE_STAGE_COMPUTE_SHADER_BIT, 0, 0, nullptr, 0, nullptr, 1, &to_general);
            if (timer != VK_NULL_HANDLE) {
                vkCmdResetQueryPool(cmd, timer, 0, 2);
                vkCmdWriteTimestamp(cmd, VK_PIPELINE_STAGE_COMPUTE_SHADER_BIT, timer, 0);
            }
            vkCmdBindPipeline(cmd, VK_PIPELINE_BIND_POINT_COMPUTE, pipeline);
            vkCmdBindDescriptorSets(cmd, VK_PIPELINE_BIND_POINT_COMPUTE, m.pipeline_layout.get(), 0,
                                    1, &m.set, 0, nullptr);
            vkCmdPushConstants(cmd, m.pipeline_layout.get(), VK_SHADER_STAGE_COMPUTE_BIT, 0,
                               sizeof pc, &pc);
            const std::uint32_t g = VF_SPARSE_LOCAL_SIZE;
            vkCmdDispatch(cmd, (o.width + g - 1) / g, (o.height + g - 1) / g, 1);
            if (timer != VK_NULL_HANDLE) {
                vkCmdWriteTimestamp(cmd, VK_PIPELINE_STAGE_COMPUTE_SHADER_BIT, timer, 1);
            }
            const VkImageMemoryBarrier to_copy = color_barrier(
                to_general.image, VK_ACCESS_SHADER_WRITE_BIT, VK_ACCESS_TRANSFER_READ_BIT,
                VK_IMAGE_LAYOUT_GENERAL, VK_IMAGE_LAYOUT_TRANSFER_SRC_OPTIMAL);
            vkCmdPipelineBarrier(cmd, VK_PIPELINE_STAGE_COMPUTE_SHADER_BIT,
                                 VK_PIPELINE_STAGE_TRANSFER_BIT, 0, 0, nullptr, 0, nullptr, 1,
                                 &to_copy);
            VkBufferImageCopy region{};
            region.imageSubresource = {VK_IMAGE_ASPECT_COLOR_BIT, 0, 0, 1};
            region.imageExtent = {o.width, o.height, 1};
            vkCmdCopyImageToBuffer(cmd, image, VK_IMAGE_LAYOUT_TRANSFER_SRC_OPTIMAL,
                                   m.target.readback.get(), 1, &region);
            VkMemoryBarrier to_host{};
            to_host.sType = VK_STRUCTURE_TYPE_MEMORY_BARRIER;
            to_host.srcAccessMask = VK_ACCESS_TRANSFER_WRITE_BIT | VK_ACCESS_SHADER_WRITE_BIT;
            to_host.dstAccessMask = VK_ACCESS_HOST_READ_BIT;
            vkCmdPipelineBarrier(
                cmd, VK_PIPELINE_STAGE_TRANSFER_BIT | VK_PIPELINE_STAGE_COMPUTE_SHADER_BIT,
                VK_PIPELINE_STAGE_HOST_BIT, 0, 1, &to_host, 0, nullptr, 0, nullptr);
        },
        "sparse trace " + std::to_string(o.width) + "x" + std::to_string(o.height));
    out.width = o.width;
    out.height = o.height;
    out.rgba.resize(pixels * 4);
    std::memcpy(out.rgba.data(), m.target.readback.data(), pixels * 4);
    out.raymarch_ms = -1;
    if (timer != VK_NULL_HANDLE) {
        out.raymarch_ms = timestamp_pair_ms(m.ctx, timer, 0, true, "sparse trace timestamps");
    }
    out.fetches = out.steps = 0;
    if (o.count) {
        const auto* c = static_cast<const std::uint32_t*>(m.counters.data());
        for (std::size_t i = 0; i < pixels; ++i) {
            out.fetches += c[2 * i];
            out.steps += c[2 * i + 1];
        }
    }
    out.surface.clear();
}

}  // namespace voxfield::vk
