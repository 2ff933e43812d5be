#pragma once
// Vulkan runtime: errors carrying the call and VkResult name, move-only RAII handles, device
// enumeration and selection (explaining every rejection), validation (the Khronos layer with
// synchronisation validation, messages collected), a compute context (headless, or able to
// present to a window's surface) with buffers allocated by intent, one-shot submissions, and
// submissions tracked by their fences so that resources still used by work in flight are
// retired (freed once that work has finished) instead of destroyed.
#include <vulkan/vulkan.h>

#include <array>
#include <chrono>
#include <cstddef>
#include <cstdint>
#include <functional>
#include <memory>
#include <mutex>
#include <stdexcept>
#include <string>
#include <type_traits>
#include <utility>
#include <vector>

namespace voxfield::vk {

// A failed Vulkan call: the API function, its VkResult name and our context. The command
// line maps it to exit code 1.
class VkError : public std::runtime_error {
  public:
    VkError(const std::string& call, VkResult result, const std::string& context);
    VkResult result() const { return result_; }

  private:
    VkResult result_;
};

// No Vulkan device can serve the request; the message lists every device and why it was
// rejected. The command line maps it to exit code 2, as OpenCL's DeviceSelectionError (the
// request cannot be served here: a device spec that matches nothing, or no driver).
class DeviceSelectionError : public std::runtime_error {
  public:
    using std::runtime_error::runtime_error;
};

// "VK_ERROR_OUT_OF_DEVICE_MEMORY", ...; "VkResult(N)" for codes it does not know.
const char* result_name(VkResult r);

// Throws VkError(call, r, context) unless r is VK_SUCCESS.
void check(VkResult r, const char* call, const std::string& context = "");

// A device-level handle destroyed by vkDestroyX(device, handle, nullptr); move-only.
template <class H>
class Owned {
  public:
    using Destroy = void (*)(VkDevice, H, const VkAllocationCallbacks*);
    Owned() = default;
    Owned(VkDevice device, H handle, Destroy destroy)
        : device_(device), handle_(handle), destroy_(destroy) {}
    ~Owned() { reset(); }
    Owned(const Owned&) = delete;
    Owned& operator=(const Owned&) = delete;
    Owned(Owned&& o) noexcept
        : device_(o.device_), handle_(std::exchange(o.handle_, H{})), destroy_(o.destroy_) {}
    Owned& operator=(Owned&& o) noexcept {
        if (this != &o) {
            reset();
            device_ = o.device_;
            handle_ = std::exchange(o.handle_, H{});
            destroy_ = o.destroy_;
        }
        return *this;
    }
    H get() const { return handle_; }
    explicit operator bool() const { return handle_ != H{}; }
    // Gives up ownership: the caller destroys the handle.
    [[nodiscard]] H release() { return std::exchange(handle_, H{}); }
    void reset() {
        if (handle_ != H{} && destroy_ != nullptr) {
            destroy_(device_, handle_, nullptr);
        }
        handle_ = H{};
    }

  private:
    VkDevice device_ = VK_NULL_HANDLE;
    H handle_{};
    Destroy destroy_ = nullptr;
};

// The messages of VK_LAYER_KHRONOS_validation (warnings and errors, synchronisation
// validation included) for every instance that shares it: kept, counted and passed to
// `on_message` (on the thread whose Vulkan call produced it). Thread-safe. Libraries never
// print: the caller decides what a message means (tests fail, `--validate` exits 1).
class ValidationLog {
  public:
    using Callback = std::function<void(const std::string&)>;
    explicit ValidationLog(Callback on_message = {}) : on_message_(std::move(on_message)) {}
    void add(const std::string& message);
    std::vector<std::string> messages() const;
    std::size_t count() const;
    void clear();

