// Exact bounded fields of sparse worlds, per tile with halos (issue 24; the tile grid of
// 64-trees of the implicit-surface rendering blog, the transforms of exact.cpp and
// separable.cpp on dense blocks).
#include "voxfield/cl/sparse_field.hpp"

#include <algorithm>
#include <bit>
#include <chrono>
#include <cmath>
#include <cstring>
#include <limits>
#include <numeric>
#include <string>
#include <thread>
#include <utility>

#include "pinned.hpp"
#include "util.hpp"
#include "voxfield/cl/exact.hpp"
#include "voxfield/cl/separable.hpp"
#include "voxfield/core/error.hpp"
#include "voxfield/core/format.hpp"

namespace voxfield::cl_sources {
extern const char* const layout_h;
extern const char* const exact_manhattan_cl;
extern const char* const sparse_tree_cl;
extern const char* const sparse_field_cl;
extern const char* const sparse_slices_cl;
}  // namespace voxfield::cl_sources

namespace voxfield::ocl {
namespace {

constexpr std::uint32_t kInsideTile = 0xFFFFFFFEu;
// Voxels of one batch of stacked blocks (and the most of one update block).
constexpr std::int64_t kBatchVoxels = std::int64_t{1} << 25;
// Several changed boxes are recomputed in one block of their hull when it holds at most this
// many voxels (128^3), else tile by tile.
constexpr std::int64_t kHullVoxels = std::int64_t{1} << 21;
// Up to this many regions are merged where they overlap and tried as blocks of their own.
constexpr std::size_t kMaxMergedRegions = 256;
// Rows per work-group of the scatter kernel (a work-item per row).
constexpr std::size_t kGroupRows = 8;
// Work-items per work-group of the GPU layout's scatter (a work-item per voxel).
constexpr std::size_t kGroupVoxels = 64;
// The largest halo (voxels): blocks beyond are larger than a batch.
constexpr std::uint32_t kMaxHalo = 512;
// Field tiles per launch of the sweep's kernels.
constexpr std::size_t kSweepSlots = 2048;
// sparse_field.cl's neighbour codes.
constexpr std::uint32_t kNbEmpty = 0xFFFFFFFFu;
constexpr std::uint32_t kNbInside = 0xFFFFFFFEu;

std::string elem_options(Format f) {
    const char* type = "uint";
    switch (f) {
        case Format::u8:
            type = "uchar";
            break;
        case Format::u16:
            type = "ushort";
            break;
        case Format::u32:
        case Format::packed32:
            break;
        case Format::i8:
            type = "char";
            break;
        case Format::i16:
            type = "short";
            break;
        case Format::i32:
            type = "int";
            break;
        case Format::f32:
            type = "float";
            break;
        case Format::f64:
            type = "double";
            break;
    }
    const int key = f == Format::packed32 ? 1 : holds_sign(f) ? 2 : 0;
    return std::string("-DELEM=") + type + " -DKEY_KIND=" + std::to_string(key) +
           " -DELEM_DOUBLE=" + (f == Format::f64 ? "1" : "0") + " -cl-std=CL1.2";
}

std::int64_t round_up_to(std::int64_t v, std::int64_t m) {
    return (v + m - 1) / m * m;
}

Box world_box(Dims d) {
    return {{0, 0, 0}, {d.x, d.y, d.z}};
}

Box grow(const Box& b, const std::uint32_t h[3]) {
    return {{b.min.x - h[0], b.min.y - h[1], b.min.z - h[2]},
            {b.max.x + h[0], b.max.y + h[1], b.max.z + h[2]}};
}

// The block of a tile's job: the tile and its halo, but along x and y no more than the world
// with one voxel of empty space around it (beyond that nothing changes a value: unsigned
// fields see solids only, signed ones the world surrounded by empty space), for worlds
// thinner than a block. Along z, the axis blocks are stacked on, the whole halo always
// separates a tile from the next block's voxels.
Dims tile_block(Dims w, const std::uint32_t h[3]) {
    return {std::min(kTileSize + 2 * h[0], w.x + 2), std::min(kTileSize + 2 * h[1], w.y + 2),
            kTileSize + 2 * h[2]};
}

// Its first voxel: the tile's minus the halo, along x and y moved inside [-1, world + 1).
Int3 tile_origin(std::int64_t tx, std::int64_t ty, std::int64_t tz, Dims w, Dims block,
                 const std::uint32_t h[3]) {
    auto axis = [](std::int64_t t, std::uint32_t halo, std::uint32_t extent, std::uint32_t b) {
        return std::clamp<std::int64_t>(t * kTileSize - halo, -1,
                                        std::int64_t{extent} + 1 - std::int64_t{b});
    };
    return {axis(tx, h[0], w.x, block.x), axis(ty, h[1], w.y, block.y), tz * kTileSize - h[2]};
}

// The tiles a box overlaps: first tile and count per axis.
struct TileSpan {
    Int3 first, count;
    std::int64_t size() const { return count.x * count.y * count.z; }
    std::int64_t packed() const { return count.x | count.y << 16 | count.z << 32; }
};

TileSpan tiles_of(const Box& b) {
    const std::int64_t s = kTileSize;
    const Int3 lo{floor_div(b.min.x, s), floor_div(b.min.y, s), floor_div(b.min.z, s)};
    const Int3 hi{floor_div(b.max.x - 1, s), floor_div(b.max.y - 1, s), floor_div(b.max.z - 1, s)};
    return {lo, {hi.x - lo.x + 1, hi.y - lo.y + 1, hi.z - lo.z + 1}};
}

template <class F>
void for_each_tile(const TileSpan& span, F&& f) {
    for (std::int64_t z = 0; z < span.count.z; ++z) {
        for (std::int64_t y = 0; y < span.count.y; ++y) {
            for (std::int64_t x = 0; x < span.count.x; ++x) {
                f(span.first.x + x, span.first.y + y, span.first.z + z);
            }
        }
    }
}

// The number of threads parallel_ranges takes for n items, at least `grain` items each.
std::size_t range_threads(std::size_t n, std::size_t grain) {
    return std::clamp<std::size_t>(
        std::min<std::size_t>(std::thread::hardware_concurrency(), n / grain), 1, 64);
}

// fn(i, first, end) for the i-th of `threads` contiguous ranges of [0, n), the first on this
// thread and the others on threads of their own; returns when all have.
template <class F>
void parallel_ranges(std::size_t n, std::size_t threads, F&& fn) {
    std::vector<std::jthread> pool;
    for (std::size_t i = 1; i < threads; ++i) {
        pool.emplace_back([&, i] { fn(i, n * i / threads, n * (i + 1) / threads); });
    }
    fn(std::size_t{0}, std::size_t{0}, n / threads);
}

// The extents of a (non-empty) block box, as a dense generator's dims.
Dims block_dims(const Box& b) {
    return {static_cast<std::uint32_t>(b.max.x - b.min.x),
            static_cast<std::uint32_t>(b.max.y - b.min.y),
            static_cast<std::uint32_t>(b.max.z - b.min.z)};
}

}  // namespace

GeneratorOptions resolve_sparse_options(const GeneratorOptions& options, bool format_given) {
    GeneratorOptions o = options;
    if (o.algorithm != Algorithm::exact) {
        throw InputError("--algorithm " + to_string(o.algorithm) +
                         ": sparse worlds have the exact bounded field only (--algorithm exact)");
    }
    if (o.indices) {
        throw InputError("--indices: sparse worlds have no feature transform; drop --indices");
    }
    if (o.chunk != 0) {
        throw InputError("--chunk does not apply to sparse worlds");
    }
    if (!o.max_distance) {
        o.max_distance = kDefaultSparseMaxDistance;
    }
    if (!format_given) {
        o.format = default_format(o.metric, o.spacing, o.signed_field);
    }
    o = resolve_options(o, Dims{1, 1, 1});
    const double smallest = std::min({o.spacing.x, o.spacing.y, o.spacing.z});
    if (std::ceil(*o.max_distance / smallest) > kMaxHalo) {
        throw InputError("--max-distance " + std::to_string(*o.max_distance) +
                         ": a sparse world's tiles take halos of at most " +
                         std::to_string(kMaxHalo) + " voxels (D / smallest spacing)");
    }
    return o;
}

// A dense generator over `blocks` stacked blocks of one shape, with the job tables.
struct SparseField::Batch {
    Dims block;
    std::uint32_t blocks = 0;
    std::unique_ptr<Generator> generator;
    cl::Buffer voxels;  // the generator's world
    cl::Buffer jobs, refs, scatter_jobs, regions, slots;
    std::size_t refs_cap = 0, slots_cap = 0;
    // A one-block batch whose generator starts with a slice stage: that stage reading the block
    // from the world's trees (sparse_slices.cl; its tree, jobs and refs arguments set per
    // update), in place of the gather and the generator's own first launch.
    ExactManhattan* slices_of = nullptr;
    cl::Kernel tree_slices;
    std::string tree_slices_name;
};

SparseField::SparseField(Context& ctx, SparseWorld& world, const Palette& palette,
                         const GeneratorOptions& options, TreeAllocator allocate)
    : SparseField(ctx, static_cast<const SparseWorld&>(world), palette, options, &world,
                  std::move(allocate)) {}

SparseField::SparseField(Context& ctx, const SparseWorld& world, const Palette& palette,
                         const GeneratorOptions& options)
    : SparseField(ctx, world, palette, options, nullptr, {}) {}

SparseField::SparseField(Context& ctx, const SparseWorld& world, const Palette& palette,
                         const GeneratorOptions& options, SparseWorld* editable,
                         TreeAllocator allocate)
    : ctx_(ctx),
      world_(world),
      palette_(palette),
      options_(options),
      device_world_(ctx, world, editable, std::move(allocate)) {
    if (!options_.max_distance) {
        throw std::invalid_argument("SparseField: options without max_distance");
    }
    const double d = *options_.max_distance;
    const double step[3] = {options_.spacing.x, options_.spacing.y, options_.spacing.z};
    for (int a = 0; a < 3; ++a) {
        halo_[a] = static_cast<std::uint32_t>(std::ceil(d / step[a]));
    }
    elem_ = element_size(options_.format);
    gpu_layout_ =
        options_.layout == Layout::automatic ? !ctx_.is_cpu() : options_.layout == Layout::gpu;
    device_world_.use_gpu_layout(gpu_layout_);
    const World one(Dims{1, 1, 1});
    far_ = encode_real_field({d}, one, palette_, options_.format);
    inside_ = encode_real_field({options_.signed_field ? -d : 0.0}, one, palette_, options_.format);
    program_ =
        ctx_.program("sparse_field.cl", {cl_sources::sparse_tree_cl, cl_sources::sparse_field_cl},
                     elem_options(options_.format));
    cl_call("making the sparse field's kernels", [&] {
        scatter_ = cl::Kernel(program_, "scatter");
        scatter_voxels_ = cl::Kernel(program_, "scatter_voxels");
        node_minima_ = cl::Kernel(program_, "node_minima");
        scatter_minima_ = cl::Kernel(program_, "scatter_minima");
        fill_slot_ = cl::Kernel(program_, "fill_slot");
        sweep_init_ = cl::Kernel(program_, "sweep_init");
        sweep_l1_ = cl::Kernel(program_, "sweep_l1");
        sweep_l1_rows_ = cl::Kernel(program_, "sweep_l1_rows");
        sweep_l1_loaded_ = cl::Kernel(program_, "sweep_l1_loaded");
        sweep_finish_ = cl::Kernel(program_, "sweep_finish");
    });
}

SparseField::~SparseField() {
    try {
        ctx_.queue().finish();
    } catch (const cl::Error&) {
    }
}

std::uint64_t SparseField::field_bytes() const {
    return std::uint64_t{slot_keys_.size()} * kTileVoxels * elem_;
}

std::vector<std::uint8_t> SparseField::constant_value(std::uint32_t entry) const {
    return entry == kInsideTile ? inside_ : far_;
}

void SparseField::ensure_slots(std::size_t slots) {
    if (slots <= pool_slots_) {
        return;
    }
    const std::size_t cap = std::max({slots, pool_slots_ + pool_slots_ / 4, std::size_t{16}});
    cl_call("allocating " + std::to_string(cap) + " field tiles", [&] {
        cl::Buffer pool(ctx_.context(), CL_MEM_READ_WRITE, cap * kTileVoxels * elem_);
        cl::Buffer coarse(ctx_.context(), CL_MEM_READ_WRITE, cap * 64 * elem_);
        if (pool_slots_ != 0) {
            ctx_.queue().enqueueCopyBuffer(pool_, pool, 0, 0, pool_slots_ * kTileVoxels * elem_);
            ctx_.queue().enqueueCopyBuffer(coarse_, coarse, 0, 0, pool_slots_ * 64 * elem_);
            ctx_.queue().finish();
            traffic_ += {2, 1};
        }
        pool_ = pool;
        coarse_ = coarse;
    });
    pool_slots_ = cap;
}

std::uint32_t SparseField::dense_slot(std::uint64_t key) {
    auto it = tiles_.find(key);
    if (it != tiles_.end() && it->second != kInsideTile) {
        return it->second;
    }
    const std::vector<std::uint8_t> value =
        constant_value(it == tiles_.end() ? kNoTile : it->second);
    const auto slot = static_cast<std::uint32_t>(slot_keys_.size());
    ensure_slots(slot + std::size_t{1});
    cl_call("filling a field tile", [&] {
        fill_slot_.setArg(0, pool_);
        fill_slot_.setArg(1, static_cast<cl_ulong>(slot));
        fill_slot_.setArg(2, value.size(), value.data());
        ctx_.queue().enqueueNDRangeKernel(fill_slot_, cl::NullRange,
                                          cl::NDRange(kTileSize, kTileSize, kTileSize),
                                          cl::NDRange(kTileSize, 1, 1));
    });
    ++traffic_.enqueues;
    slot_keys_.push_back(key);
    coarse_synced_ = false;  // the host copy lacks the new slot
    tiles_[key] = slot;
    return slot;
}

SparseField::Batch& SparseField::batch_for(Dims block, std::uint32_t blocks) {
    const auto shape = std::make_tuple(block.x, block.y, block.z, blocks);
    if (auto it = batches_.find(shape); it != batches_.end()) {
        return *it->second;
    }
    if (batches_.size() >= 8) {
        // Keep a few shapes only: an update's block follows its edit's size.
        batches_.clear();
    }
    auto b = std::make_unique<Batch>();
    b->block = block;
    b->blocks = blocks;
    const World zero(Dims{block.x, block.y, block.z * blocks});
    const GeneratorOptions& o = options_;
    if (ExactManhattan::handles(ctx_, o, zero.dims())) {
        auto g = std::make_unique<ExactManhattan>(ctx_, zero, palette_, o.format, o.layout,
                                                  o.metric, o.max_distance);
        b->voxels = g->voxels_buffer();
        if (blocks == 1 && g->slice_stage()) {
            b->slices_of = g.get();
            set_up_tree_slices(*b);
        }
        b->generator = std::move(g);
    } else {
        // Each block's z lines apart: short lines, many to a work-group (the banded passes).
        auto g = std::make_unique<ExactSeparable>(ctx_, zero, palette_, o, false, block.z);
        b->voxels = g->voxels_buffer();
        b->generator = std::move(g);
    }
    auto& c = ctx_.context();
    cl_call("allocating a sparse batch's tables", [&] {
        b->jobs = cl::Buffer(c, CL_MEM_READ_ONLY, std::size_t{blocks} * 8 * 8);
        b->scatter_jobs = cl::Buffer(c, CL_MEM_READ_ONLY, std::size_t{blocks} * 8 * 8);
        b->regions = cl::Buffer(c, CL_MEM_READ_ONLY, std::size_t{blocks} * 6 * 8);
    });
    return *(batches_[shape] = std::move(b));
}

void SparseField::set_up_tree_slices(Batch& b) {
    const ExactManhattan::SliceStage& stage = *b.slices_of->slice_stage();
    const Dims wd = world_.dims();
    cl_call("setting up the tree slices of a sparse block of " + b.block.to_string(), [&] {
        const cl::Program program =
            ctx_.program("sparse_slices.cl",
                         {cl_sources::layout_h, cl_sources::sparse_tree_cl,
                          cl_sources::exact_manhattan_cl, cl_sources::sparse_slices_cl},
                         stage.options);
        b.tree_slices_name = stage.segments ? "xy_tree_segments" : "xy_tree_local";
        cl::Kernel& k = b.tree_slices = cl::Kernel(program, b.tree_slices_name.c_str());
        k.setArg(6, stage.work);
        k.setArg(7, b.block.x);
        k.setArg(8, b.block.y);
        k.setArg(9, b.block.z);
        k.setArg(10, stage.sx);
        k.setArg(11, static_cast<cl_long>(wd.x));
        k.setArg(12, static_cast<cl_long>(wd.y));
        k.setArg(13, static_cast<cl_long>(wd.z));
        k.setArg(14, cl::Local(stage.slice_bytes));
        if (stage.segments) {
            k.setArg(15, cl::Local(stage.ends_bytes));
        }
    });
}

double SparseField::compute(const std::vector<Job>& jobs, Dims block, bool pow2_batch) {
    if (jobs.empty()) {
        return 0;
    }
    const std::int64_t per_block = std::int64_t{block.x} * block.y * block.z;
    std::int64_t want = static_cast<std::int64_t>(jobs.size());
    if (pow2_batch) {
        want = std::int64_t{1} << std::bit_width(static_cast<std::uint64_t>(want - 1));
    }
    const auto per_batch =
        static_cast<std::uint32_t>(std::clamp<std::int64_t>(kBatchVoxels / per_block, 1, want));
    Batch& batch = batch_for(block, per_batch);
    auto& q = ctx_.queue();
    double ms = 0;
    for (std::size_t first = 0; first < jobs.size(); first += per_batch) {
        const std::size_t n = std::min<std::size_t>(per_batch, jobs.size() - first);
        ++work_.batches;
        work_.blocks += n;
        work_.block_voxels += static_cast<std::uint64_t>(per_block) * n;
        std::vector<std::int64_t> gjobs, sjobs, regions;
        std::vector<std::uint64_t> refs;
        std::vector<std::uint32_t> slots;
        Int3 largest{0, 0, 0};
        for (std::size_t j = first; j < first + n; ++j) {
            const Job& job = jobs[j];
            const Box bb{job.origin,
                         {job.origin.x + block.x, job.origin.y + block.y, job.origin.z + block.z}};
            const TileSpan span = tiles_of(bb);
            gjobs.insert(gjobs.end(),
                         {job.origin.x, job.origin.y, job.origin.z, span.first.x, span.first.y,
                          span.first.z, span.packed(), static_cast<std::int64_t>(refs.size() / 2)});
            for_each_tile(span, [&](std::int64_t tx, std::int64_t ty, std::int64_t tz) {
                const auto [node_base, material_base] = device_world_.ref(tx, ty, tz);
                refs.push_back(node_base);
                refs.push_back(material_base);
            });
            const TileSpan rspan = tiles_of(job.region);
            sjobs.insert(sjobs.end(), {job.region.min.x, job.region.min.y, job.region.min.z,
                                       rspan.first.x, rspan.first.y, rspan.first.z, rspan.packed(),
                                       static_cast<std::int64_t>(slots.size())});
            for_each_tile(rspan, [&](std::int64_t tx, std::int64_t ty, std::int64_t tz) {
                slots.push_back(tiles_.at(tile_key(static_cast<std::uint32_t>(tx),
                                                   static_cast<std::uint32_t>(ty),
                                                   static_cast<std::uint32_t>(tz))));
            });
            const Int3 size{job.region.max.x - job.region.min.x,
                            job.region.max.y - job.region.min.y,
                            job.region.max.z - job.region.min.z};
            regions.insert(regions.end(),
                           {size.x, size.y, size.z, job.origin.x, job.origin.y, job.origin.z});
            work_.region_voxels += static_cast<std::uint64_t>(size.x * size.y * size.z);
            largest = {std::max(largest.x, size.x), std::max(largest.y, size.y),
                       std::max(largest.z, size.z)};
        }
        cl_call(
            "computing a sparse field batch of " + std::to_string(n) + " blocks of " +
                block.to_string(),
            [&] {
                auto& c = ctx_.context();
                if (refs.size() * 8 > batch.refs_cap) {
                    batch.refs_cap = refs.size() * 8;
                    batch.refs = cl::Buffer(c, CL_MEM_READ_ONLY, batch.refs_cap);
                }
                if (slots.size() * 4 > batch.slots_cap) {
                    batch.slots_cap = slots.size() * 4;
                    batch.slots = cl::Buffer(c, CL_MEM_READ_ONLY, batch.slots_cap);
                }
                q.enqueueWriteBuffer(batch.jobs, CL_FALSE, 0, gjobs.size() * 8, gjobs.data());
                q.enqueueWriteBuffer(batch.refs, CL_FALSE, 0, refs.size() * 8, refs.data());
                q.enqueueWriteBuffer(batch.scatter_jobs, CL_FALSE, 0, sjobs.size() * 8,
                                     sjobs.data());
                q.enqueueWriteBuffer(batch.regions, CL_FALSE, 0, regions.size() * 8,
                                     regions.data());
                q.enqueueWriteBuffer(batch.slots, CL_FALSE, 0, slots.size() * 4, slots.data());
                cl::Event ev_gather;
                device_world_.enqueue_gather(batch.jobs, batch.refs, batch.voxels, block, n,
                                             &ev_gather);
                ms += batch.generator->run();  // waits for the queue, the gather too
                traffic_ += {static_cast<std::uint32_t>(7 + batch.generator->stage_ms().size()), 1};
                ms += elapsed_ms(ev_gather, ev_gather);
                add_stage("gather", elapsed_ms(ev_gather, ev_gather));
                for (const auto& [name, stage_ms] : batch.generator->stage_ms()) {
                    add_stage(name, stage_ms);
                }
                enqueue_scatter(batch.generator->field_buffer(), batch.scatter_jobs, batch.regions,
                                batch.slots, block, largest, n, &scatters_.emplace_back());
            });
    }
    return ms;
}

void SparseField::enqueue_scatter(const cl::Buffer& field, const cl::Buffer& jobs,
                                  const cl::Buffer& regions, const cl::Buffer& slots, Dims block,
                                  Int3 largest, std::size_t count, cl::Event* event) {
    cl::Kernel& scatter = gpu_layout_ ? scatter_voxels_ : scatter_;
    scatter.setArg(0, field);
    scatter.setArg(1, pool_);
    scatter.setArg(2, jobs);
    scatter.setArg(3, regions);
    scatter.setArg(4, slots);
    scatter.setArg(5, block.x);
    scatter.setArg(6, block.y);
    scatter.setArg(7, block.z);
    const auto sx = static_cast<std::size_t>(largest.x);
    const auto sy = static_cast<std::size_t>(largest.y);
    const auto sz = static_cast<std::size_t>(largest.z);
    auto& q = ctx_.queue();
    if (gpu_layout_) {
        scatter.setArg(8, static_cast<cl_uint>(sx));
        scatter.setArg(9, static_cast<cl_uint>(sy));
        scatter.setArg(10, static_cast<cl_uint>(sz));
        q.enqueueNDRangeKernel(scatter, cl::NullRange,
                               cl::NDRange(round_up(sx, kGroupVoxels), sy, sz * count),
                               cl::NDRange(kGroupVoxels, 1, 1), nullptr, event);
    } else {
        scatter.setArg(8, static_cast<cl_uint>(sy));
        scatter.setArg(9, static_cast<cl_uint>(sz));
        q.enqueueNDRangeKernel(scatter, cl::NullRange,
                               cl::NDRange(round_up(sy, kGroupRows), sz * count),
                               cl::NDRange(kGroupRows, 1), nullptr, event);
    }
}

void SparseField::refresh_coarse(const std::vector<std::uint32_t>& slots,
                                 const std::vector<std::uint64_t>& nodes, double* ms) {
    if (slots.empty()) {
        return;
    }
    cl_call("computing the field tiles' node minima", [&] {
        auto& q = ctx_.queue();
        std::vector<std::uint32_t> tiles;
        tiles.reserve(3 * slots.size());
        for (std::uint32_t slot : slots) {
            const std::uint64_t key = slot_keys_[slot];
            tiles.insert(tiles.end(), {static_cast<std::uint32_t>(key & 0x3FFF),
                                       static_cast<std::uint32_t>(key >> 14 & 0x3FFF),
                                       static_cast<std::uint32_t>(key >> 28)});
        }
        if (slots.size() > minima_list_cap_) {
            minima_list_cap_ = std::max(slots.size(), std::size_t{64});
            minima_list_ = cl::Buffer(ctx_.context(), CL_MEM_READ_ONLY, minima_list_cap_ * 4);
            minima_coords_ = cl::Buffer(ctx_.context(), CL_MEM_READ_ONLY, minima_list_cap_ * 12);
            minima_nodes_ = cl::Buffer(ctx_.context(), CL_MEM_READ_ONLY, minima_list_cap_ * 8);
        }
        cl::Buffer& list = minima_list_;
        cl::Buffer& coords = minima_coords_;
        q.enqueueWriteBuffer(list, CL_FALSE, 0, slots.size() * 4, slots.data());
        q.enqueueWriteBuffer(coords, CL_FALSE, 0, tiles.size() * 4, tiles.data());
        q.enqueueWriteBuffer(minima_nodes_, CL_FALSE, 0, nodes.size() * 8, nodes.data());
        const Dims wd = world_.dims();
        cl::Kernel& k = node_minima_;
        k.setArg(0, pool_);
        k.setArg(1, list);
        k.setArg(2, coords);
        k.setArg(3, static_cast<cl_uint>(slots.size()));
        k.setArg(4, coarse_);
        k.setArg(5, elem_, far_.data());
        k.setArg(6, wd.x);
        k.setArg(7, wd.y);
        k.setArg(8, wd.z);
        k.setArg(9, minima_nodes_);
        cl::Event ev;
        q.enqueueNDRangeKernel(k, cl::NullRange, cl::NDRange(64, slots.size() * 64),
                               cl::NDRange(64, 1), nullptr, &ev);
        ev.wait();
        traffic_ += {4, 1};
        coarse_synced_ = false;
        *ms += elapsed_ms(ev, ev);
        add_stage("node_minima", elapsed_ms(ev, ev));
    });
}

double SparseField::settle_scatters() {
    double ms = 0;
    for (const cl::Event& e : scatters_) {
        cl_call("waiting for the field's scatter", [&] { e.wait(); });
        ms += elapsed_ms(e, e);
    }
    if (!scatters_.empty()) {
        add_stage("scatter", ms);
    }
    scatters_.clear();
    return ms;
}

void SparseField::add_stage(const std::string& name, double ms) {
    const auto it = std::find_if(stages_.begin(), stages_.end(),
                                 [&](const auto& s) { return s.first == name; });
    if (it == stages_.end()) {
        stages_.emplace_back(name, ms);
    } else {
        it->second += ms;
    }
}

double SparseField::run() {
    stages_.clear();
    host_stages_.clear();
    work_ = Work{};
    coarse_synced_ = false;
    auto lap = [this, t = Clock::now()](const char* name) mutable {
        const auto now = Clock::now();
        host_stages_.emplace_back(name, ms_between(t, now));
        t = now;
    };
    device_world_.refresh();
    lap("world_refresh");
    tiles_.clear();
    slot_keys_.clear();
    const Dims wd = world_.dims();
    const Box all = world_box(wd);
    const double d = *options_.max_distance;
    const bool packed = options_.format == Format::packed32;
    // Tiles within D of a solid voxel: the stored ones, and those whose box comes nearer than
    // D to a stored tile's solid voxels.
    auto full = [&](std::uint32_t t) {
        return world_.material_counts()[t] == world_.tile_box(t).volume();
    };
    // Per stored tile, its entry and the empty tiles within D of its solid voxels: split over
    // the hardware threads (contiguous ranges), then merged.
    struct Found {
        std::vector<std::pair<std::uint64_t, std::uint32_t>> stored;
        std::vector<std::uint64_t> near;
    };
    auto classify = [&](std::size_t first, std::size_t end, Found& out) {
        std::vector<Int3> empty;
        for (auto t = static_cast<std::uint32_t>(first); t < end; ++t) {
            const Int3 c = world_.tile_coord(t);
            const Box tb = world_.tile_box(t);
            bool inside = false;
            if (!packed && full(t)) {
                inside = true;
                if (options_.signed_field) {
                    const Box halo = grow(tb, halo_);
                    inside = intersect(halo, all) == halo;
                    for_each_tile(tiles_of(halo),
                                  [&](std::int64_t x, std::int64_t y, std::int64_t z) {
                                      const std::uint32_t n = world_.find_tile(x, y, z);
                                      inside = inside && n != kNoTile && full(n);
                                  });
                }
            }
            out.stored.emplace_back(
                tile_key(static_cast<std::uint32_t>(c.x), static_cast<std::uint32_t>(c.y),
                         static_cast<std::uint32_t>(c.z)),
                inside ? kInsideTile : kNoTile);
            // Only tiles not stored within the halo of the whole tile can be added (the solid
            // voxels' reach lies inside it): most tiles have none and need no solid bounds.
            empty.clear();
            for_each_tile(tiles_of(intersect(grow(tb, halo_), all)),
                          [&](std::int64_t x, std::int64_t y, std::int64_t z) {
                              if (world_.find_tile(x, y, z) == kNoTile) {
                                  empty.push_back({x, y, z});
                              }
                          });
            if (empty.empty()) {
                continue;
            }
            // The solid voxels' bounds, read only on the sides where such a tile lies: a tile
            // level with this one along an axis has no gap along it and always lies in the
            // reach, whatever the bounds, so the other sides stay the tile's.
            Box sb = tb;
            if (!full(t)) {
                const std::int64_t at[3] = {c.x, c.y, c.z};
                std::int64_t* lo[3] = {&sb.min.x, &sb.min.y, &sb.min.z};
                std::int64_t* hi[3] = {&sb.max.x, &sb.max.y, &sb.max.z};
                for (int a = 0; a < 3; ++a) {
                    const auto along = [a](const Int3& e) {
                        return a == 0 ? e.x : a == 1 ? e.y : e.z;
                    };
                    if (std::any_of(empty.begin(), empty.end(),
                                    [&](const Int3& e) { return along(e) < at[a]; })) {
                        *lo[a] = world_.solid_extreme(t, a, false);
                    }
                    if (std::any_of(empty.begin(), empty.end(),
                                    [&](const Int3& e) { return along(e) > at[a]; })) {
                        *hi[a] = world_.solid_extreme(t, a, true) + 1;
                    }
                }
            }
            const TileSpan reach = tiles_of(intersect(grow(sb, halo_), all));
            for (const Int3& e : empty) {
                auto within = [](std::int64_t v, std::int64_t lo, std::int64_t count) {
                    return v >= lo && v < lo + count;
                };
                if (!within(e.x, reach.first.x, reach.count.x) ||
                    !within(e.y, reach.first.y, reach.count.y) ||
                    !within(e.z, reach.first.z, reach.count.z)) {
                    continue;
                }
                const std::int64_t s = kTileSize;
                auto gap = [](std::int64_t lo, std::int64_t hi, std::int64_t slo,
                              std::int64_t shi) {
                    return std::max<std::int64_t>({0, lo - (shi - 1), slo - (hi - 1)});
                };
                const std::int64_t gx = gap(e.x * s, (e.x + 1) * s, sb.min.x, sb.max.x);
                const std::int64_t gy = gap(e.y * s, (e.y + 1) * s, sb.min.y, sb.max.y);
                const std::int64_t gz = gap(e.z * s, (e.z + 1) * s, sb.min.z, sb.max.z);
                if (metric_distance(options_.metric, options_.spacing, gx, gy, gz) < d) {
                    out.near.push_back(tile_key(static_cast<std::uint32_t>(e.x),
                                                static_cast<std::uint32_t>(e.y),
                                                static_cast<std::uint32_t>(e.z)));
                }
            }
        }
    };
    const std::uint32_t tile_count = world_.tile_count();
    std::vector<Found> found(range_threads(tile_count, 16));
    parallel_ranges(
        tile_count, found.size(),
        [&](std::size_t i, std::size_t first, std::size_t end) { classify(first, end, found[i]); });
    tiles_.reserve(tile_count * std::size_t{2});
    for (const Found& f : found) {
        for (const auto& [key, entry] : f.stored) {
            tiles_[key] = entry;
        }
    }
    for (const Found& f : found) {
        for (const std::uint64_t key : f.near) {
            tiles_.emplace(key, kNoTile);
        }
    }
    // Slots for the tiles that are not constant, in key order (z, y, x: blocks near in space
    // lie near in the batches).
    std::vector<std::uint64_t> keys;
    for (const auto& [key, entry] : tiles_) {
        if (entry != kInsideTile) {
            keys.push_back(key);
        }
    }
    std::sort(keys.begin(), keys.end());
    lap("field_tiles");
    // Headroom for the field tiles that edits add: growing the pool copies it whole (seconds
    // and twice its memory on a large world), so an edit should rarely have to.
    ensure_slots(keys.size() + keys.size() / 16 + 16);
    lap("pool");
    const bool blocks = run_method() == "blocks";
    std::vector<Job> jobs(blocks ? keys.size() : 0);
    std::vector<std::uint32_t> slots(keys.size());
    std::iota(slots.begin(), slots.end(), std::uint32_t{0});
    slot_keys_ = keys;
    const Dims block = tile_block(wd, halo_);
    // Distinct entries of tiles_ are set on each thread (find() does not change the map).
    parallel_ranges(keys.size(), range_threads(keys.size(), 4096),
                    [&](std::size_t, std::size_t first, std::size_t end) {
                        for (std::size_t slot = first; slot < end; ++slot) {
                            const std::uint64_t key = keys[slot];
                            tiles_.find(key)->second = static_cast<std::uint32_t>(slot);
                            if (!blocks) {
                                continue;
                            }
                            const Int3 t = tile_of_key(key);
                            const Box region = intersect(tile_voxels(t), all);
                            jobs[slot] = {region, tile_origin(t.x, t.y, t.z, wd, block, halo_)};
                        }
                    });
    lap("jobs");
    double ms = blocks ? compute(jobs, block) : sweep();
    lap(blocks ? "blocks" : "sweep");
    refresh_coarse(slots, std::vector<std::uint64_t>(slots.size(), ~std::uint64_t{0}), &ms);
    ms += settle_scatters();
    lap("coarse");
    return ms;
}

std::string SparseField::run_method() const {
    const GeneratorOptions& o = options_;
    const bool unit = o.spacing.x == 1 && o.spacing.y == 1 && o.spacing.z == 1;
    const bool fits = halo_[0] <= kTileSize && halo_[1] <= kTileSize && halo_[2] <= kTileSize;
    return !force_blocks_ && o.metric == Metric::manhattan && o.format != Format::packed32 &&
                   unit && fits
               ? "sweep"
               : "blocks";
}

double SparseField::sweep() {
    const std::size_t n = slot_keys_.size();
    if (n == 0) {
        return 0;
    }
    const Dims grid = world_.tile_grid();
    std::vector<std::uint64_t> refs(n);
    std::vector<std::uint32_t> nbrs(6 * n);
    // Lookups only: the slots split over the hardware threads.
    parallel_ranges(
        n, range_threads(n, 4096), [&](std::size_t, std::size_t first, std::size_t end) {
            for (std::size_t slot = first; slot < end; ++slot) {
                const std::uint64_t key = slot_keys_[slot];
                const std::int64_t t[3] = {static_cast<std::int64_t>(key & 0x3FFF),
                                           static_cast<std::int64_t>(key >> 14 & 0x3FFF),
                                           static_cast<std::int64_t>(key >> 28)};
                refs[slot] = device_world_.ref(t[0], t[1], t[2]).first;
                const std::int64_t extent[3] = {grid.x, grid.y, grid.z};
                for (int a = 0; a < 3; ++a) {
                    for (int side = 0; side < 2; ++side) {
                        std::int64_t c[3] = {t[0], t[1], t[2]};
                        c[a] += side == 0 ? -1 : 1;
                        std::uint32_t code = kNbEmpty;
                        if (c[a] >= 0 && c[a] < extent[a]) {
                            const auto it = tiles_.find(tile_key(static_cast<std::uint32_t>(c[0]),
                                                                 static_cast<std::uint32_t>(c[1]),
                                                                 static_cast<std::uint32_t>(c[2])));
                            if (it != tiles_.end()) {
                                code = it->second == kInsideTile ? kNbInside : it->second;
                            }
                        }
                        nbrs[6 * slot + 2 * static_cast<std::size_t>(a) + side] = code;
                    }
                }
            }
        });
    const auto cap = static_cast<cl_int>(halo_[0] + 1);
    const auto most = static_cast<cl_int>(std::floor(*options_.max_distance));
    const bool sgn = options_.signed_field;
    double ms = 0;
    cl_call("computing a sparse Manhattan field in its tiles", [&] {
        auto& q = ctx_.queue();
        cl::Buffer refs_buf(ctx_.context(), CL_MEM_READ_ONLY, n * 8);
        cl::Buffer nbrs_buf(ctx_.context(), CL_MEM_READ_ONLY, nbrs.size() * 4);
        q.enqueueWriteBuffer(refs_buf, CL_FALSE, 0, n * 8, refs.data());
        q.enqueueWriteBuffer(nbrs_buf, CL_FALSE, 0, nbrs.size() * 4, nbrs.data());
        device_world_.set_tree_args(sweep_init_, 0);
        sweep_init_.setArg(4, refs_buf);
        sweep_init_.setArg(5, pool_);
        sweep_init_.setArg(7, cap);
        sweep_init_.setArg(8, sgn ? -cap : cl_int{0});
        for (cl::Kernel* k : {&sweep_l1_, &sweep_l1_rows_, &sweep_l1_loaded_}) {
            k->setArg(0, pool_);
            k->setArg(1, nbrs_buf);
            k->setArg(4, static_cast<cl_uint>(halo_[0]));
            k->setArg(5, cap);
        }
        sweep_l1_loaded_.setArg(6, most);
        sweep_l1_loaded_.setArg(7, elem_, far_.data());
        sweep_l1_loaded_.setArg(8, elem_, inside_.data());
        sweep_finish_.setArg(0, pool_);
        sweep_finish_.setArg(2, most);
        sweep_finish_.setArg(3, elem_, far_.data());
        sweep_finish_.setArg(4, elem_, inside_.data());
        std::vector<std::pair<std::string, cl::Event>> events;
        // A launch per kSweepSlots tiles: global and local sizes per tile-count of a launch.
        // Every launch of a stage is enqueued before the next stage's (the passes read
        // neighbours).
        enum class Shape { voxels16, lines, planes };
        auto each_batch = [&](const std::string& stage, cl::Kernel& k, cl_uint first_arg,
                              Shape shape) {
            for (std::size_t first = 0; first < n; first += kSweepSlots) {
                const std::size_t count = std::min(kSweepSlots, n - first);
                k.setArg(first_arg, static_cast<cl_uint>(first));
                const auto [global, local] =
                    shape == Shape::voxels16  // 16 voxels along x per work-item
                        ? std::pair{cl::NDRange(kTileSize / 16, kTileSize, count * kTileSize),
                                    cl::NDRange(kTileSize / 16, 16, 1)}
                        : shape == Shape::lines
                              ? std::pair{cl::NDRange(kTileSize, kTileSize, count),
                                          cl::NDRange(kTileSize, 1, 1)}
                              : std::pair{cl::NDRange(kTileSize, count), cl::NDRange(kTileSize, 1)};
                q.enqueueNDRangeKernel(k, cl::NullRange, global, local, nullptr,
                                       &events.emplace_back(stage, cl::Event()).second);
            }
        };
        each_batch("sweep_init", sweep_init_, 6, Shape::voxels16);
        for (cl_uint axis = 0; axis < 3; ++axis) {
            // CPUs take y and z a plane of 64 lines per work-item (sweep_l1_rows), unsigned;
            // GPUs load each line whole first (sweep_l1_loaded).
            const bool planes = axis != 0 && !gpu_layout_ && !sgn;
            cl::Kernel& k = planes ? sweep_l1_rows_ : gpu_layout_ ? sweep_l1_loaded_ : sweep_l1_;
            k.setArg(3, axis);
            each_batch(std::string("sweep_") + "xyz"[axis], k, 2,
                       planes ? Shape::planes : Shape::lines);
        }
        // GPUs finish in the z pass (sweep_l1_loaded).
        if (!gpu_layout_) {
            each_batch("sweep_finish", sweep_finish_, 1, Shape::voxels16);
        }
        q.finish();
        for (const auto& [stage, e] : events) {
            const double t = elapsed_ms(e, e);
            ms += t;
            add_stage(stage, t);
        }
    });
    work_.region_voxels = std::uint64_t{n} * kTileVoxels;
    return ms;
}

SparseField::Update SparseField::update(const Box& changed) {
    device_world_.host_edited(changed);
    return recompute({changed});
}

void SparseField::set_edit_stage_events(bool on) {
    stage_events_ = on;
    device_world_.set_stage_events(on);
}

SparseField::Update SparseField::apply_brush(const Brush& brush) {
    // A lean edit's commands on the queue without profiling (they have no stage events).
    std::optional<Context::Unprofiled> lean;
    if (!stage_events_) {
        lean.emplace(ctx_);
    }
    const auto t0 = Clock::now();
    const Box changed = device_world_.apply_brush(brush);
    const auto t1 = Clock::now();
    Update u = with_edit_stages(recompute({changed}));
    if (block_times_.set) {
        const BlockTimes& b = block_times_;
        u.host_stages = {{"world edit", ms_between(t0, t1)},
                         {"field tables", ms_between(t1, b.enqueue)},
                         {"field enqueue", ms_between(b.enqueue, b.enqueued)},
                         {"wait", ms_between(b.enqueued, b.waited)},
                         {"after", ms_since(b.waited)}};
        // A lean edit's commands have no profiling times (Context::Unprofiled): no span to read.
        if (stage_events_) {
            std::vector<cl::Event> commands = device_world_.last_edit_commands();
            commands.insert(commands.end(), block_commands_.begin(), block_commands_.end());
            const CommandSpan span = command_span(commands);
            u.device_span_ms = span.span_ms;
            u.device_idle_ms = span.idle_ms;
        }
    }
    return u;
}

SparseField::Update SparseField::apply_dense_tiles(
    const cl::Buffer& vox, std::uint32_t pitch_y, std::uint32_t pitch_z,
    const std::vector<SparseDeviceWorld::DenseTile>& tiles, const std::vector<Box>& changed) {
    device_world_.encode_dense_tiles(vox, pitch_y, pitch_z, tiles);
    return with_edit_stages(recompute(changed));
}

SparseField::Update SparseField::write_tiles(const cl::Buffer& vox,
                                             const std::vector<Int3>& tiles) {
    std::vector<SparseDeviceWorld::DenseTile> dense;
    std::vector<Box> boxes;
    for (std::size_t i = 0; i < tiles.size(); ++i) {
        dense.push_back({tiles[i], i * std::uint64_t{kTileVoxels}});
        boxes.push_back(tile_voxels(tiles[i]));
    }
    return apply_dense_tiles(vox, kTileSize, kTileSize * kTileSize, dense, boxes);
}

SparseField::Update SparseField::with_edit_stages(Update result) const {
    std::vector<std::pair<std::string, double>> stages = device_world_.last_edit_stages();
    for (const auto& [name, ms] : stages) {
        result.edit_kernel_ms += ms;
    }
    result.kernel_ms += result.edit_kernel_ms;
    result.traffic += device_world_.last_edit_traffic();
    stages.insert(stages.end(), result.stages.begin(), result.stages.end());
    result.stages = std::move(stages);
    return result;
}

Box SparseField::single_block(const Box& region) const {
    const Dims wd = world_.dims();
    Box b = intersect(grow(region, halo_), Box{{-1, -1, -1}, {wd.x + 1, wd.y + 1, wd.z + 1}});
    // Extents rounded up to a multiple of 4 (more empty space beyond the world, or more of the
    // world, changes no value inside), so that edits of about one size share a block shape and
    // its dense generator instead of setting one up each (16 cost radius-8 edits 64^3 blocks
    // instead of 52^3: 1.9x the voxels).
    b.max = {b.min.x + round_up_to(b.max.x - b.min.x, 4),
             b.min.y + round_up_to(b.max.y - b.min.y, 4),
             b.min.z + round_up_to(b.max.z - b.min.z, 4)};
    return b;
}

void SparseField::prepare_edits(std::int64_t radius) {
    const Dims wd = world_.dims();
    Brush brush;
    brush.shape = BrushShape::sphere;
    brush.centre = {wd.x / 2, wd.y / 2, wd.z / 2};
    brush.radius = radius;
    const Box all = world_box(wd);
    const Box region = intersect(grow(brush_bounds(brush, wd), halo_), all);
    if (region.empty()) {
        return;
    }
    const Box b = single_block(region);
    if (b.volume() <= kBatchVoxels) {
        batch_for(block_dims(b), 1);
    }
}

SparseField::Update SparseField::recompute(const std::vector<Box>& changed) {
    Update result;
    result.profiled = stage_events_;  // the edit's events (set_edit_stage_events)
    stages_.clear();
    work_ = Work{};
    traffic_ = QueueTraffic{};
    block_times_ = BlockTimes{};
    block_commands_.clear();
    const Box all = world_box(world_.dims());
    // The voxels within D of a change, per change; merged into their hull when that is one
    // block of at most kHullVoxels (the single-block path of one edit).
    std::vector<Box> regions;
    Box region;
    for (const Box& b : changed) {
        const Box inside = intersect(b, all);
        const Box r = intersect(grow(inside, halo_), all);
        if (!inside.empty() && !r.empty()) {
            regions.push_back(r);
            region = region.empty() ? r : hull(region, r);
        }
    }
    if (regions.empty()) {
        return result;
    }
    const Dims wd = world_.dims();
    if (regions.size() > 1 && single_block(region).volume() <= kHullVoxels) {
        regions = {region};
    }
    // Per field tile (in key order) the hull of the regions' parts in it.
    const std::int64_t s = kTileSize;
    std::map<std::uint64_t, Box> parts;
    for (const Box& r : regions) {
        for_each_tile(tiles_of(r), [&](std::int64_t x, std::int64_t y, std::int64_t z) {
            const Box part = intersect(r, tile_voxels({x, y, z}));
            Box& p = parts[tile_key(static_cast<std::uint32_t>(x), static_cast<std::uint32_t>(y),
                                    static_cast<std::uint32_t>(z))];
            p = p.empty() ? part : hull(p, part);
        });
    }
    std::vector<std::uint32_t> slots;
    std::vector<std::uint64_t> nodes;  // per slot, its 16^3 nodes whose minima may change
    for (const auto& [key, part] : parts) {
        const Int3 t = tile_of_key(key);
        const auto it = tiles_.find(key);
        const bool fresh = it == tiles_.end() || it->second == kInsideTile;
        slots.push_back(dense_slot(key));
        std::uint64_t mask = 0;
        for (std::int64_t nz = (part.min.z - t.z * s) / 16; nz <= (part.max.z - 1 - t.z * s) / 16;
             ++nz) {
            for (std::int64_t ny = (part.min.y - t.y * s) / 16;
                 ny <= (part.max.y - 1 - t.y * s) / 16; ++ny) {
                for (std::int64_t nx = (part.min.x - t.x * s) / 16;
                     nx <= (part.max.x - 1 - t.x * s) / 16; ++nx) {
                    mask |= std::uint64_t{1} << (nz << 4 | ny << 2 | nx);
                }
            }
        }
        // A tile made dense now has no minima yet: all of its nodes.
        nodes.push_back(fresh ? ~std::uint64_t{0} : mask);
    }
    std::vector<Job> jobs;
    Dims block{};
    if (regions.size() == 1) {
        Box block_box = single_block(region);
        Int3 size{block_box.max.x - block_box.min.x, block_box.max.y - block_box.min.y,
                  block_box.max.z - block_box.min.z};
        // An edit near the world's edge (a smaller block) takes a shape set up already when that
        // holds it with at most twice the voxels: no generator set up, and no eviction of others.
        const Int3 need = size;
        std::int64_t best = 2 * need.x * need.y * need.z + 1;
        for (const auto& [shape, batch] : batches_) {
            const auto& [bx, by, bz, n] = shape;
            const std::int64_t v = std::int64_t{bx} * by * bz;
            if (n == 1 && bx >= need.x && by >= need.y && bz >= need.z && v < best) {
                best = v;
                size = {bx, by, bz};
            }
        }
        block_box.max = {block_box.min.x + size.x, block_box.min.y + size.y,
                         block_box.min.z + size.z};
        if (block_box.volume() <= kBatchVoxels) {
            block = block_dims(block_box);
            result.kernel_ms += update_block({region, block_box.min}, block, slots, nodes);
            result.recomputed = region;
            result.tiles = static_cast<std::uint32_t>(slots.size());
            result.stages = stages_;
            result.traffic = traffic_;
            return result;
        }
    }
    // Several regions (or one too large for one block): those that overlap merged, then the
    // smallest k of them each in a block of its own, one shape for all k (their largest extents
    // with the halo, rounded up to 16), with blocks per batch a power of two, so that updates
    // of a varying number of regions (the sand's steps) share a few batch shapes and their
    // generators; the others tile by tile (each tile's part in the tile's block, as run()
    // places it). k is the one that transforms the fewest voxels.
    if (jobs.empty()) {
        std::vector<Box> merged = regions;
        for (bool again = merged.size() <= kMaxMergedRegions; again;) {
            again = false;
            for (std::size_t i = 0; i < merged.size() && !again; ++i) {
                for (std::size_t j = i + 1; j < merged.size() && !again; ++j) {
                    if (!intersect(merged[i], merged[j]).empty()) {
                        merged[i] = hull(merged[i], merged[j]);
                        merged.erase(merged.begin() + static_cast<std::ptrdiff_t>(j));
                        again = true;
                    }
                }
            }
        }
        const Dims tb = tile_block(wd, halo_);
        const std::int64_t tile_voxels = std::int64_t{tb.x} * tb.y * tb.z;
        const auto need = [&](const Box& r) {
            return Int3{round_up_to(r.max.x - r.min.x + 2 * std::int64_t{halo_[0]}, 16),
                        round_up_to(r.max.y - r.min.y + 2 * std::int64_t{halo_[1]}, 16),
                        round_up_to(r.max.z - r.min.z + 2 * std::int64_t{halo_[2]}, 16)};
        };
        std::size_t k = 0;
        Int3 shape{0, 0, 0};
        if (regions.size() > 1 && merged.size() <= kMaxMergedRegions) {
            std::sort(merged.begin(), merged.end(), [&](const Box& a, const Box& b) {
                const Int3 na = need(a), nb = need(b);
                return na.x * na.y * na.z < nb.x * nb.y * nb.z;
            });
            // tiles[i]: the tiles of merged[i..] (their parts, counted per region).
            std::vector<std::int64_t> tiles(merged.size() + 1, 0);
            for (std::size_t i = merged.size(); i-- > 0;) {
                tiles[i] = tiles[i + 1] + tiles_of(merged[i]).size();
            }
            std::int64_t best = tiles[0] * tile_voxels;
            Int3 grow_shape{0, 0, 0};
            for (std::size_t i = 0; i < merged.size(); ++i) {
                const Int3 n = need(merged[i]);
                grow_shape = {std::max(grow_shape.x, n.x), std::max(grow_shape.y, n.y),
                              std::max(grow_shape.z, n.z)};
                const std::int64_t v = grow_shape.x * grow_shape.y * grow_shape.z;
                const std::int64_t cost =
                    static_cast<std::int64_t>(i + 1) * v + tiles[i + 1] * tile_voxels;
                if (v <= kBatchVoxels && cost < best) {
                    best = cost;
                    k = i + 1;
                    shape = grow_shape;
                }
            }
        }
        if (k > 0) {
            std::vector<Job> small_jobs;
            for (std::size_t i = 0; i < k; ++i) {
                const Box& r = merged[i];
                small_jobs.push_back(
                    {r, {r.min.x - halo_[0], r.min.y - halo_[1], r.min.z - halo_[2]}});
            }
            result.kernel_ms +=
                compute(small_jobs,
                        {static_cast<std::uint32_t>(shape.x), static_cast<std::uint32_t>(shape.y),
                         static_cast<std::uint32_t>(shape.z)},
                        true);
        }
        std::map<std::uint64_t, Box> large_parts;  // per tile, the other regions' parts
        for (std::size_t i = k; i < merged.size(); ++i) {
            const Box& r = merged[i];
            for_each_tile(tiles_of(r), [&](std::int64_t x, std::int64_t y, std::int64_t z) {
                const Box part = intersect(r, voxfield::tile_voxels({x, y, z}));
                Box& p = large_parts[tile_key(static_cast<std::uint32_t>(x),
                                              static_cast<std::uint32_t>(y),
                                              static_cast<std::uint32_t>(z))];
                p = p.empty() ? part : hull(p, part);
            });
        }
        block = tb;
        for (const auto& [key, part] : large_parts) {
            const Int3 t = tile_of_key(key);
            jobs.push_back({part, tile_origin(t.x, t.y, t.z, wd, block, halo_)});
        }
    }
    result.kernel_ms += compute(jobs, block);
    refresh_coarse(slots, nodes, &result.kernel_ms);
    result.kernel_ms += settle_scatters();
    result.recomputed = region;
    result.tiles = static_cast<std::uint32_t>(slots.size());
    result.stages = stages_;
    result.traffic = traffic_;
    return result;
}

double SparseField::update_block(const Job& job, Dims block,
                                 const std::vector<std::uint32_t>& slots,
                                 const std::vector<std::uint64_t>& nodes) {
    Batch& batch = batch_for(block, 1);
    const Dims wd = world_.dims();
    const Box bb{job.origin,
                 {job.origin.x + block.x, job.origin.y + block.y, job.origin.z + block.z}};
    const TileSpan span = tiles_of(bb);
    const std::size_t n = slots.size();
    // gather's job and refs, then scatter_minima's region, slots, tile coordinates and nodes
    // (sparse_field.cl, sparse_world.cl).
    enum { kJobs, kRefs, kRegion, kList, kCoords, kNodes, kTables };
    const std::size_t bytes[kTables] = {
        8 * 8, static_cast<std::size_t>(span.size()) * 16, 9 * 8, n * 4, n * 12, n * 8};
    if (!tables_) {
        tables_ = std::make_unique<PinnedTables>();
    }
    bool waited = false;
    tables_->fit(ctx_, bytes, &waited);
    traffic_.host_waits += waited ? 1 : 0;
    auto* gjob = tables_->host<std::int64_t>(kJobs);
    std::int64_t g[8] = {job.origin.x, job.origin.y, job.origin.z,  span.first.x,
                         span.first.y, span.first.z, span.packed(), 0};
    std::copy(g, g + 8, gjob);
    auto* refs = tables_->host<std::uint64_t>(kRefs);
    for_each_tile(span, [&](std::int64_t tx, std::int64_t ty, std::int64_t tz) {
        const auto [node_base, material_base] = device_world_.ref(tx, ty, tz);
        *refs++ = node_base;
        *refs++ = material_base;
    });
    const Int3 size{job.region.max.x - job.region.min.x, job.region.max.y - job.region.min.y,
                    job.region.max.z - job.region.min.z};
    const std::int64_t r[9] = {job.region.min.x, job.region.min.y, job.region.min.z,
                               size.x,           size.y,           size.z,
                               job.origin.x,     job.origin.y,     job.origin.z};
    std::copy(r, r + 9, tables_->host<std::int64_t>(kRegion));
    std::copy(slots.begin(), slots.end(), tables_->host<std::uint32_t>(kList));
    auto* coords = tables_->host<std::uint32_t>(kCoords);
    for (const std::uint32_t slot : slots) {
        const std::uint64_t key = slot_keys_[slot];
        *coords++ = static_cast<std::uint32_t>(key & 0x3FFF);
        *coords++ = static_cast<std::uint32_t>(key >> 14 & 0x3FFF);
        *coords++ = static_cast<std::uint32_t>(key >> 28);
    }
    std::copy(nodes.begin(), nodes.end(), tables_->host<std::uint64_t>(kNodes));
    ++work_.batches;
    ++work_.blocks;
    work_.block_voxels += std::uint64_t{block.x} * block.y * block.z;
    work_.region_voxels += static_cast<std::uint64_t>(size.x * size.y * size.z);
    std::vector<std::pair<std::string, cl::Event>> events;
    double ms = 0;
    cl_call("updating a sparse field block of " + block.to_string(), [&] {
        auto& q = ctx_.queue();
        block_times_.enqueue = Clock::now();
        // Without stage events only scatter_minima, the one waited for, has one: the next
        // fit() of the tables waits for it rather than for their write.
        tables_->write(q, stage_events_);
        if (stage_events_) {
            block_commands_.push_back(tables_->last_write());
        }
        auto* staged = stage_events_ ? &events : nullptr;
        batch.generator->set_stage_events(stage_events_);
        std::size_t generator_first = events.size();
        bool enqueued = true;
        if (batch.slices_of != nullptr) {
            // The block's slices from the trees: the gather and the generator's first launch.
            cl::Kernel& xy = batch.tree_slices;
            device_world_.set_tree_args(xy, 0);
            xy.setArg(4, tables_->buffer(kJobs));
            xy.setArg(5, tables_->buffer(kRefs));
            const ExactManhattan::SliceStage& stage = *batch.slices_of->slice_stage();
            q.enqueueNDRangeKernel(xy, cl::NullRange, stage.global, stage.local, nullptr,
                                   stage_event(staged, batch.tree_slices_name));
            batch.slices_of->enqueue_after_slices(events);
        } else {
            device_world_.enqueue_gather(tables_->buffer(kJobs), tables_->buffer(kRefs),
                                         batch.voxels, block, 1, stage_event(staged, "gather"));
            generator_first = events.size();
            enqueued = batch.generator->enqueue(events);
        }
        if (!enqueued) {
            // A generator that reads a flag back in between: its own run(), which waits.
            ms += batch.generator->run();
            ++traffic_.host_waits;
            traffic_.enqueues += static_cast<std::uint32_t>(batch.generator->stage_ms().size());
            for (const auto& [name, stage_ms] : batch.generator->stage_ms()) {
                add_stage(name, stage_ms);
            }
        }
        const std::size_t generator_end = events.size();
        // The region's values into the pool and the listed nodes' minima, in one pass: every
        // voxel of the region lies in a listed node (`nodes` holds those the parts overlap).
        cl::Kernel& k = scatter_minima_;
        k.setArg(0, batch.generator->field_buffer());
        k.setArg(1, pool_);
        k.setArg(2, tables_->buffer(kRegion));
        k.setArg(3, block.x);
        k.setArg(4, block.y);
        k.setArg(5, tables_->buffer(kList));
        k.setArg(6, tables_->buffer(kCoords));
        k.setArg(7, static_cast<cl_uint>(n));
        k.setArg(8, coarse_);
        k.setArg(9, elem_, far_.data());
        k.setArg(10, wd.x);
        k.setArg(11, wd.y);
        k.setArg(12, wd.z);
        k.setArg(13, tables_->buffer(kNodes));
        events.emplace_back("scatter_minima", cl::Event());
        q.enqueueNDRangeKernel(k, cl::NullRange, cl::NDRange(64, n * 64), cl::NDRange(64, 1),
                               nullptr, &events.back().second);
        if (!stage_events_) {
            tables_->settled_by(events.back().second);
            device_world_.settled_by(events.back().second);
        }
        // The one wait: scatter_minima done, and with it every command before it (an in-order
        // queue). The minima stay on the device (coarse_node reads them when asked).
        block_times_.enqueued = Clock::now();
        events.back().second.wait();
        block_times_.waited = Clock::now();
        coarse_synced_ = false;
        // Not where the generator ran (and waited) by itself: its commands are not listed.
        block_times_.set = enqueued;
        // The tables' write, gather, the generator's launches and scatter_minima.
        traffic_.enqueues +=
            static_cast<std::uint32_t>(3 + (enqueued ? batch.generator->last_enqueued() : 0));
        ++traffic_.host_waits;
        for (const auto& [name, e] : events) {
            block_commands_.push_back(e);
        }
        for (std::size_t i = 0; i < events.size(); ++i) {
            const double t = elapsed_ms(events[i].second, events[i].second);
            if (stage_events_) {  // else scatter_minima's alone: no breakdown
                add_stage(events[i].first, t);
            }
            if (i < generator_first || i >= generator_end) {
                ms += t;
            }
        }
        if (generator_end > generator_first) {
            ms += elapsed_ms(events[generator_first].second, events[generator_end - 1].second);
        }
    });
    return ms;
}

std::vector<std::uint8_t> SparseField::read_box(const Box& box) {
    if (box.empty() || static_cast<std::uint64_t>(box.volume()) > kMaxDenseVoxels) {
        throw InputError("a field box of " + std::to_string(box.empty() ? 0 : box.volume()) +
                         " voxels: one dense array holds 1.." + std::to_string(kMaxDenseVoxels));
    }
    const auto nx = static_cast<std::size_t>(box.max.x - box.min.x);
    const auto ny = static_cast<std::size_t>(box.max.y - box.min.y);
    const std::size_t count = static_cast<std::size_t>(box.volume());
    std::vector<std::uint8_t> out(count * elem_);
    for (std::size_t i = 0; i < count; ++i) {
        std::memcpy(out.data() + i * elem_, far_.data(), elem_);
    }
    std::vector<std::uint8_t> tile(std::size_t{kTileVoxels} * elem_);
    const Box clipped = intersect(box, world_box(world_.dims()));
    if (clipped.empty()) {
        return out;
    }
    const std::int64_t s = kTileSize;
    for_each_tile(tiles_of(clipped), [&](std::int64_t x, std::int64_t y, std::int64_t z) {
        const auto it =
            tiles_.find(tile_key(static_cast<std::uint32_t>(x), static_cast<std::uint32_t>(y),
                                 static_cast<std::uint32_t>(z)));
        if (it == tiles_.end()) {
            return;
        }
        const Box part = intersect(clipped, tile_voxels({x, y, z}));
        if (it->second == kInsideTile) {
            for (std::size_t i = 0; i < kTileVoxels; ++i) {
                std::memcpy(tile.data() + i * elem_, inside_.data(), elem_);
            }
        } else {
            cl_call("reading a field tile", [&] {
                ctx_.queue().enqueueReadBuffer(pool_, CL_TRUE,
                                               std::size_t{it->second} * kTileVoxels * elem_,
                                               tile.size(), tile.data());
            });
        }
        for (std::int64_t pz = part.min.z; pz < part.max.z; ++pz) {
            for (std::int64_t py = part.min.y; py < part.max.y; ++py) {
                const std::size_t from =
                    static_cast<std::size_t>(((pz - z * s) * s + (py - y * s)) * s +
                                             (part.min.x - x * s)) *
                    elem_;
                const std::size_t to = ((static_cast<std::size_t>(pz - box.min.z) * ny +
                                         static_cast<std::size_t>(py - box.min.y)) *
                                            nx +
                                        static_cast<std::size_t>(part.min.x - box.min.x)) *
                                       elem_;
                std::memcpy(out.data() + to, tile.data() + from,
                            static_cast<std::size_t>(part.max.x - part.min.x) * elem_);
            }
        }
    });
    return out;
}

std::vector<std::uint8_t> SparseField::read_dense() {
    return read_box(world_box(world_.dims()));
}

double SparseField::coarse_node(std::int64_t nx, std::int64_t ny, std::int64_t nz) {
    const Format f = options_.format;
    // Float values are correctly rounded, so possibly above the exact distance: one unit in
    // the last place lower bounds it (integer formats hold it rounded down already).
    auto below = [&](double v) {
        if (f == Format::f32) {
            return static_cast<double>(std::nextafter(static_cast<float>(v), 0.0f));
        }
        return f == Format::f64 ? std::nextafter(v, 0.0) : v;
    };
    auto positive = [&](const std::vector<std::uint8_t>& v) {
        return below(std::max(0.0, decode_value(v, f, 0)));
    };
    if (nx < 0 || ny < 0 || nz < 0) {
        return positive(far_);
    }
    const auto it =
        tiles_.find(tile_key(static_cast<std::uint32_t>(nx / 4), static_cast<std::uint32_t>(ny / 4),
                             static_cast<std::uint32_t>(nz / 4)));
    if (it == tiles_.end() || it->second == kInsideTile) {
        return positive(it == tiles_.end() ? far_ : inside_);
    }
    if (!coarse_synced_) {
        coarse_host_.resize(slot_keys_.size() * 64 * elem_);
        cl_call("reading the field's node minima", [&] {
            ctx_.queue().enqueueReadBuffer(coarse_, CL_TRUE, 0, coarse_host_.size(),
                                           coarse_host_.data());
        });
        coarse_synced_ = true;
    }
    const std::size_t node = static_cast<std::size_t>(it->second) * 64 +
                             static_cast<std::size_t>((nz % 4) << 4 | (ny % 4) << 2 | (nx % 4));
    const std::vector<std::uint8_t> v(coarse_host_.begin() + static_cast<long>(node * elem_),
                                      coarse_host_.begin() + static_cast<long>((node + 1) * elem_));
    // The minima of packed32 hold the distance byte itself.
    return below(std::max(0.0, decode_value(v, f == Format::packed32 ? Format::u32 : f, 0)));
}

double SparseField::coarse_tile(std::int64_t tx, std::int64_t ty, std::int64_t tz) {
    double best = std::numeric_limits<double>::infinity();
    for (std::int64_t n = 0; n < 64; ++n) {
        best =
            std::min(best, coarse_node(tx * 4 + (n & 3), ty * 4 + (n >> 2 & 3), tz * 4 + (n >> 4)));
    }
    return best;
}

}  // namespace voxfield::ocl
