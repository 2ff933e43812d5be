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

}  // namespace

bool ExactSeparable::needed(const GeneratorOptions& o) {
    return o.metric != Metric::manhattan || !o.spacing.unit() || o.signed_field || o.indices ||
           o.max_distance.has_value() || holds_sign(o.format);
}

ExactSeparable::ExactSeparable(Context& ctx, const World& world, const Palette& palette,
                               const GeneratorOptions& options, bool incremental)
    : Generator(ctx, world.dims(), options.format),
      gpu_layout_(options.layout == Layout::automatic ? !ctx.is_cpu()
                                                      : options.layout == Layout::gpu),
      incremental_(incremental),
      spacing_(options.spacing) {
    set_up(world.voxels().data(), false, {}, palette, options);
}

ExactSeparable::ExactSeparable(Context& ctx, Dims dims, std::span<const std::uint8_t> voxels,
                               const Palette& palette, const GeneratorOptions& options,
                               std::span<std::uint8_t> field)
    : Generator(ctx, dims, options.format),
      gpu_layout_(options.layout == Layout::automatic ? !ctx.is_cpu()
                                                      : options.layout == Layout::gpu),
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
    const bool in_place = ctx.computes_in_host_memory();
    set_up(voxels.data(), in_place, in_place ? field : std::span<std::uint8_t>(), palette, options);
}

void ExactSeparable::set_up(const std::uint8_t* voxels, bool in_place,
                            std::span<std::uint8_t> field, const Palette& palette,
                            const GeneratorOptions& options) {
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
    const std::size_t out_bytes = n * element_size(format_);
    const std::size_t part_bytes = n * 4;
    if (out_bytes > info.max_alloc || part_bytes > info.max_alloc) {
        throw ClError("clCreateBuffer", CL_INVALID_BUFFER_SIZE,
                      sizes + " needs a " + std::to_string(std::max(out_bytes, part_bytes) >> 20) +
                          " MiB buffer; " + info.name + " allows at most " +
                          std::to_string(info.max_alloc >> 20) + " MiB per buffer");
    }
    const OutType ot = out_type(format_);
    const bool unit = options.spacing.unit();
    const std::string build =
        std::string("-DMETRIC=") + std::to_string(static_cast<int>(options.metric)) +
        " -DUNIT=" + (unit ? "1" : "0") + " -DSIGNED=" + (options.signed_field ? "1" : "0") +
        " -DINDICES=" + (options.indices ? "1" : "0") + " -DOUT_KIND=" + std::to_string(ot.kind) +
        " -DOUT_T=" + ot.type + " -DOUT_MAX=" + ot.max + " -cl-std=CL1.2";
    program_ = ctx.program("exact_separable.cl",
                           {cl_sources::layout_h, cl_sources::exact_separable_cl}, build);

    const std::uint32_t X = dims_.x, Y = dims_.y, Z = dims_.z;
    // CPU layout: each work-item's two stacks and, without indices, its two tiles of
    // kTile lines (col_pass).
    constexpr std::size_t kTile = 16;
    tile_w_ = gpu_layout_ || options.indices ? 0 : static_cast<int>(kTile);
    col_stride_ = 2 * (std::size_t{std::max(Y, Z)} + 2) +
                  2 * std::size_t{std::max(Y, Z)} * static_cast<std::size_t>(tile_w_);
    x_stride_ = X;
    const std::size_t most_lines = std::size_t{X} * std::max(Y, Z);
    const std::size_t scratch_ints = std::max(x_items(Box{{0, 0, 0}, {X, Y, Z}}) * x_stride_,
                                              col_items(most_lines, Span{0, X}) * col_stride_);

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
        const int parts = incremental ? 3 : 2;
        for (int k = 0; k < parts; ++k) {
            g_[k] = make_buffer(part_bytes, CL_MEM_READ_WRITE);
            if (options.signed_field) {
                h_[k] = make_buffer(part_bytes, CL_MEM_READ_WRITE);
            }
        }
        for (int k = 0; k < 2 && options.indices; ++k) {
            feat_[k] = make_buffer(part_bytes, CL_MEM_READ_WRITE);
        }
        if (options.indices) {
            indices_ = make_buffer(3 * part_bytes, CL_MEM_READ_WRITE);
        }
        for (int b = 0; b < 3 && incremental; ++b) {
            track_[b] = cl::Buffer(c, CL_MEM_READ_WRITE, 7 * sizeof(cl_int));
        }
        scratch_ = make_buffer(scratch_ints * 4, CL_MEM_READ_WRITE);
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
        cap_float_ = static_cast<float>(part * (1 + 1e-6));
        // A site r voxels away along an axis is at least r * spacing away in every metric,
        // so beyond bound / spacing + 1 it cannot come under the cap.
        for (std::size_t a = 0; a < 3; ++a) {
            reach_[a] = std::min<std::int64_t>(
                extent[a], static_cast<std::int64_t>(std::ceil(bound / step[a])) + 1);
        }
    } else {
        max_distance_ = std::numeric_limits<double>::infinity();
        cap_unit_ = 0xFFFFFFFFu;
        cap_float_ = std::numeric_limits<float>::infinity();
        for (std::size_t a = 0; a < 3; ++a) {
            reach_[a] = extent[a];
        }
    }

    cl_call("setting up kernels, " + sizes, [&] {
        const Box all{{0, 0, 0}, {X, Y, Z}};
        // cols_banded where the device runs its work-groups of kBandedGroup (its registers may
        // cap them lower) and lines of Y and of Z fit its local memory.
        const bool banded =
            gpu_layout_ && !incremental && unit && !options.signed_field && !options.indices &&
            X < 0xFFFF && Y < kLinkLimit && Z < kLinkLimit &&
            cl::Kernel(program_, "cols_banded")
                    .getWorkGroupInfo<CL_KERNEL_WORK_GROUP_SIZE>(info.device) >= kBandedGroup;
        const std::uint32_t lines_y = banded ? banded_lines(Y, info.local_mem) : 0;
        const std::uint32_t lines_z = banded ? banded_lines(Z, info.local_mem) : 0;
        if (lines_y != 0 && lines_z != 0) {
            if (auto rows = gpu_x_rows(ctx, dims_, Format::u16, voxels_, g_[0])) {
                stages_.push_back(*rows);
                stages_.push_back(banded_kernel(1, Y, lines_y, X, std::size_t{X} * Y, Z, false));
                stages_.push_back(banded_kernel(2, Z, lines_z, std::size_t{X} * Y, X, Y, true));
                banded_ = true;
                return;
            }
        }
        const cl::Buffer none;
        const Span xs{0, X}, ys{0, Y}, zs{0, Z};
        stages_.push_back(items_launch("x_pass", x_kernel(all, xs, none), x_items(all)));
        // Full transforms reuse the x pass's buffer for the z pass; incremental ones keep all.
        const int last = incremental ? 2 : 0;
        stages_.push_back(items_launch("y_pass", col_kernel(1, 0, 1, xs, zs, ys, ys, none, none),
                                       col_items(std::size_t{X} * Z, xs)));
        stages_.push_back(items_launch("z_pass", col_kernel(2, 1, last, xs, ys, zs, zs, none, none),
                                       col_items(std::size_t{X} * Y, xs)));
        stages_.push_back({"finish", finish_kernel(last, all), cl::NDRange(round_up(X, 64), Y, Z),
                           cl::NDRange(64, 1, 1)});
    });
}

