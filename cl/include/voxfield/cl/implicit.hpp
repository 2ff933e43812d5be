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
    double total_ms = 0;       // from the first enqueue to the host arrays filled
    double kernel_ms = 0;      // sum of the kernels' device times
    std::uint32_t syncs = 0;   // times the host waited for the device
    std::uint32_t passes = 0;  // sample_leaves runs (2 when the first capacities overflowed)
};

class ImplicitDiscretiser {
  public:
    ImplicitDiscretiser(Context& ctx, const sdf::Part& part, ImplicitOptions options = {});
    ~ImplicitDiscretiser();
    ImplicitDiscretiser(const ImplicitDiscretiser&) = delete;
    ImplicitDiscretiser& operator=(const ImplicitDiscretiser&) = delete;

    ImplicitGrid run();
    // The same into `out`, reusing its arrays' storage (and this discretiser's device buffers
    // and kernels, as every run does): repeated discretisations allocate nothing once warm.
    void run(ImplicitGrid& out);
    const ImplicitTiming& timing() const { return timing_; }
    // Read back through page-locked staging memory (see Pinned below): by default on devices
    // that do not compute in host memory; settable to test both paths on any device.
    void set_pinned_readback(bool on) { staged_ = on; }
    bool pinned_readback() const { return staged_; }
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
    float decided_;  // the CPU layout's corner |f| that decides a centre's sign
    cl::Program program_;
    cl::Buffer tape_;
    ImplicitTiming timing_;
    // Kept across runs: kernels, device buffers (grown, never shrunk), host scratch, and the
    // last run's output counts (the next run's first guess of the room it needs).
    void grow(cl::Buffer& buffer, std::size_t& capacity, std::size_t bytes, cl_mem_flags flags);
    bool kernels_made_ = false;
    cl::Kernel classify_tiles_, classify_children_, sample_leaves_;
    cl::Buffer classes_buf_, origins_buf_, parents_buf_, leaf_nodes_buf_, counters_buf_,
        voxels_buf_, vertices_buf_;
    cl::Buffer lists_buf_[2];  // specialised tapes of two consecutive levels' nodes
    std::size_t classes_cap_ = 0, origins_cap_ = 0, parents_cap_ = 0, leaf_nodes_cap_ = 0,
                counters_cap_ = 0, voxels_cap_ = 0, vertices_cap_ = 0, lists_cap_[2] = {0, 0};
    std::vector<cl_uchar> classes_;
    std::vector<cl_uint4> frontier_, next_;        // origin (voxel), node index in w
    std::vector<cl_uint> parents_, next_parents_;  // the parent's index in its level
    std::size_t last_vertices_ = 0, last_voxels_ = 0;
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
    Pinned small_stage_, out_stage_;  // classes and counters; the leaves' outputs
};

}  // namespace voxfield::ocl
