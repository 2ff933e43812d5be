// Exact separable transforms of every metric, host side (kernels: cl/kernels/exact_separable.cl,
// Meijster, Roerdink & Hesselink 2000).
#include "voxfield/cl/separable.hpp"

#include <algorithm>
#include <string>

#include "util.hpp"

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
           holds_sign(o.format);
}

ExactSeparable::ExactSeparable(Context& ctx, const World& world, const Palette& palette,
                               const GeneratorOptions& options)
    : Generator(ctx, world.dims(), options.format),
      gpu_layout_(options.layout == Layout::automatic ? !ctx.is_cpu()
                                                      : options.layout == Layout::gpu) {
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
    const cl::Program program = ctx.program(
        "exact_separable.cl", {cl_sources::layout_h, cl_sources::exact_separable_cl}, build);

    const std::uint32_t X = dims_.x, Y = dims_.y, Z = dims_.z;
    const std::size_t rows = std::size_t{Y} * Z;
    const std::size_t y_lines = std::size_t{X} * Z, z_lines = std::size_t{X} * Y;
    // CPU: a slice of y-columns or a row of z-columns per work-item; GPU: one line each.
    const std::uint32_t row_items_per = gpu_layout_ ? 1u : std::max<std::uint32_t>(1, Y);
    const std::uint32_t col_per = gpu_layout_ ? 1u : X;
    const std::size_t y_items = (y_lines + col_per - 1) / col_per;
    const std::size_t z_items = (z_lines + col_per - 1) / col_per;
    const std::size_t stack = 2 * (std::size_t{std::max(Y, Z)} + 2);
    const std::size_t scratch_ints = std::max(y_items, z_items) * stack;

    cl_call("allocating and uploading, " + sizes, [&] {
        auto& c = ctx.context();
        auto& q = ctx.queue();
        voxels_ = cl::Buffer(c, CL_MEM_READ_ONLY, n);
        rgb_ = cl::Buffer(c, CL_MEM_READ_ONLY, 256);
        out_ = cl::Buffer(c, CL_MEM_READ_WRITE, out_bytes);
        for (int k = 0; k < 2; ++k) {
            g_[k] = cl::Buffer(c, CL_MEM_READ_WRITE, part_bytes);
            h_[k] = cl::Buffer(c, CL_MEM_READ_WRITE, options.signed_field ? part_bytes : 4);
            feat_[k] = cl::Buffer(c, CL_MEM_READ_WRITE, options.indices ? part_bytes : 4);
        }
        indices_ =
            options.indices ? cl::Buffer(c, CL_MEM_READ_WRITE, 3 * part_bytes) : cl::Buffer();
        scratch_ = cl::Buffer(c, CL_MEM_READ_WRITE, scratch_ints * 4);
        const auto table = palette.rgb332_table();
        cl::Event up_vox, up_rgb;
        q.enqueueWriteBuffer(voxels_, CL_FALSE, 0, n, world.voxels().data(), nullptr, &up_vox);
        q.enqueueWriteBuffer(rgb_, CL_FALSE, 0, table.size(), table.data(), nullptr, &up_rgb);
        q.finish();
        upload_ms_ = elapsed_ms(up_vox, up_rgb);
    });

    cl_call("setting up kernels, " + sizes, [&] {
        const auto sx = static_cast<float>(options.spacing.x);
        cl::Kernel xk(program, "x_pass");
        xk.setArg(0, voxels_);
        xk.setArg(1, g_[0]);
        xk.setArg(2, h_[0]);
        xk.setArg(3, feat_[0]);
        xk.setArg(4, X);
        xk.setArg(5, static_cast<cl_uint>(rows));
        xk.setArg(6, row_items_per);
        xk.setArg(7, sx);
        stages_.push_back({"x_pass", xk, cl::NDRange((rows + row_items_per - 1) / row_items_per)});

        auto column = [&](const char* name, int from, std::uint32_t len, std::size_t stride,
                          std::size_t mstride, std::size_t lines, std::size_t items,
                          double spacing) {
            cl::Kernel k(program, "col_pass");
            k.setArg(0, g_[from]);
            k.setArg(1, g_[1 - from]);
            k.setArg(2, h_[from]);
            k.setArg(3, h_[1 - from]);
            k.setArg(4, feat_[from]);
            k.setArg(5, feat_[1 - from]);
            k.setArg(6, scratch_);
            k.setArg(7, X);
            k.setArg(8, len);
            k.setArg(9, static_cast<cl_ulong>(stride));
            k.setArg(10, static_cast<cl_ulong>(mstride));
            k.setArg(11, static_cast<cl_uint>(lines));
            k.setArg(12, col_per);
            // CPU: each work-item's stack contiguous; GPU: interleaved across work-items.
            k.setArg(13, static_cast<cl_ulong>(gpu_layout_ ? items : 1));
            k.setArg(14, static_cast<cl_ulong>(gpu_layout_ ? 1 : stack));
            k.setArg(15, static_cast<float>(spacing));
            return Stage{name, k, cl::NDRange(items)};
        };
        stages_.push_back(
            column("y_pass", 0, Y, X, std::size_t{X} * Y, y_lines, y_items, options.spacing.y));
        stages_.push_back(
            column("z_pass", 1, Z, std::size_t{X} * Y, X, z_lines, z_items, options.spacing.z));

        cl::Kernel fk(program, "finish");
        fk.setArg(0, g_[0]);
        fk.setArg(1, h_[0]);
        fk.setArg(2, voxels_);
        fk.setArg(3, rgb_);
        fk.setArg(4, out_);
        fk.setArg(5, feat_[0]);
        fk.setArg(6, options.indices ? indices_ : feat_[0]);
        fk.setArg(7, X);
        fk.setArg(8, Y);
        fk.setArg(9, static_cast<cl_ulong>(n));
        stages_.push_back({"finish", fk, cl::NDRange(round_up(n, 64))});
    });
}

std::string ExactSeparable::variant() const {
    return gpu_layout_ ? "gpu layout" : "cpu layout";
}

double ExactSeparable::run() {
    return cl_call("running exact_separable.cl on " + dims_.to_string(), [&] {
        auto& q = ctx_.queue();
        std::vector<std::pair<std::string, cl::Event>> events;
        for (const Stage& stage : stages_) {
            events.emplace_back(stage.name, cl::Event());
            q.enqueueNDRangeKernel(stage.kernel, cl::NullRange, stage.global, cl::NullRange,
                                   nullptr, &events.back().second);
        }
        q.finish();
        record_stages(events);
        return elapsed_ms(events.front().second, events.back().second);
    });
}

}  // namespace voxfield::ocl