  private:
    mutable std::mutex mutex_;
    std::vector<std::string> messages_;
    Callback on_message_;
};

// One VkInstance, with validation when a log is given: vkCreateInstance then also enables the
// layer, VK_EXT_debug_utils and synchronisation validation (VK_EXT_validation_features), with
// a messenger for the instance's own creation and destruction and one for its lifetime, both
// reporting to the log. Move-only.
class Instance {
  public:
    Instance() = default;
    // `info` as for vkCreateInstance (its layers and extensions are kept). Throws VkError
    // (VK_ERROR_LAYER_NOT_PRESENT, naming the Debian package) when validation is asked for and
    // the layer is not installed.
    Instance(const VkInstanceCreateInfo& info, std::shared_ptr<ValidationLog> validation,
             const std::string& what);
    ~Instance() { reset(); }
    Instance(const Instance&) = delete;
    Instance& operator=(const Instance&) = delete;
    Instance(Instance&& o) noexcept;
    Instance& operator=(Instance&& o) noexcept;
    VkInstance get() const { return instance_; }
    const std::shared_ptr<ValidationLog>& validation() const { return log_; }
    // Destroys the messenger, then the instance (its devices must be gone).
    void reset();

  private:
    VkInstance instance_ = VK_NULL_HANDLE;
    VkDebugUtilsMessengerEXT messenger_ = VK_NULL_HANDLE;
    std::shared_ptr<ValidationLog> log_;  // outlives the instance: the layer reports to it
};

// Whether VK_LAYER_KHRONOS_validation is installed (Debian: vulkan-validationlayers).
bool validation_layer_available();

struct PhysicalDeviceInfo {
    std::size_t index = 0;           // position in list_devices()
    std::string name, type, driver;  // type: "discrete-gpu", "integrated-gpu", "cpu", ...
    std::uint32_t api_version = 0;
    std::string api;  // "1.3.230"
    VkDeviceSize max_storage_buffer_range = 0;
    // VkPhysicalDeviceMaintenance4Properties::maxBufferSize (0: not known, before Vulkan 1.3
    // or VK_KHR_maintenance4). maxMemoryAllocationSize is not kept: drivers allocate beyond it
    // (NVIDIA reports 4 GiB and allocates tens of GB).
    VkDeviceSize max_buffer_size = 0;
    std::uint32_t max_storage_buffers_per_stage = 0;
    std::uint32_t max_image_dimension_2d = 0;
    VkDeviceSize min_storage_buffer_offset_alignment = 0;
    // VK_EXT_external_memory_host: imported host pointers and sizes are multiples of this (0:
    // the device lacks the extension).
    VkDeviceSize min_imported_host_pointer_alignment = 0;
    std::array<std::uint8_t, 16> uuid{};  // VkPhysicalDeviceIDProperties::deviceUUID
    bool timestamps = false;              // compute queue can write timestamps
    std::vector<std::string> extensions;
    std::string rejected;  // why this device cannot serve the renderer, "" if it can

