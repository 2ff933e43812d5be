// Writing the render field into memory shared with Vulkan (kernels: cl/kernels/render_field.cl).
#include "voxfield/cl/interop.hpp"

#include "voxfield/layout.h"

#include <CL/cl_ext.h>

#include <algorithm>
#include <cstring>
#include <string>

#include "util.hpp"

namespace voxfield::cl_sources {
extern const char* const layout_h;
extern const char* const render_field_cl;
}  // namespace voxfield::cl_sources

namespace voxfield::ocl {
namespace {

cl_platform_id platform_of(const Context& ctx) {
    return ctx.info().device.getInfo<CL_DEVICE_PLATFORM>();
}

template <class F>
F extension_function(const Context& ctx, const char* name) {
    return reinterpret_cast<F>(clGetExtensionFunctionAddressForPlatform(platform_of(ctx), name));
}

// OpenCL major version of the device's platform ("OpenCL 3.0 ..." -> 3).
int platform_major(const Context& ctx) {
    const std::string v = cl::Platform(platform_of(ctx)).getInfo<CL_PLATFORM_VERSION>();
    return v.size() > 7 && v.compare(0, 7, "OpenCL ") == 0 ? v[7] - '0' : 0;
}

}  // namespace

CompactWriter::CompactWriter(Context& ctx, const ExactManhattan& exact, Dims dims, cl::Buffer dst,
                             SlabLayout layout, bool external)
    : ctx_(ctx), dst_(dst), external_(external) {
    const std::string what = "compact render field of " + dims.to_string();
    if (layout.slab_depth == 0 || layout.slab_stride_bytes % 2 != 0) {
        throw ClError("clSetKernelArg", CL_INVALID_VALUE,
                      what + ": bad slab layout (depth " + std::to_string(layout.slab_depth) +
                          ", stride " + std::to_string(layout.slab_stride_bytes) + " bytes)");
    }
    const cl::Program program = ctx.program(
        "render_field.cl", {cl_sources::layout_h, cl_sources::render_field_cl}, "-cl-std=CL1.2");
    cl_call(what, [&] {
        kernel_ = cl::Kernel(program, "to_compact");
        kernel_.setArg(0, exact.field_buffer());
        kernel_.setArg(1, exact.voxels_buffer());
        kernel_.setArg(2, dst);
        kernel_.setArg(3, static_cast<cl_ulong>(std::uint64_t{dims.x} * dims.y));
        kernel_.setArg(4, cl_uint{layout.slab_depth});
        kernel_.setArg(5, static_cast<cl_ulong>(layout.slab_stride_bytes / 2));
        kernel_.setArg(6, static_cast<cl_ulong>(dims.count()));
        const std::uint32_t b = VF_RAYMARCH_BLOCK;
        const std::size_t bx = (dims.x + b - 1) / b, by = (dims.y + b - 1) / b,
                          bz = (dims.z + b - 1) / b;
        block_count_ = bx * by * bz;
        block_min_ = cl::Buffer(ctx.context(), CL_MEM_READ_WRITE, 4 * block_count_);
        block_kernel_ = cl::Kernel(program, "block_min");
        block_kernel_.setArg(0, exact.field_buffer());
        block_kernel_.setArg(1, block_min_);
        block_kernel_.setArg(2, cl_uint4{{dims.x, dims.y, dims.z, 0}});
        blocks_ = cl::NDRange(bx, by, bz);
    });
    global_ = round_up(dims.count(), 64);
}

double CompactWriter::run() {
    if (external_) {
        acquire_external(ctx_, dst_);
    }
    return cl_call("writing the compact render field", [&] {
        cl::Event done;
        ctx_.queue().enqueueNDRangeKernel(kernel_, cl::NullRange, cl::NDRange(global_),
                                          cl::NullRange, nullptr, &done);
        ctx_.queue().enqueueNDRangeKernel(block_kernel_, cl::NullRange, blocks_);
        if (external_) {
            release_external(ctx_, dst_);
        }
        ctx_.queue().finish();  // Vulkan reads the field only after OpenCL finished writing it
        return elapsed_ms(done, done);
    });
}

std::vector<std::uint32_t> CompactWriter::block_min() {
    return cl_call("reading the ray marcher's block minima", [&] {
        std::vector<std::uint32_t> table(block_count_);
        ctx_.queue().enqueueReadBuffer(block_min_, CL_TRUE, 0, 4 * table.size(), table.data());
        return table;
    });
}

bool can_use_host_memory(const Context& ctx) {
    return ctx.is_cpu();
}

cl::Buffer wrap_host_memory(Context& ctx, void* host, std::size_t bytes) {
    return cl_call("clCreateBuffer(CL_MEM_USE_HOST_PTR) over " + std::to_string(bytes) +
                       " bytes of host memory shared with Vulkan",
                   [&] {
                       return cl::Buffer(ctx.context(), CL_MEM_READ_WRITE | CL_MEM_USE_HOST_PTR,
                                         bytes, host);
                   });
}

bool can_import_opaque_fd(const Context& ctx) {
    return ctx.info().has_extension("cl_khr_external_memory_opaque_fd") && platform_major(ctx) >= 3;
}

std::optional<std::array<std::uint8_t, 16>> device_uuid(const Context& ctx) {
    if (!ctx.info().has_extension("cl_khr_device_uuid")) {
        return std::nullopt;
    }
    std::array<std::uint8_t, 16> uuid{};
    const cl_int err =
        clGetDeviceInfo(ctx.info().device(), CL_DEVICE_UUID_KHR, uuid.size(), uuid.data(), nullptr);
    if (err != CL_SUCCESS) {
        throw ClError("clGetDeviceInfo", err, "CL_DEVICE_UUID_KHR of " + ctx.info().name);
    }
    return uuid;
}

cl::Buffer import_opaque_fd(Context& ctx, int fd, std::size_t bytes) {
    const std::string what = "importing " + std::to_string(bytes) +
                             " bytes of Vulkan memory (opaque fd) into " + ctx.info().name;
    if (!can_import_opaque_fd(ctx)) {
        throw ClError("clCreateBufferWithProperties", CL_INVALID_OPERATION,
                      what + ": the device lacks cl_khr_external_memory_opaque_fd or OpenCL 3.0");
    }
    const cl_mem_properties props[] = {
        static_cast<cl_mem_properties>(CL_EXTERNAL_MEMORY_HANDLE_OPAQUE_FD_KHR),
        static_cast<cl_mem_properties>(fd), 0};
    cl_int err = CL_SUCCESS;
    // clCreateBufferWithProperties is core OpenCL 3.0, dispatched by the ICD loader.
    cl_mem mem = clCreateBufferWithProperties(ctx.context()(), props, CL_MEM_READ_WRITE, bytes,
                                              nullptr, &err);
    if (err != CL_SUCCESS || mem == nullptr) {
        throw ClError("clCreateBufferWithProperties", err, what);
    }
    return cl::Buffer(mem);  // takes ownership of the reference
}

void acquire_external(Context& ctx, const cl::Buffer& buffer) {
    auto acquire = extension_function<clEnqueueAcquireExternalMemObjectsKHR_fn>(
        ctx, "clEnqueueAcquireExternalMemObjectsKHR");
    if (acquire == nullptr) {
        throw ClError("clGetExtensionFunctionAddressForPlatform", CL_INVALID_OPERATION,
                      "clEnqueueAcquireExternalMemObjectsKHR on " + ctx.info().name);
    }
    const cl_mem mem = buffer();
    const cl_int err = acquire(ctx.queue()(), 1, &mem, 0, nullptr, nullptr);
    if (err != CL_SUCCESS) {
        throw ClError("clEnqueueAcquireExternalMemObjectsKHR", err, "the shared render field");
    }
}

void release_external(Context& ctx, const cl::Buffer& buffer) {
    auto release = extension_function<clEnqueueReleaseExternalMemObjectsKHR_fn>(
        ctx, "clEnqueueReleaseExternalMemObjectsKHR");
    if (release == nullptr) {
        throw ClError("clGetExtensionFunctionAddressForPlatform", CL_INVALID_OPERATION,
                      "clEnqueueReleaseExternalMemObjectsKHR on " + ctx.info().name);
    }
    const cl_mem mem = buffer();
    const cl_int err = release(ctx.queue()(), 1, &mem, 0, nullptr, nullptr);
    if (err != CL_SUCCESS) {
        throw ClError("clEnqueueReleaseExternalMemObjectsKHR", err, "the shared render field");
    }
}

}  // namespace voxfield::ocl
