// Exact global Manhattan distance transform, host side (kernels: cl/kernels/exact_manhattan.cl).
#include "voxfield/cl/exact.hpp"

#include "util.hpp"
#include "x_rows.hpp"

#include <algorithm>
#include <array>
#include <cmath>
#include <optional>
#include <stdexcept>
#include <string>

namespace voxfield::cl_sources {
extern const char* const layout_h;
extern const char* const exact_manhattan_cl;
}  // namespace voxfield::cl_sources

namespace voxfield::ocl {
namespace {

struct WorkType {
    const char* name;
    std::uint32_t max;
    std::size_t bytes;
    bool is_signed;  // a signed field (i8, i16, i32: the CPU layout's SIGNED sweeps)
};

WorkType work_type(Format f) {
    switch (f) {
        case Format::u8:
        case Format::packed32:
            return {"uchar", 255u, 1, false};
        case Format::u16:
            return {"ushort", 65535u, 2, false};
        case Format::u32:
            return {"uint", 0xFFFFFFFFu, 4, false};
        case Format::i8:
            return {"char", 127u, 1, true};
        case Format::i16:
            return {"short", 32767u, 2, true};
        case Format::i32:
            return {"int", 0x7FFFFFFFu, 4, true};
        case Format::f32:
        case Format::f64:
            break;
    }
    throw std::invalid_argument(
        "exact_manhattan.cl writes u8, u16, u32, packed32 or a signed "
        "field in i8, i16, i32, not " +
        to_string(f) + " (ExactSeparable writes the others)");
}

// Values per work-item in cols_seg for a column of n voxels: 16 up to 512 voxels, then 32; the y
// pass of 2-byte work (`y_of_2_bytes`) keeps 16 up to 1024. A column of more than 2048 voxels
// takes more than 64 segments, a work-group of up to the kernel's limit (chunks of a
// work-group each beyond it): a sparse field's stacked blocks make z columns of thousands of
// voxels, where a strip in local memory, a work-item a group, took 7.5 of a sand step's 9.8 ms on
// the H100. On the H100, 1024^3 y and z passes took 2.59 and 2.56 ms in u16 with 32 values (32
// segments) against 3.07 and 5.02 with 16 (64 segments) and two columns a work-item. With four
// (44be7a1), 16 values take the u16 y pass from 2.12 to 1.72 ms but the z pass from 2.33 to 2.57;
// the whole 1024^3 u16 field 6.45 -> 6.09 ms, and u8 4.41 -> 4.61 (so u8 keeps 32). At 512^3 16
// values are the faster (0.243 and 0.260 ms against 0.255 and 0.280). 64 values cost registers and
// occupancy (on the H200, 1024^3 u16: 10.7 ms a pass, 3.5 with 16).
std::uint32_t seg_k(std::uint32_t n, bool y_of_2_bytes) {
    return n <= 512 || (n <= 1024 && y_of_2_bytes) ? 16 : 32;
}

bool use_gpu_layout(const Context& ctx, Layout layout) {
    return layout == Layout::automatic ? !ctx.is_cpu() : layout == Layout::gpu;
}

// xy_slices_seq's local bytes for two rows of `bytes`, padded (row_pad) on each side.
std::size_t slices_scratch(std::uint32_t x, std::size_t bytes) {
    return 2 * (std::size_t{x} + 2 * row_pad(x)) * bytes;
}

// Whether the CPU layout's sweeps hold a world's lines in local memory: a row's two sweeps
// with half a row's padding on each side (xy_slices_seq), and a column of the z or y strips.
// On PoCL with 1 MiB of local memory, u32 rows of 65552 voxels needed 1.5 MiB.
bool cpu_lines_fit(const Context& ctx, Dims dims, Format format) {
    const std::size_t bytes = work_type(format).bytes, local = ctx.info().local_mem;
    return slices_scratch(dims.x, bytes) <= local &&
           std::size_t{std::max(dims.y, dims.z)} * bytes <= local;
}

// The layout of a world: the one asked for (or the device's), except that an unsigned L1 field
// whose lines the CPU layout cannot hold takes the GPU layout's kernels, which hold neither
// and run on any device. (Signed fields and L-inf have the CPU layout only: such worlds take
// ExactSeparable, ExactManhattan::handles.)
bool use_gpu_layout(const Context& ctx, Layout layout, Dims dims, Format format, Metric metric) {
    if (use_gpu_layout(ctx, layout)) {
        return true;
    }
    if (work_type(format).is_signed || metric != Metric::manhattan) {
        return false;
    }
    return !cpu_lines_fit(ctx, dims, format);
}

// A bounded field's saturation in the sweeps: floor(D) (the integer formats' min(exact, D)).
std::uint32_t cap_of(std::optional<double> max_distance) {
    return max_distance
               ? static_cast<std::uint32_t>(std::min(std::floor(*max_distance), 4294967295.0))
               : 0xFFFFFFFFu;
}

// Adjacent columns per work-item in cols_seg, loaded and stored as one aligned word: four for
// 1- and 2-byte work (a 4- or 8-byte word) where rows of X elements keep those words aligned,
// else two for u16 (a 4-byte word) where they keep those aligned; otherwise one. On the H100,
// u16 columns take 0.194 and 0.218 ms (y, z) at 512^3 with four against 0.243 and 0.260 with
// two; eight byte columns were slower than four (0.190 and 0.195 ms against 0.160 and 0.159).
std::uint32_t vec_width(Format f, std::uint32_t x) {
    const std::size_t bytes = work_type(f).bytes;
    if (bytes <= 2 && x % 4 == 0) {
        return 4;
    }
    return bytes == 2 && x % 2 == 0 ? 2 : 1;
}

// Work-items along x in a cols_seg group (vw columns each) before the kernel's limits: 8, and for
// 2-byte work on columns of few segments more, up to about 256 work-items a group (at most 64,
// and no more than the row's words). With 8, a column of 64 voxels (4 segments of 16) made groups
// of 32 work-items. On the H100 (bench/README, the section on short u16 columns in larger groups),
// u16 columns of 64 voxels took 0.198 ms instead of 0.279 in long-y's z pass (64 x 32768 x 64) and
// 0.478 instead of 0.505 in long-x's y and z passes, 512^3 unchanged; u8 columns in long-x took
// 0.380 ms instead of 0.263, so 1-byte work keeps 8.
std::uint32_t seg_group_columns(std::uint32_t segs, std::size_t bytes, std::uint32_t row_words) {
    std::uint32_t cw = 8;
    if (bytes == 2) {
        while (cw < 64 && 2 * cw * segs <= 256 && 2 * cw <= row_words) {
            cw *= 2;
        }
    }
    return cw;
}

// Whether a cols_seg group of cw work-items along x (vw columns each, `word` bytes) and n segments
// fits the kernel's work-group limit and the device's local memory (its two arrays of ends).
bool seg_group_fits(std::size_t limit, std::size_t local_mem, std::uint32_t cw, std::uint32_t n,
                    std::size_t word) {
    return std::size_t{cw} * n <= limit && 2 * std::size_t{cw} * n * word <= local_mem;
}

// cols_seg's work-group limit in `program` on the context's device.
std::size_t cols_seg_limit(const Context& ctx, const cl::Program& program) {
    return cl::Kernel(program, "cols_seg")
        .getWorkGroupInfo<CL_KERNEL_WORK_GROUP_SIZE>(ctx.info().device);
}

// The build options of exact_manhattan.cl for format `f`, SEG_K = k, VW = vw and metric m,
// saturating at `cap` where it is below the work type's maximum (T_MAX: every sweep takes the
// minimum with a value that starts at most T_MAX, so the field is min(exact, cap)).
std::string program_options(Format f, std::uint32_t k, std::uint32_t vw, Metric m,
                            std::uint32_t cap, bool from_bits = false, bool empty_targets = false,
                            bool chunks = false) {
    const WorkType wt = work_type(f);
    return "-DT=" + std::string(wt.name) + " -DT_MAX=" + std::to_string(std::min(wt.max, cap)) +
           (wt.is_signed ? "" : "u") + " -DPACKED=" + (f == Format::packed32 ? "1" : "0") +
           " -DSEG_K=" + std::to_string(k) + " -DVW=" + std::to_string(vw) +
           " -DCHEBYSHEV=" + (m == Metric::chebyshev ? "1" : "0") +
           " -DSIGNED=" + (wt.is_signed ? "1" : "0") + " -DFROM_BITS=" + (from_bits ? "1" : "0") +
           " -DROW_TARGETS_EMPTY=" + (empty_targets ? "1" : "0") +
           " -DCHUNKS=" + (chunks ? "1" : "0") + " -cl-std=CL1.2";
}

// The kernels of exact_manhattan.cl built with program_options' options (cached by ctx).
cl::Program build_program(Context& ctx, Format f, std::uint32_t k, std::uint32_t vw, Metric m,
                          std::uint32_t cap, bool from_bits = false, bool empty_targets = false,
                          bool chunks = false) {
    return ctx.program("exact_manhattan.cl", {cl_sources::layout_h, cl_sources::exact_manhattan_cl},
                       program_options(f, k, vw, m, cap, from_bits, empty_targets, chunks));
}

// build_program's CHUNKS=1 build: the program of cols_seg's and x_rows_map's launches over lines
// in chunks.
cl::Program chunk_program(Context& ctx, Format f, std::uint32_t k, std::uint32_t vw, Metric m,
                          std::uint32_t cap, bool empty_targets = false) {
    return build_program(ctx, f, k, vw, m, cap, false, empty_targets, true);
}

// xy_slice_local's row stride in local memory (elements of `bytes`): X, unless rows X apart put
// 8 or more of a warp's 32 work-items (a row each) in one bank at different words; then the least
// above X whose bytes are an odd number of 4-byte words (every work-item its own bank). The
// padded slice costs a division per element in the loads and stores: a sparse field's edit
// block, 49 u8 voxels wide (2 a bank), took 4 us longer padded on an H100.
std::uint32_t slice_stride(std::uint32_t x, std::size_t bytes) {
    std::array<std::vector<std::size_t>, 32> words;
    std::size_t worst = 0;
    for (std::size_t r = 0; r < 32; ++r) {
        const std::size_t word = r * x * bytes / 4;
        auto& bank = words[word % 32];
        if (std::find(bank.begin(), bank.end(), word) == bank.end()) {
            bank.push_back(word);
            worst = std::max(worst, bank.size());
        }
    }
    if (worst < 8) {
        return x;
    }
    std::uint32_t sx = x + 1;
    while (sx * bytes % 8 != 4) {
        ++sx;
    }
    return sx;
}

// xy_slice_segments' `ends` (elements): two per 16-value segment of the pass whose lines have
// several (sweep_local_segments), at least one.
std::size_t slice_ends(Dims dims) {
    const auto segments = [](std::size_t lines, std::size_t n) {
        const std::size_t nseg = (n + 15) / 16;
        return nseg > 1 ? lines * nseg : 0;
    };
    return std::max<std::size_t>(1,
                                 2 * std::max(segments(dims.y, dims.x), segments(dims.x, dims.y)));
}

// Whether the GPU layout takes x and y in one launch (xy_slice_local or _segments): a z-slice of
// the work type within a quarter of the local memory and 16 KiB, its segments' ends beside it, in
// a world of at most kSliceWorldVoxels (a sparse field's edit blocks, small worlds). Larger
// slices, and the slices of larger worlds, take the row and column kernels: on an H100 they ran
// the x and y passes of 64 x 64 x Z worlds faster than xy_slice_local, by 2.5-6 us at 2^23 voxels,
// 14-19 us at 2^24 and 0.08-0.16 ms at 2^27 (long-z), u8 and u16 (bench/README). The bound, half
// the smallest of those, is not timed itself.
constexpr std::uint64_t kSliceWorldVoxels = std::uint64_t{1} << 22;

bool slice_in_local(Dims dims, std::size_t bytes, std::size_t local_mem) {
    const std::size_t slice = std::size_t{slice_stride(dims.x, bytes)} * dims.y * bytes;
    return dims.count() <= kSliceWorldVoxels &&
           slice <= std::min<std::size_t>(local_mem / 4, 16384) &&
           slice + slice_ends(dims) * bytes <= local_mem;
}

// The GPU layout's x pass as bits (x_words, expanded by the y pass's cols_seg): L1 into u32
// with rows of whole 16-voxel words whose positions fit 16 bits. On the H200 it made u32
// 21-25% faster at 512^3 and 1024^3 and u8 and u16 3-12% slower (the expansion costs the y
// pass more than the narrow x pass saves), so it is taken for u32 only.
bool bit_rows(Dims dims, Format f, Metric m, bool gpu_layout) {
    return gpu_layout && m == Metric::manhattan && f == Format::u32 && dims.x % 16 == 0 &&
           dims.x < 0xFFFF;
}

// The CPU layout's L1 and L-inf on bytes (exact_manhattan.cl's U: xy_bytes and z_bytes, or
// xy_slices_seq and z_king_bytes): unsigned u8, u16 and u32 fields (packed32 keeps the wide
// sweeps, which write its colours).
bool byte_sweeps(Format f, Metric m, bool gpu_layout) {
    return !gpu_layout && (m == Metric::manhattan || m == Metric::chebyshev) &&
           (f == Format::u8 || f == Format::u16 || f == Format::u32);
}

// A field whose distances the byte sweeps may have cut at 255: the output holds more and the
// bound (if any) is above 255, so the last byte kernel flags such a value and run() takes the
// wide sweeps.
bool byte_check(Format f, std::uint32_t cap) {
    return f != Format::u8 && cap > 255u;
}

// The byte sweeps' program: T uchar saturating at min(255, cap), U the output type.
cl::Program build_byte_program(Context& ctx, Format f, Metric m, std::uint32_t cap) {
    const std::string options =
        "-DT=uchar -DT_MAX=" + std::to_string(std::min(255u, cap)) + "u -DU=" + work_type(f).name +
        " -DSAT_CHECK=" + (byte_check(f, cap) ? "1" : "0") +
        " -DPACKED=0 -DSEG_K=32 -DVW=1 -DCHEBYSHEV=" + (m == Metric::chebyshev ? "1" : "0") +
        " -DSIGNED=0 -cl-std=CL1.2";
    return ctx.program("exact_manhattan.cl", {cl_sources::layout_h, cl_sources::exact_manhattan_cl},
                       options);
}

// A row kernel (x_words, x_rows_map; arguments in, out, X, the number of rows and two local
// arrays of `local_a` and `local_b` bytes per row) with `segs` work-items per row (per chunk of
// a row, where `chunks` work-groups share each row), each holding `rows_per_item` rows, rows
// stacked to about `group_items` work-items per group; nullopt where `segs` does not fit one
// group.
std::optional<KernelLaunch> row_launch(Context& ctx, cl::Kernel kernel, const char* name,
                                       const cl::Buffer& in, const cl::Buffer& out, Dims dims,
                                       std::size_t segs, std::size_t group_items,
                                       std::size_t rows_per_item, std::size_t local_a,
                                       std::size_t local_b, std::size_t chunks = 1) {
    const auto& info = ctx.info();
    const std::size_t limit = kernel.getWorkGroupInfo<CL_KERNEL_WORK_GROUP_SIZE>(info.device);
    const std::size_t rows = std::size_t{dims.y} * dims.z;
    const std::size_t group_rows = std::max<std::size_t>(1, std::min(group_items, limit) / segs);
    const std::size_t held = group_rows * rows_per_item;  // rows a group holds
    if (segs > limit || held * (local_a + local_b) > info.local_mem) {
        return std::nullopt;
    }
    kernel.setArg(0, in);
    kernel.setArg(1, out);
    kernel.setArg(2, dims.x);
    kernel.setArg(3, static_cast<cl_uint>(rows));
    kernel.setArg(4, cl::Local(held * local_a));
    kernel.setArg(5, cl::Local(held * local_b));
    return KernelLaunch{name, kernel,
                        cl::NDRange(segs * chunks, round_up(rows, held) / rows_per_item),
                        cl::NDRange(segs, group_rows)};
}

// Rows of more than kMapRowSegs segments (16 voxels each) take x_rows_map in chunks of
// kMapChunkSegs segments: a GPU's work-group holds at most 1024 work-items, and PoCL's 4096
// would keep every test row from the chunks.
constexpr std::size_t kMapRowSegs = 1024;
constexpr std::size_t kMapChunkSegs = 128;

// Whether rows of 16-voxel words take x_rows_map in chunks.
bool map_rows_in_chunks(Dims dims) {
    return dims.x / 16 > kMapRowSegs;
}

// x_rows_map: X / 16 work-items per row, each holding two rows, rows stacked to about 128
// work-items per group (in the experiments on an H100, 1024^3 u16, two rows an item in groups
// of 128 took 1.28 ms, a row an item 1.37 in groups of 128 and 1.39 in groups of 64); its local
// arrays are each row's segment masks (2 bytes a segment) and flags (a byte a segment, rows
// padded to 16). Longer rows in chunks of kMapChunkSegs segments, a work-group each, in two
// launches: x_rows_ends publishes each chunk's last and first target, x_rows_chunks sweeps
// every chunk from its own and, where it has none on a side, the nearest other chunk's (the
// row read twice, written once).
// The chunks' launches come from a program of their own (chunk_program), as cols_seg's.
std::optional<XRows> map_rows(Context& ctx, Format format, std::uint32_t cap, bool empty_targets,
                              const cl::Buffer& voxels, const cl::Buffer& work, Dims dims) {
    const std::size_t row_segs = dims.x / 16;
    auto launch = [&](const char* name, const cl::Program& from, std::size_t segs,
                      std::size_t chunks, cl_uint mode, const cl::Buffer& ends) {
        cl::Kernel kernel(from, "x_rows_map");
        kernel.setArg(6, ends);
        kernel.setArg(7, mode);
        return row_launch(ctx, kernel, name, voxels, work, dims, segs, 128, 2, segs * 2,
                          round_up(segs, 16), chunks);
    };
    if (!map_rows_in_chunks(dims)) {
        const cl::Program program =
            build_program(ctx, format, 32, 1, Metric::manhattan, cap, false, empty_targets);
        if (auto whole = launch("x_rows_map", program, row_segs, 1, 0, work)) {
            return XRows{{*whole}, cl::Buffer()};
        }
    }
    const std::size_t chunks = (row_segs + kMapChunkSegs - 1) / kMapChunkSegs;
    const std::size_t rows = std::size_t{dims.y} * dims.z;
    cl::Buffer ends(ctx.context(), CL_MEM_READ_WRITE, rows * chunks * 8);
    const cl::Program in_chunks =
        chunk_program(ctx, format, 32, 1, Metric::manhattan, cap, empty_targets);
    auto publish = launch("x_rows_ends", in_chunks, kMapChunkSegs, chunks, 1, ends);
    auto sweep = launch("x_rows_chunks", in_chunks, kMapChunkSegs, chunks, 2, ends);
    if (!publish || !sweep) {
        return std::nullopt;
    }
    return XRows{{*publish, *sweep}, ends};
}

}  // namespace

XRows gpu_x_rows(Context& ctx, Dims dims, Format format, const cl::Buffer& voxels,
                 const cl::Buffer& work, std::uint32_t cap, bool empty_targets) {
    const auto& info = ctx.info();
    const cl::Program base =
        build_program(ctx, format, 32, 1, Metric::manhattan, cap, false, empty_targets);
    const std::size_t rows = std::size_t{dims.y} * dims.z;
    if (dims.x % 16 == 0) {
        // x_rows_map: 16 voxels of two rows per work-item (one aligned word each).
        if (auto rows_map = map_rows(ctx, format, cap, empty_targets, voxels, work, dims)) {
            return *rows_map;
        }
    }
    // Ragged rows (or rows too long for x_rows_map) in x_rows_local: about 16 voxels per
    // work-item, up to 32 work-items per row, rows stacked to 256 work-items per group.
    const std::size_t per_row = std::clamp<std::size_t>(next_pow2(dims.x) / 16, 1, 32);
    cl::Kernel x_rows(base, "x_rows_local");
    const std::size_t x_limit =
        std::min<std::size_t>(256, x_rows.getWorkGroupInfo<CL_KERNEL_WORK_GROUP_SIZE>(info.device));
    const std::size_t group_rows = std::max<std::size_t>(1, x_limit / per_row);
    const std::size_t span = dims.x + dims.x / 32 + 1;
    const std::size_t x_local_bytes = group_rows * (span * 5 + 2 * per_row * 4);
    if (per_row > x_limit || x_local_bytes > info.local_mem) {
        // Rows longer still: a work-item per row, sweeping in place in global memory.
        cl::Kernel long_rows(base, "x_rows_long");
        long_rows.setArg(0, voxels);
        long_rows.setArg(1, work);
        long_rows.setArg(2, dims.x);
        long_rows.setArg(3, static_cast<cl_uint>(rows));
        return XRows{{KernelLaunch{"x_rows_long", long_rows, cl::NDRange(round_up(rows, 64)),
                                   cl::NDRange(64)}},
                     cl::Buffer()};
    }
    x_rows.setArg(0, voxels);
    x_rows.setArg(1, work);
    x_rows.setArg(2, dims.x);
    x_rows.setArg(3, static_cast<cl_uint>(rows));
    x_rows.setArg(4, static_cast<cl_uint>(per_row));
    x_rows.setArg(5, cl::Local(group_rows * span));
    x_rows.setArg(6, cl::Local(group_rows * span * 4));
    x_rows.setArg(7, cl::Local(group_rows * per_row * 4));
    x_rows.setArg(8, cl::Local(group_rows * per_row * 4));
    return XRows{
        {KernelLaunch{"x_rows_local", x_rows, cl::NDRange(round_up(rows, group_rows) * per_row),
                      cl::NDRange(group_rows * per_row)}},
        cl::Buffer()};
}

ExactManhattan::ExactManhattan(Context& ctx, Dims dims, const cl::Buffer& voxels,
                               const cl::Buffer& out, const Palette& palette, Format format,
                               Layout layout, std::optional<double> max_distance)
    : Generator(ctx, dims, format),
      gpu_layout_(use_gpu_layout(ctx, layout, dims, format, Metric::manhattan)),
      metric_(Metric::manhattan),
      cap_(cap_of(max_distance)) {
    const WorkType wt = work_type(format_);
    cl_call("setting up exact_manhattan.cl over given buffers, world " + dims_.to_string(), [&] {
        voxels_ = voxels;
        out_ = out;
        work_ = format_ == Format::packed32
                    ? make_buffer(dims_.count() * wt.bytes, CL_MEM_READ_WRITE)
                    : out_;
        rgb_ = cl::Buffer(ctx_.context(), CL_MEM_READ_ONLY, 256);
        const auto table = palette.rgb332_table();
        ctx_.queue().enqueueWriteBuffer(rgb_, CL_TRUE, 0, table.size(), table.data());
    });
    set_up_kernels();
}

bool ExactManhattan::handles(const Context& ctx, const GeneratorOptions& o, Dims dims) {
    // Where the layout these sweeps would take for the world is the CPU layout, only if its
    // local memory holds the world's lines (unsigned L1 switches to the GPU layout where it
    // does not; signed L1 and L-inf have no other).
    return handles(o, use_gpu_layout(ctx, o.layout)) &&
           (use_gpu_layout(ctx, o.layout, dims, o.format, o.metric) ||
            cpu_lines_fit(ctx, dims, o.format));
}

bool ExactManhattan::handles(const GeneratorOptions& o, bool gpu_layout) {
    const bool sweepable_format = o.format == Format::u8 || o.format == Format::u16 ||
                                  o.format == Format::u32 || o.format == Format::packed32;
    if (!o.spacing.unit() || o.indices) {
        return false;
    }
    if (o.signed_field) {
        // Signed L1 in one set of sweeps (SIGNED), CPU layout, unbounded, i8/i16/i32.
        const bool signed_format =
            o.format == Format::i8 || o.format == Format::i16 || o.format == Format::i32;
        return signed_format && !gpu_layout && o.metric == Metric::manhattan &&
               !o.max_distance.has_value();
    }
    if (!sweepable_format) {
        return false;
    }
    return o.metric == Metric::manhattan || (o.metric == Metric::chebyshev && !gpu_layout);
}

ExactManhattan::ExactManhattan(Context& ctx, const World& world, const Palette& palette,
                               Format format, Layout layout, Metric metric,
                               std::optional<double> max_distance)
    : Generator(ctx, world.dims(), format),
      gpu_layout_(use_gpu_layout(ctx, layout, world.dims(), format, metric)),
      metric_(metric),
      cap_(cap_of(max_distance)) {
    allocate(palette, world.voxels().data(), false, {});
    set_up_kernels();
}

ExactManhattan::ExactManhattan(Context& ctx, Dims dims, std::span<const std::uint8_t> voxels,
                               const Palette& palette, Format format, Layout layout, Metric metric,
                               std::span<std::uint8_t> field, std::optional<double> max_distance)
    : Generator(ctx, dims, format),
      gpu_layout_(use_gpu_layout(ctx, layout, dims, format, metric)),
      metric_(metric),
      cap_(cap_of(max_distance)) {
    if (voxels.size() != dims.count()) {
        throw std::invalid_argument("ExactManhattan: " + std::to_string(voxels.size()) +
                                    " bytes of voxels for a world of " + dims.to_string());
    }
    if (!field.empty() && field.size() != dims.count() * element_size(format)) {
        throw std::invalid_argument("ExactManhattan: " + std::to_string(field.size()) +
                                    " bytes for a " + to_string(format) + " field of " +
                                    dims.to_string());
    }
    const bool in_place = ctx.computes_in_host_memory();
    allocate(palette, voxels.data(), in_place, in_place ? field : std::span<std::uint8_t>());
    set_up_kernels();
}

void ExactManhattan::prepare(Context& ctx, Dims dims, Format format, Layout layout, Metric metric,
                             std::optional<double> max_distance) {
    const std::uint32_t cap = cap_of(max_distance);
    build_program(ctx, format, 32, 1, metric, cap);
    const bool gpu_layout = use_gpu_layout(ctx, layout, dims, format, metric);
    if (byte_sweeps(format, metric, gpu_layout)) {
        build_byte_program(ctx, format, metric, cap);
    }
    if (gpu_layout) {
        // Rows too long for one x_rows_map group take it in chunks (gpu_x_rows).
        if (dims.x % 16 == 0 && map_rows_in_chunks(dims)) {
            chunk_program(ctx, format, 32, 1, Metric::manhattan, cap);
        }
        const bool two_bytes = work_type(format).bytes == 2;
        const std::uint32_t vw = vec_width(format, dims.x);
        const std::size_t word = vw * work_type(format).bytes;
        for (const auto& [len, y_of_2_bytes] : {std::pair{dims.y, two_bytes}, {dims.z, false}}) {
            const std::uint32_t k = seg_k(len, y_of_2_bytes);
            const cl::Program source = build_program(ctx, format, k, vw, metric, cap);
            // Columns of more segments than one column's group holds take chunks (set-up's
            // columns), from their own program.
            if (!seg_group_fits(cols_seg_limit(ctx, source), ctx.info().local_mem, 1,
                                (len + k - 1) / k, word)) {
                chunk_program(ctx, format, k, vw, metric, cap);
            }
        }
        if (bit_rows(dims, format, metric, true)) {
            build_program(ctx, format, seg_k(dims.y, false), vec_width(format, dims.x), metric, cap,
                          true);
        }
    }
}

void ExactManhattan::allocate(const Palette& palette, const std::uint8_t* voxels, bool in_place,
                              std::span<std::uint8_t> field) {
    const auto& info = ctx_.info();
    const WorkType wt = work_type(format_);
    const std::size_t n = dims_.count();
    const std::size_t out_bytes = n * element_size(format_);
    const std::string sizes = "world " + dims_.to_string() + ", format " + to_string(format_);
    if (out_bytes > info.max_alloc || n > info.max_alloc) {
        throw ClError("clCreateBuffer", CL_INVALID_BUFFER_SIZE,
                      sizes + " needs a " + std::to_string(out_bytes >> 20) + " MiB buffer; " +
                          info.name + " allows at most " + std::to_string(info.max_alloc >> 20) +
                          " MiB per buffer");
    }
    cl_call("allocating and uploading, " + sizes, [&] {
        auto& q = ctx_.queue();
        // CL_MEM_READ_ONLY: the kernels never write the world they read in place.
        voxels_ = in_place ? cl::Buffer(ctx_.context(), CL_MEM_READ_ONLY | CL_MEM_USE_HOST_PTR, n,
                                        const_cast<std::uint8_t*>(voxels))
                           : make_buffer(n, CL_MEM_READ_ONLY);
        out_ = field.empty() ? make_buffer(out_bytes, CL_MEM_READ_WRITE)
                             : cl::Buffer(ctx_.context(), CL_MEM_READ_WRITE | CL_MEM_USE_HOST_PTR,
                                          out_bytes, field.data());
        work_ = format_ == Format::packed32 ? make_buffer(n * wt.bytes, CL_MEM_READ_WRITE) : out_;
        rgb_ = cl::Buffer(ctx_.context(), CL_MEM_READ_ONLY, 256);
        const auto table = palette.rgb332_table();
        cl::Event up_vox, up_rgb;
        if (!in_place) {
            q.enqueueWriteBuffer(voxels_, CL_FALSE, 0, n, voxels, nullptr, &up_vox);
        }
        q.enqueueWriteBuffer(rgb_, CL_FALSE, 0, table.size(), table.data(), nullptr, &up_rgb);
        q.finish();
        upload_ms_ = elapsed_ms(in_place ? up_rgb : up_vox, up_rgb);
    });
}

void ExactManhattan::set_up_kernels() {
    const auto& info = ctx_.info();
    const WorkType wt = work_type(format_);
    const std::string sizes = "world " + dims_.to_string() + ", format " + to_string(format_);
    if (metric_ != Metric::manhattan && (metric_ != Metric::chebyshev || gpu_layout_)) {
        throw std::invalid_argument("exact_manhattan.cl computes " + to_string(metric_) +
                                    " fields in the " + variant() + " only through ExactSeparable");
    }
    if (wt.is_signed && (gpu_layout_ || metric_ != Metric::manhattan || cap_ != 0xFFFFFFFFu)) {
        throw std::invalid_argument("exact_manhattan.cl computes signed fields (" +
                                    to_string(format_) +
                                    ") only unbounded, manhattan, in the cpu layout; the " +
                                    variant() + " takes them through ExactSeparable");
    }
    auto program = [&](std::uint32_t k, std::uint32_t vw) {
        return build_program(ctx_, format_, k, vw, metric_, cap_);
    };
    const cl::Program base = program(32, 1);
    const std::size_t plane = std::size_t{dims_.x} * dims_.y;
    std::uint32_t seg_used = 0;  // the segment length of the last cols_seg that columns() made
    auto add = [&](const KernelLaunch& launch) {
        stages_.push_back(launch);
        path_.push_back(launch.name == "cols_seg" || launch.name == "cols_bits"
                            ? launch.name + "/" + std::to_string(seg_used)
                            : launch.name);
    };
    cl_call("setting up kernels, " + sizes, [&] {
        // Columns of length len with element stride `stride`, lines of columns `m_count`
        // apart by `m_stride`; `final` writes the output format. Empty where `bits` (the y
        // pass from x_words' rows) cannot take cols_bits: the caller takes the row kernels.
        auto columns = [&](std::uint32_t len, std::uint64_t stride, std::uint64_t m_stride,
                           std::size_t m_count, bool final,
                           bool bits = false) -> std::vector<KernelLaunch> {
            // Arguments 0-7 are common to cols_seg and cols_strip.
            auto column_kernel = [&](const cl::Program& source, const char* name) {
                cl::Kernel kernel(source, name);
                kernel.setArg(0, work_);
                kernel.setArg(1, out_);
                kernel.setArg(2, voxels_);
                kernel.setArg(3, rgb_);
                kernel.setArg(4, dims_.x);
                kernel.setArg(5, len);
                kernel.setArg(6, static_cast<cl_ulong>(stride));
                kernel.setArg(7, static_cast<cl_ulong>(m_stride));
                return kernel;
            };
            if (gpu_layout_) {
                const std::uint32_t k = seg_k(len, !final && !bits && wt.bytes == 2);
                const std::uint32_t segs = (len + k - 1) / k;
                // As many work-items along x per group as the kernel's registers allow (up to
                // 8, more for short u16 columns: seg_group_columns), each holding vw adjacent
                // columns.
                const std::uint32_t vw = vec_width(format_, dims_.x);
                const cl::Program source = build_program(ctx_, format_, k, vw, metric_, cap_, bits);
                // cols_seg over `g` chunks of `n` segments, cw columns a group (`chunks`: the
                // kernel's argument of that name; ends: its buffer, where chunks is nonzero).
                const std::size_t word = std::size_t{vw} * wt.bytes;
                auto seg_launch = [&](const char* name, const cl::Program& from, std::uint32_t cw,
                                      std::uint32_t n, std::uint32_t g, cl_uint chunks,
                                      const cl::Buffer& ends) {
                    cl::Kernel seg = column_kernel(from, "cols_seg");
                    seg.setArg(8, cl_uint{final ? 1u : 0u});
                    seg.setArg(9, cl::Local(std::size_t{cw} * n * word));
                    seg.setArg(10, cl::Local(std::size_t{cw} * n * word));
                    seg.setArg(11, chunks != 0 ? ends : work_);
                    seg.setArg(12, chunks);
                    if (bits) {
                        seg.setArg(13, words_);
                        seg.setArg(14, static_cast<cl_uint>((dims_.x + 31) / 32));
                    }
                    return KernelLaunch{
                        name, seg,
                        cl::NDRange(round_up(dims_.x / vw, cw), std::size_t{n} * g, m_count),
                        cl::NDRange(cw, n, 1)};
                };
                const std::size_t limit = cols_seg_limit(ctx_, source);
                std::uint32_t cw = seg_group_columns(segs, wt.bytes, dims_.x / vw);
                while (cw > 1 && !seg_group_fits(limit, info.local_mem, cw, segs, word)) {
                    cw /= 2;
                }
                if (seg_group_fits(limit, info.local_mem, cw, segs, word)) {
                    seg_used = k;
                    return {
                        seg_launch(bits ? "cols_bits" : "cols_seg", source, cw, segs, 1, 0, work_)};
                }
                if (bits) {
                    return {};
                }
                // Columns of more segments than a work-group holds: chunks of a power of two of
                // segments, 8 columns a group (4 or 2 where the kernel allows fewer work-items),
                // any length. cols_chunk_ends publishes each chunk's ends, cols_chunks sweeps
                // every chunk from the others' (the column read twice, written once). A
                // work-item per column (in place in global memory) took 24 ms for long-z's 64 x
                // 64 x 32768 L1 u16 on the H200, where 512^3 takes 0.5.
                const cl::Program chunked = chunk_program(ctx_, format_, k, vw, metric_, cap_);
                const std::size_t chunk_limit = cols_seg_limit(ctx_, chunked);
                cw = 8;
                while (cw > 2 && chunk_limit / cw < 2) {
                    cw /= 2;
                }
                std::uint32_t n = static_cast<std::uint32_t>(next_pow2(chunk_limit / cw + 1) / 2);
                while (n > 1 && !seg_group_fits(chunk_limit, info.local_mem, cw, n, word)) {
                    n /= 2;
                }
                const std::uint32_t g = (segs + n - 1) / n;
                // (Kept by the generator: a kernel argument does not keep its buffer.)
                const cl::Buffer& ends = chunk_ends_.emplace_back(
                    make_buffer(2 * std::size_t{g} * round_up(dims_.x / vw, cw) * m_count * word,
                                CL_MEM_READ_WRITE));
                seg_used = k;
                return {seg_launch("cols_chunk_ends", chunked, cw, n, g, 1, ends),
                        seg_launch("cols_chunks", chunked, cw, n, g, 2, ends)};
            }
            // A strip of x positions per work-item, its columns copied to local scratch: the
            // whole row (the inner loop vectorises, the strip stays in L2).
            const std::size_t per_x = std::size_t{len} * wt.bytes;
            const std::size_t budget = std::min<std::size_t>(info.local_mem / 2, 512 * 1024);
            if (per_x > info.local_mem) {
                throw ClError("clEnqueueNDRangeKernel", CL_OUT_OF_RESOURCES,
                              sizes + ": a column of " + std::to_string(len) +
                                  " voxels does not fit the local memory of " + info.name);
            }
            auto strip = static_cast<std::uint32_t>(
                std::clamp<std::size_t>(budget / per_x / 16 * 16, 1, dims_.x));
            const std::size_t want_items = 4 * std::size_t{info.compute_units};
            while (strip > 16 && ((dims_.x + strip - 1) / strip) * m_count < want_items) {
                strip = std::max<std::uint32_t>(16, strip / 2);
            }
            const char* name = final ? "cols_strip_final" : "cols_strip";
            cl::Kernel kernel = column_kernel(base, name);
            kernel.setArg(8, strip);
            kernel.setArg(9, cl::Local(per_x * strip));
            return {{name, kernel, cl::NDRange((dims_.x + strip - 1) / strip, m_count),
                     cl::NDRange(1, 1)}};
        };

        if (byte_sweeps(format_, metric_, gpu_layout_) && add_byte_sweeps()) {
            if (!byte_check(format_, cap_)) {
                return;
            }
            // The wide sweeps below run only where the byte sweeps flag a distance of 255 or
            // more.
            fallback_from_ = stages_.size();
        }
        bool rows_on_gpu = false;
        if (gpu_layout_ && slice_in_local(dims_, wt.bytes, info.local_mem)) {
            // x and y in one launch, a work-group per z-slice in local memory: by segments of
            // lines where the slices fit in one wave of the compute units (each group's chain is
            // the time), else by lines (fewer instructions, the device full).
            const bool segments = dims_.z <= info.compute_units;
            const char* name = segments ? "xy_slice_segments" : "xy_slice_local";
            cl::Kernel xy(base, name);
            // 256 work-items (fewer where the kernel allows fewer): the slice's loads spread
            // wide.
            const std::size_t group = std::min<std::size_t>(
                256, xy.getWorkGroupInfo<CL_KERNEL_WORK_GROUP_SIZE>(info.device));
            xy.setArg(0, voxels_);
            xy.setArg(1, work_);
            const std::uint32_t sx = slice_stride(dims_.x, wt.bytes);
            xy.setArg(2, dims_.x);
            xy.setArg(3, dims_.y);
            xy.setArg(4, sx);
            xy.setArg(5, cl::Local(std::size_t{sx} * dims_.y * wt.bytes));
            if (segments) {
                xy.setArg(6, cl::Local(slice_ends(dims_) * wt.bytes));
            }
            // (packed32's last pass colours the field from the voxels: no other source.)
            if (stages_.empty() && format_ != Format::packed32) {
                slice_stage_ = SliceStage{segments,
                                          program_options(format_, 32, 1, metric_, cap_),
                                          sx,
                                          std::size_t{sx} * dims_.y * wt.bytes,
                                          segments ? slice_ends(dims_) * wt.bytes : 0,
                                          cl::NDRange(group * dims_.z),
                                          cl::NDRange(group),
                                          work_};
            }
            add({name, xy, cl::NDRange(group * dims_.z), cl::NDRange(group)});
            rows_on_gpu = true;
        }
        if (!rows_on_gpu && gpu_layout_ && bit_rows(dims_, format_, metric_, true)) {
            if (auto words = x_words()) {
                const std::vector<KernelLaunch> y =
                    columns(dims_.y, dims_.x, plane, dims_.z, false, true);
                if (!y.empty()) {
                    add(*words);
                    add(y.front());
                    rows_on_gpu = true;
                } else {
                    words_ = cl::Buffer();
                }
            }
        }
        if (gpu_layout_ && !rows_on_gpu) {
            XRows x = gpu_x_rows(ctx_, dims_, format_, voxels_, work_, cap_);
            for (const KernelLaunch& launch : x.launches) {
                add(launch);
            }
            if (x.ends()) {
                chunk_ends_.push_back(x.ends);
            }
            for (const KernelLaunch& y : columns(dims_.y, dims_.x, plane, dims_.z, false)) {
                add(y);
            }
            rows_on_gpu = true;
        }
        if (!rows_on_gpu) {
            const std::size_t scratch = slices_scratch(dims_.x, wt.bytes);
            if (scratch > info.local_mem) {
                throw ClError("clEnqueueNDRangeKernel", CL_OUT_OF_RESOURCES,
                              sizes + ": rows of " + std::to_string(dims_.x) +
                                  " voxels do not fit the local memory of " + info.name);
            }
            cl::Kernel xy(base, "xy_slices_seq");
            xy.setArg(0, voxels_);
            xy.setArg(1, work_);
            xy.setArg(2, dims_.x);
            xy.setArg(3, dims_.y);
            xy.setArg(4, static_cast<cl_uint>(row_pad(dims_.x)));
            xy.setArg(5, cl::Local(scratch));
            add({"xy_slices_seq", xy, cl::NDRange(dims_.z),
                 gpu_layout_ ? cl::NullRange : cl::NDRange(1)});
        }
        if (metric_ == Metric::chebyshev) {
            // L-inf's nine z moves in one sweep over the planes each way, in one work-item
            // (the planes depend on each other in turn); a row's column minima in local
            // memory.
            cl::Kernel k(base, "z_king");
            k.setArg(0, work_);
            k.setArg(1, out_);
            k.setArg(2, voxels_);
            k.setArg(3, rgb_);
            k.setArg(4, dims_.x);
            k.setArg(5, dims_.y);
            k.setArg(6, dims_.z);
            k.setArg(7, cl_uint{1});
            k.setArg(8, cl::Local((std::size_t{dims_.x} + 2) * wt.bytes));
            add({"z_king", k, cl::NDRange(1), cl::NDRange(1)});
        } else {
            for (const KernelLaunch& z : columns(dims_.z, plane, dims_.x, dims_.y, true)) {
                add(z);
            }
        }
    });
}

std::optional<KernelLaunch> ExactManhattan::x_words() {
    const std::size_t w = (std::size_t{dims_.x} + 31) / 32;
    words_ = make_buffer(std::size_t{dims_.y} * dims_.z * w * sizeof(cl_uint2), CL_MEM_READ_WRITE);
    const cl::Program base = build_program(ctx_, format_, 32, 1, metric_, cap_);
    auto launch = row_launch(ctx_, cl::Kernel(base, "x_words"), "x_words", voxels_, words_, dims_,
                             w, 256, 1, w * sizeof(cl_int), w * sizeof(cl_int));
    if (!launch) {
        words_ = cl::Buffer();
    }
    return launch;
}

bool ExactManhattan::add_byte_sweeps() {
    const auto& info = ctx_.info();
    const std::size_t plane = std::size_t{dims_.x} * dims_.y;
    const std::size_t x64 = (std::size_t{dims_.x} + 63) / 64 * 64;  // xy_bytes' row length
    const std::size_t slice = (x64 + 32) * dims_.y;
    if (x64 + 32 + slice > info.local_mem || dims_.z > info.local_mem) {
        return false;
    }
    const cl::Program bytes = build_byte_program(ctx_, format_, metric_, cap_);
    bytes_ = make_buffer(dims_.count(), CL_MEM_READ_WRITE);
    flag_ = cl::Buffer(ctx_.context(), CL_MEM_READ_WRITE, sizeof(cl_uint));
    cl::Kernel xy(bytes, "xy_bytes");
    xy.setArg(0, voxels_);
    xy.setArg(1, bytes_);
    xy.setArg(2, flag_);
    xy.setArg(3, dims_.x);
    xy.setArg(4, dims_.y);
    xy.setArg(5, cl::Local(x64 + 32));
    xy.setArg(6, cl::Local(slice));
    stages_.push_back({"xy_bytes", xy, cl::NDRange(dims_.z), cl::NDRange(1)});
    path_.push_back("xy_bytes");
    if (metric_ == Metric::chebyshev) {
        // L-inf's z moves over whole planes in one work-item, as z_king.
        cl::Kernel z(bytes, "z_king_bytes");
        z.setArg(0, bytes_);
        z.setArg(1, out_);
        z.setArg(2, flag_);
        z.setArg(3, dims_.x);
        z.setArg(4, dims_.y);
        z.setArg(5, dims_.z);
        z.setArg(6, cl::Local(std::size_t{dims_.x} + 2));
        stages_.push_back({"z_king_bytes", z, cl::NDRange(1), cl::NDRange(1)});
        path_.push_back("z_king_bytes");
        return true;
    }
    // z_bytes' strips: a whole number of 64-byte lines, their columns (chunk * Z bytes) within
    // 1 MiB so that the backward sweep reads them from L2, and at least 4 strips per core.
    std::size_t chunk =
        std::min<std::size_t>(plane, std::max<std::size_t>(64, (1024 * 1024) / dims_.z / 64 * 64));
    const std::size_t want_items = 4 * std::size_t{info.compute_units};
    while (chunk > 64 && (plane + chunk - 1) / chunk < want_items) {
        chunk = std::max<std::size_t>(64, chunk / 2 / 64 * 64);
    }
    chunk = std::min(chunk, info.local_mem / dims_.z);
    cl::Kernel z(bytes, "z_bytes");
    z.setArg(0, bytes_);
    z.setArg(1, out_);
    z.setArg(2, flag_);
    z.setArg(3, static_cast<cl_ulong>(plane));
    z.setArg(4, dims_.z);
    z.setArg(5, static_cast<cl_uint>(chunk));
    z.setArg(6, cl::Local(chunk * dims_.z));
    stages_.push_back({"z_bytes", z, cl::NDRange((plane + chunk - 1) / chunk), cl::NDRange(1)});
    path_.push_back("z_bytes");
    return true;
}

std::string ExactManhattan::variant() const {
    return gpu_layout_ ? "gpu layout" : "cpu layout";
}

bool ExactManhattan::enqueue(std::vector<std::pair<std::string, cl::Event>>& events) {
    if (fallback_from_ < stages_.size()) {
        return false;  // run() reads the byte sweeps' flag in between
    }
    cl_call("enqueueing exact_manhattan.cl on " + dims_.to_string(),
            [&] { enqueue_stages(stages_, events, stage_events_); });
    return true;
}

void ExactManhattan::enqueue_after_slices(std::vector<std::pair<std::string, cl::Event>>& events) {
    if (!slice_stage_) {
        throw std::logic_error("ExactManhattan::enqueue_after_slices without a slice stage");
    }
    cl_call("enqueueing exact_manhattan.cl after its slices on " + dims_.to_string(), [&] {
        enqueue_stages(std::span<const KernelLaunch>(stages_).subspan(1), events, stage_events_);
    });
}

double ExactManhattan::run() {
    return cl_call("running exact_manhattan.cl on " + dims_.to_string(), [&] {
        auto& q = ctx_.queue();
        const std::span<const KernelLaunch> stages(stages_);
        const std::size_t first = std::min(fallback_from_, stages.size());
        std::vector<std::pair<std::string, cl::Event>> events;
        enqueue_stages(stages.first(first), events);
        if (first < stages.size()) {
            cl_uint cut = 0;
            q.enqueueReadBuffer(flag_, CL_TRUE, 0, sizeof cut, &cut);
            if (cut != 0) {
                enqueue_stages(stages.subspan(first), events);
            }
        }
        q.finish();
        record_stages(events);
        return elapsed_ms(events.front().second, events.back().second);
    });
}

}  // namespace voxfield::ocl
