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
#include <unordered_map>
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

// sparse_trace.comp's specialization constants 0..2: shadows, counting, one chunk (of nodes
// and of materials).
struct Specialization {
    VkBool32 shadows;
    VkBool32 count;
    VkBool32 one_chunk;
};

// The uints of one tile record (sparse_trace_layout.h).
constexpr std::size_t kRecordWords = 4 * VF_SPARSE_RECORD_UVEC4S;
constexpr std::uint64_t kRecordBytes = 4 * kRecordWords;

// Chunks: read through device addresses (chunk 0 also through its binding), copied into.
constexpr VkBufferUsageFlags kChunkUsage = VK_BUFFER_USAGE_SHADER_DEVICE_ADDRESS_BIT |
                                           VK_BUFFER_USAGE_STORAGE_BUFFER_BIT |
                                           VK_BUFFER_USAGE_TRANSFER_DST_BIT;

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

// The edit arena's first capacity: nodes (about 60 worst-case tiles) and material bytes.
constexpr std::uint64_t kArenaNodes = std::uint64_t{1} << 18;
constexpr std::uint64_t kArenaMaterials = std::uint64_t{16} << 20;

// A tile whose tree lives in the edit arena: its key, nodes and materials there.
struct ArenaTile {
    std::uint64_t key = 0;
    std::uint64_t node_at = 0, material_at = 0;
    std::uint32_t nodes = 0, materials = 0;
};

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
    // By shadows | count << 1 | one chunk << 2.
    std::array<Owned<VkPipeline>, 8> pipelines;
    Owned<VkDescriptorPool> pool;
    VkDescriptorSet set = VK_NULL_HANDLE;
    Owned<VkQueryPool> queries;  // one pair: dispatch start, end

    bool loaded = false;
    Dims dims;
    std::array<std::uint32_t, 3> blocks{};
    Buffer palette, block_table, pages, records, counters;
    // The chunks (node chunk c: masks[c] and offsets[c]) and their device addresses.
    std::vector<Buffer> masks, offsets, materials;
    std::vector<VkDeviceAddress> mask_at, offset_at, material_at;
    SparseDeviceStats stats;
    std::array<std::uint32_t, 256> colours{};

    // The directory as on the device (update_tiles changes both): block table, pages (pages
    // in use and freed ones), records (in use and freed), the stored tiles per page, and the
    // device buffers' capacities (records, pages).
    std::vector<std::uint32_t> host_blocks, host_pages, host_records, page_fill;
    std::vector<std::uint32_t> free_records, free_pages;
    std::uint64_t record_capacity = 0, page_capacity = 0;
    // The edit arena: the node chunk and material chunk after the upload's (none: -1), their
    // capacity and use, and the tiles whose trees live there by record.
    int arena_nodes_chunk = -1, arena_materials_chunk = -1;
    std::uint64_t arena_node_cap = 0, arena_node_used = 0, arena_mat_cap = 0, arena_mat_used = 0;
    std::unordered_map<std::uint32_t, ArenaTile> arena;
    // Copies staged by one update_tiles or repoint: into dst at `at` from the staging bytes at
    // `from`. They go with the next trace's submission (no submission of their own); the next
    // update submits them first (flush) when no trace came in between.
    struct Copy {
        VkBuffer dst;
        VkDeviceSize at, size, from;
    };
    std::vector<std::uint8_t> staged;
    std::vector<Copy> copies;
    Buffer staging;

    // Trees read in place (upload_shared): per set, buffers over the caller's memory and their
    // addresses; per record the tile it holds (set VF_SPARSE_NONE: a free record).
    struct SharedSet {
        std::array<std::uint64_t, 3> serials{};
        bool external = false;  // exported as an opaque fd: queue family ownership moves
        Buffer masks, offsets, materials;
        VkDeviceAddress mask_at = 0, offset_at = 0, material_at = 0;
    };
    bool shared = false;
    std::vector<SharedSet> shared_sets;
    std::vector<SharedTile> shared_tiles;

    OffscreenTarget target;

    Impl(Context& c, VkDeviceSize l) : ctx(c), limit(l) {}

    Buffer storage(VkDeviceSize bytes, const void* data, VkDeviceSize data_bytes,
                   const std::string& what,
                   VkBufferUsageFlags usage = VK_BUFFER_USAGE_STORAGE_BUFFER_BIT |
                                              VK_BUFFER_USAGE_TRANSFER_DST_BIT) {
        Buffer b = ctx.make_buffer(std::max<VkDeviceSize>(bytes, 16), usage,
                                   MemoryIntent::device_local, what);
        ctx.upload(b, data, data_bytes);
        return b;
    }
    // Appends a node chunk or a material chunk, or puts one in place of chunk c.
    void set_node_chunk(std::size_t c, Buffer chunk_masks, Buffer chunk_offsets);
    void set_material_chunk(std::size_t c, Buffer chunk);
    void clear_chunks();
    void upload_all(const SparseWorld& world);
    // The directory of the tiles `coords` (record t: coords[t]) of a world of `dims`: block
    // table, pages and records on the host, the arena emptied. InputError past one binding.
    void build_directory(const Dims& dims, const std::vector<Int3>& coords);
    // The palette, block table, pages and records on the device, with room for growth.
    void make_directory_buffers(std::uint64_t tiles);
    // Directory changes of one update, staged by stage_directory.
    struct DirectoryEdit {
        std::vector<std::uint32_t> records;
        std::vector<std::uint64_t> blocks, entries;  // entries: index into host_pages
        std::vector<std::uint32_t> new_pages;  // written whole (the device's may hold anything)
    };
    // Tile c's record (VF_SPARSE_NONE when it has none).
    std::uint32_t record_of(const Int3& c);
    // Takes tile c (its record `record`) out of the directory: the record freed, its page too
    // when it held nothing else.
    void drop_tile(const Int3& c, std::uint32_t record, DirectoryEdit& e);
    // Puts tile c (not in the directory) in: a record, and a page for a block that had none.
    std::uint32_t add_tile(const Int3& c, DirectoryEdit& e);
    // Stages the edit's directory changes (whole buffers where they outgrew their capacity),
    // each place once (its lists sorted and made unique); true when a buffer was replaced (the
    // descriptor set must be written again).
    bool stage_directory(DirectoryEdit& e);
    // An update's end: its directory changes staged (u.bytes: what the next trace copies), the
    // figures counted, the descriptor set written again where a buffer was replaced or
    // `rebind` says so.
    void stage_update(DirectoryEdit& e, bool rebind, SparseTileUpdate& u);
    // Buffers over `sets`' memory (kept where the memory is the same); per set whether it moved.
    std::vector<bool> set_shared(const std::vector<SharedTreeSet>& sets);
    void write_shared_record(std::uint32_t record, const SharedTile& t);
    void stage(const Buffer& dst, VkDeviceSize at, const void* data, VkDeviceSize size);
    // The staged bytes into the staging buffer (grown when they do not fit).
    void fill_staging();
    // The staged copies into `cmd`: after earlier reads and copies, before later shader reads.
    void record_copies(VkCommandBuffer cmd);
    // Submits the staged copies now and waits for them (nothing when none).
    void flush(const std::string& what);
    // Forgets the staged copies (done, or their buffers about to be replaced whole).
    void discard_copies();
    void count_bytes();
    std::uint64_t block_of(const Int3& c) const;
    std::uint32_t& page_entry(std::uint32_t page, const Int3& c);
    // Makes the arena hold `nodes` and `materials` more, writing its live tiles (except
    // `dropping`, about to be rewritten) again into fresh buffers when it must grow; false
    // when it cannot (more than one binding).
    bool arena_fit(const SparseWorld& world, std::uint64_t nodes, std::uint64_t material_bytes,
                   const std::vector<std::uint32_t>& dropping, bool& rebuilt);
    // Appends tile t's tree to the arena; its record's node and material fields.
    ArenaTile arena_write(const SparseWorld& world, std::uint32_t t, std::uint64_t key);
    void record_arena(std::uint32_t record, const ArenaTile& a);
    // Record `record` (kRecordWords uints of host_records): its root at index `root` of a node
    // chunk, its first material at `first_material` of a material chunk.
    void write_record(std::uint32_t record, std::size_t node_chunk, std::uint64_t root,
                      std::size_t material_chunk, std::uint64_t first_material);
    void write_set();
    VkPipeline pipeline_for(bool shadows, bool count, bool one_chunk);
    void prepare_target(std::uint32_t width, std::uint32_t height);
    // Traces one image; reads it back into `out` unless null. Returns the GPU time (ms, -1).
    double dispatch(const RenderOptions& o, Image* out);
};

