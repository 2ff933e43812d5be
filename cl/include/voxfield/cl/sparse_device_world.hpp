#pragma once
// A sparse world's 64-trees on an OpenCL device (core/sparse.hpp's layout; kernels:
// cl/kernels/sparse_world.cl), edited there: the 16^3 nodes a brush's bounds overlap are decoded,
// brushed and their tiles encoded again on the device, in two kernels after one write of a pinned
// table (those nodes from their voxels, the others copied from the tile's previous tree), bit for
// bit as core's SparseWorld::encode_tile, so that an edit neither reads anything back nor encodes
// on the host.
// The host world is brought up to date (the edited tiles read back and stored) only when it is
// read: world().
//
// Where the trees lie: the main buffers hold the host world's buffers as uploaded; a tile
// encoded since (on the device, or on the host and uploaded by host_edited) lives in a slot
// of its own, sized for the worst case (kTileMaxNodes nodes, kTileVoxels materials):
// variable-size output without a count read back. A device edit writes each tile into another
// slot (its previous one is read meanwhile) and frees the previous one for later edits. Slots
// taking more than a quarter of the main buffers' bytes (at least 256 MiB) bring the host world
// up to date and upload it again whole, which frees them.
#include <cstdint>
#include <functional>
#include <memory>
#include <optional>
#include <span>
#include <string>
#include <unordered_map>
#include <unordered_set>
#include <utility>
#include <vector>

#include "voxfield/cl/runtime.hpp"
#include "voxfield/core/brush.hpp"
#include "voxfield/core/camera.hpp"
#include "voxfield/core/pick.hpp"
#include "voxfield/core/sparse.hpp"

namespace voxfield::ocl {

class PinnedHost;

// The most nodes of one tile's 64-tree: the root, 64 children of 16^3, 4096 of 4^3.
inline constexpr std::uint32_t kTileMaxNodes = 1 + 64 + 4096;

// Encodes dense tiles on the device (`voxels`: whole tiles of kTileVoxels bytes each,
// tile-local, x fastest): the 64-tree of each, as SparseWorld::encode_tile returns it.
std::vector<SparseWorld::EncodedTile> encode_tiles(Context& ctx,
                                                   std::span<const std::uint8_t> voxels);

// sparse_world.cl's two encoding passes (encode_count, encode_write).
struct EncodeKernels {
    cl::Kernel count, write;
};

// Commands an edit's path enqueued on the device (kernels and transfers) and the times the host
// waited for the device (a blocking transfer, a finish, a wait for events that were not done).
struct QueueTraffic {
    std::uint32_t enqueues = 0, host_waits = 0;
    QueueTraffic& operator+=(const QueueTraffic& o) {
        enqueues += o.enqueues;
        host_waits += o.host_waits;
        return *this;
    }
};

// Memory for the 64-trees' buffers (main and slot buffers) that another API reads in place as
// well (the viewer's Vulkan tracer; pipeline/shared_trees.hpp). Without `allocate`: plain
// device buffers.
struct TreeAllocator {
    // A read-write buffer of at least `bytes` bytes for `what`.
    std::function<cl::Buffer(std::size_t bytes, const std::string& what)> allocate;
    // Called when the world has dropped buffers it no longer uses and its queue is finished
    // (a whole upload, before it allocates the new main buffers), with the tree buffers it
    // still holds (`kept`): memory of any other buffer from `allocate` may be freed now, so
    // that the world is not held twice. May be empty.
    std::function<void(const std::vector<cl::Buffer>& kept)> dropped;
    explicit operator bool() const { return static_cast<bool>(allocate); }
};

class SparseDeviceWorld {
  public:
    // Uploads `world` (its buffers as they are). With `editable` (null, or `world` itself) the
    // world is edited on the device and lags behind it after apply_brush until world() is
    // called; without it apply_brush throws logic_error. `allocate`: where the trees' buffers
    // come from (TreeAllocator).
    SparseDeviceWorld(Context& ctx, const SparseWorld& world, SparseWorld* editable = nullptr,
                      TreeAllocator allocate = {});
    // Waits for the queue (an edit's tables may still be on their way to the device).
    ~SparseDeviceWorld();
    SparseDeviceWorld(const SparseDeviceWorld&) = delete;
    SparseDeviceWorld& operator=(const SparseDeviceWorld&) = delete;

