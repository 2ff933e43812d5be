// Writing the render field into memory shared with Vulkan (kernels: cl/kernels/render_field.cl).
#include "voxfield/cl/interop.hpp"

#include "voxfield/layout.h"

#include <CL/cl_ext.h>
#include <unistd.h>

#include <algorithm>
#include <cmath>
#include <cstring>
#include <exception>
#include <optional>
#include <stdexcept>
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

namespace {

constexpr std::size_t kLocal = 64;  // work-group size of both kernels

// render_field.cl's build options for a source field in `format`.
std::string source_options(Format format) {
    switch (format) {
        case Format::u8:
            return " -DVF_SRC_T=uchar -DVF_SRC_SHIFT=0 -DVF_SRC_MASK=0xFFu";
        case Format::u16:
            return " -DVF_SRC_T=ushort -DVF_SRC_SHIFT=0 -DVF_SRC_MASK=0xFFFFu";
        case Format::u32:
            return " -DVF_SRC_T=uint -DVF_SRC_SHIFT=0 -DVF_SRC_MASK=0xFFFFFFFFu";
        case Format::packed32:
            return " -DVF_SRC_T=uint -DVF_SRC_SHIFT=VF_PACKED_DISTANCE_SHIFT "
                   "-DVF_SRC_MASK=VF_PACKED_DISTANCE_MAX";
        case Format::i8:
        case Format::i16:
        case Format::i32:
        case Format::f32:
        case Format::f64:
            break;
    }
    throw InputError("the render field is made from a u8, u16, u32 or packed32 field, not " +
                     to_string(format) + " (integer formats hold every metric's distance)");
}

// Sets the box arguments (lo, size, count) from `first` and returns the 1-D launch size.
std::size_t set_box(cl::Kernel& kernel, cl_uint first, const Int3& lo, const Int3& hi) {
    const auto u = [](std::int64_t v) { return static_cast<cl_uint>(v); };
    const std::uint64_t count = static_cast<std::uint64_t>(hi.x - lo.x) *
                                static_cast<std::uint64_t>(hi.y - lo.y) *
                                static_cast<std::uint64_t>(hi.z - lo.z);
    kernel.setArg(first, cl_uint4{{u(lo.x), u(lo.y), u(lo.z), 0}});
    kernel.setArg(first + 1, cl_uint4{{u(hi.x - lo.x), u(hi.y - lo.y), u(hi.z - lo.z), 0}});
    kernel.setArg(first + 2, static_cast<cl_ulong>(count));
    return round_up(count, kLocal);
}

// An imported buffer held by OpenCL (cl_khr_external_memory) from construction to release():
// on a way out without release() (a throw) the release is still enqueued and the queue
// finished, so that Vulkan never finds the buffer left acquired.
class ExternalAcquire {
  public:
    ExternalAcquire(Context& ctx, const cl::Buffer& buffer) : ctx_(ctx), buffer_(buffer) {
        acquire_external(ctx_, buffer_);
        held_ = true;
    }
    ~ExternalAcquire() {
        if (held_) {
            // Unwinding already: the first error is the one reported.
            try {
                release_external(ctx_, buffer_);
                ctx_.queue().finish();
            } catch (const std::exception&) {
            }
        }
    }
    ExternalAcquire(const ExternalAcquire&) = delete;
    ExternalAcquire& operator=(const ExternalAcquire&) = delete;
    void release() {
        held_ = false;
        release_external(ctx_, buffer_);
    }

  private:
    Context& ctx_;
    const cl::Buffer& buffer_;
    bool held_ = false;
};

}  // namespace