SparseTracer::SparseTracer(Context& ctx, std::uint64_t max_binding_bytes) {
    if (!ctx.buffer_device_address()) {
        throw DeviceSelectionError("sparse tracer: " + ctx.info().name +
                                   " lacks VK_KHR_buffer_device_address (bufferDeviceAddress), "
                                   "through which the tracer reads the world's 64-trees");
    }
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
    for (std::size_t i = 0; i < m.colours.size(); ++i) {
        m.colours[i] = pack_rgba(palette[static_cast<std::uint8_t>(i)]);
    }
    m.upload_all(world);
}

void SparseTracer::Impl::upload_all(const SparseWorld& world) {
    Impl& m = *this;
    m.ctx.wait_frames_in_flight();  // renders wait for their work; nothing reads the buffers
    m.discard_copies();             // their buffers are replaced
    m.loaded = false;
    m.stats = SparseDeviceStats{};
    m.shared = false;
    m.shared_sets.clear();
    m.shared_tiles.clear();
    std::vector<Int3> coords(world.tile_count());
    for (std::uint32_t t = 0; t < world.tile_count(); ++t) {
        coords[t] = world.tile_coord(t);
    }
    m.build_directory(world.dims(), coords);
    // Nodes and materials cut at tile starts into chunks of one binding each.
    std::vector<std::uint32_t> node_chunk, material_chunk;
    const std::vector<Range> node_ranges =
        cut(world.node_bases(), world.node_counts(), m.limit / 8, node_chunk);
    const std::vector<Range> material_ranges =
        cut(world.material_bases(), world.material_counts(), m.limit, material_chunk);
    // The chunks (any number of them), then the records: their addresses.
    m.clear_chunks();
    for (std::size_t c = 0; c < node_ranges.size(); ++c) {
        const Range& r = node_ranges[c];
        const std::uint64_t n = r.end - r.begin;
        m.set_node_chunk(c,
                         m.storage(n * 8, world.node_masks().data() + r.begin, n * 8,
                                   "sparse node masks", kChunkUsage),
                         m.storage(n * 4, world.node_offsets().data() + r.begin, n * 4,
                                   "sparse node offsets", kChunkUsage));
    }
    for (std::size_t c = 0; c < material_ranges.size(); ++c) {
        const Range& r = material_ranges[c];
        const std::uint64_t n = r.end - r.begin;
        // Whole words: the bytes past the last material are never used.
        m.set_material_chunk(c, m.storage((n + 3) / 4 * 4, world.materials().data() + r.begin, n,
                                          "sparse materials", kChunkUsage));
    }
    for (std::uint32_t t = 0; t < world.tile_count(); ++t) {
        const std::uint32_t nc = node_chunk[t], mc = material_chunk[t];
        const std::uint64_t root = world.node_bases()[t] - node_ranges[nc].begin;
        m.write_record(t, nc, root, mc, world.material_bases()[t] - material_ranges[mc].begin);
    }
    m.make_directory_buffers(world.tile_count());
    m.stats.node_chunks = static_cast<std::uint32_t>(node_ranges.size());
    m.stats.material_chunks = static_cast<std::uint32_t>(material_ranges.size());
    m.count_bytes();
    m.loaded = true;
    m.write_set();
}

