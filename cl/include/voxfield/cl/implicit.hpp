#pragma once
// An implicit part (core/sdf.hpp) discretised on an OpenCL device into the reference blog's
// tile grid of contrees (farfa.dev, "implicit surface rendering for CAD"): tiles of
// 4^(depth+1) voxels per axis, each empty, full or the root of a contree whose nodes split into
// 4x4x4 children; a cell whose interval excludes 0 is not split. At the leaves (4^3 voxels) the
// 5^3 shared corners and the 64 centres are sampled in one batch; the tree keeps which voxels
// are solid (f < 0 at the centre) and, for every voxel the surface crosses (the sign of f,
// taken as f < 0 or not, differs among its 8 corners and its centre), f and grad f at its
// corners. Layouts of the records: core/sdf_layout.hpp.
#include <cstdint>
#include <functional>
#include <utility>
#include <vector>

#include "voxfield/cl/generator.hpp"
#include "voxfield/cl/runtime.hpp"
#include "voxfield/core/sdf.hpp"

namespace voxfield::ocl {

struct ImplicitOptions {
    // Contree depth: tiles of 4^(depth + 1) voxels per axis (0: a tile is one leaf of 4^3).
    std::uint32_t tile_depth = 2;
    // cpu: one work-item per leaf; gpu: a work-group of 128 per leaf; automatic: by device.
    Layout layout = Layout::automatic;
};

struct ImplicitGrid {
    Dims dims;   // voxels
    Dims tiles;  // ceil(dims / tile_edge)
    std::uint32_t tile_depth = 0;
    std::uint32_t tile_edge = 0;            // voxels per tile axis: 4^(tile_depth + 1)
    std::vector<std::uint32_t> tile_table;  // root node, VF_SDF_TILE_EMPTY or VF_SDF_TILE_FULL
    std::vector<std::uint32_t> nodes;       // VF_SDF_NODE_WORDS per node
    std::vector<std::uint32_t> voxels;      // VF_SDF_VOXEL_WORDS per crossed voxel
    std::vector<float> vertices;            // VF_SDF_VERTEX_FLOATS per kept corner: h grad f, f
    std::uint64_t leaves = 0;               // leaf nodes

    std::size_t node_count() const { return nodes.size() / VF_SDF_NODE_WORDS; }
    std::size_t crossed_count() const { return voxels.size() / VF_SDF_VOXEL_WORDS; }
    std::size_t vertex_count() const { return vertices.size() / VF_SDF_VERTEX_FLOATS; }
    std::size_t bytes() const;  // of the four arrays

    // Solid voxels (f < 0 at the centre), full cells and leaves' solid bits clipped to dims.
    std::uint64_t solid_count() const;
    // Per voxel (x fastest): bit 0 solid, bit 1 crossed, decoded from the tree.
    std::vector<std::uint8_t> flags() const;
    // Every crossed voxel: its coordinates, material and its 8 corners' (grad x, y, z, f).
    struct Crossed {
        std::uint32_t x, y, z, material;
        float corner[8][4];  // corner c = cx + 2 cy + 4 cz: h grad f (x, y, z), f
    };
    std::vector<Crossed> crossed() const;
    // Forgets the crossed voxels at which `drop(x, y, z)` is true (their occupied bits and
    // records; the solid bits and the vertices stay): a tracer then treats them as the world's
    // voxels say (a scene's .vox voxel over a part: a cube). Returns how many were dropped.
    std::size_t drop_crossed(
        const std::function<bool(std::uint32_t, std::uint32_t, std::uint32_t)>& drop);
};

// Timing of one discretisation (wall clock on the host, all phases).
struct ImplicitTiming {
    double total_ms = 0;  // from the first enqueue to the host arrays filled
    // Device times (OpenCL profiling; reruns included): every kernel, then by stage.
    double kernel_ms = 0;
    double tiles_ms = 0, levels_ms = 0, leaves_ms = 0;  // tile tests, interior levels, leaves
    double read_ms = 0;                                 // the read-backs' transfers
    // Host times, adding up to total_ms: issuing commands (and growing buffers), blocked on
    // the device, and filling the grid's arrays after the last wait.
    double host_ms = 0, wait_ms = 0, copy_ms = 0;
    std::uint32_t syncs = 0;         // times the host waited for the device
    std::uint32_t enqueues = 0;      // commands enqueued: kernels, writes, reads and copies
    std::uint32_t passes = 0;        // sample_leaves runs (2 when the first capacities overflowed)
    std::uint32_t level_reruns = 0;  // counted runs: tile tests and levels run again at the
                                     // count they reached (past the first guess of its room)
    // Whether the levels were sized by reading their counts (a first run, or a rerun after a
    // steady-state run's capacities overflowed): a wait per level; else one wait in all.
    bool counted = false;
};

// What a run produced: nodes per level (level 0: the tiles' roots; the last: the leaves), kept
// corners (vertices) and crossed voxels. A discretiser sizes its next run from its last one's.
struct ImplicitCounts {
    std::vector<std::uint32_t> nodes;
    std::uint32_t vertices = 0, voxels = 0;
    bool operator==(const ImplicitCounts&) const = default;
};

class ImplicitDiscretiser {
  public:
    ImplicitDiscretiser(Context& ctx, const sdf::Part& part, ImplicitOptions options = {});
    ~ImplicitDiscretiser();
    ImplicitDiscretiser(const ImplicitDiscretiser&) = delete;
    ImplicitDiscretiser& operator=(const ImplicitDiscretiser&) = delete;

