#pragma once
// `exact`: global exact Manhattan distance field on any OpenCL device (DESIGN §3 semantics),
// and by the same sweeps the Chebyshev field in the CPU layout.
#include <cstdint>
#include <optional>
#include <span>
#include <string>
#include <vector>

#include "voxfield/cl/generator.hpp"

namespace voxfield::ocl {

class ExactManhattan : public Generator {
  public:
    // Uploads the world and palette; throws ClError (e.g. the device cannot allocate it).
    // `max_distance` D: the bounded field min(exact, floor(D)) (DESIGN §3), from the same
    // sweeps saturating at floor(D).
    ExactManhattan(Context& ctx, const World& world, const Palette& palette, Format format,
                   Layout layout = Layout::automatic, Metric metric = Metric::manhattan,
                   std::optional<double> max_distance = std::nullopt);
    // The same for a world in host memory: `voxels` holds dims.count() palette indices (x
    // fastest). On a device that computes in host memory (Context::computes_in_host_memory)
    // the kernels read it in place, and write the field into `field` where it is given
    // (dims.count() * element_size(format) bytes; elsewhere into host memory of the
    // generator's own): nothing is copied or zero-filled. Elsewhere the world is uploaded and
    // `field` unused. Both must outlive the generator. std::invalid_argument when a size is
    // wrong.
    ExactManhattan(Context& ctx, Dims dims, std::span<const std::uint8_t> voxels,
                   const Palette& palette, Format format, Layout layout = Layout::automatic,
                   Metric metric = Metric::manhattan, std::span<std::uint8_t> field = {},
                   std::optional<double> max_distance = std::nullopt);

    // Over buffers the caller owns and keeps alive: the world `voxels` (dims.count() bytes,
    // read) and the field `out` (in `format`), such as an incremental engine's; only
    // packed32's work buffer and the palette table are allocated.
    ExactManhattan(Context& ctx, Dims dims, const cl::Buffer& voxels, const cl::Buffer& out,
                   const Palette& palette, Format format, Layout layout = Layout::automatic,
                   std::optional<double> max_distance = std::nullopt);

    // Whether these sweeps compute `o` (resolved options) for a world of `dims` on ctx:
    // unsigned fields of unit spacing without indices, bounded or not, in u8, u16, u32 or
    // packed32, manhattan in both layouts, chebyshev in the CPU layout; signed manhattan in
    // the CPU layout, unbounded, i8, i16 or i32. The CPU layout's signed and chebyshev sweeps
    // only where its local memory holds the world's rows and columns. ExactSeparable computes
    // the rest.
    static bool handles(const Context& ctx, const GeneratorOptions& o, Dims dims);
    // The same for the layout `gpu_layout` (as `o.layout` resolves on the device).
    static bool handles(const GeneratorOptions& o, bool gpu_layout);

    // Builds the kernel programs that a generator of `dims` and `format` uses into ctx's
    // program cache, so that a caller can build them while it reads the world.
    static void prepare(Context& ctx, Dims dims, Format format, Layout layout = Layout::automatic,
                        Metric metric = Metric::manhattan,
                        std::optional<double> max_distance = std::nullopt);

    double run() override;
    bool enqueue(std::vector<std::pair<std::string, cl::Event>>& events) override;
    std::string variant() const override;  // "cpu layout" or "gpu layout"
    // The kernels run() launches, in order, cols_seg with its segment length ("x_rows_local",
    // "cols_seg/64", "cols_strip_final", ...): which path a world's shape takes.
    const std::vector<std::string>& kernel_path() const { return path_; }
    // The world on the device (uint8 per voxel); writes to it show in the next run().
    const cl::Buffer& voxels_buffer() const { return voxels_; }

    // The x and y passes as one launch over z-slices in local memory (xy_slice_local, or
    // xy_slice_segments where `segments`), where the transform starts with it and no later
    // launch reads the voxels (every format but packed32): what a launch of the same sweeps
    // over another source of voxels needs (a sparse field's edit block read from its world's
    // trees, sparse_slices.cl): the program's build options, a slice's row stride in local
    // memory, the bytes of its two local arrays (`ends` 0 for xy_slice_local), the launch's
    // ranges and the buffer it writes.
    struct SliceStage {
        bool segments = false;
        std::string options;
        std::uint32_t sx = 0;
        std::size_t slice_bytes = 0, ends_bytes = 0;
        cl::NDRange global, local;
        cl::Buffer work;
    };
    const std::optional<SliceStage>& slice_stage() const { return slice_stage_; }
    // enqueue() without the slice stage, which the caller enqueued in its own form before;
    // std::logic_error where there is none.
    void enqueue_after_slices(std::vector<std::pair<std::string, cl::Event>>& events);

  private:
    // Reads `voxels` in place (`in_place`) or uploads them; `field`: host memory for the
    // output, or empty.
    void allocate(const Palette& palette, const std::uint8_t* voxels, bool in_place,
                  std::span<std::uint8_t> field);
    void set_up_kernels();
    // The byte sweeps into stages_ (false where a slice or a strip does not fit the local
    // memory).
    bool add_byte_sweeps();
    std::optional<KernelLaunch> x_words();  // allocates words_; nullopt where it cannot run

    bool gpu_layout_;
    Metric metric_;
    std::uint32_t cap_;  // the sweeps' saturation (floor(D) of a bounded field)
    cl::Buffer voxels_, rgb_, work_;
    // The kernels of one transform, in enqueue order.
    std::vector<KernelLaunch> stages_;
    // The byte sweeps' flag (a distance cut at 255) and w8; stages_ from fallback_from_ on run
    // only when the flag is set.
    cl::Buffer bytes_, flag_;
    cl::Buffer words_;  // x_words' rows of solid bits (GPU layout, unsigned L1)
    // cols_seg's chunk ends of columns too long for a work-group (GPU layout), per pass.
    std::vector<cl::Buffer> chunk_ends_;
    std::size_t fallback_from_ = SIZE_MAX;
    std::vector<std::string> path_;  // kernel_path(), beside stages_
    std::optional<SliceStage> slice_stage_;
};

}  // namespace voxfield::ocl