void SparseTracer::Impl::build_directory(const Dims& world_dims, const std::vector<Int3>& coords) {
    const std::uint32_t bt = VF_SPARSE_BLOCK_TILES;
    const auto tiles_along = [](std::uint32_t n) { return (n + kTileSize - 1) / kTileSize; };
    const Dims grid{tiles_along(world_dims.x), tiles_along(world_dims.y),
                    tiles_along(world_dims.z)};
    blocks = {(grid.x + bt - 1) / bt, (grid.y + bt - 1) / bt, (grid.z + bt - 1) / bt};
    const std::uint64_t block_count = std::uint64_t{blocks[0]} * blocks[1] * blocks[2];
    if (block_count * 4 > limit) {
        throw InputError("sparse tracer: the world " + world_dims.to_string() + " needs " +
                         std::to_string(block_count) + " directory blocks of 512^3 voxels (" +
                         mib(block_count * 4) + "), more than one storage-buffer binding holds (" +
                         mib(limit) + ")");
    }
    // The directory: a page of tile indices per block that holds a stored tile.
    host_blocks.assign(static_cast<std::size_t>(block_count), VF_SPARSE_NONE);
    host_pages.clear();
    page_fill.clear();
    free_pages.clear();
    free_records.clear();
    arena.clear();
    for (std::size_t t = 0; t < coords.size(); ++t) {
        const Int3 c = coords[t];
        if (c.x < 0 || c.y < 0 || c.z < 0 || c.x >= grid.x || c.y >= grid.y || c.z >= grid.z) {
            throw std::logic_error("sparse tracer: tile " + std::to_string(c.x) + ", " +
                                   std::to_string(c.y) + ", " + std::to_string(c.z) +
                                   " outside the tile grid " + grid.to_string());
        }
        const auto b = static_cast<std::size_t>(block_of(c));
        if (host_blocks[b] == VF_SPARSE_NONE) {
            host_blocks[b] = static_cast<std::uint32_t>(host_pages.size() / kPageTiles);
            host_pages.resize(host_pages.size() + kPageTiles, VF_SPARSE_NONE);
            page_fill.push_back(0);
        }
        std::uint32_t& entry = page_entry(host_blocks[b], c);
        if (entry != VF_SPARSE_NONE) {
            throw std::logic_error("sparse tracer: tile " + std::to_string(c.x) + ", " +
                                   std::to_string(c.y) + ", " + std::to_string(c.z) +
                                   " listed twice");
        }
        entry = static_cast<std::uint32_t>(t);
        ++page_fill[host_blocks[b]];
        if (host_pages.size() * 4 > limit) {
            throw InputError("sparse tracer: the directory of the world's " +
                             std::to_string(coords.size()) +
                             " tiles exceeds one storage-buffer binding (" + mib(limit) + ")");
        }
    }
    if (coords.size() * kRecordBytes > limit) {
        throw InputError("sparse tracer: the world's " + std::to_string(coords.size()) +
                         " tile records exceed one storage-buffer binding (" + mib(limit) + ")");
    }
    host_records.assign(coords.size() * kRecordWords, 0);
    arena_nodes_chunk = arena_materials_chunk = -1;
    arena_node_cap = arena_node_used = arena_mat_cap = arena_mat_used = 0;
    stats.blocks = block_count;
    dims = world_dims;
}

void SparseTracer::Impl::make_directory_buffers(std::uint64_t tiles) {
    palette = storage(sizeof colours, colours.data(), sizeof colours, "sparse palette");
    block_table = storage(host_blocks.size() * 4, host_blocks.data(), host_blocks.size() * 4,
                          "sparse block table");
    // Records and pages with room for the tiles and pages edits add (update_tiles).
    const std::uint64_t page_count = host_pages.size() / kPageTiles;
    page_capacity = std::min<std::uint64_t>(page_count + std::max<std::uint64_t>(page_count / 4, 4),
                                            limit / (4 * kPageTiles));
    pages = storage(page_capacity * kPageTiles * 4, host_pages.data(), host_pages.size() * 4,
                    "sparse tile pages");
    record_capacity = std::min<std::uint64_t>(tiles + std::max<std::uint64_t>(tiles / 4, 256),
                                              limit / kRecordBytes);
    records = storage(record_capacity * kRecordBytes, host_records.data(), host_records.size() * 4,
                      "sparse tile records");
}

std::uint64_t SparseTracer::Impl::block_of(const Int3& c) const {
    const std::uint32_t bt = VF_SPARSE_BLOCK_TILES;
    return (std::uint64_t(c.z / bt) * blocks[1] + std::uint64_t(c.y / bt)) * blocks[0] +
           std::uint64_t(c.x / bt);
}

std::uint32_t& SparseTracer::Impl::page_entry(std::uint32_t page, const Int3& c) {
    const std::uint32_t bt = VF_SPARSE_BLOCK_TILES;
    const std::uint64_t local =
        (std::uint64_t(c.z % bt) * bt + std::uint64_t(c.y % bt)) * bt + std::uint64_t(c.x % bt);
    return host_pages[std::size_t{page} * kPageTiles + local];
}

void SparseTracer::Impl::count_bytes() {
    stats.bytes = palette.size() + block_table.size() + pages.size() + records.size();
    for (const std::vector<Buffer>* chunks : {&masks, &offsets, &materials}) {
        for (const Buffer& b : *chunks) {
            stats.bytes += b.size();
        }
    }
    stats.shared_bytes = 0;
    for (const SharedSet& trees : shared_sets) {
        stats.shared_bytes += trees.masks.size() + trees.offsets.size() + trees.materials.size();
    }
    stats.pages = host_pages.size() / kPageTiles - free_pages.size();
    stats.arena_tiles = static_cast<std::uint32_t>(arena.size());
    stats.arena_node_chunk =
        arena_nodes_chunk < 0 ? VF_SPARSE_NONE : static_cast<std::uint32_t>(arena_nodes_chunk);
    stats.arena_nodes = arena_node_used;
    stats.arena_material_bytes = arena_mat_used;
    stats.arena_node_capacity = arena_node_cap;
    stats.arena_material_capacity = arena_mat_cap;
}

void SparseTracer::Impl::stage(const Buffer& dst, VkDeviceSize at, const void* data,
                               VkDeviceSize size) {
    if (size == 0) {
        return;
    }
    const VkDeviceSize from = staged.size();
    staged.resize(staged.size() + size);
    std::memcpy(staged.data() + from, data, size);
    copies.push_back(Copy{dst.get(), at, size, from});
}

