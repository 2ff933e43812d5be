// A sparse world's 64-trees on the device, edited there (issue 24; the implicit-surface
// rendering blog's tile grid of contrees, "Serializing the contree", encoded by kernels).
#include "voxfield/cl/sparse_device_world.hpp"

#include <algorithm>
#include <bit>
#include <initializer_list>
#include <stdexcept>
#include <string>
#include <utility>

#include "pinned.hpp"
#include "util.hpp"
#include "voxfield/core/error.hpp"

namespace voxfield::cl_sources {
extern const char* const sparse_tree_cl;
extern const char* const sparse_world_cl;
}  // namespace voxfield::cl_sources

namespace voxfield::ocl {
namespace {

constexpr std::uint64_t kSlotRef = SparseDeviceWorld::kSlotRef;
// Bytes of one slot: its worst-case nodes (mask and offset) and materials.
constexpr std::uint64_t kSlotBytes = std::uint64_t{kTileMaxNodes} * 12 + kTileVoxels;
// Host-edited boxes over more tiles than this upload the whole world instead.
constexpr std::size_t kMaxHostEditTiles = 256;
// Work-items per work-group of gather (rows, CPU layout) and gather_quads (GPU layout).
constexpr std::size_t kGatherRows = 8, kGatherQuads = 64;

cl::Program world_program(Context& ctx) {
    return ctx.program("sparse_world.cl", {cl_sources::sparse_tree_cl, cl_sources::sparse_world_cl},
                       "-cl-std=CL1.2");
}

struct Span {
    Int3 first, count;
    std::int64_t size() const { return count.x * count.y * count.z; }
};

// The tiles a non-empty box inside the world overlaps.
Span tiles_of(const Box& b) {
    const std::int64_t s = kTileSize;
    const Int3 lo{b.min.x / s, b.min.y / s, b.min.z / s};
    return {
        lo,
        {(b.max.x - 1) / s - lo.x + 1, (b.max.y - 1) / s - lo.y + 1, (b.max.z - 1) / s - lo.z + 1}};
}

template <class F>
void for_each_tile(const Span& span, F&& f) {
    for (std::int64_t z = 0; z < span.count.z; ++z) {
        for (std::int64_t y = 0; y < span.count.y; ++y) {
            for (std::int64_t x = 0; x < span.count.x; ++x) {
                f(span.first.x + x, span.first.y + y, span.first.z + z);
            }
        }
    }
}

std::uint64_t key_of(std::int64_t tx, std::int64_t ty, std::int64_t tz) {
    return tile_key(static_cast<std::uint32_t>(tx), static_cast<std::uint32_t>(ty),
                    static_cast<std::uint32_t>(tz));
}

// sparse_world.cl's edit table: a header of kTableHeader longs, a record of kRecord longs per
// tile.
constexpr std::size_t kTableHeader = 16;
constexpr std::size_t kRecord = 8;
constexpr std::int64_t kNoBrush = 3;

// With the list of dense nodes: at most 64 per tile.
std::size_t table_bytes(std::size_t tiles) {
    return (kTableHeader + (kRecord + 64) * tiles) * 8;
}

// What encode_count and encode_write read and write (sparse_world.cl): the dense nodes' voxels,
// the table, the previous trees' buffers (main and slot), scratch, the output slots.
struct EncodeBuffers {
    cl::Buffer vox;
    cl_uint pitch_y = 0, pitch_z = 0;
    cl::Buffer table, masks, offsets, materials;
    cl::Buffer leaf_masks, mid_masks, mid_counts;
    cl::Buffer slot_masks, slot_offsets, slot_materials, slot_counts;
};

// Enqueues encode_count and encode_write (`k`: those kernels) over `tiles` tiles with `dense`
// dense nodes, encode_write's work-groups a node each (`per_node`, the GPU layout's) or a tile
// each; appends their events to `events` (none when it is null).
void enqueue_encode(cl::CommandQueue& q, EncodeKernels& k, const EncodeBuffers& b,
                    std::uint32_t tiles, std::uint32_t dense, bool per_node,
                    std::vector<std::pair<std::string, cl::Event>>* events) {
    const cl::NDRange local(64, 1);
    auto set = [](cl::Kernel& kernel, std::initializer_list<const cl::Buffer*> buffers,
                  cl_uint arg) {
        for (const cl::Buffer* buffer : buffers) {
            kernel.setArg(arg++, *buffer);
        }
        return arg;
    };
    for (cl::Kernel* kernel : {&k.count, &k.write}) {
        kernel->setArg(0, b.vox);
        kernel->setArg(1, b.pitch_y);
        kernel->setArg(2, b.pitch_z);
    }
    cl_uint arg = set(k.count,
                      {&b.table, &b.masks, &b.offsets, &b.materials, &b.slot_masks, &b.slot_offsets,
                       &b.slot_materials, &b.leaf_masks, &b.mid_masks, &b.mid_counts},
                      3);
    k.count.setArg(arg++, tiles);
    k.count.setArg(arg, dense);
    // encode_count: four work-items a leaf, 256 a node (sparse_world.cl).
    q.enqueueNDRangeKernel(k.count, cl::NullRange, cl::NDRange(256, std::size_t{tiles} + dense),
                           cl::NDRange(256, 1), nullptr, stage_event(events, "encode_count"));
    arg = set(k.write,
              {&b.table, &b.masks, &b.offsets, &b.materials, &b.leaf_masks, &b.mid_masks,
               &b.mid_counts, &b.slot_masks, &b.slot_offsets, &b.slot_materials, &b.slot_counts},
              3);
    k.write.setArg(arg++, tiles);
    k.write.setArg(arg, cl_uint{per_node ? 1u : 64u});
    q.enqueueNDRangeKernel(k.write, cl::NullRange,
                           cl::NDRange(64, std::size_t{tiles} * (per_node ? 64 : 1)), local,
                           nullptr, stage_event(events, "encode_write"));
}

// The nodes of tile (tx, ty, tz) that `b` overlaps (bit z << 4 | y << 2 | x of each 16^3 node).
std::uint64_t nodes_overlapped(const Box& b, std::int64_t tx, std::int64_t ty, std::int64_t tz) {
    const std::int64_t s = kTileSize;
    const Box part =
        intersect(b, Box{{tx * s, ty * s, tz * s}, {(tx + 1) * s, (ty + 1) * s, (tz + 1) * s}});
    std::uint64_t mask = 0;
    if (part.empty()) {
        return mask;
    }
    for (std::int64_t z = part.min.z / 16; z <= (part.max.z - 1) / 16; ++z) {
        for (std::int64_t y = part.min.y / 16; y <= (part.max.y - 1) / 16; ++y) {
            for (std::int64_t x = part.min.x / 16; x <= (part.max.x - 1) / 16; ++x) {
                mask |= std::uint64_t{1} << ((z % 4) << 4 | (y % 4) << 2 | (x % 4));
            }
        }
    }
    return mask;
}

}  // namespace

std::vector<SparseWorld::EncodedTile> encode_tiles(Context& ctx,
                                                   std::span<const std::uint8_t> voxels) {
    if (voxels.size() % kTileVoxels != 0) {
        throw std::invalid_argument("encode_tiles: not a whole number of 64^3 tiles");
    }
    const auto tiles = static_cast<std::uint32_t>(voxels.size() / kTileVoxels);
    std::vector<SparseWorld::EncodedTile> out(tiles);
    if (tiles == 0) {
        return out;
    }
    return cl_call("encoding " + std::to_string(tiles) + " tiles on the device", [&] {
        auto& c = ctx.context();
        auto& q = ctx.queue();
        const cl::Program program = world_program(ctx);
        // Every node dense (read from its tile), no previous trees, no brush.
        std::vector<std::int64_t> table(table_bytes(tiles) / 8, 0);
        table[0] = kNoBrush;
        for (std::uint32_t t = 0; t < tiles; ++t) {
            std::int64_t* rec = table.data() + kTableHeader + kRecord * t;
            rec[0] = static_cast<std::int64_t>(SparseDeviceWorld::kNoRef);
            rec[2] = t;
            rec[3] = static_cast<std::int64_t>(std::uint64_t{t} * kTileVoxels);
            rec[4] = -1;
            for (std::int64_t b = 0; b < 64; ++b) {
                table[kTableHeader + kRecord * tiles + std::size_t{t} * 64 + b] = t * 64 + b;
            }
        }
        EncodeBuffers b;
        b.vox = cl::Buffer(c, CL_MEM_READ_WRITE | CL_MEM_COPY_HOST_PTR, voxels.size(),
                           const_cast<std::uint8_t*>(voxels.data()));
        b.pitch_y = kTileSize;
        b.pitch_z = kTileSize * kTileSize;
        b.table =
            cl::Buffer(c, CL_MEM_READ_ONLY | CL_MEM_COPY_HOST_PTR, table.size() * 8, table.data());
        b.masks = b.materials = b.offsets = cl::Buffer(c, CL_MEM_READ_ONLY, 8);
        b.leaf_masks = cl::Buffer(c, CL_MEM_READ_WRITE, std::size_t{tiles} * 4096 * 8);
        b.mid_masks = cl::Buffer(c, CL_MEM_READ_WRITE, std::size_t{tiles} * 64 * 8);
        b.mid_counts = cl::Buffer(c, CL_MEM_READ_WRITE, std::size_t{tiles} * 64 * 4);
        b.slot_masks = cl::Buffer(c, CL_MEM_READ_WRITE, std::size_t{tiles} * kTileMaxNodes * 8);
        b.slot_offsets = cl::Buffer(c, CL_MEM_READ_WRITE, std::size_t{tiles} * kTileMaxNodes * 4);
        b.slot_materials = cl::Buffer(c, CL_MEM_READ_WRITE, voxels.size());
        b.slot_counts = cl::Buffer(c, CL_MEM_READ_WRITE, std::size_t{tiles} * 8);
        const cl::Buffer& masks = b.slot_masks;
        const cl::Buffer& offsets = b.slot_offsets;
        const cl::Buffer& materials = b.slot_materials;
        const cl::Buffer& counts = b.slot_counts;
        std::vector<std::pair<std::string, cl::Event>> events;
        EncodeKernels k{cl::Kernel(program, "encode_count"), cl::Kernel(program, "encode_write")};
        enqueue_encode(q, k, b, tiles, tiles * 64, !ctx.is_cpu(), &events);
        std::vector<std::uint32_t> n(2 * std::size_t{tiles});
        q.enqueueReadBuffer(counts, CL_TRUE, 0, n.size() * 4, n.data());
        for (std::uint32_t t = 0; t < tiles; ++t) {
            SparseWorld::EncodedTile& e = out[t];
            e.masks.resize(n[2 * t]);
            e.offsets.resize(n[2 * t]);
            e.materials.resize(n[2 * t + 1]);
            if (!e.masks.empty()) {
                q.enqueueReadBuffer(masks, CL_FALSE, std::size_t{t} * kTileMaxNodes * 8,
                                    e.masks.size() * 8, e.masks.data());
                q.enqueueReadBuffer(offsets, CL_FALSE, std::size_t{t} * kTileMaxNodes * 4,
                                    e.offsets.size() * 4, e.offsets.data());
            }
            if (!e.materials.empty()) {
                q.enqueueReadBuffer(materials, CL_FALSE, std::size_t{t} * kTileVoxels,
                                    e.materials.size(), e.materials.data());
            }
        }
        q.finish();
        return out;
    });
}

SparseDeviceWorld::SparseDeviceWorld(Context& ctx, const SparseWorld& world, SparseWorld* editable,
                                     TreeAllocator allocate)
    : ctx_(ctx),
      world_(world),
      editable_(editable),
      program_(world_program(ctx)),
      gpu_layout_(!ctx.is_cpu()),
      allocate_(std::move(allocate)),
      pinned_(std::make_unique<PinnedHost>()) {
    if (editable != nullptr && editable != &world) {
        throw std::invalid_argument("SparseDeviceWorld: `editable` is not the world");
    }
    cl_call("making the sparse world's kernels", [&] {
        gather_ = cl::Kernel(program_, "gather");
        gather_quads_ = cl::Kernel(program_, "gather_quads");
        encode_ = {cl::Kernel(program_, "encode_count"), cl::Kernel(program_, "encode_write")};
    });
    ensure_slot_capacity(1);
    upload_whole();
}

SparseDeviceWorld::~SparseDeviceWorld() {
    try {
        ctx_.queue().finish();
    } catch (const cl::Error&) {
    }
}

void SparseDeviceWorld::host_changed_seen() {
    seen_nodes_ = world_.node_masks().size();
    seen_materials_ = world_.materials().size();
    seen_generation_ = world_.layout_generation();
    seen_tiles_ = world_.tile_count();
}

cl::Buffer SparseDeviceWorld::tree_buffer(std::size_t bytes, cl_mem_flags flags,
                                          const std::string& what) {
    return allocate_ ? allocate_.allocate(bytes, what) : cl::Buffer(ctx_.context(), flags, bytes);
}

SparseDeviceWorld::TreeBuffers SparseDeviceWorld::tree_buffers() const {
    return {masks_, offsets_, materials_, slot_masks_, slot_offsets_, slot_materials_};
}

std::vector<std::pair<Int3, std::pair<std::uint64_t, std::uint64_t>>> SparseDeviceWorld::refs()
    const {
    std::vector<std::pair<Int3, std::pair<std::uint64_t, std::uint64_t>>> out;
    out.reserve(dir_.size());
    for (const auto& [key, ref] : dir_) {
        out.emplace_back(tile_of_key(key), ref);
    }
    return out;
}

void SparseDeviceWorld::upload_whole() {
    const auto& masks = world_.node_masks();
    const auto& offsets = world_.node_offsets();
    const auto& materials = world_.materials();
    cl_call("uploading the sparse world", [&] {
        auto& q = ctx_.queue();
        const std::size_t nodes = std::max<std::size_t>(masks.size(), 1);
        // The previous buffers go first (and the allocator is told, which may free their
        // memory): a world near the device's memory fits once, not twice.
        q.finish();
        masks_ = offsets_ = materials_ = cl::Buffer();
        if (allocate_.dropped) {
            allocate_.dropped({slot_masks_, slot_offsets_, slot_materials_});
        }
        // All three or none (an allocation that fails leaves the world without main buffers:
        // its later use fails with an OpenCL error, not on a half-made set).
        cl::Buffer m = tree_buffer(nodes * 8, CL_MEM_READ_ONLY, "sparse node masks");
        cl::Buffer o = tree_buffer(nodes * 4, CL_MEM_READ_ONLY, "sparse node offsets");
        cl::Buffer mat = tree_buffer(std::max<std::size_t>(materials.size(), 1), CL_MEM_READ_ONLY,
                                     "sparse materials");
        masks_ = m;
        offsets_ = o;
        materials_ = mat;
        if (!masks.empty()) {
            q.enqueueWriteBuffer(masks_, CL_FALSE, 0, masks.size() * 8, masks.data());
            q.enqueueWriteBuffer(offsets_, CL_FALSE, 0, offsets.size() * 4, offsets.data());
        }
        if (!materials.empty()) {
            q.enqueueWriteBuffer(materials_, CL_FALSE, 0, materials.size(), materials.data());
        }
        q.finish();
    });
    dir_.clear();
    dir_.reserve(world_.tile_count());
    main_counts_.clear();
    main_counts_.reserve(world_.tile_count());
    main_nodes_ = main_materials_ = 0;
    for (std::uint32_t t = 0; t < world_.tile_count(); ++t) {
        const Int3 c = world_.tile_coord(t);
        const std::uint64_t key = key_of(c.x, c.y, c.z);
        dir_[key] = {world_.node_bases()[t], world_.material_bases()[t]};
        main_counts_[key] = {world_.node_counts()[t], world_.material_counts()[t]};
        main_nodes_ += world_.node_counts()[t];
        main_materials_ += world_.material_counts()[t];
    }
    slot_of_.clear();
    free_slots_.clear();
    slots_made_ = 0;
    host_changed_seen();
}

void SparseDeviceWorld::leave_main(std::uint64_t key) {
    if (const auto it = main_counts_.find(key); it != main_counts_.end()) {
        main_nodes_ -= it->second.first;
        main_materials_ -= it->second.second;
        main_counts_.erase(it);
    }
}

SparseDeviceWorld::Figures SparseDeviceWorld::figures() {
    Figures f;
    f.tiles = main_counts_.size();
    f.solid = main_materials_;
    f.tree_bytes = main_nodes_ * 12 + main_materials_;
    if (slot_of_.empty()) {
        return f;
    }
    std::vector<std::uint32_t> counts(2 * slots_made_);
    cl_call("reading the slots' counts", [&] {
        ctx_.queue().enqueueReadBuffer(slot_counts_, CL_TRUE, 0, counts.size() * 4, counts.data());
    });
    for (const auto& [key, slot] : slot_of_) {
        const std::uint64_t nodes = counts[2 * slot], materials = counts[2 * slot + 1];
        f.tiles += nodes != 0 ? 1 : 0;
        f.solid += materials;
        f.tree_bytes += nodes * 12 + materials;
    }
    return f;
}

void SparseDeviceWorld::ensure_slot_capacity(std::size_t slots) {
    if (slots <= slot_capacity_) {
        return;
    }
    // Doubled, but never past what release_slots_if_needed lets the slots reach (its limit plus
    // the most one edit takes): buffers it would never fill only raise the peak of the growth,
    // which holds the old buffers and the new ones at once.
    const std::size_t most = slot_limit() / kSlotBytes + 1 + kMaxHostEditTiles;
    const std::size_t cap =
        std::max(slots, std::min(std::max(2 * slot_capacity_, std::size_t{16}), most));
    cl_call("allocating " + std::to_string(cap) + " tile slots", [&] {
        auto& c = ctx_.context();
        cl::Buffer m = tree_buffer(cap * kTileMaxNodes * 8, CL_MEM_READ_WRITE, "sparse slot masks");
        cl::Buffer o =
            tree_buffer(cap * kTileMaxNodes * 4, CL_MEM_READ_WRITE, "sparse slot offsets");
        cl::Buffer mat = tree_buffer(cap * kTileVoxels, CL_MEM_READ_WRITE, "sparse slot materials");
        cl::Buffer n(c, CL_MEM_READ_WRITE, cap * 8);
        if (slot_capacity_ != 0) {
            auto& q = ctx_.queue();
            q.enqueueCopyBuffer(slot_masks_, m, 0, 0, slot_capacity_ * kTileMaxNodes * 8);
            q.enqueueCopyBuffer(slot_offsets_, o, 0, 0, slot_capacity_ * kTileMaxNodes * 4);
            q.enqueueCopyBuffer(slot_materials_, mat, 0, 0, slot_capacity_ * kTileVoxels);
            q.enqueueCopyBuffer(slot_counts_, n, 0, 0, slot_capacity_ * 8);
        }
        slot_masks_ = m;
        slot_offsets_ = o;
        slot_materials_ = mat;
        slot_counts_ = n;
    });
    slot_capacity_ = cap;
}

std::uint32_t SparseDeviceWorld::slot_for(std::uint64_t key) {
    if (const auto it = slot_of_.find(key); it != slot_of_.end()) {
        return it->second;
    }
    const std::uint32_t slot = take_slot();
    slot_of_[key] = slot;
    return slot;
}

std::uint32_t SparseDeviceWorld::take_slot() {
    if (!free_slots_.empty()) {
        const std::uint32_t slot = free_slots_.back();
        free_slots_.pop_back();
        return slot;
    }
    ensure_slot_capacity(slots_made_ + 1);  // copies the slot buffers in queue order
    return static_cast<std::uint32_t>(slots_made_++);
}

std::uint64_t SparseDeviceWorld::slot_limit() const {
    const std::uint64_t main_bytes = world_.node_masks().size() * 12 + world_.materials().size();
    return std::max<std::uint64_t>(std::uint64_t{256} << 20, main_bytes / 4);
}

void SparseDeviceWorld::release_slots_if_needed() {
    if (slots_made_ * kSlotBytes <= slot_limit()) {
        return;
    }
    world();
    upload_whole();
}

bool SparseDeviceWorld::reserve_slots(std::size_t n) {
    const auto fresh = [&] { return n > free_slots_.size() ? n - free_slots_.size() : 0; };
    if (slots_made_ + fresh() <= slot_capacity_) {
        return false;
    }
    if (!growth_refused_) {
        try {
            ensure_slot_capacity(slots_made_ + fresh());
            return false;
        } catch (const std::exception&) {
            if (slots_made_ == 0) {
                throw;
            }
            // Not tried again: each try of a refused size would cost the allocation.
            growth_refused_ = true;
        }
    }
    // The device cannot hold larger slot buffers (its memory, or one buffer's limit): the
    // world made whole again frees every slot, and the buffers there are hold the edit.
    world();
    upload_whole();
    ensure_slot_capacity(fresh());
    return true;
}

const SparseWorld& SparseDeviceWorld::world() {
    if (lagging_.empty()) {
        return world_;
    }
    cl_call("reading back the tiles edited on the device", [&] {
        auto& q = ctx_.queue();
        std::vector<std::uint32_t> counts(2 * slots_made_);
        q.enqueueReadBuffer(slot_counts_, CL_TRUE, 0, counts.size() * 4, counts.data());
        std::vector<std::uint64_t> keys(lagging_.begin(), lagging_.end());
        std::sort(keys.begin(), keys.end());
        for (const std::uint64_t key : keys) {
            const std::size_t slot = slot_of_.at(key);
            SparseWorld::EncodedTile e;
            e.masks.resize(counts[2 * slot]);
            e.offsets.resize(counts[2 * slot]);
            e.materials.resize(counts[2 * slot + 1]);
            if (!e.masks.empty()) {
                q.enqueueReadBuffer(slot_masks_, CL_FALSE, slot * kTileMaxNodes * 8,
                                    e.masks.size() * 8, e.masks.data());
                q.enqueueReadBuffer(slot_offsets_, CL_FALSE, slot * kTileMaxNodes * 4,
                                    e.offsets.size() * 4, e.offsets.data());
                q.enqueueReadBuffer(slot_materials_, CL_FALSE, slot * std::size_t{kTileVoxels},
                                    e.materials.size(), e.materials.data());
                q.finish();
            }
            const Int3 t = tile_of_key(key);
            editable_->put_tile(static_cast<std::uint32_t>(t.x), static_cast<std::uint32_t>(t.y),
                                static_cast<std::uint32_t>(t.z), e);
        }
    });
    lagging_.clear();
    host_changed_seen();
    return world_;
}

void SparseDeviceWorld::refresh() {
    world();
    if (world_.node_masks().size() != seen_nodes_ || world_.materials().size() != seen_materials_ ||
        world_.layout_generation() != seen_generation_ || world_.tile_count() != seen_tiles_) {
        upload_whole();
    }
}

void SparseDeviceWorld::host_edited(const Box& changed) {
    if (!lagging_.empty()) {
        throw std::logic_error(
            "SparseDeviceWorld::host_edited: the host world was edited while it lagged behind "
            "the device's edits (read it through world() first)");
    }
    const Dims d = world_.dims();
    const Box b = intersect(changed, Box{{0, 0, 0}, {d.x, d.y, d.z}});
    if (b.empty()) {
        return;
    }
    const Span span = tiles_of(b);
    if (static_cast<std::size_t>(span.size()) > kMaxHostEditTiles) {
        upload_whole();
        return;
    }
    if (reserve_slots(static_cast<std::size_t>(span.size()))) {
        return;  // uploaded whole, the host's edit with it
    }
    cl_call("uploading the tiles edited on the host", [&] {
        auto& q = ctx_.queue();
        for_each_tile(span, [&](std::int64_t tx, std::int64_t ty, std::int64_t tz) {
            const std::uint64_t key = key_of(tx, ty, tz);
            const std::uint32_t t = world_.find_tile(tx, ty, tz);
            leave_main(key);
            if (t == kNoTile) {
                dir_.erase(key);
                if (const auto it = slot_of_.find(key); it != slot_of_.end()) {
                    free_slots_.push_back(it->second);
                    slot_of_.erase(it);
                }
                return;
            }
            const std::size_t slot = slot_for(key);
            const std::size_t nodes = world_.node_counts()[t], mats = world_.material_counts()[t];
            const std::size_t nb = world_.node_bases()[t], mb = world_.material_bases()[t];
            q.enqueueWriteBuffer(slot_masks_, CL_FALSE, slot * kTileMaxNodes * 8, nodes * 8,
                                 world_.node_masks().data() + nb);
            q.enqueueWriteBuffer(slot_offsets_, CL_FALSE, slot * kTileMaxNodes * 4, nodes * 4,
                                 world_.node_offsets().data() + nb);
            q.enqueueWriteBuffer(slot_materials_, CL_FALSE, slot * std::size_t{kTileVoxels}, mats,
                                 world_.materials().data() + mb);
            const std::uint32_t counts[2] = {static_cast<std::uint32_t>(nodes),
                                             static_cast<std::uint32_t>(mats)};
            q.enqueueWriteBuffer(slot_counts_, CL_TRUE, slot * 8, 8, counts);
            dir_[key] = {kSlotRef | slot * kTileMaxNodes, slot * std::uint64_t{kTileVoxels}};
        });
    });
    host_changed_seen();
    release_slots_if_needed();
}

void SparseDeviceWorld::ensure_scratch(std::size_t tiles, bool dense) {
    auto& c = ctx_.context();
    if (dense && tiles > scratch_tiles_) {
        const std::size_t cap = std::max({tiles, 2 * scratch_tiles_, std::size_t{8}});
        cl_call("allocating an edit's scratch",
                [&] { scratch_ = cl::Buffer(c, CL_MEM_READ_WRITE, cap * kTileVoxels); });
        scratch_tiles_ = cap;
    }
    if (tiles > table_tiles_) {
        const std::size_t cap = std::max({tiles, 2 * table_tiles_, std::size_t{8}});
        cl_call("allocating an edit's tables", [&] {
            leaf_masks_ = cl::Buffer(c, CL_MEM_READ_WRITE, cap * 4096 * 8);
            mid_masks_ = cl::Buffer(c, CL_MEM_READ_WRITE, cap * 64 * 8);
            mid_counts_ = cl::Buffer(c, CL_MEM_READ_WRITE, cap * 64 * 4);
            table_ = cl::Buffer(c, CL_MEM_READ_ONLY, table_bytes(cap));
        });
        table_tiles_ = cap;
    }
}

Box SparseDeviceWorld::host_apply_brush(const Brush& brush) {
    world();
    const Box changed = voxfield::apply_brush(*editable_, brush);
    host_edited(changed);
    clear_edit_events();
    return changed;
}

std::int64_t* SparseDeviceWorld::edit_table(std::size_t tiles) {
    traffic_.host_waits += pinned_->settle() ? 1 : 0;
    pinned_->reserve(ctx_, table_bytes(std::max(tiles, table_tiles_)));
    auto* table = reinterpret_cast<std::int64_t*>(pinned_->data());
    std::fill(table, table + kTableHeader, std::int64_t{0});
    return table;
}

Box SparseDeviceWorld::apply_brush(const Brush& brush) {
    if (editable_ == nullptr) {
        throw std::logic_error("SparseDeviceWorld::apply_brush on a read-only world");
    }
    if ((brush.op == BrushOp::place || brush.op == BrushOp::paint) && brush.material == 0) {
        throw InputError(to_string(brush.op) + " needs a material 1..255, not 0");
    }
    traffic_ = QueueTraffic{};
    const Dims d = world_.dims();
    const Box bounds = brush_bounds(brush, d);  // checks the radius
    if (bounds.empty()) {
        clear_edit_events();
        return Box{};
    }
    const Span span = tiles_of(bounds);
    if (span.size() > kMaxEditTiles) {
        return host_apply_brush(brush);
    }
    const auto n = static_cast<std::uint32_t>(span.size());
    keys_.clear();
    host_slots_.clear();
    for_each_tile(span, [&](std::int64_t tx, std::int64_t ty, std::int64_t tz) {
        keys_.push_back(key_of(tx, ty, tz));
    });
    ensure_scratch(n, true);
    // The table: the brush; per tile its previous tree, slot, voxels in scratch (a whole tile
    // each) and the 16^3 nodes the brush's bounds overlap (decoded, brushed and encoded again).
    std::int64_t* table = edit_table(n);
    take_edit_slots(keys_);  // after every allocation of the edit but its slots'
    table[0] = brush.op == BrushOp::place ? 0 : brush.op == BrushOp::erase ? 1 : 2;
    table[1] = brush.shape == BrushShape::sphere ? 0 : 1;
    table[2] = brush.centre.x;
    table[3] = brush.centre.y;
    table[4] = brush.centre.z;
    table[5] = static_cast<std::int64_t>(brush.radius);
    table[6] = brush.material;
    table[7] = d.x;
    table[8] = d.y;
    table[9] = d.z;
    std::size_t t = 0;
    dense_.clear();
    for_each_tile(span, [&](std::int64_t tx, std::int64_t ty, std::int64_t tz) {
        const auto [node_base, material_base] = ref(tx, ty, tz);
        std::int64_t* rec = table + kTableHeader + kRecord * t;
        rec[0] = static_cast<std::int64_t>(node_base);
        rec[1] = static_cast<std::int64_t>(material_base);
        rec[2] = host_slots_[t];
        rec[3] = static_cast<std::int64_t>(t * kTileVoxels);
        const std::uint64_t nodes = nodes_overlapped(bounds, tx, ty, tz);
        rec[4] = static_cast<std::int64_t>(nodes);
        rec[5] = tx;
        rec[6] = ty;
        rec[7] = tz;
        for (std::uint64_t m = nodes; m != 0; m &= m - 1) {
            dense_.push_back(static_cast<std::int64_t>(t * 64) + std::countr_zero(m));
        }
        ++t;
    });
    std::copy(dense_.begin(), dense_.end(), table + kTableHeader + kRecord * n);
    clear_edit_events();
    try {
        cl_call("editing " + std::to_string(n) + " tiles on the device",
                [&] { enqueue_edit_encode(scratch_, kTileSize, kTileSize * kTileSize, n); });
    } catch (...) {
        untake_edit_slots(keys_);
        throw;
    }
    commit_edit_slots(keys_);
    return bounds;
}

void SparseDeviceWorld::encode_dense_tiles(const cl::Buffer& vox, std::uint32_t pitch_y,
                                           std::uint32_t pitch_z,
                                           const std::vector<DenseTile>& tiles) {
    if (editable_ == nullptr) {
        throw std::logic_error("SparseDeviceWorld::encode_dense_tiles on a read-only world");
    }
    traffic_ = QueueTraffic{};
    if (tiles.empty()) {
        clear_edit_events();
        return;
    }
    const auto n = static_cast<std::uint32_t>(tiles.size());
    keys_.clear();
    host_slots_.clear();
    for (const DenseTile& tile : tiles) {
        keys_.push_back(key_of(tile.tile.x, tile.tile.y, tile.tile.z));
    }
    ensure_scratch(n, false);
    std::int64_t* table = edit_table(n);
    take_edit_slots(keys_);  // after every allocation of the encoding but its slots'
    table[0] = kNoBrush;
    for (std::uint32_t t = 0; t < n; ++t) {
        const Int3 c = tiles[t].tile;
        const auto [node_base, material_base] = ref(c.x, c.y, c.z);
        std::int64_t* rec = table + kTableHeader + kRecord * t;
        rec[0] = static_cast<std::int64_t>(node_base);
        rec[1] = static_cast<std::int64_t>(material_base);
        rec[2] = host_slots_[t];
        rec[3] = static_cast<std::int64_t>(tiles[t].first);
        rec[4] = -1;  // every node from vox
        rec[5] = c.x;
        rec[6] = c.y;
        rec[7] = c.z;
    }
    dense_.resize(std::size_t{n} * 64);
    for (std::size_t i = 0; i < dense_.size(); ++i) {
        dense_[i] = static_cast<std::int64_t>(i);
    }
    std::copy(dense_.begin(), dense_.end(), table + kTableHeader + kRecord * n);
    clear_edit_events();
    try {
        cl_call("encoding " + std::to_string(n) + " dense tiles on the device",
                [&] { enqueue_edit_encode(vox, pitch_y, pitch_z, n); });
    } catch (...) {
        untake_edit_slots(keys_);
        throw;
    }
    commit_edit_slots(keys_);
}

void SparseDeviceWorld::take_edit_slots(const std::vector<std::uint64_t>& keys) {
    reserve_slots(keys.size());  // nothing below allocates: all slots taken or none
    std::vector<std::uint32_t> freed;
    previous_slots_.clear();
    for (const std::uint64_t key : keys) {
        const std::uint32_t slot = take_slot();
        const auto it = slot_of_.find(key);
        previous_slots_.push_back(it != slot_of_.end() ? it->second : kNoSlot);
        if (it != slot_of_.end()) {
            freed.push_back(it->second);
        }
        slot_of_[key] = slot;
        host_slots_.push_back(slot);
    }
    free_slots_.insert(free_slots_.end(), freed.begin(), freed.end());
}

void SparseDeviceWorld::untake_edit_slots(const std::vector<std::uint64_t>& keys) {
    // The previous slots, appended to free_slots_ last, are the keys' again; the taken ones
    // are free.
    const auto freed =
        static_cast<std::size_t>(std::count_if(previous_slots_.begin(), previous_slots_.end(),
                                               [](std::uint32_t s) { return s != kNoSlot; }));
    free_slots_.resize(free_slots_.size() - freed);
    for (std::size_t i = 0; i < keys.size(); ++i) {
        if (previous_slots_[i] != kNoSlot) {
            slot_of_[keys[i]] = previous_slots_[i];
        } else {
            slot_of_.erase(keys[i]);
        }
        free_slots_.push_back(host_slots_[i]);
    }
    previous_slots_.clear();
}

void SparseDeviceWorld::commit_edit_slots(const std::vector<std::uint64_t>& keys) {
    for (std::size_t i = 0; i < keys.size(); ++i) {
        leave_main(keys[i]);
        dir_[keys[i]] = {kSlotRef | host_slots_[i] * std::uint64_t{kTileMaxNodes},
                         host_slots_[i] * std::uint64_t{kTileVoxels}};
        lagging_.insert(keys[i]);
    }
    release_slots_if_needed();
}

void SparseDeviceWorld::enqueue_edit_encode(const cl::Buffer& vox, std::uint32_t pitch_y,
                                            std::uint32_t pitch_z, std::uint32_t tiles) {
    auto& q = ctx_.queue();
    const std::size_t bytes = (kTableHeader + kRecord * tiles + dense_.size()) * 8;
    // With stage events the write has one too (where the edit's device span starts); without,
    // none (NVIDIA's driver takes several us of host time for an event): the pinned table is
    // then fenced by a later command (settled_by), else the next edit waits for the queue.
    if (stage_events_) {
        q.enqueueWriteBuffer(table_, CL_FALSE, 0, bytes, pinned_->data(), nullptr,
                             &pinned_->last());
        edit_write_ = pinned_->last();
    } else {
        q.enqueueWriteBuffer(table_, CL_FALSE, 0, bytes, pinned_->data());
        pinned_->unfenced();
    }
    EncodeBuffers b;
    b.vox = vox;
    b.pitch_y = pitch_y;
    b.pitch_z = pitch_z;
    b.table = table_;
    b.masks = masks_;
    b.offsets = offsets_;
    b.materials = materials_;
    b.leaf_masks = leaf_masks_;
    b.mid_masks = mid_masks_;
    b.mid_counts = mid_counts_;
    b.slot_masks = slot_masks_;
    b.slot_offsets = slot_offsets_;
    b.slot_materials = slot_materials_;
    b.slot_counts = slot_counts_;
    enqueue_encode(q, encode_, b, tiles, static_cast<std::uint32_t>(dense_.size()), gpu_layout_,
                   stage_events_ ? &edit_events_ : nullptr);
    traffic_.enqueues += 3;
    q.flush();  // submitted now: the device encodes while the host lists the field's update
}

void SparseDeviceWorld::settled_by(const cl::Event& later) {
    pinned_->last() = later;
}

double SparseDeviceWorld::last_edit_kernel_ms() const {
    double ms = 0;
    for (const auto& [name, ms_of] : last_edit_stages()) {
        ms += ms_of;
    }
    return ms;
}

std::vector<std::pair<std::string, double>> SparseDeviceWorld::last_edit_stages() const {
    std::vector<std::pair<std::string, double>> stages;
    cl_call("waiting for an edit's kernels", [&] {
        for (const auto& [name, e] : edit_events_) {
            if (e.getInfo<CL_EVENT_COMMAND_EXECUTION_STATUS>() != CL_COMPLETE) {
                e.wait();
            }
            stages.emplace_back(name, elapsed_ms(e, e));
        }
    });
    return stages;
}

std::vector<cl::Event> SparseDeviceWorld::last_edit_commands() const {
    std::vector<cl::Event> commands;
    if (edit_write_() == nullptr) {
        return commands;  // an edit that enqueued nothing (or the host's)
    }
    commands.push_back(edit_write_);
    for (const auto& [name, e] : edit_events_) {
        commands.push_back(e);
    }
    return commands;
}

void SparseDeviceWorld::clear_edit_events() {
    edit_events_.clear();
    edit_write_ = cl::Event();
}

void SparseDeviceWorld::enqueue_gather(const cl::Buffer& jobs, const cl::Buffer& refs,
                                       const cl::Buffer& out, Dims block, std::size_t count,
                                       cl::Event* event) {
    const Dims d = world_.dims();
    cl::Kernel& k = gpu_layout_ ? gather_quads_ : gather_;
    k.setArg(0, masks_);
    k.setArg(1, offsets_);
    k.setArg(2, materials_);
    k.setArg(3, slot_masks_);
    k.setArg(4, slot_offsets_);
    k.setArg(5, slot_materials_);
    k.setArg(6, jobs);
    k.setArg(7, refs);
    k.setArg(8, out);
    k.setArg(9, block.x);
    k.setArg(10, block.y);
    k.setArg(11, block.z);
    k.setArg(12, static_cast<cl_long>(d.x));
    k.setArg(13, static_cast<cl_long>(d.y));
    k.setArg(14, static_cast<cl_long>(d.z));
    // Fixed work-group sizes: PoCL compiles a kernel once per local size.
    const std::size_t planes = std::size_t{block.z} * count;
    if (gpu_layout_) {
        // block.x / 4 + 2 work-items a row (sparse_world.cl).
        const std::size_t quads = std::size_t{block.x / 4 + 2} * block.y;
        ctx_.queue().enqueueNDRangeKernel(k, cl::NullRange,
                                          cl::NDRange(round_up(quads, kGatherQuads), planes),
                                          cl::NDRange(kGatherQuads, 1), nullptr, event);
    } else {
        ctx_.queue().enqueueNDRangeKernel(k, cl::NullRange,
                                          cl::NDRange(round_up(block.y, kGatherRows), planes),
                                          cl::NDRange(kGatherRows, 1), nullptr, event);
    }
}

void SparseDeviceWorld::set_tree_args(cl::Kernel& k, cl_uint first) {
    cl_call("setting a kernel's tree arguments", [&] {
        k.setArg(first, masks_);
        k.setArg(first + 1, offsets_);
        k.setArg(first + 2, slot_masks_);
        k.setArg(first + 3, slot_offsets_);
    });
}

void SparseDeviceWorld::one_tile_job(std::size_t i, const Int3& first, const Int3& tile,
                                     std::vector<std::int64_t>& jobs,
                                     std::vector<std::uint64_t>& refs) const {
    std::int64_t* job = jobs.data() + 8 * i;
    job[0] = first.x;
    job[1] = first.y;
    job[2] = first.z;
    job[3] = tile.x;
    job[4] = tile.y;
    job[5] = tile.z;
    job[6] = std::int64_t{1} | std::int64_t{1} << 16 | std::int64_t{1} << 32;  // one tile
    job[7] = static_cast<std::int64_t>(i);
    const auto r = ref(tile.x, tile.y, tile.z);
    refs[2 * i] = r.first;
    refs[2 * i + 1] = r.second;
}

std::vector<std::uint8_t> SparseDeviceWorld::voxels(std::span<const Int3> cells) {
    std::vector<std::uint8_t> out(cells.size(), 0);
    if (cells.empty()) {
        return out;
    }
    // gather's jobs (see sparse_world.cl): per cell a 1^3 block at the cell, its one tile.
    // Launches take a power of two of at least 64 jobs, the extra ones outside the world: PoCL
    // builds a kernel again for each new launch size (about 70 ms here), so sizes are few.
    const std::size_t launch = std::bit_ceil(std::max<std::size_t>(cells.size(), 64));
    std::vector<std::int64_t> jobs(8 * launch);
    std::vector<std::uint64_t> cell_refs(2 * launch);
    for (std::size_t i = 0; i < launch; ++i) {
        const Int3 c = i < cells.size() ? cells[i] : Int3{-1, -1, -1};
        one_tile_job(i, c, {c.x >> 6, c.y >> 6, c.z >> 6}, jobs, cell_refs);
    }
    cl_call("reading " + std::to_string(cells.size()) + " voxels of the sparse world", [&] {
        auto& c = ctx_.context();
        auto& q = ctx_.queue();
        if (launch > voxel_capacity_) {
            voxel_jobs_ = cl::Buffer(c, CL_MEM_READ_ONLY, launch * 64);
            voxel_refs_ = cl::Buffer(c, CL_MEM_READ_ONLY, launch * 16);
            voxel_out_ = cl::Buffer(c, CL_MEM_WRITE_ONLY, launch);
            voxel_capacity_ = launch;
        }
        // The writes do not block: the read waits for the queue, and with it for them (on a
        // failure the queue is finished before `jobs` and `cell_refs` go).
        try {
            q.enqueueWriteBuffer(voxel_jobs_, CL_FALSE, 0, jobs.size() * 8, jobs.data());
            q.enqueueWriteBuffer(voxel_refs_, CL_FALSE, 0, cell_refs.size() * 8, cell_refs.data());
            enqueue_gather(voxel_jobs_, voxel_refs_, voxel_out_, Dims{1, 1, 1}, launch);
            q.enqueueReadBuffer(voxel_out_, CL_TRUE, 0, out.size(), out.data());
        } catch (...) {
            try {
                q.finish();
            } catch (const cl::Error&) {
            }
            throw;
        }
    });
    return out;
}

void SparseDeviceWorld::gather_tiles(const std::vector<Int3>& tiles, const cl::Buffer& out) {
    if (tiles.empty()) {
        return;
    }
    // gather's jobs: per tile a block of kTileSize^3 at its first voxel, its one tile.
    std::vector<std::int64_t> jobs(8 * tiles.size());
    std::vector<std::uint64_t> tile_refs(2 * tiles.size());
    const std::int64_t ts = kTileSize;
    for (std::size_t i = 0; i < tiles.size(); ++i) {
        const Int3 t = tiles[i];
        one_tile_job(i, {t.x * ts, t.y * ts, t.z * ts}, t, jobs, tile_refs);
    }
    cl_call("gathering " + std::to_string(tiles.size()) + " tiles of the sparse world", [&] {
        auto& c = ctx_.context();
        // Copied at creation: the host vectors may go before the kernel runs.
        cl::Buffer job_buf(c, CL_MEM_READ_ONLY | CL_MEM_COPY_HOST_PTR, jobs.size() * 8,
                           jobs.data());
        cl::Buffer ref_buf(c, CL_MEM_READ_ONLY | CL_MEM_COPY_HOST_PTR, tile_refs.size() * 8,
                           tile_refs.data());
        const auto side = static_cast<std::uint32_t>(kTileSize);
        enqueue_gather(job_buf, ref_buf, out, Dims{side, side, side}, tiles.size());
    });
}

std::optional<PickHit> SparseDeviceWorld::pick(const Vec3d& origin, const Vec3d& direction,
                                               double max_distance) {
    const Dims d = world_.dims();
    std::vector<Int3> cells;
    pick_solid_voxel(
        d,
        [&cells](std::uint32_t x, std::uint32_t y, std::uint32_t z) {
            cells.push_back({x, y, z});
            return false;
        },
        origin, direction, max_distance);
    const std::vector<std::uint8_t> v = voxels(cells);
    std::size_t next = 0;
    return pick_solid_voxel(
        d, [&](std::uint32_t, std::uint32_t, std::uint32_t) { return v.at(next++) != 0; }, origin,
        direction, max_distance);
}

std::pair<std::uint64_t, std::uint64_t> SparseDeviceWorld::ref(std::int64_t tx, std::int64_t ty,
                                                               std::int64_t tz) const {
    const Dims g = world_.tile_grid();
    if (tx < 0 || ty < 0 || tz < 0 || tx >= g.x || ty >= g.y || tz >= g.z) {
        return {kNoRef, 0};
    }
    const auto it = dir_.find(key_of(tx, ty, tz));
    return it == dir_.end() ? std::pair<std::uint64_t, std::uint64_t>{kNoRef, 0} : it->second;
}

}  // namespace voxfield::ocl
