#pragma once
// Writing the renderer's field straight into memory Vulkan reads (DESIGN §2 sharing paths 1
// and 2). cl/ never includes Vulkan headers: it takes a host pointer or a file descriptor.
#include <array>
#include <cstddef>
#include <cstdint>
#include <optional>
#include <utility>
#include <vector>

#include <CL/cl_ext.h>

#include "voxfield/cl/runtime.hpp"
#include "voxfield/core/chunks.hpp"
#include "voxfield/core/format.hpp"
#include "voxfield/core/world.hpp"

namespace voxfield::ocl {

// Where the field's z-slabs lie in the destination buffer (the ray marcher's FieldLayout),
// and its block minima.
struct SlabLayout {
    std::uint32_t slab_depth = 0;         // z-slices per slab
    std::uint64_t slab_stride_bytes = 0;  // slab s starts at s * slab_stride_bytes (even)
    // The block-minimum table at this byte offset of the destination (a multiple of 4, past
    // the slabs): paths 1/2, where the ray marcher reads it in place
    // (vk::Raymarcher::bind_shared_block_min). Absent: in a buffer of the writer's own, read
    // back with block_min() (path 3).
    std::optional<std::uint64_t> block_min_offset;
};

// Converts a distance field and its world's voxels into the compact render format (layout.h
// VF_COMPACT_*, 2 bytes per voxel) in `dst`, and computes the ray marcher's coarse table
// (per-block minimum distance; in `dst` or its own buffer, SlabLayout::block_min_offset).
// `field` holds the field in `format` (DESIGN §3;
// packed32 contributes its 8-bit distance, so its block minima are at most 255), `voxels` one
// byte per voxel; both x fastest, dims.count() elements. Holds references to the three
// buffers; run() again after the field changed. `dst_memory` says who else reads dst (below).
// Where dst is: OpenCL's own memory (path 3: read back with clEnqueueRead*), memory imported
// with import_opaque_fd (path 1: run() acquires it before the kernels and releases it after,
// clEnqueueAcquire/ReleaseExternalMemObjectsKHR), or host memory wrapped by wrap_host_memory
// (path 2: the host, i.e. Vulkan's import of the same pages, may read it only while OpenCL has
// it mapped, OpenCL 3.0 §5.5.2 "Accessing mapped regions" / CL_MEM_USE_HOST_PTR: run() unmaps
// it before the kernels write and maps it for reading again after them, so that between runs,
// and from construction until the writer is destroyed, dst is mapped whole; the mapped pointer
// is the host pointer itself, checked).
enum class DstMemory { device, external, host };

class ExternalSemaphore;

class CompactWriter {
  public:
    // `step`: the field's largest voxel spacing; its distances (in the spacing's units) are
    // turned into lower bounds in voxels, floor(d / step), which the ray marcher steps by.
    CompactWriter(Context& ctx, const cl::Buffer& field, Format format, const cl::Buffer& voxels,
                  Dims dims, cl::Buffer dst, SlabLayout layout,
                  DstMemory dst_memory = DstMemory::device, double step = 1.0);
    // Path 2: unmaps dst (and waits for that).
    ~CompactWriter();
    CompactWriter(const CompactWriter&) = delete;
    CompactWriter& operator=(const CompactWriter&) = delete;
    // Converts the whole field, or only the voxels of `regions` (boxes clipped to the world;
    // the block minima of every block they touch are recomputed, and no others). Enqueues
    // the kernels and waits for them (clFinish): afterwards Vulkan may read dst, field and
    // table. Returns the kernels' time in ms (profiling events).
    double run();
    double run(const std::vector<Box>& regions);
    // Path 1 ordered on the devices (cl_khr_external_semaphore, DESIGN §2 "Synchronisation"):
    // as run(regions), but the kernels first wait for `wait` (when given: Vulkan signalled it
    // after the frames that read dst), and `signal` is signalled after dst's release, for the
    // frames that read next to wait for. Nothing is waited for on the host (the queue is
    // flushed). Returns the kernels' time in ms of the earlier ordered runs found finished
    // when it is called (event status, no wait): a run's time counts at a later call, usually
    // the next. Throws std::logic_error unless dst is external memory.
    double run_ordered(const std::vector<Box>& regions, const ExternalSemaphore* wait,
                       const ExternalSemaphore& signal);
    // The blocks whose minima the last run() recomputed: per region that met the world, the
    // box of blocks covering it (block coordinates over ceil(dims / VF_RAYMARCH_BLOCK); boxes
    // of overlapping regions may overlap).
    const std::vector<Box>& changed_blocks() const { return changed_blocks_; }
    // The per-block minima (layout.h VF_RAYMARCH_BLOCK; x fastest), read back: the whole
    // table (1/512 of the voxels), or only the blocks of `blocks` (block boxes inside the
    // grid, e.g. changed_blocks()), box after box and x fastest in each, which is all that
    // path 3 copies into the ray marcher after an edit (vk::Raymarcher::update_block_min).
    std::vector<std::uint32_t> block_min();
    std::vector<std::uint32_t> block_min(const std::vector<Box>& blocks);