void SparseTracer::Impl::fill_staging() {
    if (staging.size() < staged.size()) {
        staging = Buffer{};
        staging = ctx.make_buffer(std::max<VkDeviceSize>(staged.size(), VkDeviceSize{1} << 20),
                                  VK_BUFFER_USAGE_TRANSFER_SRC_BIT, MemoryIntent::upload,
                                  "sparse tracer staging");
    }
    std::memcpy(staging.data(), staged.data(), staged.size());
}

void SparseTracer::Impl::record_copies(VkCommandBuffer cmd) {
    // After the last trace's reads and the previous update's copies.
    VkMemoryBarrier before{};
    before.sType = VK_STRUCTURE_TYPE_MEMORY_BARRIER;
    before.srcAccessMask = VK_ACCESS_TRANSFER_WRITE_BIT;
    before.dstAccessMask = VK_ACCESS_TRANSFER_WRITE_BIT;
    vkCmdPipelineBarrier(cmd, VK_PIPELINE_STAGE_COMPUTE_SHADER_BIT | VK_PIPELINE_STAGE_TRANSFER_BIT,
                         VK_PIPELINE_STAGE_TRANSFER_BIT, 0, 1, &before, 0, nullptr, 0, nullptr);
    std::size_t i = 0;
    while (i < copies.size()) {
        std::vector<VkBufferCopy> regions;
        const VkBuffer dst = copies[i].dst;
        for (; i < copies.size() && copies[i].dst == dst; ++i) {
            regions.push_back(VkBufferCopy{copies[i].from, copies[i].at, copies[i].size});
        }
        vkCmdCopyBuffer(cmd, staging.get(), dst, static_cast<std::uint32_t>(regions.size()),
                        regions.data());
    }
    // Before the next trace reads them.
    VkMemoryBarrier after{};
    after.sType = VK_STRUCTURE_TYPE_MEMORY_BARRIER;
    after.srcAccessMask = VK_ACCESS_TRANSFER_WRITE_BIT;
    after.dstAccessMask = VK_ACCESS_SHADER_READ_BIT;
    vkCmdPipelineBarrier(cmd, VK_PIPELINE_STAGE_TRANSFER_BIT, VK_PIPELINE_STAGE_COMPUTE_SHADER_BIT,
                         0, 1, &after, 0, nullptr, 0, nullptr);
}

void SparseTracer::Impl::flush(const std::string& what) {
    if (copies.empty()) {
        return;
    }
    fill_staging();
    ctx.submit_and_wait([&](VkCommandBuffer cmd) { record_copies(cmd); }, what);
    discard_copies();
}

void SparseTracer::Impl::discard_copies() {
    staged.clear();
    copies.clear();
}

bool SparseTracer::Impl::arena_fit(const SparseWorld& world, std::uint64_t nodes,
                                   std::uint64_t material_bytes,
                                   const std::vector<std::uint32_t>& dropping, bool& rebuilt) {
    if (arena_nodes_chunk >= 0 && arena_node_used + nodes <= arena_node_cap &&
        arena_mat_used + material_bytes <= arena_mat_cap) {
        return true;
    }
    // Grow: fresh buffers twice what stays live plus what comes, the live trees written again.
    std::uint64_t live_nodes = nodes, live_materials = material_bytes;
    std::vector<std::uint32_t> keep;
    for (const auto& [record, a] : arena) {
        if (std::find(dropping.begin(), dropping.end(), record) == dropping.end()) {
            live_nodes += a.nodes;
            live_materials += a.materials;
            keep.push_back(record);
        }
    }
    const std::uint64_t node_cap = std::max(kArenaNodes, 2 * live_nodes);
    const std::uint64_t mat_cap = std::max(kArenaMaterials, 2 * live_materials);
    if (live_nodes * 8 > limit || live_materials > limit) {
        return false;
    }
    const std::uint64_t nodes_fit = std::min(node_cap, limit / 8);
    const std::uint64_t mats_fit = std::min(mat_cap, limit) / 4 * 4;
    const auto make = [&](VkDeviceSize bytes, const std::string& what) {
        return ctx.make_buffer(bytes, kChunkUsage, MemoryIntent::device_local, what);
    };
    Buffer new_masks = make(nodes_fit * 8, "sparse arena node masks");
    Buffer new_offsets = make(nodes_fit * 4, "sparse arena node offsets");
    Buffer new_materials = make(mats_fit, "sparse arena materials");
    if (arena_nodes_chunk < 0) {
        arena_nodes_chunk = static_cast<int>(masks.size());
        arena_materials_chunk = static_cast<int>(materials.size());
    }
    set_node_chunk(static_cast<std::size_t>(arena_nodes_chunk), std::move(new_masks),
                   std::move(new_offsets));
    set_material_chunk(static_cast<std::size_t>(arena_materials_chunk), std::move(new_materials));
    arena_node_cap = nodes_fit;
    arena_mat_cap = mats_fit;
    arena_node_used = arena_mat_used = 0;
    for (const std::uint32_t record : keep) {
        const ArenaTile old = arena.at(record);
        const Int3 c = tile_of_key(old.key);
        const std::uint32_t t = world.find_tile(c.x, c.y, c.z);
        const ArenaTile a = arena_write(world, t, old.key);
        arena[record] = a;
        record_arena(record, a);
    }
    rebuilt = true;
    return true;
}

ArenaTile SparseTracer::Impl::arena_write(const SparseWorld& world, std::uint32_t t,
                                          std::uint64_t key) {
    ArenaTile a;
    a.key = key;
    a.nodes = world.node_counts()[t];
    a.materials = world.material_counts()[t];
    a.node_at = arena_node_used;
    a.material_at = arena_mat_used;
    const std::uint64_t nb = world.node_bases()[t], mb = world.material_bases()[t];
    const auto nodes_chunk = static_cast<std::size_t>(arena_nodes_chunk);
    stage(masks[nodes_chunk], a.node_at * 8, world.node_masks().data() + nb,
          VkDeviceSize{a.nodes} * 8);
    stage(offsets[nodes_chunk], a.node_at * 4, world.node_offsets().data() + nb,
          VkDeviceSize{a.nodes} * 4);
    stage(materials[static_cast<std::size_t>(arena_materials_chunk)], a.material_at,
          world.materials().data() + mb, a.materials);
    arena_node_used += a.nodes;
    arena_mat_used += a.materials;
    return a;
}