CompactWriter::CompactWriter(Context& ctx, const cl::Buffer& field, Format format,
                             const cl::Buffer& voxels, Dims dims, cl::Buffer dst, SlabLayout layout,
                             DstMemory dst_memory, double step)
    : ctx_(ctx), dims_(dims), dst_(dst), dst_memory_(dst_memory) {
    if (!(step > 0) || !std::isfinite(step)) {
        throw std::invalid_argument("CompactWriter: the voxel step must be positive and finite");
    }
    // 1 / step rounded down with room for the kernel's float rounding (relative 2^-23 on
    // distances below 2^20), so that floor(d * inv) never exceeds d / step.
    const float inv_step =
        step == 1.0 ? 1.0f : static_cast<float>((1.0 / step) * (1.0 - std::ldexp(1.0, -20)));
    const std::string what = "compact render field of " + dims.to_string();
    if (layout.slab_depth == 0 || layout.slab_stride_bytes % 2 != 0) {
        throw ClError("clSetKernelArg", CL_INVALID_VALUE,
                      what + ": bad slab layout (depth " + std::to_string(layout.slab_depth) +
                          ", stride " + std::to_string(layout.slab_stride_bytes) + " bytes)");
    }
    const std::uint32_t b = VF_RAYMARCH_BLOCK;
    blocks_ = Dims{(dims.x + b - 1) / b, (dims.y + b - 1) / b, (dims.z + b - 1) / b};
    const std::size_t table_bytes = 4 * blocks_.count();
    if (layout.block_min_offset) {
        block_min_offset_ = *layout.block_min_offset;
        if (block_min_offset_ % 4 != 0 ||
            block_min_offset_ + table_bytes > dst.getInfo<CL_MEM_SIZE>()) {
            throw ClError("clSetKernelArg", CL_INVALID_VALUE,
                          what + ": the block minima (" + std::to_string(table_bytes) +
                              " bytes at " + std::to_string(block_min_offset_) +
                              ") do not fit in the destination");
        }
    }
    const cl::Program program =
        ctx.program("render_field.cl", {cl_sources::layout_h, cl_sources::render_field_cl},
                    "-cl-std=CL1.2" + source_options(format));
    const cl_uint4 d{{dims.x, dims.y, dims.z, 0}};
    cl_call(what, [&] {
        kernel_ = cl::Kernel(program, "to_compact");
        kernel_.setArg(0, field);
        kernel_.setArg(1, voxels);
        kernel_.setArg(2, dst);
        kernel_.setArg(3, d);
        kernel_.setArg(4, cl_uint{layout.slab_depth});
        kernel_.setArg(5, static_cast<cl_ulong>(layout.slab_stride_bytes / 2));
        kernel_.setArg(8, inv_step);
        block_min_ = layout.block_min_offset
                         ? dst
                         : cl::Buffer(ctx.context(), CL_MEM_READ_WRITE, table_bytes);
        block_kernel_ = cl::Kernel(program, "block_min");
        block_kernel_.setArg(0, field);
        block_kernel_.setArg(1, block_min_);
        block_kernel_.setArg(2, d);
        block_kernel_.setArg(6, inv_step);
        block_kernel_.setArg(7, static_cast<cl_ulong>(block_min_offset_ / 4));
    });
}

CompactWriter::~CompactWriter() {
    if (mapped_ != nullptr) {
        // Nothing to report from a destructor: the buffer is released after this anyway.
        try {
            ctx_.queue().enqueueUnmapMemObject(dst_, mapped_);
            ctx_.queue().finish();
        } catch (const std::exception&) {
        }
    }
}

double CompactWriter::run() {
    return run({Box{{0, 0, 0}, {dims_.x, dims_.y, dims_.z}}});
}

void CompactWriter::enqueue_regions(const std::vector<Box>& regions,
                                    std::vector<cl::Event>& events) {
    const Box world{{0, 0, 0}, {dims_.x, dims_.y, dims_.z}};
    const std::int64_t b = VF_RAYMARCH_BLOCK;
    changed_blocks_.clear();
    for (const Box& region : regions) {
        const Box r = intersect(region, world);
        if (r.empty()) {
            continue;
        }
        const auto u = [](std::int64_t v) { return static_cast<cl_uint>(v); };
        const Int3 n{r.max.x - r.min.x, r.max.y - r.min.y, r.max.z - r.min.z};
        kernel_.setArg(6, cl_uint4{{u(r.min.x), u(r.min.y), u(r.min.z), 0}});
        kernel_.setArg(7, cl_uint4{{u(n.x), u(n.y), u(n.z), 0}});
        events.emplace_back();
        ctx_.queue().enqueueNDRangeKernel(
            kernel_, cl::NullRange,
            cl::NDRange(round_up(static_cast<std::size_t>(n.x), kLocal),
                        static_cast<std::size_t>(n.y), static_cast<std::size_t>(n.z)),
            cl::NDRange(kLocal, 1, 1), nullptr, &events.back());
        const Int3 lo{r.min.x / b, r.min.y / b, r.min.z / b};
        const Int3 hi{(r.max.x + b - 1) / b, (r.max.y + b - 1) / b, (r.max.z + b - 1) / b};
        changed_blocks_.push_back(Box{lo, hi});
        events.emplace_back();
        ctx_.queue().enqueueNDRangeKernel(block_kernel_, cl::NullRange,
                                          cl::NDRange(set_box(block_kernel_, 3, lo, hi)),
                                          cl::NDRange(kLocal), nullptr, &events.back());
    }
}

