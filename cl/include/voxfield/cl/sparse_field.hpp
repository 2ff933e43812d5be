#pragma once
// Exact bounded distance fields of sparse worlds (core/sparse.hpp), tile by tile, on any
// OpenCL device (kernels: cl/kernels/sparse_field.cl, the world's 64-trees on the device:
// sparse_device_world.hpp; the transforms: exact.hpp and separable.hpp). Each tile to compute is
// gathered with a halo of ceil(D / spacing) voxels per axis from its neighbour tiles into a dense
// block; blocks are stacked along z into one dense world and transformed by the dense bounded
// generator, and each block's interior is scattered into the field tiles. A voxel within D of
// another depends on nothing outside the block, so the result equals the dense bounded field voxel
// for voxel.
//
// Field tiles: 64^3 values in the output format, in a pool of slots on the device, stored for
// every tile within D of a solid voxel; tiles beyond D hold the far value (D in the format)
// and are not stored, nor are tiles whose every value is the "inside" value (unsigned fields:
// a tile full of solid voxels, 0; signed: a full tile whose halo is full, -D), except in
// packed32, whose solid voxels carry their colour.
#include <algorithm>
#include <bit>
#include <cstdint>
#include <map>
#include <memory>
#include <optional>
#include <stdexcept>
#include <string>
#include <utility>
#include <vector>

#include "voxfield/cl/generator.hpp"
#include "voxfield/cl/sparse_device_world.hpp"
#include "voxfield/core/clock.hpp"
#include "voxfield/core/sparse.hpp"

namespace voxfield::ocl {

class PinnedTables;

// --max-distance of sparse worlds when none is given.
inline constexpr double kDefaultSparseMaxDistance = 16;

// Checks and completes options for a sparse world: algorithm exact, no indices, no chunk;
// max_distance defaults to kDefaultSparseMaxDistance; the format defaults as for dense
// worlds when `format_given` is false. Throws InputError naming what to change.
GeneratorOptions resolve_sparse_options(const GeneratorOptions& options, bool format_given);

// Tile key (core/sparse.hpp's tile_key) -> 32-bit entry: open addressing with linear probing in
// one flat array, at most half full (no allocation per entry: std::unordered_map's made most of
// run()'s listing of a large world's field tiles). The part of std::unordered_map's interface
// that SparseField uses; an insert that grows it invalidates iterators and references. Threads
// may find() and set distinct entries' values at once.
class TileMap {
  public:
    using Entry = std::pair<std::uint64_t, std::uint32_t>;
    template <class E>
    class Iter {
      public:
        Iter(E* at, E* end) : at_(at), end_(end) { skip(); }
        E& operator*() const { return *at_; }
        E* operator->() const { return at_; }
        Iter& operator++() {
            ++at_;
            skip();
            return *this;
        }
        bool operator==(const Iter& o) const { return at_ == o.at_; }

      private:
        void skip() {
            while (at_ != end_ && at_->first == kFree) {
                ++at_;
            }
        }
        E* at_;
        E* end_;
    };
    using iterator = Iter<Entry>;
    using const_iterator = Iter<const Entry>;

    iterator begin() { return {entries_.data(), entries_.data() + entries_.size()}; }
    iterator end() {
        return {entries_.data() + entries_.size(), entries_.data() + entries_.size()};
    }
    const_iterator begin() const { return {entries_.data(), entries_.data() + entries_.size()}; }
    const_iterator end() const {
        return {entries_.data() + entries_.size(), entries_.data() + entries_.size()};
    }
    std::size_t size() const { return size_; }
    void clear() {
        entries_.clear();
        size_ = 0;
    }
    // Room for n entries without growing.
    void reserve(std::size_t n) {
        if (2 * n > entries_.size()) {
            rehash(std::bit_ceil(std::max<std::size_t>(2 * n, 16)));
        }
    }
    iterator find(std::uint64_t key) {
        return {entries_.data() + probe(key), entries_.data() + entries_.size()};
    }
    const_iterator find(std::uint64_t key) const {
        return {entries_.data() + probe(key), entries_.data() + entries_.size()};
    }
    const std::uint32_t& at(std::uint64_t key) const {
        const const_iterator it = find(key);
        if (it == end()) {
            throw std::out_of_range("TileMap::at: no entry for the tile");
        }
        return it->second;
    }
    // The entry of `key`, inserted as 0 when there was none.
    std::uint32_t& operator[](std::uint64_t key) { return insert(key, 0)->second; }
    // Inserts (key, value) unless `key` has an entry; true when it inserted.
    bool emplace(std::uint64_t key, std::uint32_t value) {
        const std::size_t before = size_;
        insert(key, value);
        return size_ != before;
    }