void SparseTracer::Impl::record_arena(std::uint32_t record, const ArenaTile& a) {
    write_record(record, static_cast<std::size_t>(arena_nodes_chunk), a.node_at,
                 static_cast<std::size_t>(arena_materials_chunk), a.material_at);
}

void SparseTracer::Impl::write_record(std::uint32_t record, std::size_t node_chunk,
                                      std::uint64_t root, std::size_t material_chunk,
                                      std::uint64_t first_material) {
    std::uint32_t* r = host_records.data() + kRecordWords * record;
    const auto split = [](std::uint32_t* at, VkDeviceAddress a) {
        at[0] = static_cast<std::uint32_t>(a);
        at[1] = static_cast<std::uint32_t>(a >> 32);
    };
    r[0] = static_cast<std::uint32_t>(root);
    r[1] = static_cast<std::uint32_t>(first_material);
    split(r + 2, mask_at[node_chunk] + 8 * root);
    split(r + 4, offset_at[node_chunk] + 4 * root);
    split(r + 6, material_at[material_chunk]);
}

void SparseTracer::Impl::set_node_chunk(std::size_t c, Buffer chunk_masks, Buffer chunk_offsets) {
    if (c == masks.size()) {
        masks.emplace_back();
        offsets.emplace_back();
        mask_at.push_back(0);
        offset_at.push_back(0);
    }
    mask_at[c] = ctx.device_address(chunk_masks);
    offset_at[c] = ctx.device_address(chunk_offsets);
    masks[c] = std::move(chunk_masks);
    offsets[c] = std::move(chunk_offsets);
}

void SparseTracer::Impl::clear_chunks() {
    masks.clear();
    offsets.clear();
    materials.clear();
    mask_at.clear();
    offset_at.clear();
    material_at.clear();
}

void SparseTracer::Impl::set_material_chunk(std::size_t c, Buffer chunk) {
    if (c == materials.size()) {
        materials.emplace_back();
        material_at.push_back(0);
    }
    material_at[c] = ctx.device_address(chunk);
    materials[c] = std::move(chunk);
}

SparseTileUpdate SparseTracer::update_tiles(const SparseWorld& world, const Box& changed) {
    Impl& m = *impl_;
    if (!m.loaded) {
        throw std::logic_error("SparseTracer::update_tiles before upload");
    }
    if (world.dims() != m.dims) {
        throw std::logic_error("SparseTracer::update_tiles: the world is not the one uploaded");
    }
    if (m.shared) {
        throw std::logic_error("SparseTracer::update_tiles on trees read in place (repoint)");
    }
    SparseTileUpdate u;
    const Dims d = world.dims();
    const Box box = intersect(changed, Box{{0, 0, 0}, {d.x, d.y, d.z}});
    if (box.empty()) {
        return u;
    }
    m.ctx.wait_frames_in_flight();
    // The previous update's copies when no trace took them: before any of their buffers is
    // replaced, and so that one submission never copies twice to the same place.
    m.flush("sparse tracer: the previous tile update");
    // The tiles the box overlaps: each one's tile in the world (or none) and its record.
    struct Touched {
        Int3 c;
        std::uint32_t tile, record;
    };
    std::vector<Touched> touched;
    std::vector<std::uint32_t> dropping;
    std::uint64_t nodes = 0, materials = 0;
    const std::int64_t ts = kTileSize;
    for (std::int64_t tz = box.min.z / ts; tz <= (box.max.z - 1) / ts; ++tz) {
        for (std::int64_t ty = box.min.y / ts; ty <= (box.max.y - 1) / ts; ++ty) {
            for (std::int64_t tx = box.min.x / ts; tx <= (box.max.x - 1) / ts; ++tx) {
                const Int3 c{tx, ty, tz};
                const std::uint32_t page = m.host_blocks[m.block_of(c)];
                const std::uint32_t record =
                    page == VF_SPARSE_NONE ? VF_SPARSE_NONE : m.page_entry(page, c);
                const std::uint32_t t = world.find_tile(tx, ty, tz);
                if (t == kNoTile && record == VF_SPARSE_NONE) {
                    continue;
                }
                touched.push_back({c, t, record});
                if (record != VF_SPARSE_NONE && m.arena.contains(record)) {
                    dropping.push_back(record);
                }
                if (t != kNoTile) {
                    nodes += world.node_counts()[t];
                    materials += world.material_counts()[t];
                }
            }
        }
    }
    if (touched.empty()) {
        return u;
    }
    try {
        if (!m.arena_fit(world, nodes, materials, dropping, u.arena_rebuilt)) {
            m.upload_all(world);
            u.whole = true;
            u.bytes = m.stats.bytes;
            u.tiles_written = world.tile_count();
            return u;
        }
        Impl::DirectoryEdit e;
        for (const Touched& k : touched) {
            if (k.tile == kNoTile) {
                m.drop_tile(k.c, k.record, e);
                ++u.tiles_removed;
                continue;
            }
            const std::uint32_t record = k.record == VF_SPARSE_NONE ? m.add_tile(k.c, e) : k.record;
            const ArenaTile a = m.arena_write(
                world, k.tile,
                tile_key(static_cast<std::uint32_t>(k.c.x), static_cast<std::uint32_t>(k.c.y),
                         static_cast<std::uint32_t>(k.c.z)));
            m.arena[record] = a;
            m.record_arena(record, a);
            e.records.push_back(record);
            ++u.tiles_written;
        }
        if (u.arena_rebuilt) {
            for (const auto& [record, a] : m.arena) {
                e.records.push_back(record);
            }
        }
        // The arena is chunk 0, bound, when the world had none: a rebuilt one is bound again.
        m.stage_update(e, u.arena_rebuilt, u);
    } catch (...) {
        // Buffers may have been replaced and the descriptor set not written again: nothing is
        // traced (its staged copies dropped) until a whole upload.
        m.discard_copies();
        m.loaded = false;
        throw;
    }
    return u;
}

