#include "voxfield/vk/shared.hpp"

#include <algorithm>
#include <cstdlib>
#include <cstring>
#include <stdexcept>
#include <utility>

namespace voxfield::vk {
namespace {

VkDeviceSize round_up(VkDeviceSize v, VkDeviceSize a) {
    return a == 0 ? v : (v + a - 1) / a * a;
}

template <class F>
F device_function(const Context& ctx, const char* name) {
    auto f = reinterpret_cast<F>(vkGetDeviceProcAddr(ctx.device(), name));
    if (f == nullptr) {
        throw VkError("vkGetDeviceProcAddr", VK_ERROR_EXTENSION_NOT_PRESENT,
                      std::string(name) + " on " + ctx.info().name);
    }
    return f;
}

// Memory for buffers read through device addresses (VK_BUFFER_USAGE_SHADER_DEVICE_ADDRESS_BIT in
// `usage`) is allocated with VK_MEMORY_ALLOCATE_DEVICE_ADDRESS_BIT; flags 0 otherwise.
VkMemoryAllocateFlagsInfo address_flags(VkBufferUsageFlags usage) {
    VkMemoryAllocateFlagsInfo info{};
    info.sType = VK_STRUCTURE_TYPE_MEMORY_ALLOCATE_FLAGS_INFO;
    if ((usage & VK_BUFFER_USAGE_SHADER_DEVICE_ADDRESS_BIT) != 0) {
        info.flags = VK_MEMORY_ALLOCATE_DEVICE_ADDRESS_BIT;
    }
    return info;
}

}  // namespace

std::string describe(SharingPath path) {
    switch (path) {
        case SharingPath::opaque_fd:
            return "path 1: Vulkan-exported device memory imported by OpenCL (opaque fd), no copy";
        case SharingPath::host_pointer:
            return "path 2: one host allocation used by OpenCL (CL_MEM_USE_HOST_PTR) and "
                   "imported by Vulkan (VK_EXT_external_memory_host), no copy";
        case SharingPath::copy:
            break;
    }
    return "path 3: copy (the field is read back from OpenCL and uploaded to Vulkan)";
}

bool supports(const Context& ctx, SharingPath path) {
    switch (path) {
        case SharingPath::opaque_fd:
            return ctx.enabled(VK_KHR_EXTERNAL_MEMORY_FD_EXTENSION_NAME);
        case SharingPath::host_pointer:
            return ctx.enabled(VK_EXT_EXTERNAL_MEMORY_HOST_EXTENSION_NAME) &&
                   ctx.info().min_imported_host_pointer_alignment != 0;
        case SharingPath::copy:
            break;
    }
    return true;
}

ExternalMemory::~ExternalMemory() {
    release();
}

ExternalMemory::ExternalMemory(ExternalMemory&& o) noexcept
    : ctx_(o.ctx_),
      path_(o.path_),
      memory_(std::move(o.memory_)),
      size_(std::exchange(o.size_, 0)),
      memory_type_(o.memory_type_),
      handle_type_(o.handle_type_),
      host_(std::exchange(o.host_, nullptr)) {}

ExternalMemory& ExternalMemory::operator=(ExternalMemory&& o) noexcept {
    if (this != &o) {
        release();
        ctx_ = o.ctx_;
        path_ = o.path_;
        memory_ = std::move(o.memory_);
        size_ = std::exchange(o.size_, 0);
        memory_type_ = o.memory_type_;
        handle_type_ = o.handle_type_;
        host_ = std::exchange(o.host_, nullptr);
    }
    return *this;
}

void ExternalMemory::release() noexcept {
    memory_.reset();  // the Vulkan import first, then the host allocation it refers to
    std::free(host_);
    host_ = nullptr;
}

ExternalMemory ExternalMemory::host_allocation(Context& ctx, VkDeviceSize bytes,
                                               VkBufferUsageFlags usage, const std::string& what) {
    if (!supports(ctx, SharingPath::host_pointer)) {
        throw VkError("vkAllocateMemory", VK_ERROR_EXTENSION_NOT_PRESENT,
                      what + ": " + ctx.info().name + " lacks VK_EXT_external_memory_host");
    }
    const VkExternalMemoryHandleTypeFlagBits type =
        VK_EXTERNAL_MEMORY_HANDLE_TYPE_HOST_ALLOCATION_BIT_EXT;
    const VkDeviceSize align =
        std::max<VkDeviceSize>(ctx.info().min_imported_host_pointer_alignment, 4096);
    ExternalMemory m;
    m.ctx_ = &ctx;
    m.path_ = SharingPath::host_pointer;
    m.handle_type_ = type;
    m.size_ = round_up(std::max<VkDeviceSize>(bytes, 4), align);
    void* host = nullptr;
    if (posix_memalign(&host, static_cast<std::size_t>(align), static_cast<std::size_t>(m.size_)) !=
        0) {
        throw VkError("posix_memalign", VK_ERROR_OUT_OF_HOST_MEMORY,
                      what + ", " + std::to_string(m.size_) + " bytes");
    }
    m.host_ = host;
    std::memset(host, 0, static_cast<std::size_t>(m.size_));

    auto properties = device_function<PFN_vkGetMemoryHostPointerPropertiesEXT>(
        ctx, "vkGetMemoryHostPointerPropertiesEXT");
    VkMemoryHostPointerPropertiesEXT props{};
    props.sType = VK_STRUCTURE_TYPE_MEMORY_HOST_POINTER_PROPERTIES_EXT;
    check(properties(ctx.device(), type, host, &props), "vkGetMemoryHostPointerPropertiesEXT",
          what);
    const VkMemoryRequirements req = ctx.external_buffer_requirements(m.size_, usage, type, what);
    const std::uint32_t allowed = props.memoryTypeBits & req.memoryTypeBits;
    if (allowed == 0) {
        throw VkError("vkGetMemoryHostPointerPropertiesEXT", VK_ERROR_FEATURE_NOT_PRESENT,
                      what + ": no memory type can import host memory for a storage buffer");
    }
    VkImportMemoryHostPointerInfoEXT import{};
    import.sType = VK_STRUCTURE_TYPE_IMPORT_MEMORY_HOST_POINTER_INFO_EXT;
    import.handleType = type;
    import.pHostPointer = host;
    VkMemoryAllocateFlagsInfo address = address_flags(usage);
    import.pNext = address.flags != 0 ? &address : nullptr;
    VkMemoryAllocateInfo info{};
    info.sType = VK_STRUCTURE_TYPE_MEMORY_ALLOCATE_INFO;
    info.pNext = &import;
    info.allocationSize = m.size_;
    info.memoryTypeIndex = ctx.memory_type_for(allowed, VK_MEMORY_PROPERTY_HOST_COHERENT_BIT, what);
    VkDeviceMemory memory = VK_NULL_HANDLE;
    check(vkAllocateMemory(ctx.device(), &info, nullptr, &memory), "vkAllocateMemory",
          what + ": importing " + std::to_string(m.size_) + " bytes of host memory");
    m.memory_ = Owned<VkDeviceMemory>(ctx.device(), memory, vkFreeMemory);
    return m;
}

ExternalMemory ExternalMemory::exportable(Context& ctx, VkDeviceSize bytes,
                                          VkBufferUsageFlags usage, const std::string& what) {
    if (!supports(ctx, SharingPath::opaque_fd)) {
        throw VkError("vkAllocateMemory", VK_ERROR_EXTENSION_NOT_PRESENT,
                      what + ": " + ctx.info().name + " lacks VK_KHR_external_memory_fd");
    }
    const VkExternalMemoryHandleTypeFlagBits type = VK_EXTERNAL_MEMORY_HANDLE_TYPE_OPAQUE_FD_BIT;
    VkPhysicalDeviceExternalBufferInfo query{};
    query.sType = VK_STRUCTURE_TYPE_PHYSICAL_DEVICE_EXTERNAL_BUFFER_INFO;
    query.usage = usage;
    query.handleType = type;
    VkExternalBufferProperties external{};
    external.sType = VK_STRUCTURE_TYPE_EXTERNAL_BUFFER_PROPERTIES;
    vkGetPhysicalDeviceExternalBufferProperties(ctx.physical(), &query, &external);
    if ((external.externalMemoryProperties.externalMemoryFeatures &
         VK_EXTERNAL_MEMORY_FEATURE_EXPORTABLE_BIT) == 0) {
        throw VkError(
            "vkGetPhysicalDeviceExternalBufferProperties", VK_ERROR_FEATURE_NOT_PRESENT,
            what + ": " + ctx.info().name + " cannot export storage-buffer memory as an opaque fd");
    }
    ExternalMemory m;
    m.ctx_ = &ctx;
    m.path_ = SharingPath::opaque_fd;
    m.handle_type_ = type;
    m.size_ = std::max<VkDeviceSize>(bytes, 4);
    const VkMemoryRequirements req = ctx.external_buffer_requirements(m.size_, usage, type, what);
    VkExportMemoryAllocateInfo exported{};
    exported.sType = VK_STRUCTURE_TYPE_EXPORT_MEMORY_ALLOCATE_INFO;
    exported.handleTypes = type;
    VkMemoryAllocateFlagsInfo address = address_flags(usage);
    exported.pNext = address.flags != 0 ? &address : nullptr;
    VkMemoryAllocateInfo info{};
    info.sType = VK_STRUCTURE_TYPE_MEMORY_ALLOCATE_INFO;
    info.pNext = &exported;
    info.allocationSize = std::max(m.size_, req.size);
    info.memoryTypeIndex =
        ctx.memory_type_for(req.memoryTypeBits, VK_MEMORY_PROPERTY_DEVICE_LOCAL_BIT, what);
    m.size_ = info.allocationSize;
    m.memory_type_ = info.memoryTypeIndex;
    VkDeviceMemory memory = VK_NULL_HANDLE;
    check(vkAllocateMemory(ctx.device(), &info, nullptr, &memory), "vkAllocateMemory",
          what + ": " + std::to_string(m.size_) + " exportable bytes");
    m.memory_ = Owned<VkDeviceMemory>(ctx.device(), memory, vkFreeMemory);
    return m;
}

int ExternalMemory::export_fd() const {
    if (path_ != SharingPath::opaque_fd || ctx_ == nullptr) {
        throw std::logic_error("ExternalMemory::export_fd on memory that is not exportable");
    }
    auto get_fd = device_function<PFN_vkGetMemoryFdKHR>(*ctx_, "vkGetMemoryFdKHR");
    VkMemoryGetFdInfoKHR info{};
    info.sType = VK_STRUCTURE_TYPE_MEMORY_GET_FD_INFO_KHR;
    info.memory = memory_.get();
    info.handleType = VK_EXTERNAL_MEMORY_HANDLE_TYPE_OPAQUE_FD_BIT;
    int fd = -1;
    check(get_fd(ctx_->device(), &info, &fd), "vkGetMemoryFdKHR", "exporting the shared field");
    return fd;
}

bool can_export_semaphore_fd(const Context& ctx) {
    if (!ctx.enabled(VK_KHR_EXTERNAL_SEMAPHORE_FD_EXTENSION_NAME)) {
        return false;
    }
    VkPhysicalDeviceExternalSemaphoreInfo query{};
    query.sType = VK_STRUCTURE_TYPE_PHYSICAL_DEVICE_EXTERNAL_SEMAPHORE_INFO;
    query.handleType = VK_EXTERNAL_SEMAPHORE_HANDLE_TYPE_OPAQUE_FD_BIT;
    VkExternalSemaphoreProperties props{};
    props.sType = VK_STRUCTURE_TYPE_EXTERNAL_SEMAPHORE_PROPERTIES;
    vkGetPhysicalDeviceExternalSemaphoreProperties(ctx.physical(), &query, &props);
    return (props.externalSemaphoreFeatures & VK_EXTERNAL_SEMAPHORE_FEATURE_EXPORTABLE_BIT) != 0;
}

ExportedSemaphore::ExportedSemaphore(Context& ctx, const std::string& what)
    : ctx_(&ctx), what_(what) {
    if (!can_export_semaphore_fd(ctx)) {
        throw VkError(
            "vkCreateSemaphore", VK_ERROR_EXTENSION_NOT_PRESENT,
            what + ": " + ctx.info().name +
                " cannot export a semaphore as an opaque fd (VK_KHR_external_semaphore_fd)");
    }
    VkExportSemaphoreCreateInfo exported{};
    exported.sType = VK_STRUCTURE_TYPE_EXPORT_SEMAPHORE_CREATE_INFO;
    exported.handleTypes = VK_EXTERNAL_SEMAPHORE_HANDLE_TYPE_OPAQUE_FD_BIT;
    VkSemaphoreCreateInfo info{};
    info.sType = VK_STRUCTURE_TYPE_SEMAPHORE_CREATE_INFO;
    info.pNext = &exported;
    VkSemaphore semaphore = VK_NULL_HANDLE;
    check(vkCreateSemaphore(ctx.device(), &info, nullptr, &semaphore), "vkCreateSemaphore", what);
    semaphore_ = Owned<VkSemaphore>(ctx.device(), semaphore, vkDestroySemaphore);
}

int ExportedSemaphore::export_fd() const {
    if (!semaphore_ || ctx_ == nullptr) {
        throw std::logic_error("ExportedSemaphore::export_fd without a semaphore");
    }
    auto get_fd = device_function<PFN_vkGetSemaphoreFdKHR>(*ctx_, "vkGetSemaphoreFdKHR");
    VkSemaphoreGetFdInfoKHR info{};
    info.sType = VK_STRUCTURE_TYPE_SEMAPHORE_GET_FD_INFO_KHR;
    info.semaphore = semaphore_.get();
    info.handleType = VK_EXTERNAL_SEMAPHORE_HANDLE_TYPE_OPAQUE_FD_BIT;
    int fd = -1;
    check(get_fd(ctx_->device(), &info, &fd), "vkGetSemaphoreFdKHR", what_);
    return fd;
}

}  // namespace voxfield::vk