  private:
    static constexpr std::uint64_t kFree = ~std::uint64_t{0};
    static std::size_t hash(std::uint64_t k) {
        k ^= k >> 33;
        k *= 0xff51afd7ed558ccdULL;
        k ^= k >> 33;
        return static_cast<std::size_t>(k);
    }
    // The index of key's entry, or entries_.size() when it has none.
    std::size_t probe(std::uint64_t key) const {
        if (entries_.empty()) {
            return 0;
        }
        const std::size_t mask = entries_.size() - 1;
        for (std::size_t i = hash(key) & mask;; i = (i + 1) & mask) {
            if (entries_[i].first == key) {
                return i;
            }
            if (entries_[i].first == kFree) {
                return entries_.size();
            }
        }
    }
    Entry* insert(std::uint64_t key, std::uint32_t value) {
        if (2 * (size_ + 1) > entries_.size()) {
            rehash(std::max<std::size_t>(2 * entries_.size(), 16));
        }
        const std::size_t mask = entries_.size() - 1;
        std::size_t i = hash(key) & mask;
        while (entries_[i].first != key && entries_[i].first != kFree) {
            i = (i + 1) & mask;
        }
        if (entries_[i].first == kFree) {
            entries_[i] = {key, value};
            ++size_;
        }
        return &entries_[i];
    }
    void rehash(std::size_t capacity) {
        std::vector<Entry> old(capacity, Entry{kFree, 0});
        old.swap(entries_);
        size_ = 0;
        for (const Entry& e : old) {
            if (e.first != kFree) {
                insert(e.first, e.second);
            }
        }
    }
    std::vector<Entry> entries_;
    std::size_t size_ = 0;
};

class SparseField {
  public:
    // Uploads the world's buffers; `world` and `palette` must outlive the field (update()
    // reads the world's edits). Options as resolve_sparse_options returns them. A read-only
    // world takes no apply_brush.
    SparseField(Context& ctx, const SparseWorld& world, const Palette& palette,
                const GeneratorOptions& options);
    // The same, with a world the field edits on the device (apply_brush): `world` lags behind
    // the device until it is read through world(). `allocate`: where the device world's trees
    // live (SparseDeviceWorld's TreeAllocator; empty: plain device buffers).
    SparseField(Context& ctx, SparseWorld& world, const Palette& palette,
                const GeneratorOptions& options, TreeAllocator allocate = {});
    ~SparseField();
    SparseField(const SparseField&) = delete;
    SparseField& operator=(const SparseField&) = delete;

    // The whole field from scratch; returns the kernel time (first kernel start to last
    // kernel end, summed over batches).
    double run();