std::uint32_t ExactSeparable::banded_lines(std::uint32_t n, std::size_t local_mem) {
    for (std::uint32_t c = kBandedGroup / 8; c >= 1; c /= 2) {
        if (banded_local_bytes(n, c) <= local_mem) {
            return c;
        }
    }
    return 0;
}

std::size_t ExactSeparable::banded_local_bytes(std::uint32_t n, std::uint32_t lines) {
    // gl (4 bytes), prv, nxt, owner (2 each) per position and line; first and last per band.
    return banded_cells(n, lines) * 10 + 2 * std::size_t{kBandedGroup} * 4;
}

std::size_t ExactSeparable::banded_cells(std::uint32_t n, std::uint32_t lines) {
    return std::size_t{n} * lines;
}

KernelLaunch ExactSeparable::items_launch(const char* name, const cl::Kernel& k,
                                          std::size_t items) const {
    const std::size_t local = gpu_layout_ ? 64 : 1;
    return {name, k, cl::NDRange(round_up(items, local)), cl::NDRange(local)};
}

KernelLaunch ExactSeparable::banded_kernel(int axis, std::uint32_t n, std::uint32_t c,
                                           std::uint64_t stride, std::uint64_t mstride,
                                           std::uint32_t lines_o, bool final) {
    const std::uint32_t k = kBandedGroup / c;
    cl::Kernel kernel(program_, "cols_banded");
    const bool y = axis == 1;
    kernel.setArg(0, g_[y ? 0 : 1]);
    kernel.setArg(1, g_[y ? 0 : 1]);
    kernel.setArg(2, g_[y ? 1 : 0]);
    kernel.setArg(3, out_);
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
    kernel.setArg(13, cl::Local(cells * 4));
    kernel.setArg(14, cl::Local(cells * 2));
    kernel.setArg(15, cl::Local(cells * 2));
    kernel.setArg(16, cl::Local(cells * 2));
    kernel.setArg(17, cl::Local(std::size_t{2} * kBandedGroup * 4));
    return {y ? "y_banded" : "z_banded", kernel,
            cl::NDRange(round_up(dims_.x, c), std::size_t{lines_o} * k), cl::NDRange(c, k)};
}