double CompactWriter::run_ordered(const std::vector<Box>& regions, const ExternalSemaphore* wait,
                                  const ExternalSemaphore& signal) {
    if (dst_memory_ != DstMemory::external) {
        throw std::logic_error(
            "CompactWriter::run_ordered: the destination is not imported memory");
    }
    return cl_call("writing the compact render field (ordered by semaphores)", [&] {
        // The times of the earlier ordered runs that have finished (a failed one counts
        // nothing), before anything is enqueued: a failing query then changes no semaphore.
        double ms = 0;
        std::erase_if(ordered_, [&](const std::pair<cl::Event, cl::Event>& run) {
            const cl_int status = run.second.getInfo<CL_EVENT_COMMAND_EXECUTION_STATUS>();
            if (status == CL_COMPLETE) {
                ms += elapsed_ms(run.first, run.second);
            }
            return status == CL_COMPLETE || status < 0;
        });
        std::vector<cl::Event> events;
        if (wait != nullptr) {
            wait->enqueue_wait(ctx_);  // the frames that read dst have finished
        }
        {
            ExternalAcquire acquired(ctx_, dst_);
            enqueue_regions(regions, events);
            acquired.release();
        }
        signal.enqueue_signal(ctx_);  // after the release: the next frames may read dst
        ctx_.queue().flush();
        if (!events.empty()) {
            ordered_.emplace_back(events.front(), events.back());
        }
        return ms;
    });
}

double CompactWriter::run(const std::vector<Box>& regions) {
    return cl_call("writing the compact render field", [&] {
        std::vector<cl::Event> events;
        std::optional<ExternalAcquire> acquired;
        if (dst_memory_ == DstMemory::external) {
            acquired.emplace(ctx_, dst_);
        }
        if (mapped_ != nullptr) {
            // Path 2: the host gives the pages back before the kernels write them.
            ctx_.queue().enqueueUnmapMemObject(dst_, mapped_);
            mapped_ = nullptr;
        }
        enqueue_regions(regions, events);
        if (acquired) {
            acquired->release();
        }
        if (dst_memory_ == DstMemory::host) {
            // Path 2: mapped for reading, the kernels' writes are visible through the host
            // pointer, which Vulkan reads, until the next run.
            const std::size_t bytes = dst_.getInfo<CL_MEM_SIZE>();
            void* host = dst_.getInfo<CL_MEM_HOST_PTR>();
            mapped_ = ctx_.queue().enqueueMapBuffer(dst_, CL_FALSE, CL_MAP_READ, 0, bytes);
            if (mapped_ != host) {
                ctx_.queue().finish();
                ctx_.queue().enqueueUnmapMemObject(dst_, mapped_);
                mapped_ = nullptr;
                ctx_.queue().finish();
                throw ClError("clEnqueueMapBuffer", CL_INVALID_OPERATION,
                              "the shared render field was mapped at a copy, not at the host "
                              "memory Vulkan reads (CL_MEM_USE_HOST_PTR is not zero-copy here)");
            }
        }
        ctx_.queue().finish();  // Vulkan reads the field only after OpenCL finished writing it
        return events.empty() ? 0.0 : elapsed_ms(events.front(), events.back());
    });
}

std::vector<std::uint32_t> CompactWriter::block_min() {
    return block_min({Box{{0, 0, 0}, {blocks_.x, blocks_.y, blocks_.z}}});
}