std::uint32_t SparseTracer::Impl::record_of(const Int3& c) {
    const std::uint32_t page = host_blocks[block_of(c)];
    return page == VF_SPARSE_NONE ? VF_SPARSE_NONE : page_entry(page, c);
}

void SparseTracer::Impl::drop_tile(const Int3& c, std::uint32_t record, DirectoryEdit& e) {
    const std::uint64_t b = block_of(c);
    const std::uint32_t page = host_blocks[b];
    std::uint32_t& entry = page_entry(page, c);
    e.entries.push_back(static_cast<std::uint64_t>(&entry - host_pages.data()));
    entry = VF_SPARSE_NONE;
    arena.erase(record);
    free_records.push_back(record);
    if (--page_fill[page] == 0) {
        host_blocks[b] = VF_SPARSE_NONE;
        free_pages.push_back(page);
        e.blocks.push_back(b);
    }
}

namespace {

// The last freed index of `freed`, else `make()`'s new one.
template <class Make>
std::uint32_t reuse_or(std::vector<std::uint32_t>& freed, Make make) {
    if (freed.empty()) {
        return make();
    }
    const std::uint32_t i = freed.back();
    freed.pop_back();
    return i;
}

}  // namespace

std::uint32_t SparseTracer::Impl::add_tile(const Int3& c, DirectoryEdit& e) {
    const std::uint32_t record = reuse_or(free_records, [&] {
        const auto r = static_cast<std::uint32_t>(host_records.size() / kRecordWords);
        host_records.resize(host_records.size() + kRecordWords, 0);
        return r;
    });
    const std::uint64_t b = block_of(c);
    if (host_blocks[b] == VF_SPARSE_NONE) {
        const std::uint32_t page = reuse_or(free_pages, [&] {
            const auto p = static_cast<std::uint32_t>(host_pages.size() / kPageTiles);
            host_pages.resize(host_pages.size() + kPageTiles, VF_SPARSE_NONE);
            page_fill.push_back(0);
            return p;
        });
        host_blocks[b] = page;
        e.blocks.push_back(b);
        e.new_pages.push_back(page);
    }
    const std::uint32_t page = host_blocks[b];
    std::uint32_t& entry = page_entry(page, c);
    entry = record;
    e.entries.push_back(static_cast<std::uint64_t>(&entry - host_pages.data()));
    ++page_fill[page];
    return record;
}

void SparseTracer::Impl::stage_update(DirectoryEdit& e, bool rebind, SparseTileUpdate& u) {
    const bool replaced = stage_directory(e);
    u.bytes = staged.size();
    count_bytes();
    if (replaced || rebind) {
        write_set();
    }
}

bool SparseTracer::Impl::stage_directory(DirectoryEdit& e) {
    // Each place once (a record moved and rewritten in one update is listed twice): the copies
    // of one submission never overlap.
    const auto sort_unique = [](auto& list) {
        std::sort(list.begin(), list.end());
        list.erase(std::unique(list.begin(), list.end()), list.end());
    };
    sort_unique(e.blocks);
    sort_unique(e.entries);
    sort_unique(e.records);
    sort_unique(e.new_pages);
    bool rebind = false;
    const std::uint64_t record_count = host_records.size() / kRecordWords;
    if (record_count > record_capacity) {
        if (record_count * kRecordBytes > limit) {
            throw InputError("sparse tracer: the directory's " + std::to_string(record_count) +
                             " tile records exceed one storage-buffer binding (" + mib(limit) +
                             ")");
        }
        record_capacity = std::min<std::uint64_t>(2 * record_count, limit / kRecordBytes);
        records = Buffer{};
        records =
            ctx.make_buffer(record_capacity * kRecordBytes,
                            VK_BUFFER_USAGE_STORAGE_BUFFER_BIT | VK_BUFFER_USAGE_TRANSFER_DST_BIT,
                            MemoryIntent::device_local, "sparse tile records");
        stage(records, 0, host_records.data(), host_records.size() * 4);
        rebind = true;
    } else {
        for (const std::uint32_t r : e.records) {
            stage(records, VkDeviceSize{r} * kRecordBytes, host_records.data() + kRecordWords * r,
                  kRecordBytes);
        }
    }
    const std::uint64_t page_count = host_pages.size() / kPageTiles;
    if (page_count > page_capacity) {
        if (host_pages.size() * 4 > limit) {
            throw InputError("sparse tracer: the directory's " + std::to_string(page_count) +
                             " tile pages exceed one storage-buffer binding (" + mib(limit) + ")");
        }
        page_capacity = std::min<std::uint64_t>(2 * page_count, limit / (4 * kPageTiles));
        pages = Buffer{};
        pages =
            ctx.make_buffer(page_capacity * kPageTiles * 4,
                            VK_BUFFER_USAGE_STORAGE_BUFFER_BIT | VK_BUFFER_USAGE_TRANSFER_DST_BIT,
                            MemoryIntent::device_local, "sparse tile pages");
        stage(pages, 0, host_pages.data(), host_pages.size() * 4);
        rebind = true;
    } else {
        for (const std::uint32_t p : e.new_pages) {
            stage(pages, VkDeviceSize{p} * kPageTiles * 4,
                  host_pages.data() + std::size_t{p} * kPageTiles, kPageTiles * 4);
        }
        for (const std::uint64_t entry : e.entries) {
            stage(pages, entry * 4, host_pages.data() + entry, 4);
        }
    }
    for (const std::uint64_t b : e.blocks) {
        stage(block_table, b * 4, host_blocks.data() + b, 4);
    }
    return rebind;
}

