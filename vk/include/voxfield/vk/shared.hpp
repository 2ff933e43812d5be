#pragma once
// Memory that OpenCL and Vulkan both see (DESIGN §2 "Sharing buffers between OpenCL and
// Vulkan"): path 1 exports Vulkan device memory as an opaque fd for OpenCL to import; path 2
// imports one page-aligned host allocation that OpenCL uses with CL_MEM_USE_HOST_PTR. Path 3
// (copy) needs none of this. vk/ never includes OpenCL headers: the OpenCL side takes the fd
// or the host pointer (voxfield/cl/interop.hpp).
#include <cstdint>
#include <string>

#include "voxfield/vk/context.hpp"

namespace voxfield::vk {

enum class SharingPath { opaque_fd = 1, host_pointer = 2, copy = 3 };

// "path 1: Vulkan-exported memory imported by OpenCL (opaque fd)", ...
std::string describe(SharingPath path);

// Whether this Vulkan device can take part in `path` (its extension is enabled; copy: always).
// Whether the OpenCL device can as well is for cl/ to say.
bool supports(const Context& ctx, SharingPath path);

// Move-only. The memory is freed after every buffer bound to it is gone (callers destroy
// their buffers first) and, for path 2, the host allocation after the Vulkan memory; the
// OpenCL buffer using it must be released before this object is destroyed.
class ExternalMemory {
  public:
    ExternalMemory() = default;
    ~ExternalMemory();
    ExternalMemory(ExternalMemory&& o) noexcept;
    ExternalMemory& operator=(ExternalMemory&& o) noexcept;
    ExternalMemory(const ExternalMemory&) = delete;
    ExternalMemory& operator=(const ExternalMemory&) = delete;

    // Path 2: `bytes` (rounded up to minImportedHostPointerAlignment) of zeroed host memory
    // from posix_memalign, imported with VkImportMemoryHostPointerInfoEXT. Buffers bound to
    // it must come from make_external_buffer(..., handle_type()).
    static ExternalMemory host_allocation(Context& ctx, VkDeviceSize bytes,
                                          VkBufferUsageFlags usage, const std::string& what);
    // Path 1: device memory allocated exportable as an opaque fd (VkExportMemoryAllocateInfo).
    static ExternalMemory exportable(Context& ctx, VkDeviceSize bytes, VkBufferUsageFlags usage,
                                     const std::string& what);

    SharingPath path() const { return path_; }
    VkDeviceMemory memory() const { return memory_.get(); }
    VkDeviceSize size() const { return size_; }
    // The memory type index it was allocated with (an importer of path 1's fd on another
    // VkDevice of the same GPU allocates with the same index and size).
    std::uint32_t memory_type() const { return memory_type_; }
    VkExternalMemoryHandleTypeFlags handle_type() const { return handle_type_; }
    // Path 2: the host allocation (nullptr otherwise).
    void* host_pointer() const { return host_; }
    // Path 1: a new file descriptor for the memory (vkGetMemoryFdKHR); the caller owns it.
    int export_fd() const;

  private:
    void release() noexcept;

    Context* ctx_ = nullptr;
    SharingPath path_ = SharingPath::copy;
    Owned<VkDeviceMemory> memory_;
    VkDeviceSize size_ = 0;
    std::uint32_t memory_type_ = 0;
    VkExternalMemoryHandleTypeFlags handle_type_ = 0;
    void* host_ = nullptr;  // freed after memory_
};

// Ordering OpenCL's writes into path 1's memory against the frames that read it, without a
// CPU wait (DESIGN §2 "Synchronisation"): binary semaphores created here, exported as opaque
// fds (VK_KHR_external_semaphore_fd) and imported by OpenCL (cl_khr_external_semaphore_opaque_fd,
// ocl::ExternalSemaphore); Context::signal_semaphore / wait_semaphore use them on the queue.
// Whether this device can: the extension is enabled and a binary semaphore can be exported as
// an opaque fd (vkGetPhysicalDeviceExternalSemaphoreProperties).
bool can_export_semaphore_fd(const Context& ctx);

// A binary semaphore exportable as an opaque fd. Move-only; destroyed with vkDestroySemaphore,
// which the owner calls only after every batch and every OpenCL command that uses it has
// finished, and after OpenCL released its import.
class ExportedSemaphore {
  public:
    ExportedSemaphore() = default;
    // Throws VkError when the device cannot (can_export_semaphore_fd).
    ExportedSemaphore(Context& ctx, const std::string& what);
    VkSemaphore get() const { return semaphore_.get(); }
    // A new file descriptor for the semaphore (vkGetSemaphoreFdKHR); the caller owns it (an
    // import elsewhere may take it over, ocl::ExternalSemaphore does).
    int export_fd() const;

  private:
    Context* ctx_ = nullptr;
    Owned<VkSemaphore> semaphore_;
    std::string what_;
};

}  // namespace voxfield::vk