  private:
    // Enqueues the two kernels per region that meets the world (their events in `events`) and
    // notes the blocks they recompute.
    void enqueue_regions(const std::vector<Box>& regions, std::vector<cl::Event>& events);

    Context& ctx_;
    Dims dims_, blocks_;
    cl::Buffer dst_, block_min_;          // block_min_: dst_ itself or the writer's own buffer
    std::uint64_t block_min_offset_ = 0;  // bytes
    cl::Kernel kernel_, block_kernel_;
    DstMemory dst_memory_ = DstMemory::device;
    void* mapped_ = nullptr;  // path 2: dst mapped for reading (the host pointer)
    std::vector<Box> changed_blocks_;
    // run_ordered: the first and last kernel event of the runs whose time is not counted yet.
    std::vector<std::pair<cl::Event, cl::Event>> ordered_;
};

// Path 2: CL_MEM_USE_HOST_PTR is zero-copy on CPU devices (PoCL's pthread device computes in
// host memory), so this is true exactly for CPU devices.
bool can_use_host_memory(const Context& ctx);
// A buffer over `bytes` at `host` (CL_MEM_READ_WRITE | CL_MEM_USE_HOST_PTR). The memory must
// stay allocated until the buffer (every copy of the handle) is released. Anything else that
// reads `host` (Vulkan) may do so only while the buffer is mapped (CompactWriter with
// DstMemory::host keeps it so).
cl::Buffer wrap_host_memory(Context& ctx, void* host, std::size_t bytes);

// Path 1: the device has cl_khr_external_memory_opaque_fd and its platform exports
// clCreateBufferWithPropertiesKHR or clCreateBufferWithProperties (OpenCL 3.0).
bool can_import_opaque_fd(const Context& ctx);
// CL_DEVICE_UUID_KHR (cl_khr_device_uuid), to match the Vulkan device's deviceUUID.
std::optional<std::array<std::uint8_t, 16>> device_uuid(const Context& ctx);
// A buffer over memory exported by Vulkan as an opaque fd
// (CL_EXTERNAL_MEMORY_HANDLE_OPAQUE_FD_KHR). Takes `fd` on every way out: cl_khr_external_memory
// ("File Descriptor Handle Types") says a successful import transfers the fd's ownership to the
// OpenCL implementation and the application must not perform any operation on it afterwards
// (as vkAllocateMemory's import does in Vulkan); when the import fails (or is not attempted) the
// fd is closed here. The caller never closes it.
cl::Buffer import_opaque_fd(Context& ctx, int fd, std::size_t bytes);
// cl_khr_external_memory ordering: enqueue the acquire before OpenCL uses an imported buffer
// and the release after (the queue is finished before Vulkan reads it).
void acquire_external(Context& ctx, const cl::Buffer& buffer);
void release_external(Context& ctx, const cl::Buffer& buffer);

// Path 1's ordering without a CPU wait: binary semaphores that Vulkan created and exported as
// opaque fds (vk::ExportedSemaphore), imported here. The device has cl_khr_external_semaphore
// and cl_khr_external_semaphore_opaque_fd, imports CL_SEMAPHORE_HANDLE_OPAQUE_FD_KHR
// (CL_DEVICE_SEMAPHORE_IMPORT_HANDLE_TYPES_KHR) and binary semaphores, and its platform exports
// the cl_khr_semaphore entry points.
bool can_import_semaphore_fd(const Context& ctx);

// A binary semaphore imported from an opaque fd (CL_SEMAPHORE_HANDLE_OPAQUE_FD_KHR) into the
// context's one device. Move-only; released (clReleaseSemaphoreKHR) when destroyed, which the
// owner does after the queue finished every command using it and before the exporting API
// destroys its semaphore.
class ExternalSemaphore {
  public:
    ExternalSemaphore() = default;
    // Takes `fd` on every way out, as import_opaque_fd does: cl_khr_external_semaphore ("File
    // Descriptor Handle Types") says importing a semaphore payload from a file descriptor
    // transfers its ownership to the OpenCL implementation and the application must not perform
    // any operation on it after a successful import; when the import fails (or is not
    // attempted) the fd is closed here. The caller never closes it.
    ExternalSemaphore(Context& ctx, int fd);
    ~ExternalSemaphore();
    ExternalSemaphore(ExternalSemaphore&& o) noexcept;
    ExternalSemaphore& operator=(ExternalSemaphore&& o) noexcept;
    ExternalSemaphore(const ExternalSemaphore&) = delete;
    ExternalSemaphore& operator=(const ExternalSemaphore&) = delete;
    // clEnqueueWaitSemaphoresKHR / clEnqueueSignalSemaphoresKHR on the context's queue.
    void enqueue_wait(Context& ctx) const;
    void enqueue_signal(Context& ctx) const;

  private:
    void release() noexcept;

    cl_semaphore_khr semaphore_ = nullptr;
    cl_platform_id platform_ = nullptr;
};

}  // namespace voxfield::ocl