std::vector<std::uint32_t> CompactWriter::block_min(const std::vector<Box>& blocks) {
    const Box grid{{0, 0, 0}, {blocks_.x, blocks_.y, blocks_.z}};
    std::size_t words = 0;
    for (const Box& box : blocks) {
        if (!box.empty() && intersect(box, grid) != box) {
            throw std::invalid_argument(
                "CompactWriter::block_min: a block box leaves the grid of " + blocks_.to_string() +
                " blocks");
        }
        words += box.empty() ? 0 : static_cast<std::size_t>(box.volume());
    }
    return cl_call("reading the ray marcher's block minima", [&] {
        std::vector<std::uint32_t> table(words);
        std::size_t next = 0;
        // Row by row of blocks (contiguous in the table), rows that continue each other in
        // one read (a box of whole rows or slices: one read); one wait for them all.
        std::size_t run_first = 0, run_words = 0;
        const auto flush = [&] {
            if (run_words != 0) {
                ctx_.queue().enqueueReadBuffer(block_min_, CL_FALSE,
                                               block_min_offset_ + 4 * run_first, 4 * run_words,
                                               table.data() + next);
                next += run_words;
            }
            run_words = 0;
        };
        for (const Box& box : blocks) {
            if (box.empty()) {
                continue;
            }
            const auto row = static_cast<std::size_t>(box.max.x - box.min.x);
            for (std::int64_t z = box.min.z; z < box.max.z; ++z) {
                for (std::int64_t y = box.min.y; y < box.max.y; ++y) {
                    const auto first =
                        static_cast<std::size_t>((z * blocks_.y + y) * blocks_.x + box.min.x);
                    if (run_words == 0 || first != run_first + run_words) {
                        flush();
                        run_first = first;
                    }
                    run_words += row;
                }
            }
        }
        flush();
        ctx_.queue().finish();
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

namespace {

// A file descriptor closed when it goes out of scope unless released (fd = -1): an imported
// handle is ours until a successful import hands it to the OpenCL implementation.
struct OwnedFd {
    int fd;
    ~OwnedFd() {
        if (fd >= 0) {
            close(fd);
        }
    }
};

}  // namespace

cl::Buffer import_opaque_fd(Context& ctx, int fd, std::size_t bytes) {
    // Ours until a successful import hands it to the OpenCL implementation.
    OwnedFd owned{fd};
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
    owned.fd = -1;           // the OpenCL implementation owns it now
    return cl::Buffer(mem);  // takes ownership of the reference
}

bool can_import_semaphore_fd(const Context& ctx) {
    const DeviceInfo& info = ctx.info();
    if (!info.has_extension("cl_khr_external_semaphore") ||
        !info.has_extension("cl_khr_external_semaphore_opaque_fd")) {
        return false;
    }
    // A list of cl_uint values of the device (nullopt: the query is not answered).
    const auto device_list = [&](cl_device_info what) -> std::optional<std::vector<cl_uint>> {
        std::size_t bytes = 0;
        if (clGetDeviceInfo(info.device(), what, 0, nullptr, &bytes) != CL_SUCCESS) {
            return std::nullopt;
        }
        std::vector<cl_uint> values(bytes / sizeof(cl_uint));
        if (!values.empty() && clGetDeviceInfo(info.device(), what, values.size() * sizeof(cl_uint),
                                               values.data(), nullptr) != CL_SUCCESS) {
            return std::nullopt;
        }
        return values;
    };
    const auto has = [](const std::optional<std::vector<cl_uint>>& values, cl_uint v) {
        return values && std::find(values->begin(), values->end(), v) != values->end();
    };
    // Binary semaphores are cl_khr_semaphore's one type: refused only where the device lists
    // its types without it.
    const auto types = device_list(CL_DEVICE_SEMAPHORE_TYPES_KHR);
    return has(device_list(CL_DEVICE_SEMAPHORE_IMPORT_HANDLE_TYPES_KHR),
               CL_SEMAPHORE_HANDLE_OPAQUE_FD_KHR) &&
           (!types || has(types, CL_SEMAPHORE_TYPE_BINARY_KHR)) &&
           extension_function<clCreateSemaphoreWithPropertiesKHR_fn>(
               ctx, "clCreateSemaphoreWithPropertiesKHR") != nullptr &&
           extension_function<clEnqueueWaitSemaphoresKHR_fn>(ctx, "clEnqueueWaitSemaphoresKHR") !=
               nullptr &&
           extension_function<clEnqueueSignalSemaphoresKHR_fn>(
               ctx, "clEnqueueSignalSemaphoresKHR") != nullptr &&
           extension_function<clReleaseSemaphoreKHR_fn>(ctx, "clReleaseSemaphoreKHR") != nullptr;
}

ExternalSemaphore::ExternalSemaphore(Context& ctx, int fd) : platform_(platform_of(ctx)) {
    // Ours until a successful import hands it to the OpenCL implementation
    // (cl_khr_external_semaphore, "File Descriptor Handle Types").
    OwnedFd owned{fd};
    const std::string what = "importing a Vulkan semaphore (opaque fd) into " + ctx.info().name;
    if (!can_import_semaphore_fd(ctx)) {
        throw ClError("clCreateSemaphoreWithPropertiesKHR", CL_INVALID_OPERATION,
                      what + ": the device lacks cl_khr_external_semaphore_opaque_fd");
    }
    auto create = extension_function<clCreateSemaphoreWithPropertiesKHR_fn>(
        ctx, "clCreateSemaphoreWithPropertiesKHR");
    // No device list: the context has one device, for which the list is optional; its
    // property's value differs between the provisional extension that Debian's header
    // describes (CL_DEVICE_HANDLE_LIST_KHR, 0x2051) and the final one (0x2053).
    const cl_semaphore_properties_khr props[] = {
        static_cast<cl_semaphore_properties_khr>(CL_SEMAPHORE_TYPE_KHR),
        static_cast<cl_semaphore_properties_khr>(CL_SEMAPHORE_TYPE_BINARY_KHR),
        static_cast<cl_semaphore_properties_khr>(CL_SEMAPHORE_HANDLE_OPAQUE_FD_KHR),
        static_cast<cl_semaphore_properties_khr>(fd), 0};
    cl_int err = CL_SUCCESS;
    cl_semaphore_khr semaphore = create(ctx.context()(), props, &err);
    if (err != CL_SUCCESS || semaphore == nullptr) {
        throw ClError("clCreateSemaphoreWithPropertiesKHR", err, what);
    }
    owned.fd = -1;  // the OpenCL implementation owns it now
    semaphore_ = semaphore;
}

ExternalSemaphore::~ExternalSemaphore() {
    release();
}

ExternalSemaphore::ExternalSemaphore(ExternalSemaphore&& o) noexcept
    : semaphore_(std::exchange(o.semaphore_, nullptr)), platform_(o.platform_) {}

ExternalSemaphore& ExternalSemaphore::operator=(ExternalSemaphore&& o) noexcept {
    if (this != &o) {
        release();
        semaphore_ = std::exchange(o.semaphore_, nullptr);
        platform_ = o.platform_;
    }
    return *this;
}

void ExternalSemaphore::release() noexcept {
    if (semaphore_ != nullptr) {
        auto release = reinterpret_cast<clReleaseSemaphoreKHR_fn>(
            clGetExtensionFunctionAddressForPlatform(platform_, "clReleaseSemaphoreKHR"));
        if (release != nullptr) {
            release(semaphore_);
        }
        semaphore_ = nullptr;
    }
}

namespace {

// clEnqueueWaitSemaphoresKHR or clEnqueueSignalSemaphoresKHR (the same signature) of one
// semaphore on ctx's queue; `what` names the work it orders.
template <typename Fn>
void enqueue_semaphore(Context& ctx, const char* name, cl_semaphore_khr semaphore,
                       const std::string& what) {
    auto fn = extension_function<Fn>(ctx, name);
    if (fn == nullptr || semaphore == nullptr) {
        throw ClError(name, CL_INVALID_OPERATION,
                      "no imported semaphore or entry point on " + ctx.info().name);
    }
    const cl_int err = fn(ctx.queue()(), 1, &semaphore, nullptr, 0, nullptr, nullptr);
    if (err != CL_SUCCESS) {
        throw ClError(name, err, what);
    }
}

}  // namespace

void ExternalSemaphore::enqueue_wait(Context& ctx) const {
    enqueue_semaphore<clEnqueueWaitSemaphoresKHR_fn>(ctx, "clEnqueueWaitSemaphoresKHR", semaphore_,
                                                     "the frames reading the render field");
}

void ExternalSemaphore::enqueue_signal(Context& ctx) const {
    enqueue_semaphore<clEnqueueSignalSemaphoresKHR_fn>(ctx, "clEnqueueSignalSemaphoresKHR",
                                                       semaphore_, "the render field written");
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
