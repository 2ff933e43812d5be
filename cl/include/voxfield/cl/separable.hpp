#pragma once
// `exact` for everything beyond unit-spacing Manhattan: L1, L-inf and L2 with voxel spacing,
// signed fields and the feature transform (kernels: cl/kernels/exact_separable.cl).
#include <array>
#include <span>
#include <string>
#include <vector>

#include "voxfield/cl/generator.hpp"
#include "voxfield/core/chunks.hpp"

namespace voxfield::ocl {

class ExactSeparable : public Generator {
  public:
    // Whether `options` (algorithm exact) need this generator rather than ExactManhattan.
    static bool needed(const GeneratorOptions& options);

    // Uploads the world and palette and builds the kernels; options as resolve_options
    // returns them. `incremental` keeps every pass's partial distances (4 bytes per voxel
    // each, twice for signed fields) so that update() can recompute only what an edit
    // changes. Throws ClError when the device cannot hold the buffers or lacks fp64. The
    // world is copied: it need not outlive the generator. `z_period` (full transforms
    // without indices): the world is blocks of that many z-slices stacked along z, each block
    // a world of its own, whose values the caller reads only where its own solids decide
    // them (a sparse field's blocks, bounded, read at least the bound from a block's ends):
    // the GPU layout's banded z pass then takes each block's lines apart, as short lines fit
    // more of them in a work-group. Values within the bound of a block's z ends may differ
    // from the stacked world's. 0: one world.
    ExactSeparable(Context& ctx, const World& world, const Palette& palette,
                   const GeneratorOptions& options, bool incremental = false,
                   std::uint32_t z_period = 0);
    // A full (not incremental) transform of a world in host memory, as ExactManhattan's span
    // constructor: on a device that computes in host memory the kernels read `voxels`
    // (dims.count() palette indices) in place and write the field into `field` where given
    // (dims.count() * element_size(options.format) bytes), and with options.indices the
    // index planes into `indices` where given (3 * dims.count() int32, read_indices()'s
    // layout); elsewhere the world is uploaded and `field`, `indices` unused. All must
    // outlive the generator; std::invalid_argument on a size mismatch. `zero_targets`: the
    // distances are to the nearest zero voxel instead of the nearest nonzero one (SciPy's
    // convention; the world need not be inverted first); unsigned fields only.
    ExactSeparable(Context& ctx, Dims dims, std::span<const std::uint8_t> voxels,
                   const Palette& palette, const GeneratorOptions& options,
                   std::span<std::uint8_t> field = {}, std::span<std::int32_t> indices = {},
                   bool zero_targets = false);

    double run() override;
    bool enqueue(std::vector<std::pair<std::string, cl::Event>>& events) override;
    std::string variant() const override;  // "cpu layout" or "gpu layout"
    // The world on the device (one uchar per voxel); writes to it show in the next run().
    const cl::Buffer& voxels_buffer() const { return voxels_; }

    struct Update {
        std::uint64_t voxels_recomputed = 0;  // positions the three passes recomputed
        Box changed;                          // the voxels whose distance changed
    };
    // Incremental generators only: after the voxels inside `edited` were rewritten on the
    // device (in the queue before this call), brings the field up to date exactly: the x
    // pass over the rows through `edited`, then the y and z passes over exactly the lines
    // whose input changed, then the output of the changed voxels and of `edited`. Appends
    // its events to `events` and waits for the queue once (to size the output launch).
    Update update(const Box& edited, std::vector<cl::Event>& events);

  private:
    // The constructors' common part: `voxels` read in place (`in_place`) or uploaded, the
    // field written into `field` when it is not empty.
    void set_up(const std::uint8_t* voxels, bool in_place, std::span<std::uint8_t> field,
                std::span<std::int32_t> indices, const Palette& palette,
                const GeneratorOptions& options);