    struct Update {
        Box recomputed;           // the voxels whose field was recomputed (Box{} when none)
        std::uint32_t tiles = 0;  // field tiles written
        double kernel_ms = 0;
        double edit_kernel_ms = 0;  // of which apply_brush's decoding, brush and encoding
        // kernel_ms by kernel (name, ms; summed per name), in first-launch order.
        std::vector<std::pair<std::string, double>> stages;
        // Commands enqueued and host waits (the world's edit included).
        QueueTraffic traffic;
        // Where the wall time of an update of one block (an edit's) went, by the host's clock
        // (name, ms): for apply_brush "world edit" (its table made, its commands enqueued),
        // then for the block "field tables" (made on the host), "field enqueue", "wait" (for
        // the last kernel: every command done), "after" (profiling read, minima kept). Only
        // apply_brush fills it, and not for updates of several blocks or where the block's
        // generator ran (and waited) by itself.
        std::vector<std::pair<std::string, double>> host_stages;
        // The same update's commands (transfers and kernels, the world's edit included) by
        // their profiling events: the first start to the last end, and the part of that span in
        // which none ran (the device waiting for the host or between launches). 0 when
        // host_stages is empty.
        double device_span_ms = 0, device_idle_ms = 0;
        // False for an update made without stage events (set_edit_stage_events(false)): a
        // one-block update then has no stages and edit_kernel_ms 0; apply_brush's commands run
        // on the queue without profiling (Context::Unprofiled), so its kernel_ms and
        // device_span_ms are 0 too; for update(), apply_dense_tiles() and write_tiles()
        // kernel_ms is a lower bound, the kernels that had events.
        bool profiled = true;
    };
    // Whether apply_brush gives every command a profiling event (the default: per-kernel
    // stages and the device's idle time) or only those it must wait for (its tables' writes
    // and the last kernel), on the context's queue without profiling (Context::Unprofiled: no
    // times at all). NVIDIA's driver spends about 7 us more host time on a launch with an
    // event (bench/cl_overhead.c), 6 of an edit's 8 commands, and about a third more on any
    // command of a profiling queue (bench/README.md).
    void set_edit_stage_events(bool on);
    // After the world's voxels inside `changed` were edited on the host (SparseWorld::edit /
    // apply_brush return that box), brings the device's world and the field up to date:
    // uploads the tiles `changed` overlaps and recomputes the voxels within D of `changed`
    // only, in the tiles they lie in.
    Update update(const Box& changed);
    // Applies `brush` to the world on the device (SparseDeviceWorld::apply_brush: decoded,
    // brushed and encoded there, nothing read back) and updates the field as update() does
    // for the brush's bounds; kernel_ms includes the edit's kernels. InputError as core's
    // apply_brush; logic_error for a read-only world.
    Update apply_brush(const Brush& brush);
    // After a kernel wrote whole tiles of the world into `vox` on the device (the sparse sand
    // simulation, sparse_sand.hpp): encodes them into the world there
    // (SparseDeviceWorld::encode_dense_tiles) and recomputes the voxels within D of the boxes
    // `changed` , as update()
    // does for one box. kernel_ms includes the encoding (edit_kernel_ms); recomputed is the
    // hull of the recomputed boxes. logic_error for a read-only world.
    Update apply_dense_tiles(const cl::Buffer& vox, std::uint32_t pitch_y, std::uint32_t pitch_z,
                             const std::vector<SparseDeviceWorld::DenseTile>& tiles,
                             const std::vector<Box>& changed);
    // Writes whole tiles back into the world (`vox`: kTileVoxels per tile in the order of
    // `tiles`, as SparseDeviceWorld::gather_tiles lays them out) and recomputes the voxels within
    // D of them: the sparse viewer's undo and redo. logic_error for a read-only world.
    Update write_tiles(const cl::Buffer& vox, const std::vector<Int3>& tiles);
    // Sets up what the update of one edit of `radius` transforms (the dense generator of its
    // block, whose programs a device builds on first use unless its program cache has them:
    // about 2 s on the H200), so that the first such edit does not wait for it.
    void prepare_edits(std::int64_t radius);
    // The world, brought up to date with the device's edits first.
    const SparseWorld& world() { return device_world_.world(); }
    const SparseDeviceWorld& device_world() const { return device_world_; }
    SparseDeviceWorld& device_world() { return device_world_; }

    // The last run()'s or update's work: dense blocks and batches, voxels gathered and
    // transformed (halos included) and voxels written (the blocks' regions); kernel ms per
    // kernel (name, ms; summed per name) in first-launch order.
    struct Work {
        std::uint64_t blocks = 0, batches = 0, block_voxels = 0, region_voxels = 0;
    };
    const Work& last_work() const { return work_; }
    const std::vector<std::pair<std::string, double>>& last_stages() const { return stages_; }
    // The last run()'s wall clock per step (ms): the world brought up to date on the device,
    // the field tiles found, the pool allocated, the jobs listed, the field computed (kernels
    // and waits), the node minima.
    const std::vector<std::pair<std::string, double>>& last_host_stages() const {
        return host_stages_;
    }