    // The host world, brought up to date with the device's edits first (the tiles edited on
    // the device read back and stored with SparseWorld::put_tile).
    const SparseWorld& world();
    bool host_lags() const { return !lagging_.empty(); }

    // After the host world's voxels inside `changed` were edited on the host (SparseWorld::edit
    // returns that box): uploads the tiles that box overlaps (or, for many, the whole world).
    void host_edited(const Box& changed);
    // Uploads the whole host world again when it changed since the device last saw it (an edit
    // not reported through host_edited).
    void refresh();

    // Applies `brush` (core/brush.hpp semantics, clipped to the world) on the device and
    // returns the box of voxels it may have changed (its bounds in the world; Box{} when
    // none). A brush over more than kMaxEditTiles tiles is applied to the host world (brought up
    // to date first) and uploaded. InputError as core's apply_brush; logic_error when read only.
    Box apply_brush(const Brush& brush);
    static constexpr std::uint32_t kMaxEditTiles = 64;
    // A whole tile written by a kernel into a dense device buffer: its tile coordinates and
    // the index of its voxel (0, 0, 0) in that buffer.
    struct DenseTile {
        Int3 tile;
        std::uint64_t first = 0;
    };
    // Encodes `tiles` from `vox` (rows of `pitch_y`, slices of `pitch_z` voxels; 0 beyond the
    // world) into the world on the device, as apply_brush encodes a brushed tile, with every
    // 16^3 node read from `vox`. The caller keeps `vox` unchanged until the queue reaches the
    // encoding. logic_error when read only.
    void encode_dense_tiles(const cl::Buffer& vox, std::uint32_t pitch_y, std::uint32_t pitch_z,
                            const std::vector<DenseTile>& tiles);
    // The voxels at `cells` as the device has them now (0 outside the world and in tiles not
    // stored), read in one transfer (a gather of a 1^3 block per cell) without bringing the
    // host world up to date: one host wait.
    std::vector<std::uint8_t> voxels(std::span<const Int3> cells);
    // The world's figures as the device has them now, without bringing the host world up to
    // date: its stored tiles, solid voxels and the bytes of their 64-trees (12 per node, 1 per
    // material; what world() would then report as tile_count(), solid_count() and the live
    // part of bytes()). The counts of the tiles in slots are read in one transfer.
    struct Figures {
        std::uint64_t tiles = 0, solid = 0, tree_bytes = 0;
    };
    Figures figures();
    // Whole tiles of the world as the device has them now, into `out` on the device (kTileVoxels
    // bytes per tile in the order of `tiles`, tile-local, x fastest; 0 beyond the world and in
    // tiles not stored): nothing is read back. `out` holds tiles.size() * kTileVoxels bytes.
    // encode_dense_tiles (pitches kTileSize, kTileSize^2) writes such tiles back: an undo.
    void gather_tiles(const std::vector<Int3>& tiles, const cl::Buffer& out);
    // core's pick_solid_voxel over the device's voxels: the ray's cells walked once without the
    // world, their voxels read with voxels(), the walk again over them (the same cells in the
    // same order), so the hit is exactly the host world's after world().
    std::optional<PickHit> pick(const Vec3d& origin, const Vec3d& direction, double max_distance);

    // Device time of the kernels of the last apply_brush (ms; valid once the queue finished).
    double last_edit_kernel_ms() const;
    // The same per kernel (name, ms), in launch order (waits for them when they are not done).
    std::vector<std::pair<std::string, double>> last_edit_stages() const;
    // The commands and host waits of the last apply_brush or encode_dense_tiles.
    const QueueTraffic& last_edit_traffic() const { return traffic_; }
    // The same commands' events (its table's write, then its kernels), for their timeline.
    std::vector<cl::Event> last_edit_commands() const;
    // Whether apply_brush and encode_dense_tiles give their commands profiling events (the
    // default). Without, last_edit_stages() and last_edit_commands() are empty: NVIDIA's
    // driver spends about 7 us more host time on a launch with an event (bench/cl_overhead.c).
    void set_stage_events(bool on) { stage_events_ = on; }
    // Names a command enqueued after the last edit's on the same in-order queue, one the caller
    // waits for: once it is done, the next edit rewrites the edit's pinned table without waiting
    // for the queue (an edit without stage events writes its table without an event).
    void settled_by(const cl::Event& later);