std::size_t ExactSeparable::x_items(const Box& rows) const {
    // CPU: the rows of one z per work-item (as x_kernel sets them); GPU: one row each.
    const auto ny = static_cast<std::size_t>(rows.max.y - rows.min.y);
    const auto nz = static_cast<std::size_t>(rows.max.z - rows.min.z);
    return gpu_layout_ ? ny * nz : nz;
}

std::size_t ExactSeparable::col_items(std::size_t lines, Span xs) const {
    // CPU: the lines of one x row per work-item; GPU: one line each.
    const auto row = static_cast<std::size_t>(xs.hi - xs.lo);
    return gpu_layout_ ? lines : (lines + row - 1) / row;
}

void ExactSeparable::set_cap(cl::Kernel& k, cl_uint index) const {
    if (spacing_.unit()) {
        k.setArg(index, cap_unit_);
    } else {
        k.setArg(index, cap_float_);
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
    k.setArg(8, gpu_layout_ ? cl_uint{1} : static_cast<cl_uint>(size.s[1]));
    k.setArg(9, static_cast<float>(spacing_.x));
    k.setArg(10, scratch_);
    k.setArg(11, static_cast<cl_ulong>(x_stride_));
    k.setArg(12, box);
    k.setArg(13, static_cast<cl_int>(in.lo));
    k.setArg(14, static_cast<cl_int>(in.hi));
    set_cap(k, 15);
    return k;
}

cl::Kernel ExactSeparable::col_kernel(int axis, int from, int to, Span xs, Span others, Span out,
                                      Span in, const cl::Buffer& skip, const cl::Buffer& box) {
    const std::uint32_t X = dims_.x, Y = dims_.y;
    const bool along_y = axis == 1;
    const std::size_t lines =
        static_cast<std::size_t>(xs.hi - xs.lo) * static_cast<std::size_t>(others.hi - others.lo);
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
    k.setArg(14, gpu_layout_ ? cl_uint{1} : static_cast<cl_uint>(xs.hi - xs.lo));
    // CPU: each work-item's stack contiguous; GPU: interleaved across work-items.
    k.setArg(15, static_cast<cl_ulong>(gpu_layout_ ? col_items(lines, xs) : 1));
    k.setArg(16, static_cast<cl_ulong>(gpu_layout_ ? 1 : col_stride_));
    k.setArg(17, static_cast<float>(along_y ? spacing_.y : spacing_.z));
    k.setArg(18, cl_int{axis});
    k.setArg(19, skip);
    k.setArg(20, box);
    k.setArg(21, static_cast<cl_int>(out.lo));
    k.setArg(22, static_cast<cl_int>(out.hi));
    k.setArg(23, static_cast<cl_int>(in.lo));
    k.setArg(24, static_cast<cl_int>(in.hi));
    set_cap(k, 25);
    k.setArg(26, cl_int{tile_w_});
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

double ExactSeparable::run() {
    return cl_call("running exact_separable.cl on " + dims_.to_string(), [&] {
        auto& q = ctx_.queue();
        std::vector<std::pair<std::string, cl::Event>> events;
        for (const KernelLaunch& stage : stages_) {
            events.emplace_back(stage.name, cl::Event());
            q.enqueueNDRangeKernel(stage.kernel, cl::NullRange, stage.global, stage.local, nullptr,
                                   &events.back().second);
        }
        q.finish();
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
        launch(
            col_kernel(1, 0, 1, xo, zb_rows, yo, yi, box[0], box[1]),
            col_items(static_cast<std::size_t>((xo.hi - xo.lo) * (zb_rows.hi - zb_rows.lo)), xo));
        launch(col_kernel(2, 1, 2, xo, yo, zo, zi, box[1], box[2]),
               col_items(static_cast<std::size_t>((xo.hi - xo.lo) * (yo.hi - yo.lo)), xo));
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