    const GeneratorOptions& options() const { return options_; }
    // How run() computes the whole field: "sweep" (Manhattan fields, signed or not, of unit
    // spacing whose halo fits in one neighbour tile, not packed32: 1-D passes in the field
    // tiles themselves, see sparse_field.cl) or "blocks" (every other field, and updates: each
    // tile's block with its halo through a dense generator). force_blocks(true) makes run()
    // take blocks always (tests and benchmarks compare the two).
    std::string run_method() const;
    void force_blocks(bool on) { force_blocks_ = on; }
    std::uint32_t halo(int axis) const { return halo_[axis]; }
    // Field tiles with values of their own on the device, and all field tiles (constant
    // ones included).
    std::uint32_t dense_tiles() const { return static_cast<std::uint32_t>(slot_keys_.size()); }
    std::uint64_t field_bytes() const;  // device bytes of the stored field tiles
    // The encoded value of voxels beyond D (element_size(format) bytes).
    const std::vector<std::uint8_t>& far_value() const { return far_; }

    // The field of `box` (element_size(format) bytes per voxel, x fastest); InputError when
    // it holds more than kMaxDenseVoxels voxels.
    std::vector<std::uint8_t> read_box(const Box& box);
    // The whole field as one dense array (DESIGN §3's layout), as read_box of the world.
    std::vector<std::uint8_t> read_dense();

    // Conservative coarse distances (ray skipping): a lower bound of the field's distance to
    // the nearest solid (the field's value, its positive part when signed) over every voxel
    // of tile (tx, ty, tz), or of the 16^3 node (nx, ny, nz) (node units: voxel / 16). D for
    // tiles beyond the bound. Float formats' values are lowered by one unit in the last place,
    // so that the coarse distance bounds the exact distance as well. The minima live on the
    // device; the first call after a run or an update reads them back whole.
    double coarse_tile(std::int64_t tx, std::int64_t ty, std::int64_t tz);
    double coarse_node(std::int64_t nx, std::int64_t ny, std::int64_t nz);

  private:
    SparseField(Context& ctx, const SparseWorld& world, const Palette& palette,
                const GeneratorOptions& options, SparseWorld* editable, TreeAllocator allocate);
    struct Job {
        Box region;   // voxels written: inside one block, clipped to the world
        Int3 origin;  // world coordinates of the block's first voxel
    };
    struct Batch;  // a dense generator of one block shape and its buffers
    Batch& batch_for(Dims block, std::uint32_t blocks);
    // Builds the kernel of a one-block batch's slice stage from the trees (Batch::tree_slices).
    void set_up_tree_slices(Batch& b);
    // Computes `jobs` (each block: block dims) in batches; returns kernel ms and adds them per
    // kernel to stages_, except the last scatters', which are left in scatters_ (nothing waits
    // for them): settle_scatters() waits and returns their ms.
    // `pow2_batch`: blocks per batch rounded up to a power of two (the extra blocks transformed
    // and not scattered), so that varying job counts share batch shapes.
    double compute(const std::vector<Job>& jobs, Dims block, bool pow2_batch = false);
    // An update's single block `job`: its tables in one write, gather, the dense generator (or,
    // where the batch has tree slices, those and the generator's later launches), then the
    // scatter and the node minima of `slots` (per slot, the nodes set in `nodes`,
    // which must hold every node the region overlaps) in one kernel, enqueued without a wait;
    // then the one wait, for that kernel. Returns kernel ms. Its host times and commands go to
    // block_times_ and block_commands_.
    double update_block(const Job& job, Dims block, const std::vector<std::uint32_t>& slots,
                        const std::vector<std::uint64_t>& nodes);
    // Enqueues the scatter of `count` blocks of the dense `field` into the pool (tables `jobs`,
    // `regions`, `slots`), each region at most `largest`.
    void enqueue_scatter(const cl::Buffer& field, const cl::Buffer& jobs, const cl::Buffer& regions,
                         const cl::Buffer& slots, Dims block, Int3 largest, std::size_t count,
                         cl::Event* event);
    // run()'s Manhattan sweep over slots [0, slot_keys_.size()); returns kernel ms.
    double sweep();
    double settle_scatters();
    void add_stage(const std::string& name, double ms);
    // Recomputes the voxels within D of the boxes `changed` (the device's world already
    // edited): one box in one block (tile by tile when that is too large), several in one
    // block of their hull when it is small, else tile by tile.
    Update recompute(const std::vector<Box>& changed);
    // The block of a single region's update: the voxels within D of the region (clipped to
    // the world and one voxel beyond), extents rounded up to a multiple of 4.
    Box single_block(const Box& region) const;
    // `result` with the device world's last edit stages (decoding, brushing, encoding) put
    // before its own and counted in its kernel times.
    Update with_edit_stages(Update result) const;
    // The slot of field tile `key`, made dense (filled with its constant) when it was not.
    std::uint32_t dense_slot(std::uint64_t key);
    void ensure_slots(std::size_t slots);
    // The node minima of the listed field slots: per slot, the nodes set in `nodes`.
    void refresh_coarse(const std::vector<std::uint32_t>& slots,
                        const std::vector<std::uint64_t>& nodes, double* ms);
    std::vector<std::uint8_t> constant_value(std::uint32_t entry) const;