    // Enqueues sparse_world.cl's gather of `count` blocks of `block` voxels stacked along z into
    // `out` (`jobs`, `refs`: its tables): a work-item per four voxels of a leaf's row
    // (gather_quads) in the GPU layout, per row (gather) in the CPU layout.
    void enqueue_gather(const cl::Buffer& jobs, const cl::Buffer& refs, const cl::Buffer& out,
                        Dims block, std::size_t count, cl::Event* event = nullptr);
    // Sets arguments first..first+3 of `k` to the trees' node masks and offsets: the main
    // buffers', then the slot buffers' (sparse_field.cl's sweep_init).
    void set_tree_args(cl::Kernel& k, cl_uint first);
    // A tile's node base and material base for gather's refs (kNoRef, 0 when not stored).
    static constexpr std::uint64_t kNoRef = ~std::uint64_t{0};
    std::pair<std::uint64_t, std::uint64_t> ref(std::int64_t tx, std::int64_t ty,
                                                std::int64_t tz) const;
    // Whether the encoding takes the GPU layout's work-groups (a 16^3 node each; else a tile
    // each); by default on a device that is not a CPU.
    void use_gpu_layout(bool on) { gpu_layout_ = on; }
    // Slots in use (tiles encoded since the last whole upload).
    std::size_t slots_used() const { return slot_of_.size(); }

    // For a reader of the trees in place (TreeAllocator's memory): the buffers as they are now
    // (main: the host world as last uploaded; slots: kTileMaxNodes nodes and kTileVoxels
    // materials per slot). Either set is replaced by a whole upload, the slots also when they
    // grow. Reading them is ordered after the device's edits by the queue's finish.
    struct TreeBuffers {
        cl::Buffer masks, offsets, materials, slot_masks, slot_offsets, slot_materials;
    };
    TreeBuffers tree_buffers() const;
    // Whether a ref's node base points into the slot buffers (its index there: the rest).
    static constexpr std::uint64_t kSlotRef = std::uint64_t{1} << 63;
    // Every stored tile's coordinates and ref (as ref()), in no particular order.
    std::vector<std::pair<Int3, std::pair<std::uint64_t, std::uint64_t>>> refs() const;

  private:
    void upload_whole();
    // gather's job `i` (sparse_world.cl: 8 longs) for a block whose first voxel is `first`, all
    // in `tile`, and its refs entry (2 per job).
    void one_tile_job(std::size_t i, const Int3& first, const Int3& tile,
                      std::vector<std::int64_t>& jobs, std::vector<std::uint64_t>& refs) const;
    // A buffer for the trees: from allocate_ when set.
    cl::Buffer tree_buffer(std::size_t bytes, cl_mem_flags flags, const std::string& what);
    std::uint32_t slot_for(std::uint64_t key);
    // A slot no tile holds: a freed one, else a new one (the slot buffers grow to fit it).
    std::uint32_t take_slot();
    void ensure_slot_capacity(std::size_t slots);
    // Scratch and encoding buffers for `tiles` tiles (`dense`: with a whole tile of voxels each).
    void ensure_scratch(std::size_t tiles, bool dense);
    // The slot bytes past which release_slots_if_needed uploads the world whole again.
    std::uint64_t slot_limit() const;
    void release_slots_if_needed();
    // Makes sure `n` slots can be taken without allocating. When the slot buffers cannot grow
    // (an allocation refused) while slots are in use, the world is uploaded whole first (the
    // host world brought up to date), which frees them all, and it returns true; growth is then
    // not tried again (later edits upload whole when the slots are full). Else the error
    // propagates.
    bool reserve_slots(std::size_t n);
    // A tile leaves the main buffers (into a slot, or removed): its counts leave main_counts_.
    void leave_main(std::uint64_t key);
    void host_changed_seen();
    void clear_edit_events();
    Box host_apply_brush(const Brush& brush);
    // Per tile of `keys` a fresh slot into host_slots_ (never the one its previous tree lies
    // in: slots freed here are taken by later edits only).
    void take_edit_slots(const std::vector<std::uint64_t>& keys);
    // take_edit_slots undone (the enqueue of the edit failed): the keys' previous slots back.
    void untake_edit_slots(const std::vector<std::uint64_t>& keys);
    // The edited tiles `keys` now live in host_slots_: the directory points there, the host lags.
    void commit_edit_slots(const std::vector<std::uint64_t>& keys);
    // The pinned table of an edit of `tiles` tiles (sparse_world.cl's header and records), once
    // its last write is done.
    std::int64_t* edit_table(std::size_t tiles);
    // Writes the table (one transfer) and enqueues the encoding of its `tiles` tiles from `vox`.
    void enqueue_edit_encode(const cl::Buffer& vox, std::uint32_t pitch_y, std::uint32_t pitch_z,
                             std::uint32_t tiles);