void SparseTracer::upload_shared(Dims dims, const Palette& palette,
                                 const std::vector<SharedTreeSet>& sets,
                                 const std::vector<SharedTile>& tiles) {
    Impl& m = *impl_;
    for (std::size_t i = 0; i < m.colours.size(); ++i) {
        m.colours[i] = pack_rgba(palette[static_cast<std::uint8_t>(i)]);
    }
    m.ctx.wait_frames_in_flight();
    m.discard_copies();  // their buffers are replaced
    m.loaded = false;
    m.stats = SparseDeviceStats{};
    // The copy's chunks go: nothing of the trees is the tracer's.
    m.clear_chunks();
    std::vector<Int3> coords(tiles.size());
    for (std::size_t i = 0; i < tiles.size(); ++i) {
        coords[i] = tiles[i].tile;
    }
    m.build_directory(dims, coords);
    m.shared = true;
    m.shared_sets.clear();
    m.set_shared(sets);
    m.shared_tiles = tiles;
    for (std::size_t i = 0; i < tiles.size(); ++i) {
        m.write_shared_record(static_cast<std::uint32_t>(i), tiles[i]);
    }
    m.make_directory_buffers(tiles.size());
    m.count_bytes();
    m.loaded = true;
    m.write_set();
}

SparseTileUpdate SparseTracer::repoint(const std::vector<SharedTreeSet>& sets,
                                       const std::vector<SharedTile>& tiles,
                                       const std::vector<Int3>& removed) {
    Impl& m = *impl_;
    if (!m.loaded || !m.shared) {
        throw std::logic_error("SparseTracer::repoint before upload_shared");
    }
    m.ctx.wait_frames_in_flight();
    SparseTileUpdate u;
    try {
        // As in update_tiles: the previous repoint's copies when no trace took them.
        m.flush("sparse tracer: the previous repoint");
        Impl::DirectoryEdit e;
        // Tiles in a set whose memory was replaced: the same places in the new memory.
        const std::vector<bool> moved = m.set_shared(sets);
        if (std::find(moved.begin(), moved.end(), true) != moved.end()) {
            for (std::size_t r = 0; r < m.shared_tiles.size(); ++r) {
                const SharedTile& t = m.shared_tiles[r];
                if (t.set != VF_SPARSE_NONE && moved.at(t.set)) {
                    m.write_shared_record(static_cast<std::uint32_t>(r), t);
                    e.records.push_back(static_cast<std::uint32_t>(r));
                    ++u.tiles_moved;
                }
            }
        }
        for (const Int3& c : removed) {
            if (const std::uint32_t record = m.record_of(c); record != VF_SPARSE_NONE) {
                m.drop_tile(c, record, e);
                m.shared_tiles[record].set = VF_SPARSE_NONE;
                ++u.tiles_removed;
            }
        }
        for (const SharedTile& t : tiles) {
            std::uint32_t record = m.record_of(t.tile);
            if (record == VF_SPARSE_NONE) {
                record = m.add_tile(t.tile, e);
                ++u.tiles_added;
            }
            if (record >= m.shared_tiles.size()) {
                SharedTile none;
                none.set = VF_SPARSE_NONE;
                m.shared_tiles.resize(record + 1, none);
            }
            m.shared_tiles[record] = t;
            m.write_shared_record(record, t);
            e.records.push_back(record);
            ++u.tiles_written;
        }
        m.stage_update(e, false, u);
    } catch (...) {
        // Records may point at memory the sets no longer view: nothing is traced until a whole
        // upload_shared.
        m.discard_copies();
        m.loaded = false;
        m.shared_sets.clear();
        throw;
    }
    return u;
}

void SparseTracer::drop_shared() {
    Impl& m = *impl_;
    m.ctx.wait_frames_in_flight();
    m.discard_copies();
    m.loaded = false;
    m.shared_sets.clear();
}

std::vector<bool> SparseTracer::Impl::set_shared(const std::vector<SharedTreeSet>& sets) {
    std::vector<bool> moved(sets.size(), false);
    shared_sets.resize(sets.size());
    for (std::size_t i = 0; i < sets.size(); ++i) {
        const SharedTreeSet& in = sets[i];
        if (in.serials == shared_sets[i].serials) {
            continue;
        }
        moved[i] = true;
        SharedSet trees;  // assigned whole below, once every view is made
        trees.serials = in.serials;
        if (in.masks != nullptr && in.offsets != nullptr && in.materials != nullptr) {
            const auto view = [&](const ExternalMemory& mem, const std::string& what) {
                Buffer b =
                    ctx.make_external_buffer(mem.size(), kSharedTreeUsage, mem.handle_type(), what);
                ctx.bind(b, mem.memory(), 0, what);
                return b;
            };
            trees.external = in.masks->path() == SharingPath::opaque_fd;
            trees.masks = view(*in.masks, "shared sparse node masks");
            trees.offsets = view(*in.offsets, "shared sparse node offsets");
            trees.materials = view(*in.materials, "shared sparse materials");
            trees.mask_at = ctx.device_address(trees.masks);
            trees.offset_at = ctx.device_address(trees.offsets);
            trees.material_at = ctx.device_address(trees.materials);
        }
        shared_sets[i] = std::move(trees);
    }
    return moved;
}