    Context& ctx_;
    const SparseWorld& world_;
    const Palette& palette_;
    GeneratorOptions options_;
    std::uint32_t halo_[3] = {0, 0, 0};
    std::size_t elem_ = 0;
    std::vector<std::uint8_t> far_, inside_;
    cl::Program program_;
    // Whether gather and scatter take a work-item per voxel (GPU layout) or per row.
    bool gpu_layout_ = false;
    cl::Kernel scatter_, scatter_voxels_, node_minima_;  // arguments set per launch
    cl::Kernel scatter_minima_;  // scatter and node_minima of update_block's one region
    cl::Kernel fill_slot_, sweep_init_, sweep_l1_, sweep_l1_rows_, sweep_finish_;
    cl::Kernel sweep_l1_loaded_;  // sweep_l1 of the GPU layout
    bool force_blocks_ = false;
    bool stage_events_ = true;        // set_edit_stage_events
    SparseDeviceWorld device_world_;  // the world's 64-trees on the device
    // node_minima's slots, tile coordinates and nodes of refresh_coarse.
    cl::Buffer minima_list_, minima_coords_, minima_nodes_;
    std::size_t minima_list_cap_ = 0;
    // Field tiles: key -> slot on the device, or kInsideTile (constant inside value).
    TileMap tiles_;
    std::vector<std::uint64_t> slot_keys_;  // per slot, its tile key
    cl::Buffer pool_;                       // slots of kTileVoxels * elem_ bytes
    std::size_t pool_slots_ = 0;
    cl::Buffer coarse_;  // per slot, its 64 nodes' least KEY (sparse_field.cl), in the format
    // A host copy of coarse_, read whole by coarse_node when the device's has changed since.
    std::vector<std::uint8_t> coarse_host_;
    bool coarse_synced_ = false;
    std::map<std::tuple<std::uint32_t, std::uint32_t, std::uint32_t, std::uint32_t>,
             std::unique_ptr<Batch>>
        batches_;
    std::vector<std::pair<std::string, double>> stages_;       // of the running run() or update
    std::vector<std::pair<std::string, double>> host_stages_;  // of the last run()
    std::vector<cl::Event> scatters_;
    Work work_;
    QueueTraffic traffic_;  // of the running update
    // The last update_block's times (its first enqueue, its last, the end of its wait) and
    // commands, for Update::host_stages and device_span_ms.
    struct BlockTimes {
        bool set = false;
        Clock::time_point enqueue, enqueued, waited;
    };
    BlockTimes block_times_;
    std::vector<cl::Event> block_commands_;
    // update_block's tables.
    std::unique_ptr<PinnedTables> tables_;
};

}  // namespace voxfield::ocl