    // One work-group of cols_banded: `banded_lines(n, gt_bytes, local_mem, key_bytes)` lines
    // of n positions of gt_bytes (banded_site_bytes: partials, 16-bit distances or targets) and
    // key_bytes more per position (the y pass's target x with index planes) (0: lines of n do
    // not fit that much local memory), each in `banded_bands(n, lines)` bands (work-items) of a
    // multiple of 32 positions, at most kBandedGroup work-items; lines shorter than kSiteLimit
    // (positions are 16 bits in the sites' keys).
    static constexpr std::uint32_t kBandedGroup = 256;
    static constexpr std::uint32_t kSiteLimit = 0xFFFE;
    // The local memory the banded passes use at most (GPUs have 32-64 KiB; PoCL's 2 MiB would
    // hide the global lists below from its tests); a pass whose lines do not fit keeps its
    // lists in global memory (cols_banded built with BANDED_GLOBAL), kBandedGlobalLines lines
    // a work-group.
    static constexpr std::size_t kBandedLocalCap = std::size_t{64} << 10;
    static constexpr std::uint32_t kBandedGlobalLines = 8;
    static std::uint32_t banded_lines(std::uint32_t n, std::size_t gt_bytes, std::size_t local_mem,
                                      std::size_t key_bytes = 0);
    static std::uint32_t banded_bands(std::uint32_t n, std::uint32_t lines);
    static std::size_t banded_local_bytes(std::uint32_t n, std::uint32_t lines,
                                          std::size_t gt_bytes, std::size_t key_bytes = 0);
    static std::size_t banded_cells(std::uint32_t n, std::uint32_t lines);  // per local array
    // The mask's words (one per 32 positions and line) and the bands' first and last sites.
    static std::size_t banded_mask_bytes(std::uint32_t n, std::uint32_t lines);
    static std::size_t banded_ends_bytes(std::uint32_t n, std::uint32_t lines);
    // The global lists' scratch buffers of a pass over lines of n positions (the world's y or
    // z lines, or its blocks' z lines), kBandedGlobalLines a group: sites, mask words and the y
    // pass's target x with index planes (else a token).
    std::array<std::size_t, 3> banded_scratch(std::uint32_t n, bool y_pass, bool indices) const;
    // Bytes per position of cols_banded's sites: in the y pass their x rows' 16-bit distances;
    // in the z pass the partials (gt_bytes_), or with index planes the y pass's targets (4).
    std::size_t banded_site_bytes(bool y_pass, bool indices) const {
        return y_pass ? 2 : indices ? 4 : gt_bytes_;
    }
    // The banded y (axis 1) or z (axis 2) pass over lines of n positions `stride` apart, `c`
    // lines per work-group, line starts x + o * mstride for the lines_o values of o (the z
    // pass: in each of the world's blocks of z_period_ slices, where it has them), from and
    // to the partials `parts` (x rows in parts[0], y into parts[1], z into parts[0]); `final`
    // writes the output format; `border` (z only) counts the voxels outside the world as
    // targets (a signed field's inner transform). With index planes the y pass writes its
    // targets into feat_[1], and the z pass reads them and writes the planes.
    KernelLaunch banded_kernel(int axis, std::uint32_t n, std::uint32_t c, std::uint64_t stride,
                               std::uint64_t mstride, std::uint32_t lines_o, bool final,
                               const cl::Buffer* parts, bool border = false);
    // A launch of `items` work-items (rounded up to the layout's work-group size).
    KernelLaunch items_launch(const char* name, const cl::Kernel& k, std::size_t items) const;
    void enqueue(const cl::Kernel& k, std::size_t items, cl::Event* event);
    // One work-item per voxel of `b` (finish).
    void enqueue_voxels(const cl::Kernel& k, const Box& b, cl::Event* event);
    struct Span {
        std::int64_t lo = 0, hi = 0;  // [lo, hi) along one axis
    };
    // x pass over `rows` (its x extent: the voxels written) from the voxels `in` of each row.
    cl::Kernel x_kernel(const Box& rows, Span in, const cl::Buffer& box);
    // y (axis 1) or z (axis 2) pass from partials g_[from] to g_[to], over the lines at x in
    // `xs` and z (y pass) or y (z pass) in `others`, positions `out` from sites `in`.
    // `final`: the z pass writes the output (and index planes) itself (col_pass's `final`).
    cl::Kernel col_kernel(int axis, int from, int to, Span xs, Span others, Span out, Span in,
                          const cl::Buffer& skip, const cl::Buffer& box, bool final = false);
    void set_cap(cl::Kernel& k, cl_uint index) const;
    // A spacing argument in the scans' type (double with fp64_, else float).
    void set_spacing(cl::Kernel& k, cl_uint index, double s) const;
    cl::Kernel finish_kernel(int from, const Box& voxels);
    // Rows per work-item and work-items of an x pass over `rows`.
    std::size_t x_per_item(const Box& rows) const;
    std::size_t x_items(const Box& rows) const;
    // Lines per work-item and work-items of a y or z pass over count_x * count_o lines
    // (count_x adjacent in x), and the scratch ints that pass needs along `axis` (1 y, 2 z).
    std::size_t col_per_item(std::size_t count_x, std::size_t count_o) const;
    std::size_t col_items(std::size_t count_x, std::size_t count_o) const;
    std::size_t col_scratch(int axis, std::size_t count_x, std::size_t count_o) const;