void SparseTracer::Impl::write_shared_record(std::uint32_t record, const SharedTile& t) {
    if (t.set >= shared_sets.size() || shared_sets[t.set].masks.get() == VK_NULL_HANDLE) {
        throw std::logic_error("SparseTracer: a shared tile in set " + std::to_string(t.set) +
                               ", which has no memory");
    }
    const SharedSet& trees = shared_sets[t.set];
    std::uint32_t* r = host_records.data() + kRecordWords * record;
    const auto split = [](std::uint32_t* at, VkDeviceAddress a) {
        at[0] = static_cast<std::uint32_t>(a);
        at[1] = static_cast<std::uint32_t>(a >> 32);
    };
    // The root's index is read only through chunk 0's binding, which shared trees never take.
    r[0] = 0;
    r[1] = static_cast<std::uint32_t>(t.material & 3);
    split(r + 2, trees.mask_at + 8 * t.node);
    split(r + 4, trees.offset_at + 4 * t.node);
    split(r + 6, trees.material_at + (t.material & ~std::uint64_t{3}));
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
    // A world without tiles, or read in place (shared trees), has no chunks: the block table
    // stands in (never read).
    add(VF_SPARSE_BINDING_MASKS0, masks.empty() ? block_table : masks[0]);
    add(VF_SPARSE_BINDING_OFFSETS0, offsets.empty() ? block_table : offsets[0]);
    add(VF_SPARSE_BINDING_MATERIALS0, materials.empty() ? block_table : materials[0]);
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

VkPipeline SparseTracer::Impl::pipeline_for(bool shadows, bool count, bool one_chunk) {
    Owned<VkPipeline>& slot =
        pipelines[(shadows ? 1u : 0u) | (count ? 2u : 0u) | (one_chunk ? 4u : 0u)];
    if (slot) {
        return slot.get();
    }
    const auto flag = [](bool b) { return b ? VkBool32{VK_TRUE} : VkBool32{VK_FALSE}; };
    const Specialization data{flag(shadows), flag(count), flag(one_chunk)};
    const std::array<VkSpecializationMapEntry, 3> entries = {
        VkSpecializationMapEntry{0, offsetof(Specialization, shadows), sizeof(VkBool32)},
        VkSpecializationMapEntry{1, offsetof(Specialization, count), sizeof(VkBool32)},
        VkSpecializationMapEntry{2, offsetof(Specialization, one_chunk), sizeof(VkBool32)}};
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
    impl_->dispatch(o, &out);
}

double SparseTracer::trace(const RenderOptions& o) {
    return impl_->dispatch(o, nullptr);
}

double SparseTracer::Impl::dispatch(const RenderOptions& o, Image* out) {
    Impl& m = *this;
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
    const VkPipeline pipeline =
        m.pipeline_for(o.shading == Shading::lit, o.count,
                       !m.shared && m.masks.size() <= 1 && m.materials.size() <= 1);
    const VkImage image = m.target.image.get();
    const VkQueryPool timer = m.queries.get();
    // The last update's copies go first in the trace's own submission.
    const bool copying = !m.copies.empty();
    if (copying) {
        m.fill_staging();
    }
    m.ctx.submit_and_wait(
        [&](VkCommandBuffer cmd) {
            if (copying) {
                m.record_copies(cmd);
            }
            const VkImageMemoryBarrier to_general =
                color_barrier(image, 0, VK_ACCESS_SHADER_WRITE_BIT, VK_IMAGE_LAYOUT_UNDEFINED,
                              VK_IMAGE_LAYOUT_GENERAL);
            // After the previous render's copy out of the image and its dispatch.
            vkCmdPipelineBarrier(
                cmd, VK_PIPELINE_STAGE_TRANSFER_BIT | VK_PIPELINE_STAGE_COMPUTE_SHADER_BIT,
                VK_PIPELINE_STAGE_COMPUTE_SHADER_BIT, 0, 0, nullptr, 0, nullptr, 1, &to_general);
            // Trees in memory exported as an opaque fd (OpenCL wrote them): acquired from
            // VK_QUEUE_FAMILY_EXTERNAL before the dispatch reads them, released back after.
            std::vector<VkBufferMemoryBarrier> ownership;
            for (const Impl::SharedSet& trees : m.shared_sets) {
                if (!trees.external) {
                    continue;
                }
                for (const Buffer* b : {&trees.masks, &trees.offsets, &trees.materials}) {
                    VkBufferMemoryBarrier acquire{};
                    acquire.sType = VK_STRUCTURE_TYPE_BUFFER_MEMORY_BARRIER;
                    acquire.dstAccessMask = VK_ACCESS_SHADER_READ_BIT;
                    acquire.srcQueueFamilyIndex = VK_QUEUE_FAMILY_EXTERNAL;
                    acquire.dstQueueFamilyIndex = m.ctx.queue_family();
                    acquire.buffer = b->get();
                    acquire.size = VK_WHOLE_SIZE;
                    ownership.push_back(acquire);
                }
            }
            if (!ownership.empty()) {
                vkCmdPipelineBarrier(cmd, VK_PIPELINE_STAGE_TOP_OF_PIPE_BIT,
                                     VK_PIPELINE_STAGE_COMPUTE_SHADER_BIT, 0, 0, nullptr,
                                     static_cast<std::uint32_t>(ownership.size()), ownership.data(),
                                     0, nullptr);
            }
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
            if (!ownership.empty()) {
                for (VkBufferMemoryBarrier& b : ownership) {
                    b.srcAccessMask = 0;
                    b.dstAccessMask = 0;
                    std::swap(b.srcQueueFamilyIndex, b.dstQueueFamilyIndex);
                }
                vkCmdPipelineBarrier(cmd, VK_PIPELINE_STAGE_COMPUTE_SHADER_BIT,
                                     VK_PIPELINE_STAGE_BOTTOM_OF_PIPE_BIT, 0, 0, nullptr,
                                     static_cast<std::uint32_t>(ownership.size()), ownership.data(),
                                     0, nullptr);
            }
            const VkImageMemoryBarrier to_copy = color_barrier(
                to_general.image, VK_ACCESS_SHADER_WRITE_BIT, VK_ACCESS_TRANSFER_READ_BIT,
                VK_IMAGE_LAYOUT_GENERAL, VK_IMAGE_LAYOUT_TRANSFER_SRC_OPTIMAL);
            if (out == nullptr) {
                return;  // the image stays on the device
            }
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
    m.discard_copies();  // done (after a failed submission they stay, for the next trace)
    double ms = -1;
    if (timer != VK_NULL_HANDLE) {
        ms = timestamp_pair_ms(m.ctx, timer, 0, true, "sparse trace timestamps");
    }
    if (out == nullptr) {
        return ms;
    }
    out->width = o.width;
    out->height = o.height;
    out->rgba.resize(pixels * 4);
    std::memcpy(out->rgba.data(), m.target.readback.data(), pixels * 4);
    out->raymarch_ms = ms;
    out->fetches = out->steps = 0;
    if (o.count) {
        const auto* c = static_cast<const std::uint32_t*>(m.counters.data());
        for (std::size_t i = 0; i < pixels; ++i) {
            out->fetches += c[2 * i];
            out->steps += c[2 * i + 1];
        }
    }
    out->surface.clear();
    return ms;
}

}  // namespace voxfield::vk