    bool has_extension(const std::string& ext) const;
};

// Every physical device, with why it is unusable (if it is). Throws VkError when no Vulkan
// loader / driver is installed.
std::vector<PhysicalDeviceInfo> list_devices();

// The device a headless Context(spec) takes (ContextOptions::device), without creating it.
// Throws DeviceSelectionError explaining why each device was rejected.
PhysicalDeviceInfo select_device(const std::string& spec);

// The one device selection of vk/ (Context and Presenter both take it): among the physical
// devices of `instance`, the one `spec` asks for ("" = $VOXFIELD_VK_DEVICE, else the first
// discrete GPU, integrated GPU, virtual GPU, then CPU; "gpu", "cpu" or an index from
// list_devices()), of those that serve `purpose`: the ray marcher's needs
// (PhysicalDeviceInfo::rejected) or, presenting only, Vulkan 1.1. With a `surface`, also
// VK_KHR_swapchain and a queue family that does graphics (and compute, for the ray marcher) and
// presents to it: `family` is that family (else the first compute family). Throws
// DeviceSelectionError explaining why each device was rejected.
enum class DevicePurpose { ray_marching, presenting };
struct DeviceChoice {
    VkPhysicalDevice physical = VK_NULL_HANDLE;
    PhysicalDeviceInfo info;  // timestamps: also those of `family`
    std::uint32_t family = 0;
};
DeviceChoice choose_device(VkInstance instance, VkSurfaceKHR surface, const std::string& spec,
                           DevicePurpose purpose);

// Intent of a buffer's memory: where the GPU reads it fastest, or where the host writes /
// reads it (host-visible, coherent; readback prefers cached memory).
enum class MemoryIntent { device_local, upload, readback };

class Context;

// A buffer with its own memory; host-visible memory stays mapped (data() non-null).
class Buffer {
  public:
    Buffer() = default;
    Buffer(Buffer&& o) noexcept
        : memory_(std::move(o.memory_)),
          buffer_(std::move(o.buffer_)),
          size_(std::exchange(o.size_, 0)),
          mapped_(std::exchange(o.mapped_, nullptr)) {}
    // The old buffer is destroyed before the memory it is bound to is freed.
    Buffer& operator=(Buffer&& o) noexcept {
        if (this != &o) {
            buffer_.reset();
            memory_ = std::move(o.memory_);
            buffer_ = std::move(o.buffer_);
            size_ = std::exchange(o.size_, 0);
            mapped_ = std::exchange(o.mapped_, nullptr);
        }
        return *this;
    }
    VkBuffer get() const { return buffer_.get(); }
    VkDeviceSize size() const { return size_; }
    void* data() const { return mapped_; }
    bool host_visible() const { return mapped_ != nullptr; }

  private:
    friend class Context;
    Owned<VkDeviceMemory> memory_;  // declared first: freed after the buffer is destroyed
    Owned<VkBuffer> buffer_;
    VkDeviceSize size_ = 0;
    void* mapped_ = nullptr;  // unmapped implicitly when the memory is freed
};

struct ContextOptions {
    // "" (default: $VOXFIELD_VK_DEVICE, else the first discrete GPU, integrated GPU, virtual
    // GPU, then CPU), "gpu", "cpu" or an index from list_devices().
    std::string device;
    // Non-null: validation on (the layer must be installed), every message goes to this log.
    std::shared_ptr<ValidationLog> validation = nullptr;
    // Presentation (set both): the window system's instance extensions (e.g.
    // glfwGetRequiredInstanceExtensions) and a function that makes the window's surface on the
    // instance (throws on failure; the context destroys the surface). Selection then also
    // requires a queue family that does compute and graphics and presents to that surface, and
    // VK_KHR_swapchain, which it enables.
    std::vector<std::string> instance_extensions = {};
    std::function<VkSurfaceKHR(VkInstance)> make_surface = nullptr;
    // What the device serves (choose_device): the ray marcher, or, for a Presenter on a device
    // of its own, presenting only (the queue family then need not compute).
    DevicePurpose purpose = DevicePurpose::ray_marching;
};

// Owns the instance (and the surface when presenting), one logical device with one queue and
// a command pool.
class Context {
  public:
    // spec: ContextOptions::device. Throws DeviceSelectionError explaining why each device
    // was rejected.
    explicit Context(const std::string& spec = "") : Context(ContextOptions{spec}) {}
    explicit Context(const ContextOptions& options);
    ~Context();
    Context(const Context&) = delete;
    Context& operator=(const Context&) = delete;

    const PhysicalDeviceInfo& info() const { return info_; }
    VkInstance instance() const { return instance_.get(); }
    // The window's surface (VK_NULL_HANDLE for a headless context).
    VkSurfaceKHR surface() const { return surface_; }
    bool presents() const { return surface_ != VK_NULL_HANDLE; }
    VkDevice device() const { return device_; }
    VkPhysicalDevice physical() const { return physical_; }
    VkQueue queue() const { return queue_; }
    std::uint32_t queue_family() const { return family_; }
    float timestamp_period_ns() const { return timestamp_period_; }
    // The validation log (nullptr: validation off).
    const std::shared_ptr<ValidationLog>& validation() const { return instance_.validation(); }