    bool gpu_layout_;
    bool zero_targets_ = false;  // targets are the zero voxels (x_pass's `solid` 0)
    bool banded_ = false;        // the full GPU transform by cols_banded
    bool global_y_ = false;      // its y pass's lists in global memory (program_global_)
    bool global_z_ = false;      // its z pass's
    cl::Program program_global_;
    cl::Program banded_program_[2];  // the y and z passes' in local memory (BANDED_AXIS)
    cl::Buffer banded_scratch_[3];
    // The banded transforms' x rows in chunks: the chunks' ends (outer, inner).
    cl::Buffer row_ends_[2];
    bool incremental_;
    std::uint32_t z_period_ = 0;  // z-slices per stacked block (0: one world)
    Spacing spacing_;
    cl::Program program_;
    cl::Buffer voxels_, rgb_, g_[3], h_[3], feat_[2], scratch_, track_[3];
    bool wide_ = false;           // unit-spacing L2 in 64-bit partials (squares reach 2^30)
    bool fp64_ = false;           // f64 with spacing: the scans in double
    bool shared_parts_ = false;   // one buffer of partials for every pass (CPU layout, full)
    bool l1_keys_ = false;        // unit L1 with indices by l1_xy_keys and l1_z_out (CPU)
    std::size_t gt_bytes_ = 4;    // bytes per partial
    std::size_t max_items_ = 32;  // work-items per pass at most (CPU layout)
    // Per y and z pass (CPU layout): ints per work-item's stacks and tiles, lines per tile.
    std::size_t col_stride_[2] = {0, 0};
    int tile_w_[2] = {0, 0};
    std::array<cl_int, 7> track_init_{};  // an empty change box, 0 voxels
    // The y and z passes' change boxes read back by update(): members, so that a read still
    // in flight when a later enqueue throws writes into live memory.
    std::array<std::array<cl_int, 7>, 2> track_read_{};
    // --max-distance: the output's bound (+inf: none), the partials' cap in the kernels' own
    // units, and per axis how far (voxels) a site can matter: a whole line when unbounded.
    double max_distance_ = 0;
    cl_uint cap_unit_ = 0;
    cl_ulong cap_wide_ = 0;
    float cap_float_ = 0;
    double cap_double_ = 0;
    std::int64_t reach_[3] = {0, 0, 0};
    std::vector<KernelLaunch> stages_;
};

}  // namespace voxfield::ocl
