// The compute context: logical device, queue, buffers by intent, submissions tracked by
// their fences and the resources retired on them (context.hpp).
#include "voxfield/vk/context.hpp"

#include <algorithm>
#include <cstring>

#include "instance.hpp"

namespace voxfield::vk {
namespace {

// A one-time command buffer and the fence of its submission. Going, it frees the command
// buffer and destroys the fence: a submission that may still run is retired as one.
struct OneShot {
    VkDevice device;
    VkCommandPool pool;
    VkCommandBuffer cmd = VK_NULL_HANDLE;
    Owned<VkFence> fence;
    OneShot(VkDevice d, VkCommandPool p) : device(d), pool(p) {}
    OneShot(OneShot&& o) noexcept
        : device(o.device),
          pool(o.pool),
          cmd(std::exchange(o.cmd, VK_NULL_HANDLE)),
          fence(std::move(o.fence)) {}
    ~OneShot() {
        if (cmd != VK_NULL_HANDLE) {
            vkFreeCommandBuffers(device, pool, 1, &cmd);
        }
    }
};

// `record` recorded into a new one-time command buffer of `pool`, with a new (unsignalled)
// fence for its submission.
OneShot record_one_shot(VkDevice device, VkCommandPool pool,
                        const std::function<void(VkCommandBuffer)>& record,
                        const std::string& what) {
    OneShot s(device, pool);
    VkCommandBufferAllocateInfo alloc{};
    alloc.sType = VK_STRUCTURE_TYPE_COMMAND_BUFFER_ALLOCATE_INFO;
    alloc.commandPool = pool;
    alloc.level = VK_COMMAND_BUFFER_LEVEL_PRIMARY;
    alloc.commandBufferCount = 1;
    check(vkAllocateCommandBuffers(device, &alloc, &s.cmd), "vkAllocateCommandBuffers", what);
    VkCommandBufferBeginInfo begin{};
    begin.sType = VK_STRUCTURE_TYPE_COMMAND_BUFFER_BEGIN_INFO;
    begin.flags = VK_COMMAND_BUFFER_USAGE_ONE_TIME_SUBMIT_BIT;
    check(vkBeginCommandBuffer(s.cmd, &begin), "vkBeginCommandBuffer", what);
    record(s.cmd);
    check(vkEndCommandBuffer(s.cmd), "vkEndCommandBuffer", what);
    VkFenceCreateInfo fence_info{};
    fence_info.sType = VK_STRUCTURE_TYPE_FENCE_CREATE_INFO;
    VkFence fence = VK_NULL_HANDLE;
    check(vkCreateFence(device, &fence_info, nullptr, &fence), "vkCreateFence", what);
    s.fence = Owned<VkFence>(device, fence, vkDestroyFence);
    return s;
}

}  // namespace

Context::Context(const ContextOptions& options) {
    const bool presenting = static_cast<bool>(options.make_surface);
    instance_ = create_instance(options.validation, options.instance_extensions);
    try {
        if (presenting) {
            surface_ = options.make_surface(instance_.get());
        }
        // Presenting: the window's surface from a queue that also ray-marches (unless the
        // context only presents).
        const DeviceChoice choice =
            choose_device(instance_.get(), surface_, options.device, options.purpose);
        info_ = choice.info;
        physical_ = choice.physical;
        family_ = choice.family;
        VkPhysicalDeviceProperties props{};
        vkGetPhysicalDeviceProperties(physical_, &props);
        timestamp_period_ = props.limits.timestampPeriod;
        vkGetPhysicalDeviceMemoryProperties(physical_, &memory_);

        const float priority = 1.0f;
        VkDeviceQueueCreateInfo q{};
        q.sType = VK_STRUCTURE_TYPE_DEVICE_QUEUE_CREATE_INFO;
        q.queueFamilyIndex = family_;
        q.queueCount = 1;
        q.pQueuePriorities = &priority;
        // External memory (DESIGN §2 sharing paths 1 and 2) and semaphores (path 1's ordering)
        // where the device has them.
        std::vector<const char*> extensions;
        if (presenting) {
            extensions.push_back(VK_KHR_SWAPCHAIN_EXTENSION_NAME);
            enabled_.emplace_back(VK_KHR_SWAPCHAIN_EXTENSION_NAME);
        }
        for (const char* ext :
             {VK_KHR_EXTERNAL_MEMORY_FD_EXTENSION_NAME, VK_EXT_EXTERNAL_MEMORY_HOST_EXTENSION_NAME,
              VK_KHR_EXTERNAL_SEMAPHORE_FD_EXTENSION_NAME}) {
            if (info_.has_extension(ext)) {
                extensions.push_back(ext);
                enabled_.emplace_back(ext);
            }
        }
        // Device addresses (the sparse tracer reads its chunks through them) where the device
        // has the extension and its feature.
        VkPhysicalDeviceBufferDeviceAddressFeaturesKHR addresses{};
        addresses.sType = VK_STRUCTURE_TYPE_PHYSICAL_DEVICE_BUFFER_DEVICE_ADDRESS_FEATURES_KHR;
        if (info_.has_extension(VK_KHR_BUFFER_DEVICE_ADDRESS_EXTENSION_NAME)) {
            VkPhysicalDeviceFeatures2 features{};
            features.sType = VK_STRUCTURE_TYPE_PHYSICAL_DEVICE_FEATURES_2;
            features.pNext = &addresses;
            vkGetPhysicalDeviceFeatures2(physical_, &features);
        }
        const bool use_addresses = addresses.bufferDeviceAddress == VK_TRUE;
        if (use_addresses) {
            extensions.push_back(VK_KHR_BUFFER_DEVICE_ADDRESS_EXTENSION_NAME);
            enabled_.emplace_back(VK_KHR_BUFFER_DEVICE_ADDRESS_EXTENSION_NAME);
            addresses.bufferDeviceAddressCaptureReplay = VK_FALSE;
            addresses.bufferDeviceAddressMultiDevice = VK_FALSE;
        }
        VkDeviceCreateInfo info{};
        info.sType = VK_STRUCTURE_TYPE_DEVICE_CREATE_INFO;
        info.pNext = use_addresses ? &addresses : nullptr;
        info.queueCreateInfoCount = 1;
        info.pQueueCreateInfos = &q;
        info.enabledExtensionCount = static_cast<std::uint32_t>(extensions.size());
        info.ppEnabledExtensionNames = extensions.data();
        check(vkCreateDevice(physical_, &info, nullptr, &device_), "vkCreateDevice", info_.name);
        vkGetDeviceQueue(device_, family_, 0, &queue_);
        if (use_addresses) {
            get_buffer_address_ = reinterpret_cast<PFN_vkGetBufferDeviceAddressKHR>(
                vkGetDeviceProcAddr(device_, "vkGetBufferDeviceAddressKHR"));
        }

        VkCommandPoolCreateInfo pool{};
        pool.sType = VK_STRUCTURE_TYPE_COMMAND_POOL_CREATE_INFO;
        pool.flags = VK_COMMAND_POOL_CREATE_TRANSIENT_BIT;
        pool.queueFamilyIndex = family_;
        VkCommandPool handle = VK_NULL_HANDLE;
        check(vkCreateCommandPool(device_, &pool, nullptr, &handle), "vkCreateCommandPool");
        pool_ = Owned<VkCommandPool>(device_, handle, vkDestroyCommandPool);
    } catch (...) {
        pool_.reset();
        if (device_ != VK_NULL_HANDLE) {
            vkDestroyDevice(device_, nullptr);
        }
        if (surface_ != VK_NULL_HANDLE) {
            vkDestroySurfaceKHR(instance_.get(), surface_, nullptr);
        }
        throw;  // instance_ destroys the instance
    }
}

Context::~Context() {
    if (device_ != VK_NULL_HANDLE) {
        vkDeviceWaitIdle(device_);
        finish(submitted_);
    }
    pool_.reset();
    if (device_ != VK_NULL_HANDLE) {
        vkDestroyDevice(device_, nullptr);
    }
    if (surface_ != VK_NULL_HANDLE) {
        vkDestroySurfaceKHR(instance_.get(), surface_, nullptr);
    }
}

std::uint32_t Context::memory_type(std::uint32_t allowed, MemoryIntent intent,
                                   const std::string& what) const {
    const VkMemoryPropertyFlags host =
        VK_MEMORY_PROPERTY_HOST_VISIBLE_BIT | VK_MEMORY_PROPERTY_HOST_COHERENT_BIT;
    VkMemoryPropertyFlags required = 0, preferred = 0;
    switch (intent) {
        case MemoryIntent::device_local:
            preferred = VK_MEMORY_PROPERTY_DEVICE_LOCAL_BIT;
            break;
        case MemoryIntent::upload:
            required = host;
            break;
        case MemoryIntent::readback:
            required = host;
            preferred = VK_MEMORY_PROPERTY_HOST_CACHED_BIT;
            break;
    }
    int fallback = -1;
    for (std::uint32_t i = 0; i < memory_.memoryTypeCount; ++i) {
        const VkMemoryPropertyFlags f = memory_.memoryTypes[i].propertyFlags;
        if ((allowed & (1u << i)) == 0 || (f & required) != required) {
            continue;
        }
        if ((f & preferred) == preferred) {
            return i;
        }
        if (fallback < 0) {
            fallback = static_cast<int>(i);
        }
    }
    if (fallback < 0) {
        throw VkError("vkAllocateMemory", VK_ERROR_FEATURE_NOT_PRESENT,
                      "no memory type fits " + what);
    }
    return static_cast<std::uint32_t>(fallback);
}

Owned<VkDeviceMemory> Context::allocate(const VkMemoryRequirements& req, MemoryIntent intent,
                                        const std::string& what, VkMemoryAllocateFlags flags) {
    VkMemoryAllocateFlagsInfo flags_info{};
    flags_info.sType = VK_STRUCTURE_TYPE_MEMORY_ALLOCATE_FLAGS_INFO;
    flags_info.flags = flags;
    VkMemoryAllocateInfo info{};
    info.sType = VK_STRUCTURE_TYPE_MEMORY_ALLOCATE_INFO;
    info.pNext = flags != 0 ? &flags_info : nullptr;
    info.allocationSize = req.size;
    info.memoryTypeIndex = memory_type(req.memoryTypeBits, intent, what);
    VkDeviceMemory memory = VK_NULL_HANDLE;
    check(vkAllocateMemory(device_, &info, nullptr, &memory), "vkAllocateMemory",
          what + ", " + std::to_string(req.size) + " bytes");
    return Owned<VkDeviceMemory>(device_, memory, vkFreeMemory);
}

VkDeviceAddress Context::device_address(const Buffer& buffer) const {
    if (get_buffer_address_ == nullptr) {
        throw VkError("vkGetBufferDeviceAddressKHR", VK_ERROR_FEATURE_NOT_PRESENT,
                      info_.name + " has no buffer device addresses");
    }
    VkBufferDeviceAddressInfoKHR info{};
    info.sType = VK_STRUCTURE_TYPE_BUFFER_DEVICE_ADDRESS_INFO_KHR;
    info.buffer = buffer.get();
    return get_buffer_address_(device_, &info);
}

bool Context::enabled(const std::string& extension) const {
    return std::find(enabled_.begin(), enabled_.end(), extension) != enabled_.end();
}

VkMemoryRequirements Context::external_buffer_requirements(
    VkDeviceSize size, VkBufferUsageFlags usage, VkExternalMemoryHandleTypeFlags handle_types,
    const std::string& what) {
    Buffer probe = make_external_buffer(size, usage, handle_types, what);
    VkMemoryRequirements req{};
    vkGetBufferMemoryRequirements(device_, probe.get(), &req);
    return req;
}

Buffer Context::make_external_buffer(VkDeviceSize size, VkBufferUsageFlags usage,
                                     VkExternalMemoryHandleTypeFlags handle_types,
                                     const std::string& what) {
    Buffer b;
    b.size_ = size;
    VkExternalMemoryBufferCreateInfo external{};
    external.sType = VK_STRUCTURE_TYPE_EXTERNAL_MEMORY_BUFFER_CREATE_INFO;
    external.handleTypes = handle_types;
    VkBufferCreateInfo info{};
    info.sType = VK_STRUCTURE_TYPE_BUFFER_CREATE_INFO;
    info.pNext = &external;
    info.size = std::max<VkDeviceSize>(size, 4);
    info.usage = usage;
    info.sharingMode = VK_SHARING_MODE_EXCLUSIVE;
    VkBuffer handle = VK_NULL_HANDLE;
    check(vkCreateBuffer(device_, &info, nullptr, &handle), "vkCreateBuffer",
          what + ", " + std::to_string(size) + " bytes of external memory");
    b.buffer_ = Owned<VkBuffer>(device_, handle, vkDestroyBuffer);
    return b;
}

void Context::bind(const Buffer& buffer, VkDeviceMemory memory, VkDeviceSize offset,
                   const std::string& what) {
    VkMemoryRequirements req{};
    vkGetBufferMemoryRequirements(device_, buffer.get(), &req);
    if (offset % req.alignment != 0) {
        throw VkError("vkBindBufferMemory", VK_ERROR_VALIDATION_FAILED_EXT,
                      what + ": offset " + std::to_string(offset) + " is not a multiple of " +
                          std::to_string(req.alignment));
    }
    check(vkBindBufferMemory(device_, buffer.get(), memory, offset), "vkBindBufferMemory", what);
}

std::uint32_t Context::memory_type_for(std::uint32_t allowed, VkMemoryPropertyFlags preferred,
                                       const std::string& what) const {
    int fallback = -1;
    for (std::uint32_t i = 0; i < memory_.memoryTypeCount; ++i) {
        if ((allowed & (1u << i)) == 0) {
            continue;
        }
        if ((memory_.memoryTypes[i].propertyFlags & preferred) == preferred) {
            return i;
        }
        if (fallback < 0) {
            fallback = static_cast<int>(i);
        }
    }
    if (fallback < 0) {
        throw VkError("vkAllocateMemory", VK_ERROR_FEATURE_NOT_PRESENT,
                      "no memory type fits " + what);
    }
    return static_cast<std::uint32_t>(fallback);
}

Buffer Context::make_buffer(VkDeviceSize size, VkBufferUsageFlags usage, MemoryIntent intent,
                            const std::string& what) {
    Buffer b;
    b.size_ = size;
    VkBufferCreateInfo info{};
    info.sType = VK_STRUCTURE_TYPE_BUFFER_CREATE_INFO;
    info.size = std::max<VkDeviceSize>(size, 4);
    info.usage = usage;
    info.sharingMode = VK_SHARING_MODE_EXCLUSIVE;
    VkBuffer handle = VK_NULL_HANDLE;
    check(vkCreateBuffer(device_, &info, nullptr, &handle), "vkCreateBuffer",
          what + ", " + std::to_string(size) + " bytes");
    b.buffer_ = Owned<VkBuffer>(device_, handle, vkDestroyBuffer);
    VkMemoryRequirements req{};
    vkGetBufferMemoryRequirements(device_, handle, &req);
    const bool addressed = (usage & VK_BUFFER_USAGE_SHADER_DEVICE_ADDRESS_BIT) != 0;
    b.memory_ = allocate(req, intent, what, addressed ? VK_MEMORY_ALLOCATE_DEVICE_ADDRESS_BIT : 0);
    check(vkBindBufferMemory(device_, handle, b.memory_.get(), 0), "vkBindBufferMemory", what);
    const std::uint32_t type = memory_type(req.memoryTypeBits, intent, what);
    const VkMemoryPropertyFlags host =
        VK_MEMORY_PROPERTY_HOST_VISIBLE_BIT | VK_MEMORY_PROPERTY_HOST_COHERENT_BIT;
    if ((memory_.memoryTypes[type].propertyFlags & host) == host) {
        check(vkMapMemory(device_, b.memory_.get(), 0, VK_WHOLE_SIZE, 0, &b.mapped_), "vkMapMemory",
              what);
    }
    return b;
}

void Context::upload(const Buffer& dst, const void* bytes, VkDeviceSize size, VkDeviceSize offset) {
    if (size == 0) {
        return;
    }
    if (dst.host_visible()) {
        std::memcpy(static_cast<std::uint8_t*>(dst.data()) + offset, bytes, size);
        return;
    }
    const VkDeviceSize chunk = std::min<VkDeviceSize>(size, VkDeviceSize{64} << 20);
    Buffer staging =
        make_buffer(chunk, VK_BUFFER_USAGE_TRANSFER_SRC_BIT, MemoryIntent::upload, "staging");
    for (VkDeviceSize done = 0; done < size; done += chunk) {
        const VkDeviceSize n = std::min(chunk, size - done);
        std::memcpy(staging.data(), static_cast<const std::uint8_t*>(bytes) + done, n);
        try {
            submit_and_wait(
                [&](VkCommandBuffer cmd) {
                    VkBufferCopy region{0, offset + done, n};
                    vkCmdCopyBuffer(cmd, staging.get(), dst.get(), 1, &region);
                },
                "upload");
        } catch (...) {
            retire(std::move(staging));  // the copy may still read it
            throw;
        }
    }
}

void Context::submit_and_wait(const std::function<void(VkCommandBuffer)>& record,
                              const std::string& what, std::chrono::nanoseconds timeout) {
    collect_retired(false);
    OneShot shot = record_one_shot(device_, pool_.get(), record, what);
    VkSubmitInfo info{};
    info.sType = VK_STRUCTURE_TYPE_SUBMIT_INFO;
    info.commandBufferCount = 1;
    info.pCommandBuffers = &shot.cmd;
    submit(info, shot.fence.get(), what);
    const std::uint64_t serial = submitted_;
    const std::uint64_t ns =
        timeout == std::chrono::nanoseconds::max()
            ? UINT64_MAX
            : static_cast<std::uint64_t>(std::max<std::int64_t>(timeout.count(), 0));
    const VkFence fence = shot.fence.get();
    const VkResult r = vkWaitForFences(device_, 1, &fence, VK_TRUE, ns);
    if (r != VK_SUCCESS) {
        // The GPU may still run the command buffer (and read what it refers to): both stay
        // alive until its fence signals.
        retire(std::move(shot));
        throw VkError("vkWaitForFences", r, what);
    }
    finish(serial);
}

std::uint64_t Context::submit_unwaited(const std::function<void(VkCommandBuffer)>& record,
                                       const std::string& what) {
    collect_retired(false);
    // The command buffer and fence of a submission nobody waits for: freed once it finished.
    OneShot u = record_one_shot(device_, pool_.get(), record, what);
    VkSubmitInfo info{};
    info.sType = VK_STRUCTURE_TYPE_SUBMIT_INFO;
    info.commandBufferCount = 1;
    info.pCommandBuffers = &u.cmd;
    submit(info, u.fence.get(), what);
    const std::uint64_t serial = submitted_;
    retire(std::move(u));
    return serial;
}

std::uint64_t Context::signal_semaphore(VkSemaphore semaphore, const std::string& what) {
    collect_retired(false);
    // One execution barrier over all commands: the batch's signal then also follows the waits
    // of earlier batches (through the commands after them), not only their commands.
    OneShot shot = record_one_shot(
        device_, pool_.get(),
        [](VkCommandBuffer cmd) {
            vkCmdPipelineBarrier(cmd, VK_PIPELINE_STAGE_ALL_COMMANDS_BIT,
                                 VK_PIPELINE_STAGE_ALL_COMMANDS_BIT, 0, 0, nullptr, 0, nullptr, 0,
                                 nullptr);
        },
        what);
    VkSubmitInfo info{};
    info.sType = VK_STRUCTURE_TYPE_SUBMIT_INFO;
    info.commandBufferCount = 1;
    info.pCommandBuffers = &shot.cmd;
    info.signalSemaphoreCount = 1;
    info.pSignalSemaphores = &semaphore;
    submit(info, shot.fence.get(), what);
    const std::uint64_t serial = submitted_;
    retire(std::move(shot));
    return serial;
}

std::uint64_t Context::wait_semaphore(VkSemaphore semaphore, const std::string& what) {
    collect_retired(false);
    OneShot shot(device_, pool_.get());
    VkFenceCreateInfo fence_info{};
    fence_info.sType = VK_STRUCTURE_TYPE_FENCE_CREATE_INFO;
    VkFence fence = VK_NULL_HANDLE;
    check(vkCreateFence(device_, &fence_info, nullptr, &fence), "vkCreateFence", what);
    shot.fence = Owned<VkFence>(device_, fence, vkDestroyFence);
    const VkPipelineStageFlags stage = VK_PIPELINE_STAGE_ALL_COMMANDS_BIT;
    VkSubmitInfo info{};
    info.sType = VK_STRUCTURE_TYPE_SUBMIT_INFO;
    info.waitSemaphoreCount = 1;
    info.pWaitSemaphores = &semaphore;
    info.pWaitDstStageMask = &stage;
    submit(info, fence, what);
    const std::uint64_t serial = submitted_;
    retire(std::move(shot));
    return serial;
}

void Context::submit(const VkSubmitInfo& info, VkFence fence, const std::string& what) {
    if (injected_failure_ != VK_SUCCESS) {
        const VkResult r = std::exchange(injected_failure_, VK_SUCCESS);
        throw VkError("vkQueueSubmit", r, what + " (injected failure)");
    }
    check(vkQueueSubmit(queue_, 1, &info, fence), "vkQueueSubmit", what);
    pending_.push_back(Pending{++submitted_, fence});
}

void Context::wait(VkFence fence, const std::string& what) {
    check(vkWaitForFences(device_, 1, &fence, VK_TRUE, UINT64_MAX), "vkWaitForFences", what);
    std::uint64_t serial = 0;
    for (const Pending& p : pending_) {
        if (p.fence == fence) {
            serial = std::max(serial, p.serial);
        }
    }
    finish(serial);
}

void Context::finish(std::uint64_t serial) {
    // A fence's signal covers every earlier submission to the queue.
    finished_ = std::max(finished_, serial);
    std::erase_if(pending_, [&](const Pending& p) { return p.serial <= finished_; });
    std::erase_if(retired_, [&](const Retired& r) { return r.serial <= finished_; });
}

void Context::retire_erased(std::shared_ptr<void> resource) {
    if (submitted_ == finished_) {
        return;  // nothing in flight: `resource` goes now
    }
    retired_.push_back(Retired{submitted_, std::move(resource)});
}

bool Context::busy() {
    return !finished(submitted_);
}

bool Context::finished(std::uint64_t serial) {
    if (serial > finished_) {
        collect_retired(false);
    }
    return serial <= finished_;
}

void Context::wait_for(std::uint64_t serial) {
    if (serial <= finished_) {
        return;
    }
    // Submissions are pending in serial order; a fence covers every earlier submission.
    for (const Pending& p : pending_) {
        if (p.serial >= serial) {
            const VkFence fence = p.fence;
            const std::uint64_t covered = p.serial;
            check(vkWaitForFences(device_, 1, &fence, VK_TRUE, UINT64_MAX), "vkWaitForFences",
                  "the frames in flight");
            finish(covered);
            return;
        }
    }
    if (!pending_.empty()) {
        wait_for(pending_.back().serial);
    }
}

void Context::wait_frames_in_flight() {
    collect_retired(true);
}

std::size_t Context::retired_in_flight() {
    collect_retired(false);
    return retired_.size();
}

void Context::collect_retired(bool wait) {
    if (wait && finished_ < submitted_) {
        // The latest submission's fence covers every earlier one: no device idle.
        if (!pending_.empty()) {
            const Pending last = pending_.back();
            check(vkWaitForFences(device_, 1, &last.fence, VK_TRUE, UINT64_MAX), "vkWaitForFences",
                  "the frames in flight");
            finish(last.serial);
        }
        return;
    }
    // The latest submission whose fence signalled, or never will (a lost device).
    for (auto it = pending_.rbegin(); it != pending_.rend(); ++it) {
        if (vkGetFenceStatus(device_, it->fence) != VK_NOT_READY) {
            finish(it->serial);
            return;
        }
    }
}

}  // namespace voxfield::vk