    // The first run counts each level on the host before launching the next (a wait per
    // level); later runs launch every level at once, sized from the last run's counts (the
    // kernels read the true counts on the device and store what fits), and wait once for the
    // counts and the whole output together; counts above those capacities rerun counted.
    ImplicitGrid run();
    // The same into `out`, reusing its arrays' storage (and this discretiser's device buffers
    // and kernels, as every run does): repeated discretisations allocate nothing once warm.
    void run(ImplicitGrid& out);
    const ImplicitTiming& timing() const { return timing_; }
    const ImplicitCounts& counts() const { return counts_; }
    // Sizes the next run from `expected` (e.g. a similar part's counts) as from a last run's:
    // one wait when they hold. `expected.nodes` has tile_depth + 1 levels.
    void expect(const ImplicitCounts& expected);
    // Read back through page-locked staging memory (see Pinned below): by default on devices
    // that do not compute in host memory; settable to test both paths on any device.
    void set_pinned_readback(bool on) { staged_ = on; }
    bool pinned_readback() const { return staged_; }
    // The corner |f| past which a leaf takes a corner's sign for its voxel's centre instead of
    // sampling it: half the voxel's diagonal (f is 1-Lipschitz) plus a rounding margin by
    // default; settable so that tests can show that a smaller one is caught.
    float centre_bound() const { return decided_; }
    void set_centre_bound(float bound) { decided_ = bound; }
    bool gpu_layout() const { return gpu_layout_; }

    // Brute force, for checking: f at every grid corner ((X+1)(Y+1)(Z+1), x fastest) and at
    // every voxel centre (X Y Z), by the same device code.
    std::vector<float> sample_corners();
    std::vector<float> sample_centres();

  private:
    Context& ctx_;
    sdf::Part part_;  // a copy: the caller's part may go
    ImplicitOptions options_;
    bool gpu_layout_;
    float decided_;  // a corner |f| that decides its voxel centre's sign
    cl::Program program_;
    cl::Buffer tape_;
    ImplicitTiming timing_;
    ImplicitCounts counts_;  // the last run's; empty before the first
    // Capacities of one attempt: nodes per level, vertices, voxels.
    struct Caps {
        std::vector<std::size_t> level;
        std::size_t vertices = 0, voxels = 0;
    };
    bool attempt_at_once(ImplicitGrid& out, const Caps& caps);
    void attempt_counted(ImplicitGrid& out);
    // Enqueueing: the kernels (with their events), zeroing counters, and a wait.
    void enqueue_tiles(const ImplicitGrid& out, std::size_t capacity);
    void enqueue_level(std::uint32_t level, std::size_t capacity, std::size_t next_capacity,
                       std::size_t node_capacity, std::size_t groups);
    void enqueue_leaves(std::size_t capacity, std::size_t node_capacity, std::size_t vertices,
                        std::size_t voxels, std::size_t groups);
    void zero_counters(std::uint32_t first, std::uint32_t count);
    const cl_uint* read_counters();  // blocking
    void wait();
    // The counters and the output (up to these sizes) in one go, one wait, then the grid's
    // arrays (no more than the counters say).
    void read_output(ImplicitGrid& out, std::size_t node_words, std::size_t voxel_words,
                     std::size_t vertex_floats);
    // Kept across runs: kernels, device buffers (grown, never shrunk).
    void grow(cl::Buffer& buffer, std::size_t& capacity, std::size_t bytes,
              std::size_t keep_bytes = 0);
    void size_levels(const Caps& caps, std::size_t tiles);
    bool kernels_made_ = false;
    cl::Kernel classify_tiles_, classify_children_, sample_leaves_;
    cl::Buffer counters_buf_, table_buf_, nodes_buf_, voxels_buf_, vertices_buf_;
    // The frontiers of levels L and L + 1: nodes' origins (node index in w) and their
    // specialised tapes (list_bytes() each; none for tapes too long to specialise).
    cl::Buffer origins_buf_[2], lists_buf_[2];
    std::size_t list_bytes() const;
    std::size_t counters_cap_ = 0, table_cap_ = 0, nodes_cap_ = 0, voxels_cap_ = 0,
                vertices_cap_ = 0, origins_cap_[2] = {0, 0}, lists_cap_[2] = {0, 0};
    std::vector<std::pair<int, cl::Event>> events_;  // (stage, event) of this run's commands
    std::vector<cl_uint> host_counters_;
    const std::vector<cl_uint> zeros_ = std::vector<cl_uint>(VF_SDF_COUNTERS, 0);
    // A device outside host memory (a GPU) reads back through page-locked host memory: a
    // CL_MEM_ALLOC_HOST_PTR buffer mapped once and kept mapped (full-speed DMA, no driver
    // bounce buffer), then copied into the grid's arrays. Host-memory devices read directly.
    struct Pinned {
        cl::Buffer buffer;
        std::uint8_t* data = nullptr;
        std::size_t capacity = 0;
    };
    std::uint8_t* pinned(Pinned& p, std::size_t bytes);
    void unmap(Pinned& p);
    bool staged_;
    Pinned small_stage_, out_stage_;  // counters; the whole output
};

}  // namespace voxfield::ocl