    // A buffer with memory of its own; with VK_BUFFER_USAGE_SHADER_DEVICE_ADDRESS_BIT in
    // `usage` (buffer_device_address() only) its memory is allocated for device addresses.
    Buffer make_buffer(VkDeviceSize size, VkBufferUsageFlags usage, MemoryIntent intent,
                       const std::string& what);
    // Device extensions enabled on the logical device (VK_KHR_external_memory_fd,
    // VK_EXT_external_memory_host, VK_KHR_external_semaphore_fd and
    // VK_KHR_buffer_device_address with its feature, where the physical device has them).
    bool enabled(const std::string& extension) const;
    // Whether shaders may read buffers through device addresses (VK_KHR_buffer_device_address:
    // GLSL's GL_EXT_buffer_reference), and the address of a buffer made for them.
    bool buffer_device_address() const { return get_buffer_address_ != nullptr; }
    VkDeviceAddress device_address(const Buffer& buffer) const;
    // A buffer without memory, created for external memory of `handle_types`; bind() it.
    Buffer make_external_buffer(VkDeviceSize size, VkBufferUsageFlags usage,
                                VkExternalMemoryHandleTypeFlags handle_types,
                                const std::string& what);
    // The requirements such a buffer has (memory type bits, alignment).
    VkMemoryRequirements external_buffer_requirements(VkDeviceSize size, VkBufferUsageFlags usage,
                                                      VkExternalMemoryHandleTypeFlags handle_types,
                                                      const std::string& what);
    // Binds `buffer` to `memory` (owned elsewhere, which must outlive the buffer) at `offset`.
    void bind(const Buffer& buffer, VkDeviceMemory memory, VkDeviceSize offset,
              const std::string& what);
    // The first memory type in `allowed` with all `preferred` flags, else the first allowed.
    std::uint32_t memory_type_for(std::uint32_t allowed, VkMemoryPropertyFlags preferred,
                                  const std::string& what) const;
    const VkPhysicalDeviceMemoryProperties& memory_properties() const { return memory_; }
    // Allocates memory for `requirements` by intent (for images).
    // `flags`: VkMemoryAllocateFlagsInfo's (VK_MEMORY_ALLOCATE_DEVICE_ADDRESS_BIT), 0: none.
    Owned<VkDeviceMemory> allocate(const VkMemoryRequirements& requirements, MemoryIntent intent,
                                   const std::string& what, VkMemoryAllocateFlags flags = 0);
    // Copies `bytes` into `dst` at `offset`: directly when it is mapped, else through a
    // staging buffer (needs VK_BUFFER_USAGE_TRANSFER_DST_BIT).
    void upload(const Buffer& dst, const void* bytes, VkDeviceSize size, VkDeviceSize offset = 0);
    // Records `record` into a fresh command buffer, submits it and waits for its fence at
    // most `timeout` (so for all work submitted before it too). When the wait fails
    // (VK_TIMEOUT, a lost device) it throws VkError and retires the command buffer and fence.
    void submit_and_wait(const std::function<void(VkCommandBuffer)>& record,
                         const std::string& what,
                         std::chrono::nanoseconds timeout = std::chrono::nanoseconds::max());