    Context& ctx_;
    const SparseWorld& world_;
    SparseWorld* editable_ = nullptr;
    cl::Program program_;
    bool gpu_layout_ = false;
    cl::Kernel gather_, gather_quads_;  // arguments set per launch (enqueue_gather)
    EncodeKernels encode_;
    // Main buffers: the host world as uploaded; dir_: per stored tile key, its refs.
    cl::Buffer masks_, offsets_, materials_;
    TreeAllocator allocate_;
    std::unordered_map<std::uint64_t, std::pair<std::uint64_t, std::uint64_t>> dir_;
    // Per tile in the main buffers, its node and material counts (figures()); a tile leaves
    // when it goes into a slot or is removed.
    std::unordered_map<std::uint64_t, std::pair<std::uint32_t, std::uint32_t>> main_counts_;
    std::uint64_t main_nodes_ = 0, main_materials_ = 0;
    // Slots: buffers of slot_capacity_ worst-case tiles, per slot its node and material counts.
    cl::Buffer slot_masks_, slot_offsets_, slot_materials_, slot_counts_;
    std::size_t slot_capacity_ = 0;
    std::unordered_map<std::uint64_t, std::uint32_t> slot_of_;
    std::vector<std::uint32_t> free_slots_;
    // Per key of the last take_edit_slots, its previous slot (kNoSlot: none), for
    // untake_edit_slots.
    static constexpr std::uint32_t kNoSlot = ~std::uint32_t{0};
    std::vector<std::uint32_t> previous_slots_;
    bool growth_refused_ = false;  // a slot growth was refused (reserve_slots)
    std::size_t slots_made_ = 0;
    // Tiles edited on the device that the host world lacks.
    std::unordered_set<std::uint64_t> lagging_;
    // What the host world's buffers were when the device last matched it.
    std::uint64_t seen_nodes_ = 0, seen_materials_ = 0, seen_generation_ = 0;
    std::uint32_t seen_tiles_ = 0;
    // An edit's tiles of voxels (scratch_, for scratch_tiles_ tiles) and encoding passes' buffers
    // and table (for table_tiles_ tiles); the table's pinned host copy.
    cl::Buffer scratch_, leaf_masks_, mid_masks_, mid_counts_, table_;
    std::size_t scratch_tiles_ = 0, table_tiles_ = 0;
    std::unique_ptr<PinnedHost> pinned_;
    std::vector<std::uint64_t> keys_;
    std::vector<std::int64_t> dense_;  // the table's dense nodes (tile * 64 + child bit)
    std::vector<std::uint32_t> host_slots_;
    // voxels()'s jobs, refs and output, for voxel_capacity_ cells (grown as needed).
    cl::Buffer voxel_jobs_, voxel_refs_, voxel_out_;
    std::size_t voxel_capacity_ = 0;
    // The last edit's table write (null when it enqueued none or had no stage events), kernels
    // and traffic.
    cl::Event edit_write_;
    std::vector<std::pair<std::string, cl::Event>> edit_events_;
    bool stage_events_ = true;
    QueueTraffic traffic_;
};

}  // namespace voxfield::ocl
