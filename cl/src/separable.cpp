// Exact separable transforms of every metric, host side (kernels: cl/kernels/exact_separable.cl,
// Meijster, Roerdink & Hesselink 2000).
#include "voxfield/cl/separable.hpp"

#include <algorithm>
#include <cmath>
#include <limits>
#include <stdexcept>
#include <string>

#include "util.hpp"
#include "x_rows.hpp"

namespace voxfield::cl_sources {
extern const char* const layout_h;
extern const char* const exact_separable_cl;
}  // namespace voxfield::cl_sources

namespace voxfield::ocl {
namespace {

struct OutType {
    int kind;  // OUT_KIND of the kernel
    const char* type;
    const char* max;
};

OutType out_type(Format f) {
    switch (f) {
        case Format::u8:
            return {0, "uchar", "255u"};
        case Format::u16:
            return {0, "ushort", "65535u"};
        case Format::u32:
            return {0, "uint", "4294967295u"};
        case Format::packed32:
            return {4, "uint", "255u"};
        case Format::i8:
            return {1, "char", "127"};
        case Format::i16:
            return {1, "short", "32767"};
        case Format::i32:
            return {1, "int", "2147483647"};
        case Format::f32:
            return {2, "float", "0"};
        case Format::f64:
            return {3, "double", "0"};
    }
    return {0, "uint", "4294967295u"};
}

// x_pass's scratch ints per work-item: in the CPU layout row_doubling's two rows of X + 2 P
// (P = row_pad(X), its largest step), in the GPU layout row_nearest's X.
std::size_t x_stride(bool gpu_layout, std::size_t X) {
    return gpu_layout ? X : 2 * (X + 2 * row_pad(X));
}

}  // namespace

bool ExactSeparable::needed(const GeneratorOptions& o) {
    return o.metric != Metric::manhattan || !o.spacing.unit() || o.signed_field || o.indices ||
           o.max_distance.has_value() || holds_sign(o.format);
}

ExactSeparable::ExactSeparable(Context& ctx, const World& world, const Palette& palette,
                               const GeneratorOptions& options, bool incremental,
                               std::uint32_t z_period)
    : Generator(ctx, world.dims(), options.format),
      gpu_layout_(options.layout == Layout::automatic ? !ctx.is_cpu()
                                                      : options.layout == Layout::gpu),
      incremental_(incremental),
      z_period_(z_period),
      spacing_(options.spacing) {
    if (z_period != 0 && (world.dims().z % z_period != 0 || incremental || options.indices)) {
        throw std::invalid_argument(
            "ExactSeparable: a z period of " + std::to_string(z_period) + " for a world of " +
            world.dims().to_string() + (incremental ? ", incremental" : "") +
            (options.indices ? ", with indices" : "") +
            " (it must divide the world's z and serve a full transform without indices)");
    }
    // Uploaded: the generator owns its copy (incremental edits rewrite it), so the world
    // need not outlive it. Reading in place is the span constructor's explicit choice.
    set_up(world.voxels().data(), false, {}, {}, palette, options);
}

ExactSeparable::ExactSeparable(Context& ctx, Dims dims, std::span<const std::uint8_t> voxels,
                               const Palette& palette, const GeneratorOptions& options,
                               std::span<std::uint8_t> field, std::span<std::int32_t> indices,
                               bool zero_targets)
    : Generator(ctx, dims, options.format),
      gpu_layout_(options.layout == Layout::automatic ? !ctx.is_cpu()
                                                      : options.layout == Layout::gpu),
      zero_targets_(zero_targets),
      incremental_(false),
      spacing_(options.spacing) {
    if (voxels.size() != dims.count()) {
        throw std::invalid_argument("ExactSeparable: " + std::to_string(voxels.size()) +
                                    " bytes of voxels for a world of " + dims.to_string());
    }
    if (!field.empty() && field.size() != dims.count() * element_size(options.format)) {
        throw std::invalid_argument("ExactSeparable: " + std::to_string(field.size()) +
                                    " bytes for a " + to_string(options.format) + " field of " +
                                    dims.to_string());
    }
    if (!indices.empty() && (!options.indices || indices.size() != 3 * dims.count())) {
        throw std::invalid_argument("ExactSeparable: " + std::to_string(indices.size()) +
                                    " index elements for a world of " + dims.to_string() +
                                    (options.indices ? "" : " without options.indices"));
    }
    if (zero_targets && options.signed_field) {
        throw std::invalid_argument("ExactSeparable: zero targets make unsigned fields only");
    }
    const bool in_place = ctx.computes_in_host_memory();
    set_up(voxels.data(), in_place, in_place ? field : std::span<std::uint8_t>(),
           in_place ? indices : std::span<std::int32_t>(), palette, options);
}

void ExactSeparable::set_up(const std::uint8_t* voxels, bool in_place,
                            std::span<std::uint8_t> field, std::span<std::int32_t> indices,
                            const Palette& palette, const GeneratorOptions& options) {
    Context& ctx = ctx_;
    const bool incremental = incremental_;
    const auto& info = ctx.info();
    const std::size_t n = dims_.count();
    const std::string sizes = "world " + dims_.to_string() + ", " + to_string(options.metric) +
                              ", format " + to_string(format_);
    if (std::find(info.extensions.begin(), info.extensions.end(), "cl_khr_fp64") ==
        info.extensions.end()) {
        throw ClError("clBuildProgram", CL_INVALID_DEVICE,
                      sizes + ": " + info.name +
                          " lacks cl_khr_fp64, which the separable transforms need for their "
                          "final values");
    }
    if (incremental && options.indices) {
        throw std::invalid_argument("ExactSeparable: incremental updates keep no indices");
    }
    if (options.signed_field && options.indices) {
        throw std::invalid_argument("ExactSeparable: indices are of unsigned fields only");
    }
    const std::size_t out_bytes = n * element_size(format_);
    const OutType ot = out_type(format_);
    const bool unit = options.spacing.unit();
    const std::uint32_t X = dims_.x, Y = dims_.y, Z = dims_.z;
    // Unit-spacing L2 squares whose separators' numerators could pass 2^31: 64-bit partials.
    const auto sq = [](std::uint32_t a) { return std::uint64_t{a - 1} * (a - 1); };
    wide_ = unit && options.metric == Metric::euclidean &&
            sq(X) + sq(Y) + sq(Z) >= (std::uint64_t{1} << 30);
    // f64 fields with spacing: the scans in double.
    fp64_ = !unit && format_ == Format::f64;
    gt_bytes_ = wide_ || fp64_ ? 8 : 4;
    const std::string build =
        std::string("-DMETRIC=") + std::to_string(static_cast<int>(options.metric)) +
        " -DUNIT=" + (unit ? "1" : "0") + " -DWIDE=" + (wide_ ? "1" : "0") +
        " -DFP64=" + (fp64_ ? "1" : "0") + " -DSIGNED=" + (options.signed_field ? "1" : "0") +
        " -DINDICES=" + (options.indices ? "1" : "0") +
        " -DCPU_LAYOUT=" + (gpu_layout_ ? "0" : "1") + " -DOUT_KIND=" + std::to_string(ot.kind) +
        " -DOUT_T=" + ot.type + " -DOUT_MAX=" + ot.max + " -cl-std=CL1.2";
    program_ = ctx.program("exact_separable.cl",
                           {cl_sources::layout_h, cl_sources::exact_separable_cl}, build);
    const std::size_t part_bytes = n * gt_bytes_;
    if (out_bytes > info.max_alloc || part_bytes > info.max_alloc ||
        (options.indices && 3 * n * 4 > info.max_alloc)) {
        const std::size_t most = std::max({out_bytes, part_bytes, options.indices ? 3 * n * 4 : 0});
        throw ClError("clCreateBuffer", CL_INVALID_BUFFER_SIZE,
                      sizes + " needs a " + std::to_string(most >> 20) + " MiB buffer; " +
                          info.name + " allows at most " + std::to_string(info.max_alloc >> 20) +
                          " MiB per buffer");
    }

    // cols_banded where the device runs its work-groups of kBandedGroup (its registers may
    // cap them lower) and lines of Y and of Z fit its local memory (partials of gt_bytes_);
    // any spacing (the x rows' 1-D distance in voxels, scaled by the x spacing). Zero targets
    // (SciPy's convention) take x rows whose targets are the world's zero voxels.
    // Signed fields take it twice: the world's solids as targets, then its empty voxels (and
    // the space around it, cols_banded's border) for the solids' inner distances, whose z
    // pass writes the signed values. The feature transform takes the same passes; the y pass finds
    // its sites' keys from the x rows and the world, and the z pass writes the index planes.
    // The z pass's lines: the world's, or each stacked block's (z_period_).
    const std::uint32_t zline = z_period_ != 0 ? z_period_ : Z;
    const auto group_fits = [&](const cl::Program& program) {
        return cl::Kernel(program, "cols_banded")
                   .getWorkGroupInfo<CL_KERNEL_WORK_GROUP_SIZE>(info.device) >= kBandedGroup;
    };
    bool banded_fits = gpu_layout_ && !incremental && X < 0xFFFF && Y < kSiteLimit &&
                       zline < kSiteLimit && group_fits(program_);
    // With index planes the y pass also keeps each position's target x (2 bytes). At most
    // kBandedLocalCap of local memory, as on a GPU (so that PoCL runs what GPUs run).
    const std::size_t banded_local = std::min(info.local_mem, kBandedLocalCap);
    std::uint32_t lines_y = banded_fits ? banded_lines(Y, banded_site_bytes(true, options.indices),
                                                       banded_local, options.indices ? 2 : 0)
                                        : 0;
    std::uint32_t lines_z =
        banded_fits ? banded_lines(zline, banded_site_bytes(false, options.indices), banded_local)
                    : 0;
    // A pass whose lines do not fit keeps its lists in global memory (BANDED_GLOBAL, a second
    // program), kBandedGlobalLines lines a group, where its scratch fits one buffer.
    global_y_ = banded_fits && lines_y == 0;
    global_z_ = banded_fits && lines_z == 0;
    std::array<std::size_t, 3> scratch_bytes{};  // banded_scratch of those passes, the larger
    if (global_y_ || global_z_) {
        lines_y = global_y_ ? kBandedGlobalLines : lines_y;
        lines_z = global_z_ ? kBandedGlobalLines : lines_z;
        for (const int axis : {1, 2}) {
            if (axis == 1 ? global_y_ : global_z_) {
                const auto b = banded_scratch(axis == 1 ? Y : zline, axis == 1, options.indices);
                for (std::size_t i = 0; i < b.size(); ++i) {
                    scratch_bytes[i] = std::max(scratch_bytes[i], b[i]);
                }
            }
        }
        banded_fits =
            *std::max_element(scratch_bytes.begin(), scratch_bytes.end()) <= info.max_alloc;
        if (banded_fits) {
            program_global_ = ctx.program("exact_separable.cl",
                                          {cl_sources::layout_h, cl_sources::exact_separable_cl},
                                          build + " -DBANDED_GLOBAL=1");
            banded_fits = group_fits(program_global_);
        }
        if (!banded_fits) {
            lines_y = lines_z = 0;
            global_y_ = global_z_ = false;
        }
    }
    // The passes with their lists in local memory from programs built for their axis
    // (BANDED_AXIS: no test of which pass in their loops), where the work-group still fits;
    // else from program_, which takes the pass from its arguments.
    for (const int axis : {1, 2}) {
        cl::Program& own = banded_program_[axis - 1];
        own = program_;
        if (banded_fits && (axis == 1 ? lines_y : lines_z) != 0 &&
            !(axis == 1 ? global_y_ : global_z_)) {
            const cl::Program p = ctx.program(
                "exact_separable.cl", {cl_sources::layout_h, cl_sources::exact_separable_cl},
                build + " -DBANDED_AXIS=" + std::to_string(axis));
            if (group_fits(p)) {
                own = p;
            }
        }
    }

    // Unit L1 with indices, a full unsigned transform in the CPU layout: l1_xy_keys and
    // l1_z_out, where the keys' 16-bit x and y hold X and Y and the local memory the rows and
    // a z strip of 16 lines.
    const std::size_t l1_pad = X > 1 ? next_pow2(X) / 2 : 1;
    const std::size_t l1_x32 = (std::size_t{X} + 31) / 32 * 32;
    const std::size_t l1_rows_bytes = 3 * (l1_x32 + 2 * l1_pad) * 2;
    const std::size_t l1_run_bytes = 2 * l1_x32 * 4;
    const auto l1_z_bytes = [&](std::size_t chunk) { return (2 * std::size_t{Z} + 2) * chunk * 4; };
    l1_keys_ = !gpu_layout_ && !incremental && unit && options.metric == Metric::manhattan &&
               options.indices && !options.signed_field && !options.max_distance && X < 0xFFFF &&
               Y < 0xFFFF && l1_rows_bytes + l1_run_bytes <= info.local_mem &&
               l1_z_bytes(16) <= info.local_mem;

    // CPU layout: at most max_items_ work-items per pass, each with its three stacks and its
    // tiles of tile_w_ lines (col_pass), sized by the pass's own line length.
    max_items_ = std::max<std::size_t>(32, 16 * std::size_t{info.compute_units});
    for (int a = 0; a < 2; ++a) {
        const std::size_t len = a == 0 ? Y : Z;
        // Tiles of up to 64 lines within about 2 MiB per work-item, at least one line; a
        // multiple of 16 from 16 on (the kernels' vector paths take sub-tiles of 16 lines).
        const std::size_t fit =
            std::clamp<std::size_t>((std::size_t{2} << 20) / (len * 2 * (gt_bytes_ + 4)), 1, 64);
        tile_w_[a] = gpu_layout_ ? 0 : static_cast<int>(fit < 16 ? fit : fit / 16 * 16);
        const std::size_t tile = static_cast<std::size_t>(tile_w_[a]) * len;
        // With indices the features' tiles, and for tile_window_l2 (unit L2 below WIDE) its
        // 64-bit candidates of 16 lines, 8-byte aligned.
        const bool windows = unit && !wide_ && options.metric == Metric::euclidean;
        col_stride_[a] = 3 * (len + 2) + 2 * tile * gt_bytes_ / 4 +
                         (options.indices ? 2 * tile + (windows ? 32 * len + 1 : 0) : 0);
        col_stride_[a] += col_stride_[a] % 2;  // 8-byte partials stay aligned
    }
    // The CPU layout's passes read each line whole before writing it: a full transform runs
    // them in place in one buffer of partials (the output's own where its elements are as
    // wide) and keeps the features in the first index plane. The GPU layout alternates two
    // buffers, the first of them the output's where its elements are as wide.
    shared_parts_ = !gpu_layout_ && !incremental;
    const bool out_is_g = !incremental && element_size(format_) == gt_bytes_;
    const Box all{{0, 0, 0}, {X, Y, Z}};
    const Span xs{0, X}, ys{0, Y}, zs{0, Z};
    const std::size_t scratch_ints =
        std::max({(gpu_layout_ ? x_items(all) : std::min<std::size_t>(Z, max_items_)) *
                      x_stride(gpu_layout_, X),
                  col_scratch(1, X, Z), col_scratch(2, X, Y)});

    cl_call("allocating and uploading, " + sizes, [&] {
        auto& c = ctx.context();
        auto& q = ctx.queue();
        // Read in place, the world is never written (incremental generators upload theirs).
        voxels_ = in_place ? cl::Buffer(c, CL_MEM_READ_ONLY | CL_MEM_USE_HOST_PTR, n,
                                        const_cast<std::uint8_t*>(voxels))
                           : make_buffer(n, CL_MEM_READ_WRITE);
        rgb_ = cl::Buffer(c, CL_MEM_READ_ONLY, 256);
        out_ = field.empty() ? make_buffer(out_bytes, CL_MEM_READ_WRITE)
                             : cl::Buffer(c, CL_MEM_READ_WRITE | CL_MEM_USE_HOST_PTR, out_bytes,
                                          field.data());
        // On the banded passes, g_[0] holds only 16-bit x rows where the z pass writes the
        // output itself (an unsigned field), and a signed field's inner transform needs only
        // h_[0] for its x rows (its y pass writes g_[1], free by then). With indices the y pass
        // hands the z pass its targets in feat_[1], no partials: g_[1] is not needed.
        const int parts = incremental ? 3 : l1_keys_ ? 0 : shared_parts_ ? 1 : 2;
        const bool banded_rows = lines_y != 0 && lines_z != 0;
        const std::size_t rows_bytes = n * 2;
        for (int k = 0; k < parts; ++k) {
            g_[k] = k == 0 && out_is_g ? out_
                    : k == 0 && banded_rows && !options.signed_field
                        ? make_buffer(rows_bytes, CL_MEM_READ_WRITE)
                    : k == 1 && banded_rows && options.indices
                        ? g_[0]
                        : make_buffer(part_bytes, CL_MEM_READ_WRITE);
            if (options.signed_field && (k == 0 || !banded_rows)) {
                h_[k] =
                    make_buffer(k == 0 && banded_rows ? rows_bytes : part_bytes, CL_MEM_READ_WRITE);
            }
        }
        if (options.indices) {
            indices_ = indices.empty() ? make_buffer(3 * n * 4, CL_MEM_READ_WRITE)
                                       : cl::Buffer(c, CL_MEM_READ_WRITE | CL_MEM_USE_HOST_PTR,
                                                    3 * n * 4, indices.data());
            feat_[0] = indices_;
            feat_[1] = shared_parts_ ? indices_ : make_buffer(n * 4, CL_MEM_READ_WRITE);
        }
        for (std::size_t i = 0; i < scratch_bytes.size() && (global_y_ || global_z_); ++i) {
            banded_scratch_[i] = make_buffer(scratch_bytes[i], CL_MEM_READ_WRITE);
        }
        for (int k = parts; k < 3; ++k) {
            g_[k] = g_[0];
            h_[k] = h_[0];
        }
        for (int b = 0; b < 3 && incremental; ++b) {
            track_[b] = cl::Buffer(c, CL_MEM_READ_WRITE, 7 * sizeof(cl_int));
        }
        const auto table = palette.rgb332_table();
        cl::Event up_vox, up_rgb;
        if (!in_place) {
            q.enqueueWriteBuffer(voxels_, CL_FALSE, 0, n, voxels, nullptr, &up_vox);
        }
        q.enqueueWriteBuffer(rgb_, CL_FALSE, 0, table.size(), table.data(), nullptr, &up_rgb);
        q.finish();
        upload_ms_ = elapsed_ms(in_place ? up_rgb : up_vox, up_rgb);
    });
    for (std::size_t axis = 0; axis < 3; ++axis) {
        track_init_[2 * axis] = 0x7FFFFFFF;
        track_init_[2 * axis + 1] = -1;
    }
    const std::int64_t extent[3] = {X, Y, Z};
    const double step[3] = {spacing_.x, spacing_.y, spacing_.z};
    if (options.max_distance) {
        const double bound = *options.max_distance;
        const double part = options.metric == Metric::euclidean ? bound * bound : bound;
        max_distance_ = bound;
        cap_unit_ = static_cast<cl_uint>(std::min(std::ceil(part), 4294967294.0));
        cap_wide_ = static_cast<cl_ulong>(std::min(std::ceil(part), 4e18));
        cap_float_ = static_cast<float>(part * (1 + 1e-6));
        cap_double_ = part * (1 + 1e-12);
        // A site r voxels away along an axis is at least r * spacing away in every metric,
        // so beyond bound / spacing + 1 it cannot come under the cap.
        for (std::size_t a = 0; a < 3; ++a) {
            reach_[a] = std::min<std::int64_t>(
                extent[a], static_cast<std::int64_t>(std::ceil(bound / step[a])) + 1);
        }
    } else {
        max_distance_ = std::numeric_limits<double>::infinity();
        cap_unit_ = 0xFFFFFFFFu;
        cap_wide_ = ~cl_ulong{0};
        cap_float_ = std::numeric_limits<float>::infinity();
        cap_double_ = std::numeric_limits<double>::infinity();
        for (std::size_t a = 0; a < 3; ++a) {
            reach_[a] = extent[a];
        }
    }

    cl_call("setting up kernels, " + sizes, [&] {
        if (l1_keys_) {
            cl::Kernel xy(program_, "l1_xy_keys");
            xy.setArg(0, voxels_);
            xy.setArg(1, indices_);
            xy.setArg(2, X);
            xy.setArg(3, Y);
            xy.setArg(4, static_cast<cl_uint>(l1_pad));
            xy.setArg(5, cl_int{zero_targets_ ? 0 : 1});
            xy.setArg(6, cl::Local(l1_rows_bytes));
            xy.setArg(7, cl::Local(l1_run_bytes / 2));
            xy.setArg(8, cl::Local(l1_run_bytes / 2));
            stages_.push_back({"l1_xy_keys", xy, cl::NDRange(Z), cl::NDRange(1)});
            // Strips of whole 64-byte lines whose tiles stay within about 1 MiB (the core's
            // L2 holds them between the sweeps), at least 4 per core.
            const std::size_t plane = std::size_t{X} * Y;
            const std::size_t plane16 = (plane + 15) / 16 * 16;
            const std::size_t budget = std::min<std::size_t>(info.local_mem, 1 << 20);
            // At least 32 where they fit: the u16 output's stores then fill whole lines.
            const std::size_t least = l1_z_bytes(32) <= info.local_mem ? 32 : 16;
            std::size_t chunk = std::clamp<std::size_t>(budget / l1_z_bytes(1) / 16 * 16, least,
                                                        std::max(least, plane16));
            const std::size_t want_items = 4 * std::size_t{info.compute_units};
            while (chunk > least && (plane + chunk - 1) / chunk < want_items) {
                chunk = std::max<std::size_t>(least, chunk / 2 / 16 * 16);
            }
            cl::Kernel z(program_, "l1_z_out");
            z.setArg(0, indices_);
            z.setArg(1, out_);
            z.setArg(2, voxels_);
            z.setArg(3, rgb_);
            z.setArg(4, indices_);
            z.setArg(5, X);
            z.setArg(6, static_cast<cl_ulong>(plane));
            z.setArg(7, Z);
            z.setArg(8, static_cast<cl_uint>(chunk));
            z.setArg(9, cl::Local(2 * std::size_t{Z} * chunk * 4));
            z.setArg(10, cl::Local(2 * chunk * 4));
            stages_.push_back(
                {"l1_z_out", z, cl::NDRange((plane + chunk - 1) / chunk), cl::NDRange(1)});
            return;
        }
        if (lines_y != 0 && lines_z != 0) {
            const bool sgn = options.signed_field;
            // The first transform's targets: the solids, or with zero targets the empty
            // voxels; a signed field's inner transform takes the empty voxels too. The x rows
            // read the world as it is (ROW_TARGETS_EMPTY), no inverted copy.
            const std::size_t plane = std::size_t{X} * Y;
            const XRows rows =
                gpu_x_rows(ctx, dims_, Format::u16, voxels_, g_[0], 0xFFFFFFFFu, zero_targets_);
            stages_.insert(stages_.end(), rows.launches.begin(), rows.launches.end());
            row_ends_[0] = rows.ends;
            stages_.push_back(banded_kernel(1, Y, lines_y, X, plane, Z, false, g_));
            stages_.push_back(banded_kernel(2, zline, lines_z, plane, X, Y, !sgn, g_));
            if (sgn) {
                XRows inner_rows =
                    gpu_x_rows(ctx, dims_, Format::u16, voxels_, h_[0], 0xFFFFFFFFu, true);
                for (KernelLaunch& launch : inner_rows.launches) {
                    launch.name = inner_rows.launches.size() == 1 ? std::string("x_rows_inner")
                                                                  : launch.name + "_inner";
                    stages_.push_back(launch);
                }
                row_ends_[1] = inner_rows.ends;
                // The inner x rows in h_[0], its y pass's partials in g_[1] (the first
                // z pass has read them), its z pass writing the output.
                const cl::Buffer inner[2] = {h_[0], g_[1]};
                KernelLaunch y = banded_kernel(1, Y, lines_y, X, plane, Z, false, inner);
                KernelLaunch z = banded_kernel(2, zline, lines_z, plane, X, Y, true, inner, true);
                y.name += "_inner";
                z.name += "_inner";
                stages_.push_back(y);
                stages_.push_back(z);
            }
            banded_ = true;
            return;
        }
        // x_pass's rows and col_pass's stacks: only this path's (not the banded passes').
        scratch_ = make_buffer(scratch_ints * 4, CL_MEM_READ_WRITE);
        const cl::Buffer none;
        stages_.push_back(items_launch("x_pass", x_kernel(all, xs, none), x_items(all)));
        // Full transforms reuse the x pass's buffer for the z pass; incremental ones keep all.
        const int last = incremental ? 2 : 0;
        // The CPU layout's tiled z pass of a full unsigned transform writes the output (and
        // the index planes) itself: no finish pass over the partials.
        const bool final = !gpu_layout_ && !incremental && !options.signed_field;
        stages_.push_back(items_launch("y_pass", col_kernel(1, 0, 1, xs, zs, ys, ys, none, none),
                                       col_items(X, Z)));
        stages_.push_back(items_launch(final ? "z_pass_out" : "z_pass",
                                       col_kernel(2, 1, last, xs, ys, zs, zs, none, none, final),
                                       col_items(X, Y)));
        if (!final) {
            stages_.push_back({"finish", finish_kernel(last, all),
                               cl::NDRange(round_up(X, 64), Y, Z), cl::NDRange(64, 1, 1)});
        }
    });
}

std::uint32_t ExactSeparable::banded_lines(std::uint32_t n, std::size_t gt_bytes,
                                           std::size_t local_mem, std::size_t key_bytes) {
    for (std::uint32_t c = kBandedGroup / 8; c >= 1; c /= 2) {
        if (banded_local_bytes(n, c, gt_bytes, key_bytes) <= local_mem) {
            return c;
        }
    }
    return 0;
}

std::uint32_t ExactSeparable::banded_bands(std::uint32_t n, std::uint32_t lines) {
    // As many as the group holds, but no more than n's words of 32 positions (rounded up to a
    // power of two): a band's mask words are its work-item's own.
    return static_cast<std::uint32_t>(
        std::min<std::size_t>(kBandedGroup / lines, next_pow2((std::size_t{n} + 31) / 32)));
}

std::size_t ExactSeparable::banded_local_bytes(std::uint32_t n, std::uint32_t lines,
                                               std::size_t gt_bytes, std::size_t key_bytes) {
    // gl (gt_bytes) and keyx (key_bytes, without keys a 2-byte token) per position and line;
    // the mask's word per 32 positions and line; first and last per band: each local argument
    // rounded up to 16 bytes for the runtime's alignment.
    const auto arg = [](std::size_t bytes) { return (bytes + 15) / 16 * 16; };
    const std::size_t cells = banded_cells(n, lines);
    return arg(cells * gt_bytes) + arg(key_bytes == 0 ? 2 : cells * key_bytes) +
           arg(banded_mask_bytes(n, lines)) + arg(banded_ends_bytes(n, lines));
}

std::array<std::size_t, 3> ExactSeparable::banded_scratch(std::uint32_t n, bool y_pass,
                                                          bool indices) const {
    // Every group's lines: X rounded up to whole groups, times the lines' other axis (and
    // blocks), n positions each.
    const auto lines =
        static_cast<std::uint32_t>(round_up(dims_.x, kBandedGlobalLines) * dims_.y * dims_.z / n);
    const std::size_t cells = banded_cells(n, lines);
    return {cells * banded_site_bytes(y_pass, indices), banded_mask_bytes(n, lines),
            indices && y_pass ? cells * 2 : 16};
}

std::size_t ExactSeparable::banded_cells(std::uint32_t n, std::uint32_t lines) {
    return std::size_t{n} * lines;
}

std::size_t ExactSeparable::banded_mask_bytes(std::uint32_t n, std::uint32_t lines) {
    return (std::size_t{n} + 31) / 32 * lines * 4;
}

std::size_t ExactSeparable::banded_ends_bytes(std::uint32_t n, std::uint32_t lines) {
    return 2 * std::size_t{lines} * banded_bands(n, lines) * 4;
}

KernelLaunch ExactSeparable::items_launch(const char* name, const cl::Kernel& k,
                                          std::size_t items) const {
    const std::size_t local = gpu_layout_ ? 64 : 1;
    return {name, k, cl::NDRange(round_up(items, local)), cl::NDRange(local)};
}

KernelLaunch ExactSeparable::banded_kernel(int axis, std::uint32_t n, std::uint32_t c,
                                           std::uint64_t stride, std::uint64_t mstride,
                                           std::uint32_t lines_o, bool final,
                                           const cl::Buffer* parts, bool border) {
    const std::uint32_t k = banded_bands(n, c);
    const bool y = axis == 1;
    const bool global = y ? global_y_ : global_z_;
    cl::Kernel kernel(global ? program_global_ : banded_program_[y ? 0 : 1], "cols_banded");
    // With indices the y pass writes its targets into feat_[1], the z pass reads them; neither
    // reads `in` nor writes `gout` (arguments 1 and 2), which may then be the x rows' buffer.
    const bool keyed = indices_() != nullptr;
    kernel.setArg(0, parts[y ? 0 : 1]);
    kernel.setArg(1, parts[y ? 0 : 1]);
    kernel.setArg(2, parts[y ? 1 : 0]);
    kernel.setArg(3, out_);
    // The world: the y pass's keys name the x rows' targets (with zero targets its empty voxels).
    kernel.setArg(4, voxels_);
    kernel.setArg(5, rgb_);
    kernel.setArg(6, dims_.x);
    kernel.setArg(7, n);
    kernel.setArg(8, static_cast<cl_ulong>(stride));
    kernel.setArg(9, static_cast<cl_ulong>(mstride));
    kernel.setArg(10, cl_uint{y ? 1u : 0u});
    kernel.setArg(11, cl_uint{final ? 1u : 0u});
    kernel.setArg(12, max_distance_);
    const std::size_t cells = banded_cells(n, c);
    if (global) {
        kernel.setArg(13, banded_scratch_[0]);
        kernel.setArg(14, banded_scratch_[1]);
    } else {
        kernel.setArg(13, cl::Local(cells * banded_site_bytes(y, keyed)));
        kernel.setArg(14, cl::Local(banded_mask_bytes(n, c)));
    }
    kernel.setArg(15, cl::Local(banded_ends_bytes(n, c)));
    kernel.setArg(16, lines_o);
    kernel.setArg(17, cl_uint{border ? 1u : 0u});
    // Valid buffers where there are no features (the kernel does not touch them then).
    kernel.setArg(18, keyed && !y ? feat_[1] : voxels_);
    kernel.setArg(19, keyed && y ? feat_[1] : out_);
    kernel.setArg(20, keyed ? indices_ : out_);
    kernel.setArg(21, static_cast<cl_ulong>(dims_.count()));
    // A signed field's solids' partials, from the first transform's z pass (read by the
    // second's, `final`).
    kernel.setArg(22, g_[0]);
    // The spacing along x, along the lines' other axis and along the lines.
    set_spacing(kernel, 23, spacing_.x);
    set_spacing(kernel, 24, y ? spacing_.z : spacing_.y);
    set_spacing(kernel, 25, y ? spacing_.y : spacing_.z);
    // The y pass's target x per position, for its keys (a token 2 bytes elsewhere).
    if (global) {
        kernel.setArg(26, banded_scratch_[2]);
    } else {
        kernel.setArg(26, cl::Local(keyed && y ? cells * 2 : 2));
    }
    kernel.setArg(27, cl_uint{zero_targets_ ? 1u : 0u});
    // The z pass of stacked blocks (n = z_period_): lines_o lines per block, n z-slices apart.
    const std::uint32_t blocks = y ? 1 : dims_.z / n;
    kernel.setArg(28, static_cast<cl_ulong>(stride * n));
    return {std::string(y ? "y_banded" : "z_banded") + (global ? "_global" : ""), kernel,
            cl::NDRange(round_up(dims_.x, c), std::size_t{lines_o} * blocks * k),
            cl::NDRange(c, k)};
}

std::size_t ExactSeparable::x_per_item(const Box& rows) const {
    // CPU: whole z slices of rows per work-item, at most max_items_ work-items; GPU: a row.
    const auto ny = static_cast<std::size_t>(rows.max.y - rows.min.y);
    const auto nz = static_cast<std::size_t>(rows.max.z - rows.min.z);
    return gpu_layout_ ? 1 : ny * ((nz + max_items_ - 1) / max_items_);
}

std::size_t ExactSeparable::x_items(const Box& rows) const {
    const auto ny = static_cast<std::size_t>(rows.max.y - rows.min.y);
    const auto nz = static_cast<std::size_t>(rows.max.z - rows.min.z);
    const std::size_t per = x_per_item(rows);
    return per == 0 ? 0 : (ny * nz + per - 1) / per;
}

std::size_t ExactSeparable::col_per_item(std::size_t count_x, std::size_t count_o) const {
    // CPU: whole x rows of lines per work-item, at most max_items_ work-items; GPU: a line.
    return gpu_layout_ ? 1 : count_x * ((count_o + max_items_ - 1) / max_items_);
}

std::size_t ExactSeparable::col_items(std::size_t count_x, std::size_t count_o) const {
    const std::size_t per = col_per_item(count_x, count_o);
    return per == 0 ? 0 : (count_x * count_o + per - 1) / per;
}

std::size_t ExactSeparable::col_scratch(int axis, std::size_t count_x, std::size_t count_o) const {
    // CPU: col_stride_ ints per work-item (of a pass over these lines or any fewer rows);
    // GPU: the three stacks of each line, interleaved.
    const std::size_t len = axis == 1 ? dims_.y : dims_.z;
    return gpu_layout_ ? count_x * count_o * 3 * (len + 2)
                       : std::min(count_o, max_items_) * col_stride_[axis - 1];
}

void ExactSeparable::set_cap(cl::Kernel& k, cl_uint index) const {
    if (wide_) {
        k.setArg(index, cap_wide_);
    } else if (spacing_.unit()) {
        k.setArg(index, cap_unit_);
    } else if (fp64_) {
        k.setArg(index, cap_double_);
    } else {
        k.setArg(index, cap_float_);
    }
}

void ExactSeparable::set_spacing(cl::Kernel& k, cl_uint index, double s) const {
    if (fp64_) {
        k.setArg(index, s);
    } else {
        k.setArg(index, static_cast<float>(s));
    }
}

cl::Kernel ExactSeparable::x_kernel(const Box& rows, Span in, const cl::Buffer& box) {
    const cl_int4 lo{{static_cast<cl_int>(rows.min.x), static_cast<cl_int>(rows.min.y),
                      static_cast<cl_int>(rows.min.z), 0}};
    const cl_int4 size{{static_cast<cl_int>(rows.max.x - rows.min.x),
                        static_cast<cl_int>(rows.max.y - rows.min.y),
                        static_cast<cl_int>(rows.max.z - rows.min.z), 0}};
    cl::Kernel k(program_, "x_pass");
    k.setArg(0, voxels_);
    k.setArg(1, g_[0]);
    k.setArg(2, h_[0]);
    k.setArg(3, feat_[0]);
    k.setArg(4, dims_.x);
    k.setArg(5, dims_.y);
    k.setArg(6, lo);
    k.setArg(7, size);
    k.setArg(8, static_cast<cl_uint>(x_per_item(rows)));
    set_spacing(k, 9, spacing_.x);
    k.setArg(10, scratch_);
    k.setArg(11, static_cast<cl_ulong>(x_stride(gpu_layout_, dims_.x)));
    k.setArg(12, box);
    k.setArg(13, static_cast<cl_int>(in.lo));
    k.setArg(14, static_cast<cl_int>(in.hi));
    set_cap(k, 15);
    k.setArg(16, cl_int{zero_targets_ ? 0 : 1});
    k.setArg(17, dims_.z);
    return k;
}

cl::Kernel ExactSeparable::col_kernel(int axis, int from, int to, Span xs, Span others, Span out,
                                      Span in, const cl::Buffer& skip, const cl::Buffer& box,
                                      bool final) {
    const std::uint32_t X = dims_.x, Y = dims_.y;
    const bool along_y = axis == 1;
    const auto count_x = static_cast<std::size_t>(xs.hi - xs.lo);
    const auto count_o = static_cast<std::size_t>(others.hi - others.lo);
    cl::Kernel k(program_, "col_pass");
    k.setArg(0, g_[from]);
    k.setArg(1, g_[to]);
    k.setArg(2, h_[from]);
    k.setArg(3, h_[to]);
    k.setArg(4, feat_[from == 0 ? 0 : 1]);
    k.setArg(5, feat_[from == 0 ? 1 : 0]);
    k.setArg(6, scratch_);
    k.setArg(7, along_y ? Y : dims_.z);
    k.setArg(8, static_cast<cl_ulong>(along_y ? X : std::size_t{X} * Y));
    k.setArg(9, static_cast<cl_ulong>(along_y ? std::size_t{X} * Y : X));
    k.setArg(10, static_cast<cl_int>(xs.lo));
    k.setArg(11, static_cast<cl_int>(xs.hi - xs.lo));
    k.setArg(12, static_cast<cl_int>(others.lo));
    k.setArg(13, static_cast<cl_int>(others.hi - others.lo));
    k.setArg(14, static_cast<cl_uint>(col_per_item(count_x, count_o)));
    // CPU: each work-item's stack contiguous; GPU: interleaved across work-items.
    k.setArg(15, static_cast<cl_ulong>(gpu_layout_ ? col_items(count_x, count_o) : 1));
    k.setArg(16, static_cast<cl_ulong>(gpu_layout_ ? 1 : col_stride_[axis - 1]));
    set_spacing(k, 17, along_y ? spacing_.y : spacing_.z);
    k.setArg(18, cl_int{axis});
    k.setArg(19, skip);
    k.setArg(20, box);
    k.setArg(21, static_cast<cl_int>(out.lo));
    k.setArg(22, static_cast<cl_int>(out.hi));
    k.setArg(23, static_cast<cl_int>(in.lo));
    k.setArg(24, static_cast<cl_int>(in.hi));
    set_cap(k, 25);
    k.setArg(26, cl_int{tile_w_[axis - 1]});
    k.setArg(27, cl_int{final ? 1 : 0});
    k.setArg(28, out_);
    k.setArg(29, voxels_);
    k.setArg(30, rgb_);
    // A valid buffer where there are no index planes (the kernel does not touch it then).
    k.setArg(31, indices_() != nullptr ? indices_ : out_);
    k.setArg(32, max_distance_);
    return k;
}

cl::Kernel ExactSeparable::finish_kernel(int from, const Box& voxels) {
    const cl_int4 lo{{static_cast<cl_int>(voxels.min.x), static_cast<cl_int>(voxels.min.y),
                      static_cast<cl_int>(voxels.min.z), 0}};
    const cl_int4 size{{static_cast<cl_int>(voxels.max.x - voxels.min.x),
                        static_cast<cl_int>(voxels.max.y - voxels.min.y),
                        static_cast<cl_int>(voxels.max.z - voxels.min.z), 0}};
    cl::Kernel k(program_, "finish");
    k.setArg(0, g_[from]);
    k.setArg(1, h_[from]);
    k.setArg(2, voxels_);
    k.setArg(3, rgb_);
    k.setArg(4, out_);
    k.setArg(5, feat_[0]);
    k.setArg(6, indices_);
    k.setArg(7, dims_.x);
    k.setArg(8, dims_.y);
    k.setArg(9, static_cast<cl_ulong>(dims_.count()));
    k.setArg(10, lo);
    k.setArg(11, size);
    k.setArg(12, max_distance_);
    k.setArg(13, dims_.z);
    return k;
}

void ExactSeparable::enqueue(const cl::Kernel& k, std::size_t items, cl::Event* event) {
    // Fixed work-group sizes, the global size rounded up to them (the kernels skip the
    // rest): PoCL compiles a kernel per work-group size, and update() launches every size.
    const std::size_t local = gpu_layout_ ? 64 : 1;
    ctx_.queue().enqueueNDRangeKernel(k, cl::NullRange, cl::NDRange(round_up(items, local)),
                                      cl::NDRange(local), nullptr, event);
}

void ExactSeparable::enqueue_voxels(const cl::Kernel& k, const Box& b, cl::Event* event) {
    ctx_.queue().enqueueNDRangeKernel(
        k, cl::NullRange,
        cl::NDRange(round_up(static_cast<std::size_t>(b.max.x - b.min.x), 64),
                    static_cast<std::size_t>(b.max.y - b.min.y),
                    static_cast<std::size_t>(b.max.z - b.min.z)),
        cl::NDRange(64, 1, 1), nullptr, event);
}

std::string ExactSeparable::variant() const {
    return !gpu_layout_ ? "cpu layout" : banded_ ? "gpu layout, banded" : "gpu layout";
}

bool ExactSeparable::enqueue(std::vector<std::pair<std::string, cl::Event>>& events) {
    cl_call("enqueueing exact_separable.cl on " + dims_.to_string(),
            [&] { enqueue_stages(stages_, events, stage_events_); });
    return true;
}

double ExactSeparable::run() {
    return cl_call("running exact_separable.cl on " + dims_.to_string(), [&] {
        std::vector<std::pair<std::string, cl::Event>> events;
        enqueue_stages(stages_, events);
        ctx_.queue().finish();
        record_stages(events);
        return elapsed_ms(events.front().second, events.back().second);
    });
}

ExactSeparable::Update ExactSeparable::update(const Box& edited, std::vector<cl::Event>& events) {
    if (!incremental_) {
        throw std::logic_error("ExactSeparable::update needs an incremental generator");
    }
    return cl_call("updating exact_separable.cl's field of " + dims_.to_string(), [&] {
        auto& q = ctx_.queue();
        const std::int64_t X = dims_.x, Y = dims_.y, Z = dims_.z;
        // Unbounded: whole lines. Bounded: what can change lies within reach_ of the edit,
        // and depends on the voxels within reach_ of that.
        auto near = [](std::int64_t lo, std::int64_t hi, std::int64_t r, std::int64_t n) {
            return Span{std::max<std::int64_t>(0, lo - r), std::min(n, hi + r)};
        };
        const Span xo = near(edited.min.x, edited.max.x, reach_[0], X);
        const Span xi = near(edited.min.x, edited.max.x, 2 * reach_[0], X);
        const Span yo = near(edited.min.y, edited.max.y, reach_[1], Y);
        const Span yi = near(edited.min.y, edited.max.y, 2 * reach_[1], Y);
        const Span zo = near(edited.min.z, edited.max.z, reach_[2], Z);
        const Span zi = near(edited.min.z, edited.max.z, 2 * reach_[2], Z);
        const Box rows{{xo.lo, edited.min.y, edited.min.z}, {xo.hi, edited.max.y, edited.max.z}};
        const std::size_t row_count =
            static_cast<std::size_t>((rows.max.y - rows.min.y) * (rows.max.z - rows.min.z));
        // The change boxes of the x, y and z passes (7 ints each, as mark() writes them).
        const cl::Buffer* box = track_;
        for (int b = 0; b < 3; ++b) {
            events.emplace_back();
            q.enqueueWriteBuffer(track_[b], CL_FALSE, 0, sizeof(track_init_), track_init_.data(),
                                 nullptr, &events.back());
        }
        auto launch = [&](const cl::Kernel& k, std::size_t items) {
            events.emplace_back();
            enqueue(k, items, &events.back());
        };
        const Span zb_rows{edited.min.z, edited.max.z};
        launch(x_kernel(rows, xi, box[0]), x_items(rows));
        launch(col_kernel(1, 0, 1, xo, zb_rows, yo, yi, box[0], box[1]),
               col_items(static_cast<std::size_t>(xo.hi - xo.lo),
                         static_cast<std::size_t>(zb_rows.hi - zb_rows.lo)));
        launch(col_kernel(2, 1, 2, xo, yo, zo, zi, box[1], box[2]),
               col_items(static_cast<std::size_t>(xo.hi - xo.lo),
                         static_cast<std::size_t>(yo.hi - yo.lo)));
        std::array<cl_int, 7>& yb = track_read_[0];
        std::array<cl_int, 7>& zb = track_read_[1];
        q.enqueueReadBuffer(track_[1], CL_FALSE, 0, sizeof(yb), yb.data());
        q.enqueueReadBuffer(track_[2], CL_TRUE, 0, sizeof(zb), zb.data());
        Update u;
        u.voxels_recomputed =
            static_cast<std::uint64_t>(row_count) * static_cast<std::uint64_t>(xo.hi - xo.lo) +
            static_cast<std::uint64_t>(yb[6]) + static_cast<std::uint64_t>(zb[6]);
        const Box changed =
            zb[0] > zb[1] ? Box{} : Box{{zb[0], zb[2], zb[4]}, {zb[1] + 1, zb[3] + 1, zb[5] + 1}};
        u.changed = changed;
        // The output of the changed voxels (the z pass marked them) and of the edited box.
        for (const Box& b : {changed, edited}) {
            if (!b.empty()) {
                events.emplace_back();
                enqueue_voxels(finish_kernel(2, b), b, &events.back());
            }
        }
        q.finish();
        return u;
    });
}

}  // namespace voxfield::ocl