    // Records `record` into a fresh command buffer and submits it without waiting: the
    // command buffer and its fence are retired (freed once it has finished). Whatever `record`
    // reads or writes is ordered against other work by its own barriers (queue order). Returns
    // the submission's serial.
    std::uint64_t submit_unwaited(const std::function<void(VkCommandBuffer)>& record,
                                  const std::string& what);
    // Binary semaphores shared with OpenCL (ExportedSemaphore, DESIGN §2 "Synchronisation"),
    // each in a batch of its own, tracked like submit_unwaited (returns the serial).
    // signal_semaphore: a batch that signals `semaphore` once every command submitted before it
    // has finished (Vulkan: a queue submission's signal covers all commands earlier in
    // submission order; its one execution barrier over all commands orders the waits of
    // earlier batches before the signal too). wait_semaphore: a batch of no commands that waits
    // for `semaphore` at every stage, so that no command submitted after it starts before the
    // signal (a submission's wait covers all commands later in submission order). The caller
    // keeps a binary semaphore's signals and waits alternating, each wait after its signal was
    // submitted (or enqueued by OpenCL).
    std::uint64_t signal_semaphore(VkSemaphore semaphore, const std::string& what);
    std::uint64_t wait_semaphore(VkSemaphore semaphore, const std::string& what);
    // Submits `info` to the queue, signalling `fence` (which stays the caller's) when it and
    // all work submitted before it have finished. The caller waits for that fence with wait(),
    // never resetting or destroying it before.
    void submit(const VkSubmitInfo& info, VkFence fence, const std::string& what);
    // For tests of error paths: the next submit() (or submit_and_wait) fails with `result`
    // (an error code) without submitting anything, as vkQueueSubmit failing would.
    void fail_next_submit(VkResult result) { injected_failure_ = result; }
    // Waits for a fence of submit() (or an unsubmitted, signalled one) and frees what was
    // retired before that submission.
    void wait(VkFence fence, const std::string& what);
    // Keeps `resource` (any move-only object: buffers, images, descriptor pools) alive until
    // every submission made so far has finished, then destroys it (checked at each
    // submission and wait, or when the context is destroyed). Anything a recorded but not yet
    // submitted command buffer uses must not be retired.
    template <class T>
    void retire(T&& resource) {
        retire_erased(std::make_shared<std::decay_t<T>>(std::forward<T>(resource)));
    }
    // Whether work submitted is not known to have finished (no wait).
    bool busy();
    // The serial the next submission (submit or submit_and_wait) gets, and whether submission
    // `serial` is known to have finished (no wait).
    std::uint64_t next_serial() const { return submitted_ + 1; }
    bool finished(std::uint64_t serial);
    // Waits until submission `serial` (and so every one before it) has finished, on the fence
    // of the first submission at or after it (no device idle), and frees what they retired.
    // A serial never submitted (the submission failed) waits for what was submitted.
    void wait_for(std::uint64_t serial);
    // Waits until all submitted work has finished (frames in flight included), on the fence of
    // the latest submission (no device idle), and frees everything retired.
    void wait_frames_in_flight();
    // Retired resources (failed submit_and_wait submissions included) not freed yet.
    std::size_t retired_in_flight();

  private:
    struct Pending {
        std::uint64_t serial;
        VkFence fence;
    };
    struct Retired {
        std::uint64_t serial;  // freed once this submission has finished
        std::shared_ptr<void> resource;
    };
    std::uint32_t memory_type(std::uint32_t allowed, MemoryIntent intent,
                              const std::string& what) const;
    void retire_erased(std::shared_ptr<void> resource);
    // Submission `serial` and all before it have finished: frees what they retired.
    void finish(std::uint64_t serial);
    // Notes the submissions whose fence signalled (all of them with `wait`, after
    // vkDeviceWaitIdle) and frees what was retired before them.
    void collect_retired(bool wait);

    Instance instance_;
    VkSurfaceKHR surface_ = VK_NULL_HANDLE;
    VkPhysicalDevice physical_ = VK_NULL_HANDLE;
    VkDevice device_ = VK_NULL_HANDLE;
    VkQueue queue_ = VK_NULL_HANDLE;
    std::uint32_t family_ = 0;
    float timestamp_period_ = 1;
    VkPhysicalDeviceMemoryProperties memory_{};
    PhysicalDeviceInfo info_;
    std::vector<std::string> enabled_;
    PFN_vkGetBufferDeviceAddressKHR get_buffer_address_ = nullptr;
    Owned<VkCommandPool> pool_;
    std::uint64_t submitted_ = 0, finished_ = 0;  // serials of submissions
    VkResult injected_failure_ = VK_SUCCESS;      // fail_next_submit
    std::vector<Pending> pending_;                // submitted, not known to be finished
    std::vector<Retired> retired_;
};

}  // namespace voxfield::vk
