// Window presentation: swapchain, host image copy, overlay render pass (present.hpp).
#include "voxfield/vk/present.hpp"

#include <unistd.h>
#include <algorithm>
#include <array>
#include <cstring>
#include <optional>
#include <stdexcept>
#include <string>
#include <vector>

namespace voxfield::vk {

std::string to_string(PresentMode mode) {
    switch (mode) {
        case PresentMode::fifo:
            return "fifo";
        case PresentMode::mailbox:
            return "mailbox";
        case PresentMode::immediate:
            return "immediate";
    }
    return "?";
}

namespace {

VkPresentModeKHR to_vk(PresentMode m) {
    switch (m) {
        case PresentMode::mailbox:
            return VK_PRESENT_MODE_MAILBOX_KHR;
        case PresentMode::immediate:
            return VK_PRESENT_MODE_IMMEDIATE_KHR;
        case PresentMode::fifo:
            break;
    }
    return VK_PRESENT_MODE_FIFO_KHR;
}

}  // namespace

// Frames recorded and submitted while earlier ones still run on the GPU.
constexpr std::uint32_t kFramesInFlight = 2;

struct Presenter::Impl {
    // Presenting on a Context (its instance, surface, device and queue, submissions through
    // it), else on the presenter's own instance and device.
    Context* ctx = nullptr;
    Instance own_instance;
    VkInstance instance = VK_NULL_HANDLE;
    VkSurfaceKHR surface = VK_NULL_HANDLE;
    VkPhysicalDevice physical = VK_NULL_HANDLE;
    VkDevice device = VK_NULL_HANDLE;
    VkQueue queue = VK_NULL_HANDLE;
    std::uint32_t family = 0;
    std::string name;
    VkPhysicalDeviceMemoryProperties memory{};
    VkSurfaceFormatKHR format{};
    bool swizzle = false;  // BGRA swapchain: swap R and B when copying
    PresentMode mode = PresentMode::fifo;
    std::vector<PresentMode> wanted;

    VkSwapchainKHR swapchain = VK_NULL_HANDLE;
    VkExtent2D extent{0, 0};
    std::uint32_t min_images = 2;
    std::vector<VkImage> images;
    std::vector<VkImageView> views;
    std::vector<VkFramebuffer> framebuffers;
    VkRenderPass pass = VK_NULL_HANDLE;
    VkCommandPool pool = VK_NULL_HANDLE;
    // One render-finished semaphore per swapchain image (what presenting it waits on): a
    // semaphore is signalled again only after its image was acquired again, i.e. after the
    // presentation that waited on it is done with it.
    std::vector<VkSemaphore> rendered;
    // Replaced swapchains with their views, framebuffers and render-finished semaphores, kept
    // until the presentation engine provably finished with them. A present gives no signal
    // when it has waited on its semaphore, so (as ANGLE does, "Queue Present Wait Semaphore
    // Management") they go once the image of the new swapchain's first present was acquired
    // again and the frame that waited on that acquire finished: the presentation engine gave
    // that image back, so it processed that present, and every present queued before it.
    struct OldSwapchain {
        VkSwapchainKHR swapchain = VK_NULL_HANDLE;
        std::vector<VkImageView> views;
        std::vector<VkFramebuffer> framebuffers;
        std::vector<VkSemaphore> rendered;
    };
    std::vector<OldSwapchain> old_swapchains;
    // The image of the new swapchain's first present (none yet), the slot of the frame that
    // acquired it again, and whether that frame was submitted (its fence then proves it).
    std::optional<std::uint32_t> first_present;
    std::optional<std::uint32_t> release_slot;
    bool release_submitted = false;
    // More replaced swapchains than this pending: wait for the device and free them (a window
    // resized continuously would otherwise hold swapchains without bound).
    static constexpr std::size_t kMaxOldSwapchains = 8;

    // A frame slot: its command buffer, the fence of its last submission, the semaphore its
    // acquired image signals, and the staging buffer of present()'s host pixels.
    struct Slot {
        VkCommandBuffer cmd = VK_NULL_HANDLE;
        VkFence fence = VK_NULL_HANDLE;
        VkSemaphore acquired = VK_NULL_HANDLE;
        VkBuffer staging = VK_NULL_HANDLE;
        VkDeviceMemory staging_memory = VK_NULL_HANDLE;
        VkDeviceSize staging_size = 0;
        void* staging_map = nullptr;
    };
    std::array<Slot, kFramesInFlight> slots{};
    std::uint32_t current = 0;  // the slot of the next frame

    // Frames rendered by another VkDevice of this GPU (import_frame).
    bool external_memory_fd = false;  // VK_KHR_external_memory_fd enabled
    std::array<std::uint8_t, VK_UUID_SIZE> uuid{};
    VkBuffer imported = VK_NULL_HANDLE;
    VkDeviceMemory imported_memory = VK_NULL_HANDLE;
    VkDeviceSize imported_size = 0;

    // capture_next_frame(): the next presented image (overlay included) copied to the host.
    bool can_capture = false, capture_requested = false, captured = false;
    std::uint32_t capture_slot = 0;  // the slot whose submission copies it
    VkBuffer capture = VK_NULL_HANDLE;
    VkDeviceMemory capture_memory = VK_NULL_HANDLE;
    void* capture_map = nullptr;
    VkExtent2D capture_extent{0, 0};

    ~Impl() {
        if (device != VK_NULL_HANDLE) {
            // Teardown waits for the whole device: presents are not fenced, so the frames'
            // fences (what wait_idle waits for on a shared Context) do not cover the
            // semaphores a present still holds (VUID-vkDestroySemaphore-semaphore-01137).
            vkDeviceWaitIdle(device);
            destroy_old_swapchains();
            destroy_swapchain();
            for (Slot& slot : slots) {
                destroy_staging(slot);
                if (slot.fence)
                    vkDestroyFence(device, slot.fence, nullptr);
                if (slot.acquired)
                    vkDestroySemaphore(device, slot.acquired, nullptr);
            }
            destroy_imported();
            destroy_capture();
            if (pass)
                vkDestroyRenderPass(device, pass, nullptr);
            if (pool)
                vkDestroyCommandPool(device, pool, nullptr);
            if (ctx == nullptr) {
                vkDestroyDevice(device, nullptr);
            }
        }
        if (ctx == nullptr && surface != VK_NULL_HANDLE) {
            vkDestroySurfaceKHR(instance, surface, nullptr);
        }
        own_instance.reset();
    }

    // Submissions and waits go through the Context when presenting on one (it tracks them
    // for what the ray marcher retires).
    void submit(const VkSubmitInfo& info, VkFence fence, const std::string& what) {
        if (ctx != nullptr) {
            ctx->submit(info, fence, what);
        } else {
            check(vkQueueSubmit(queue, 1, &info, fence), "vkQueueSubmit", what);
        }
    }
    void wait(VkFence fence) {
        if (ctx != nullptr) {
            ctx->wait(fence, "frame in flight");
        } else {
            check(vkWaitForFences(device, 1, &fence, VK_TRUE, UINT64_MAX), "vkWaitForFences",
                  "frame in flight");
        }
    }
    void wait_frames() {
        for (std::uint32_t i = 0; i < kFramesInFlight; ++i) {
            wait(slots[i].fence);
            release_old_swapchains_after(i);
        }
    }
    void wait_idle() {
        if (ctx != nullptr) {
            ctx->wait_frames_in_flight();
        } else {
            vkDeviceWaitIdle(device);
        }
        for (std::uint32_t i = 0; i < kFramesInFlight; ++i) {
            release_old_swapchains_after(i);
        }
    }
    // A frame whose image was acquired failed before its submission (a throwing ray march or
    // overlay, a failed submit): the acquire's semaphore is signalled and the image ours. Both
    // go back: a submission that waits on the semaphore, clears the image and signals its
    // render-finished semaphore, then the present of that image, on the slot's fence. If even
    // that cannot be submitted, the slot gets a fresh fence (signalled) and semaphore, so that
    // the next frame neither waits forever nor acquires into a signalled semaphore.
    void abandon_frame(std::uint32_t index) noexcept;
    // Submits the current slot's `cmd` on its fence: it waits (at transfers) for the slot's
    // acquired image and signals image `index`'s render-finished semaphore. The fence is reset
    // last: a failure before the submission leaves it signalled (abandon_frame handles one of
    // the submission itself).
    void submit_to_present(VkCommandBuffer cmd, std::uint32_t index, const std::string& what) {
        Slot& slot = slots[current];
        const VkPipelineStageFlags wait_stage = VK_PIPELINE_STAGE_TRANSFER_BIT;
        VkSubmitInfo s{};
        s.sType = VK_STRUCTURE_TYPE_SUBMIT_INFO;
        s.waitSemaphoreCount = 1;
        s.pWaitSemaphores = &slot.acquired;
        s.pWaitDstStageMask = &wait_stage;
        s.commandBufferCount = 1;
        s.pCommandBuffers = &cmd;
        s.signalSemaphoreCount = 1;
        s.pSignalSemaphores = &rendered[index];
        check(vkResetFences(device, 1, &slot.fence), "vkResetFences", what);
        submit(s, slot.fence, what);
    }
    // Moves on to the next slot and queues the present of image `index` (after its
    // render-finished semaphore), noting what the old swapchains' release waits for.
    VkResult present(std::uint32_t index) {
        if (release_slot == current) {
            release_submitted = true;
        }
        if (!first_present) {
            first_present = index;
        }
        current = (current + 1) % kFramesInFlight;
        VkPresentInfoKHR p{};
        p.sType = VK_STRUCTURE_TYPE_PRESENT_INFO_KHR;
        p.waitSemaphoreCount = 1;
        p.pWaitSemaphores = &rendered[index];
        p.swapchainCount = 1;
        p.pSwapchains = &swapchain;
        p.pImageIndices = &index;
        return vkQueuePresentKHR(queue, &p);
    }
    // Replaces the current slot's fence (signalled) and acquire semaphore (unsignalled).
    void renew_slot_sync() noexcept;

    // The swapchain's format and the overlay's render pass, the command pool and the frame
    // slots (after the device and surface are known).
    void init_frames();

    void destroy_staging(Slot& slot) {
        if (slot.staging)
            vkDestroyBuffer(device, slot.staging, nullptr);
        if (slot.staging_memory)
            vkFreeMemory(device, slot.staging_memory, nullptr);
        slot.staging = VK_NULL_HANDLE;
        slot.staging_memory = VK_NULL_HANDLE;
        slot.staging_map = nullptr;
        slot.staging_size = 0;
    }

    void destroy_capture() {
        if (capture)
            vkDestroyBuffer(device, capture, nullptr);
        if (capture_memory)
            vkFreeMemory(device, capture_memory, nullptr);
        capture = VK_NULL_HANDLE;
        capture_memory = VK_NULL_HANDLE;
        capture_map = nullptr;
    }

    // Records the copy of swapchain image `image` (after the overlay's pass) into a fresh
    // host-visible buffer, in `cmd`.
    void record_capture(VkCommandBuffer cmd, VkImage image);

    void destroy_imported() {
        if (imported)
            vkDestroyBuffer(device, imported, nullptr);
        if (imported_memory)
            vkFreeMemory(device, imported_memory, nullptr);
        imported = VK_NULL_HANDLE;
        imported_memory = VK_NULL_HANDLE;
        imported_size = 0;
    }

    // Waits until the current slot's last frame has finished, recreates the swapchain when
    // the framebuffer size changed and acquires an image; false when the frame must be
    // skipped (zero size, out of date).
    bool begin_frame(std::uint32_t fb_width, std::uint32_t fb_height, std::uint32_t& index);
    // What a frame copies into the swapchain image (bytes already in the swapchain's order):
    // a buffer with rows of `row_length` pixels (external: acquired from another VkDevice), or
    // the image `march` records (the ray marcher on this device), in TRANSFER_SRC layout.
    struct Source {
        VkBuffer buffer = VK_NULL_HANDLE;
        bool external = false;
        std::uint32_t row_length = 0;
        std::function<VkImage(VkCommandBuffer)> march;
    };
    // Records the current slot's frame: `src` cropped to w x h, then the overlay; submits
    // it without waiting, presents it and moves on to the next slot.
    bool submit_frame(const Source& src, std::uint32_t w, std::uint32_t h, std::uint32_t index,
                      std::uint32_t fb_width, std::uint32_t fb_height,
                      const std::function<void(VkCommandBuffer)>& overlay);
    // submit_frame's recording and submission into the current slot (no present, the slot
    // stays current); on a throw the caller abandons the frame.
    void record_and_submit(const Source& src, std::uint32_t w, std::uint32_t h, std::uint32_t index,
                           const std::function<void(VkCommandBuffer)>& overlay);

    void destroy(OldSwapchain& old) {
        for (VkFramebuffer f : old.framebuffers)
            vkDestroyFramebuffer(device, f, nullptr);
        for (VkImageView v : old.views)
            vkDestroyImageView(device, v, nullptr);
        for (VkSemaphore r : old.rendered)
            vkDestroySemaphore(device, r, nullptr);
        if (old.swapchain)
            vkDestroySwapchainKHR(device, old.swapchain, nullptr);
        old = OldSwapchain{};
    }
    // The current swapchain and what belongs to it, as an OldSwapchain (the members emptied).
    OldSwapchain take_swapchain() {
        OldSwapchain old{swapchain, std::move(views), std::move(framebuffers), std::move(rendered)};
        swapchain = VK_NULL_HANDLE;
        views.clear();
        framebuffers.clear();
        rendered.clear();
        images.clear();
        return old;
    }
    void destroy_swapchain() {
        OldSwapchain current_one = take_swapchain();
        destroy(current_one);
    }
    void destroy_old_swapchains() {
        for (OldSwapchain& old : old_swapchains) {
            destroy(old);
        }
        old_swapchains.clear();
        release_slot.reset();
        release_submitted = false;
    }
    // After waiting for slot `slot`'s fence: frees the replaced swapchains once the frame that
    // re-acquired the first presented image of the current one has finished.
    void release_old_swapchains_after(std::uint32_t slot) {
        if (release_submitted && release_slot == slot) {
            destroy_old_swapchains();
        }
    }

    std::uint32_t memory_type(std::uint32_t allowed, VkMemoryPropertyFlags flags) const {
        for (std::uint32_t i = 0; i < memory.memoryTypeCount; ++i) {
            if ((allowed & (1u << i)) && (memory.memoryTypes[i].propertyFlags & flags) == flags) {
                return i;
            }
        }
        throw VkError("vkAllocateMemory", VK_ERROR_OUT_OF_DEVICE_MEMORY,
                      "no host-visible coherent memory type for the presentation staging buffer");
    }

    // A mapped host-visible, coherent buffer of `size` bytes (staging, window capture).
    void make_host_buffer(VkDeviceSize size, VkBufferUsageFlags usage, const std::string& what,
                          VkBuffer& buffer, VkDeviceMemory& buffer_memory, void*& map) {
        VkBufferCreateInfo b{};
        b.sType = VK_STRUCTURE_TYPE_BUFFER_CREATE_INFO;
        b.size = size;
        b.usage = usage;
        check(vkCreateBuffer(device, &b, nullptr, &buffer), "vkCreateBuffer", what);
        VkMemoryRequirements req;
        vkGetBufferMemoryRequirements(device, buffer, &req);
        VkMemoryAllocateInfo a{};
        a.sType = VK_STRUCTURE_TYPE_MEMORY_ALLOCATE_INFO;
        a.allocationSize = req.size;
        a.memoryTypeIndex =
            memory_type(req.memoryTypeBits,
                        VK_MEMORY_PROPERTY_HOST_VISIBLE_BIT | VK_MEMORY_PROPERTY_HOST_COHERENT_BIT);
        check(vkAllocateMemory(device, &a, nullptr, &buffer_memory), "vkAllocateMemory",
              what + ", " + std::to_string(size) + " bytes");
        check(vkBindBufferMemory(device, buffer, buffer_memory, 0), "vkBindBufferMemory", what);
        check(vkMapMemory(device, buffer_memory, 0, VK_WHOLE_SIZE, 0, &map), "vkMapMemory", what);
    }

    // The slot's frame has finished (begin_frame waited for it).
    void ensure_staging(Slot& slot, VkDeviceSize size) {
        if (size <= slot.staging_size) {
            return;
        }
        destroy_staging(slot);
        make_host_buffer(size, VK_BUFFER_USAGE_TRANSFER_SRC_BIT, "present staging", slot.staging,
                         slot.staging_memory, slot.staging_map);
        slot.staging_size = size;
    }

    // Frames in flight may still use the current swapchain's framebuffers and the
    // presentation engine its semaphores: it is kept (old_swapchains) until both provably
    // finished, with no wait here.
    void create_swapchain(std::uint32_t w, std::uint32_t h) {
        if (old_swapchains.size() >= kMaxOldSwapchains) {
            wait_idle();
            destroy_old_swapchains();
        }
        VkSurfaceCapabilitiesKHR caps;
        check(vkGetPhysicalDeviceSurfaceCapabilitiesKHR(physical, surface, &caps),
              "vkGetPhysicalDeviceSurfaceCapabilitiesKHR");
        VkExtent2D e = caps.currentExtent;
        if (e.width == 0xFFFFFFFFu) {
            e.width = std::clamp(w, caps.minImageExtent.width, caps.maxImageExtent.width);
            e.height = std::clamp(h, caps.minImageExtent.height, caps.maxImageExtent.height);
        }
        std::uint32_t count = 0;
        vkGetPhysicalDeviceSurfacePresentModesKHR(physical, surface, &count, nullptr);
        std::vector<VkPresentModeKHR> modes(count);
        vkGetPhysicalDeviceSurfacePresentModesKHR(physical, surface, &count, modes.data());
        mode = PresentMode::fifo;
        for (PresentMode m : wanted) {
            if (std::find(modes.begin(), modes.end(), to_vk(m)) != modes.end()) {
                mode = m;
                break;
            }
        }
        min_images = std::max(caps.minImageCount, 2u);
        if (caps.maxImageCount != 0) {
            min_images = std::min(min_images, caps.maxImageCount);
        }
        VkSwapchainCreateInfoKHR s{};
        s.sType = VK_STRUCTURE_TYPE_SWAPCHAIN_CREATE_INFO_KHR;
        s.surface = surface;
        s.minImageCount = min_images;
        s.imageFormat = format.format;
        s.imageColorSpace = format.colorSpace;
        s.imageExtent = e;
        s.imageArrayLayers = 1;
        s.imageUsage = VK_IMAGE_USAGE_COLOR_ATTACHMENT_BIT | VK_IMAGE_USAGE_TRANSFER_DST_BIT;
        can_capture = (caps.supportedUsageFlags & VK_IMAGE_USAGE_TRANSFER_SRC_BIT) != 0;
        if (can_capture) {
            s.imageUsage |= VK_IMAGE_USAGE_TRANSFER_SRC_BIT;
        }
        s.imageSharingMode = VK_SHARING_MODE_EXCLUSIVE;
        s.preTransform = caps.currentTransform;
        s.compositeAlpha = (caps.supportedCompositeAlpha & VK_COMPOSITE_ALPHA_OPAQUE_BIT_KHR)
                               ? VK_COMPOSITE_ALPHA_OPAQUE_BIT_KHR
                               : VK_COMPOSITE_ALPHA_INHERIT_BIT_KHR;
        s.presentMode = to_vk(mode);
        s.clipped = VK_TRUE;
        s.oldSwapchain = swapchain;
        VkSwapchainKHR fresh = VK_NULL_HANDLE;
        check(vkCreateSwapchainKHR(device, &s, nullptr, &fresh), "vkCreateSwapchainKHR",
              std::to_string(e.width) + "x" + std::to_string(e.height) + ", " + to_string(mode));
        old_swapchains.push_back(take_swapchain());
        first_present.reset();
        release_slot.reset();
        release_submitted = false;
        swapchain = fresh;
        extent = e;
        vkGetSwapchainImagesKHR(device, swapchain, &count, nullptr);
        images.resize(count);
        vkGetSwapchainImagesKHR(device, swapchain, &count, images.data());
        for (VkImage image : images) {
            VkImageViewCreateInfo v{};
            v.sType = VK_STRUCTURE_TYPE_IMAGE_VIEW_CREATE_INFO;
            v.image = image;
            v.viewType = VK_IMAGE_VIEW_TYPE_2D;
            v.format = format.format;
            v.subresourceRange = {VK_IMAGE_ASPECT_COLOR_BIT, 0, 1, 0, 1};
            VkImageView view = VK_NULL_HANDLE;
            check(vkCreateImageView(device, &v, nullptr, &view), "vkCreateImageView");
            views.push_back(view);
            VkFramebufferCreateInfo f{};
            f.sType = VK_STRUCTURE_TYPE_FRAMEBUFFER_CREATE_INFO;
            f.renderPass = pass;
            f.attachmentCount = 1;
            f.pAttachments = &view;
            f.width = e.width;
            f.height = e.height;
            f.layers = 1;
            VkFramebuffer fb = VK_NULL_HANDLE;
            check(vkCreateFramebuffer(device, &f, nullptr, &fb), "vkCreateFramebuffer");
            framebuffers.push_back(fb);
            VkSemaphoreCreateInfo si{};
            si.sType = VK_STRUCTURE_TYPE_SEMAPHORE_CREATE_INFO;
            VkSemaphore done = VK_NULL_HANDLE;
            check(vkCreateSemaphore(device, &si, nullptr, &done), "vkCreateSemaphore",
                  "render finished");
            rendered.push_back(done);
        }
    }
};

Presenter::Presenter(Context& ctx, std::vector<PresentMode> modes)
    : impl_(std::make_unique<Impl>()) {
    Impl& m = *impl_;
    if (!ctx.presents()) {
        throw std::logic_error("Presenter on a Context that was not created to present");
    }
    m.ctx = &ctx;
    m.wanted = std::move(modes);
    m.instance = ctx.instance();
    m.surface = ctx.surface();
    m.physical = ctx.physical();
    m.device = ctx.device();
    m.queue = ctx.queue();
    m.family = ctx.queue_family();
    m.name = ctx.info().name;
    m.memory = ctx.memory_properties();
    m.init_frames();
}

Presenter::Presenter(const PresenterOptions& options) : impl_(std::make_unique<Impl>()) {
    Impl& m = *impl_;
    m.wanted = options.modes;
    std::vector<const char*> exts;
    for (const auto& e : options.instance_extensions) {
        exts.push_back(e.c_str());
    }
    VkApplicationInfo app{};
    app.sType = VK_STRUCTURE_TYPE_APPLICATION_INFO;
    app.pApplicationName = "voxfield view";
    app.apiVersion = VK_API_VERSION_1_1;
    VkInstanceCreateInfo ii{};
    ii.sType = VK_STRUCTURE_TYPE_INSTANCE_CREATE_INFO;
    ii.pApplicationInfo = &app;
    ii.enabledExtensionCount = static_cast<std::uint32_t>(exts.size());
    ii.ppEnabledExtensionNames = exts.data();
    m.own_instance = Instance(ii, options.validation,
                              "presentation instance with the window system's surface extensions");
    m.instance = m.own_instance.get();
    m.surface = options.make_surface(m.instance);

    // A device with a queue family that does graphics and presents to the surface, chosen as
    // every Vulkan device of voxfield is ($VOXFIELD_VK_DEVICE included).
    const DeviceChoice choice =
        choose_device(m.instance, m.surface, options.device, DevicePurpose::presenting);
    m.physical = choice.physical;
    m.family = choice.family;
    m.name = choice.info.name;
    vkGetPhysicalDeviceMemoryProperties(m.physical, &m.memory);

    const float priority = 1;
    VkDeviceQueueCreateInfo q{};
    q.sType = VK_STRUCTURE_TYPE_DEVICE_QUEUE_CREATE_INFO;
    q.queueFamilyIndex = m.family;
    q.queueCount = 1;
    q.pQueuePriorities = &priority;
    // Importing frames the ray marcher's device exported (same GPU, no host round trip).
    std::vector<const char*> dev_ext = {VK_KHR_SWAPCHAIN_EXTENSION_NAME};
    if (choice.info.has_extension(VK_KHR_EXTERNAL_MEMORY_FD_EXTENSION_NAME)) {
        m.external_memory_fd = true;
        dev_ext.push_back(VK_KHR_EXTERNAL_MEMORY_FD_EXTENSION_NAME);
    }
    m.uuid = choice.info.uuid;
    VkDeviceCreateInfo di{};
    di.sType = VK_STRUCTURE_TYPE_DEVICE_CREATE_INFO;
    di.queueCreateInfoCount = 1;
    di.pQueueCreateInfos = &q;
    di.enabledExtensionCount = static_cast<std::uint32_t>(dev_ext.size());
    di.ppEnabledExtensionNames = dev_ext.data();
    check(vkCreateDevice(m.physical, &di, nullptr, &m.device), "vkCreateDevice",
          m.name + " (presentation)");
    vkGetDeviceQueue(m.device, m.family, 0, &m.queue);
    m.init_frames();
}

void Presenter::Impl::init_frames() {
    Impl& m = *this;
    // Surface format: 8-bit UNORM (the ray marcher's bytes are already display-encoded).
    std::uint32_t fc = 0;
    vkGetPhysicalDeviceSurfaceFormatsKHR(m.physical, m.surface, &fc, nullptr);
    std::vector<VkSurfaceFormatKHR> formats(fc);
    vkGetPhysicalDeviceSurfaceFormatsKHR(m.physical, m.surface, &fc, formats.data());
    if (formats.empty()) {
        throw DeviceSelectionError(m.name + " reports no surface format for the window");
    }
    m.format = formats[0];
    for (VkFormat want : {VK_FORMAT_R8G8B8A8_UNORM, VK_FORMAT_B8G8R8A8_UNORM}) {
        auto it = std::find_if(formats.begin(), formats.end(),
                               [&](const VkSurfaceFormatKHR& f) { return f.format == want; });
        if (it != formats.end()) {
            m.format = *it;
            break;
        }
    }
    m.swizzle =
        m.format.format == VK_FORMAT_B8G8R8A8_UNORM || m.format.format == VK_FORMAT_B8G8R8A8_SRGB;

    VkAttachmentDescription att{};
    att.format = m.format.format;
    att.samples = VK_SAMPLE_COUNT_1_BIT;
    att.loadOp = VK_ATTACHMENT_LOAD_OP_LOAD;
    att.storeOp = VK_ATTACHMENT_STORE_OP_STORE;
    att.stencilLoadOp = VK_ATTACHMENT_LOAD_OP_DONT_CARE;
    att.stencilStoreOp = VK_ATTACHMENT_STORE_OP_DONT_CARE;
    att.initialLayout = VK_IMAGE_LAYOUT_TRANSFER_DST_OPTIMAL;
    att.finalLayout = VK_IMAGE_LAYOUT_PRESENT_SRC_KHR;
    VkAttachmentReference ref{0, VK_IMAGE_LAYOUT_COLOR_ATTACHMENT_OPTIMAL};
    VkSubpassDescription sub{};
    sub.pipelineBindPoint = VK_PIPELINE_BIND_POINT_GRAPHICS;
    sub.colorAttachmentCount = 1;
    sub.pColorAttachments = &ref;
    VkSubpassDependency dep{};
    dep.srcSubpass = VK_SUBPASS_EXTERNAL;
    dep.dstSubpass = 0;
    dep.srcStageMask = VK_PIPELINE_STAGE_TRANSFER_BIT;
    dep.dstStageMask = VK_PIPELINE_STAGE_COLOR_ATTACHMENT_OUTPUT_BIT;
    dep.srcAccessMask = VK_ACCESS_TRANSFER_WRITE_BIT;
    dep.dstAccessMask = VK_ACCESS_COLOR_ATTACHMENT_READ_BIT | VK_ACCESS_COLOR_ATTACHMENT_WRITE_BIT;
    VkRenderPassCreateInfo rp{};
    rp.sType = VK_STRUCTURE_TYPE_RENDER_PASS_CREATE_INFO;
    rp.attachmentCount = 1;
    rp.pAttachments = &att;
    rp.subpassCount = 1;
    rp.pSubpasses = &sub;
    rp.dependencyCount = 1;
    rp.pDependencies = &dep;
    check(vkCreateRenderPass(m.device, &rp, nullptr, &m.pass), "vkCreateRenderPass", "overlay");

    VkCommandPoolCreateInfo pi{};
    pi.sType = VK_STRUCTURE_TYPE_COMMAND_POOL_CREATE_INFO;
    pi.flags = VK_COMMAND_POOL_CREATE_RESET_COMMAND_BUFFER_BIT;
    pi.queueFamilyIndex = m.family;
    check(vkCreateCommandPool(m.device, &pi, nullptr, &m.pool), "vkCreateCommandPool");
    for (Slot& slot : m.slots) {
        VkCommandBufferAllocateInfo ai{};
        ai.sType = VK_STRUCTURE_TYPE_COMMAND_BUFFER_ALLOCATE_INFO;
        ai.commandPool = m.pool;
        ai.level = VK_COMMAND_BUFFER_LEVEL_PRIMARY;
        ai.commandBufferCount = 1;
        check(vkAllocateCommandBuffers(m.device, &ai, &slot.cmd), "vkAllocateCommandBuffers");
        VkFenceCreateInfo fi{};
        fi.sType = VK_STRUCTURE_TYPE_FENCE_CREATE_INFO;
        fi.flags = VK_FENCE_CREATE_SIGNALED_BIT;
        check(vkCreateFence(m.device, &fi, nullptr, &slot.fence), "vkCreateFence");
        VkSemaphoreCreateInfo si{};
        si.sType = VK_STRUCTURE_TYPE_SEMAPHORE_CREATE_INFO;
        check(vkCreateSemaphore(m.device, &si, nullptr, &slot.acquired), "vkCreateSemaphore");
    }
}

Presenter::~Presenter() = default;

VkInstance Presenter::instance() const {
    return impl_->instance;
}
bool Presenter::shares_context() const {
    return impl_->ctx != nullptr;
}
std::uint32_t Presenter::frames_in_flight() const {
    return kFramesInFlight;
}
VkPhysicalDevice Presenter::physical() const {
    return impl_->physical;
}
VkDevice Presenter::device() const {
    return impl_->device;
}
VkQueue Presenter::queue() const {
    return impl_->queue;
}
std::uint32_t Presenter::queue_family() const {
    return impl_->family;
}
VkRenderPass Presenter::render_pass() const {
    return impl_->pass;
}
std::uint32_t Presenter::image_count() const {
    return std::max<std::uint32_t>(static_cast<std::uint32_t>(impl_->images.size()),
                                   impl_->min_images);
}
std::uint32_t Presenter::min_image_count() const {
    return impl_->min_images;
}
PresentMode Presenter::mode() const {
    return impl_->mode;
}
std::string Presenter::device_name() const {
    return impl_->name;
}
VkFormat Presenter::format() const {
    return impl_->format.format;
}
std::vector<VkSemaphore> Presenter::render_finished_semaphores() const {
    return impl_->rendered;
}

std::size_t Presenter::retired_swapchains() const {
    return impl_->old_swapchains.size();
}

void Presenter::wait_idle() {
    impl_->wait_idle();
}

void Presenter::submit_and_wait(const std::function<void(VkCommandBuffer)>& record) {
    Impl& m = *impl_;
    if (m.ctx != nullptr) {
        m.ctx->submit_and_wait(record, "presenter");
        return;
    }
    Impl::Slot& slot = m.slots[m.current];
    m.wait(slot.fence);
    check(vkResetCommandBuffer(slot.cmd, 0), "vkResetCommandBuffer");
    VkCommandBufferBeginInfo b{};
    b.sType = VK_STRUCTURE_TYPE_COMMAND_BUFFER_BEGIN_INFO;
    b.flags = VK_COMMAND_BUFFER_USAGE_ONE_TIME_SUBMIT_BIT;
    check(vkBeginCommandBuffer(slot.cmd, &b), "vkBeginCommandBuffer");
    record(slot.cmd);
    check(vkEndCommandBuffer(slot.cmd), "vkEndCommandBuffer");
    VkSubmitInfo s{};
    s.sType = VK_STRUCTURE_TYPE_SUBMIT_INFO;
    s.commandBufferCount = 1;
    s.pCommandBuffers = &slot.cmd;
    check(vkResetFences(m.device, 1, &slot.fence), "vkResetFences");
    try {
        m.submit(s, slot.fence, "presenter");
    } catch (...) {
        m.renew_slot_sync();  // else the next frame would wait for the unsignalled fence
        throw;
    }
    m.wait(slot.fence);
}

void Presenter::Impl::record_capture(VkCommandBuffer cmd, VkImage image) {
    if (capture != VK_NULL_HANDLE) {
        wait(slots[capture_slot].fence);  // the last capture's copy may still run
    }
    destroy_capture();
    make_host_buffer(VkDeviceSize{extent.width} * extent.height * 4,
                     VK_BUFFER_USAGE_TRANSFER_DST_BIT, "window capture", capture, capture_memory,
                     capture_map);
    capture_extent = extent;

    VkImageMemoryBarrier to_src{};
    to_src.sType = VK_STRUCTURE_TYPE_IMAGE_MEMORY_BARRIER;
    to_src.srcAccessMask = VK_ACCESS_COLOR_ATTACHMENT_WRITE_BIT;
    to_src.dstAccessMask = VK_ACCESS_TRANSFER_READ_BIT;
    to_src.oldLayout = VK_IMAGE_LAYOUT_PRESENT_SRC_KHR;
    to_src.newLayout = VK_IMAGE_LAYOUT_TRANSFER_SRC_OPTIMAL;
    to_src.srcQueueFamilyIndex = VK_QUEUE_FAMILY_IGNORED;
    to_src.dstQueueFamilyIndex = VK_QUEUE_FAMILY_IGNORED;
    to_src.image = image;
    to_src.subresourceRange = {VK_IMAGE_ASPECT_COLOR_BIT, 0, 1, 0, 1};
    vkCmdPipelineBarrier(cmd, VK_PIPELINE_STAGE_COLOR_ATTACHMENT_OUTPUT_BIT,
                         VK_PIPELINE_STAGE_TRANSFER_BIT, 0, 0, nullptr, 0, nullptr, 1, &to_src);
    VkBufferImageCopy c{};
    c.imageSubresource = {VK_IMAGE_ASPECT_COLOR_BIT, 0, 0, 1};
    c.imageExtent = {extent.width, extent.height, 1};
    vkCmdCopyImageToBuffer(cmd, image, VK_IMAGE_LAYOUT_TRANSFER_SRC_OPTIMAL, capture, 1, &c);
    VkImageMemoryBarrier to_present = to_src;
    to_present.srcAccessMask = VK_ACCESS_TRANSFER_READ_BIT;
    to_present.dstAccessMask = 0;
    to_present.oldLayout = VK_IMAGE_LAYOUT_TRANSFER_SRC_OPTIMAL;
    to_present.newLayout = VK_IMAGE_LAYOUT_PRESENT_SRC_KHR;
    VkMemoryBarrier to_host{};
    to_host.sType = VK_STRUCTURE_TYPE_MEMORY_BARRIER;
    to_host.srcAccessMask = VK_ACCESS_TRANSFER_WRITE_BIT;
    to_host.dstAccessMask = VK_ACCESS_HOST_READ_BIT;
    vkCmdPipelineBarrier(cmd, VK_PIPELINE_STAGE_TRANSFER_BIT,
                         VK_PIPELINE_STAGE_HOST_BIT | VK_PIPELINE_STAGE_BOTTOM_OF_PIPE_BIT, 0, 1,
                         &to_host, 0, nullptr, 1, &to_present);
}

bool Presenter::Impl::begin_frame(std::uint32_t fb_width, std::uint32_t fb_height,
                                  std::uint32_t& index) {
    Impl& m = *this;
    if (fb_width == 0 || fb_height == 0) {
        return false;  // a zero-size window, e.g. minimised
    }
    m.wait(m.slots[m.current].fence);  // the only wait of a frame: reusing its slot
    m.release_old_swapchains_after(m.current);
    if (m.swapchain == VK_NULL_HANDLE || m.extent.width != fb_width ||
        m.extent.height != fb_height) {
        m.create_swapchain(fb_width, fb_height);
    }
    VkResult r = vkAcquireNextImageKHR(m.device, m.swapchain, UINT64_MAX,
                                       m.slots[m.current].acquired, VK_NULL_HANDLE, &index);
    if (r == VK_ERROR_OUT_OF_DATE_KHR) {
        m.create_swapchain(fb_width, fb_height);
        return false;
    }
    if (r != VK_SUBOPTIMAL_KHR) {
        check(r, "vkAcquireNextImageKHR");
    }
    if (!m.old_swapchains.empty() && m.first_present == index && !m.release_slot) {
        m.release_slot = m.current;  // the image of the first present came back
    }
    return true;
}

bool Presenter::Impl::submit_frame(const Source& src, std::uint32_t w, std::uint32_t h,
                                   std::uint32_t index, std::uint32_t fb_width,
                                   std::uint32_t fb_height,
                                   const std::function<void(VkCommandBuffer)>& overlay) {
    Impl& m = *this;
    try {
        record_and_submit(src, w, h, index, overlay);
    } catch (...) {
        m.abandon_frame(index);
        throw;
    }
    const VkResult r = m.present(index);
    if (r == VK_ERROR_OUT_OF_DATE_KHR || r == VK_SUBOPTIMAL_KHR) {
        m.create_swapchain(fb_width, fb_height);
        return true;
    }
    check(r, "vkQueuePresentKHR");
    return true;
}

void Presenter::Impl::record_and_submit(const Source& src, std::uint32_t w, std::uint32_t h,
                                        std::uint32_t index,
                                        const std::function<void(VkCommandBuffer)>& overlay) {
    Impl& m = *this;
    Slot& slot = m.slots[m.current];
    const VkCommandBuffer cmd = slot.cmd;
    check(vkResetCommandBuffer(cmd, 0), "vkResetCommandBuffer");
    VkCommandBufferBeginInfo b{};
    b.sType = VK_STRUCTURE_TYPE_COMMAND_BUFFER_BEGIN_INFO;
    b.flags = VK_COMMAND_BUFFER_USAGE_ONE_TIME_SUBMIT_BIT;
    check(vkBeginCommandBuffer(cmd, &b), "vkBeginCommandBuffer");
    // The ray march runs before the acquired image is needed (only transfers wait for it).
    const VkImage marched = src.march ? src.march(cmd) : VK_NULL_HANDLE;
    VkImageMemoryBarrier to_dst{};
    to_dst.sType = VK_STRUCTURE_TYPE_IMAGE_MEMORY_BARRIER;
    to_dst.srcAccessMask = 0;
    to_dst.dstAccessMask = VK_ACCESS_TRANSFER_WRITE_BIT;
    to_dst.oldLayout = VK_IMAGE_LAYOUT_UNDEFINED;
    to_dst.newLayout = VK_IMAGE_LAYOUT_TRANSFER_DST_OPTIMAL;
    to_dst.srcQueueFamilyIndex = VK_QUEUE_FAMILY_IGNORED;
    to_dst.dstQueueFamilyIndex = VK_QUEUE_FAMILY_IGNORED;
    to_dst.image = m.images[index];
    to_dst.subresourceRange = {VK_IMAGE_ASPECT_COLOR_BIT, 0, 1, 0, 1};
    // An imported frame is acquired from the device that rendered it (it released it).
    VkBufferMemoryBarrier acquire{};
    acquire.sType = VK_STRUCTURE_TYPE_BUFFER_MEMORY_BARRIER;
    acquire.srcAccessMask = 0;
    acquire.dstAccessMask = VK_ACCESS_TRANSFER_READ_BIT;
    acquire.srcQueueFamilyIndex = VK_QUEUE_FAMILY_EXTERNAL;
    acquire.dstQueueFamilyIndex = m.family;
    acquire.buffer = src.buffer;
    acquire.offset = 0;
    acquire.size = VK_WHOLE_SIZE;
    // Transfers wait for the acquired image (the submission's wait stage): the layout
    // transition follows that wait.
    vkCmdPipelineBarrier(cmd, VK_PIPELINE_STAGE_TRANSFER_BIT, VK_PIPELINE_STAGE_TRANSFER_BIT, 0, 0,
                         nullptr, src.external ? 1 : 0, &acquire, 1, &to_dst);
    if (w < m.extent.width || h < m.extent.height) {
        const VkClearColorValue black{{0, 0, 0, 1}};
        vkCmdClearColorImage(cmd, m.images[index], VK_IMAGE_LAYOUT_TRANSFER_DST_OPTIMAL, &black, 1,
                             &to_dst.subresourceRange);
        VkMemoryBarrier mb{};
        mb.sType = VK_STRUCTURE_TYPE_MEMORY_BARRIER;
        mb.srcAccessMask = VK_ACCESS_TRANSFER_WRITE_BIT;
        mb.dstAccessMask = VK_ACCESS_TRANSFER_WRITE_BIT;
        vkCmdPipelineBarrier(cmd, VK_PIPELINE_STAGE_TRANSFER_BIT, VK_PIPELINE_STAGE_TRANSFER_BIT, 0,
                             1, &mb, 0, nullptr, 0, nullptr);
    }
    if (w > 0 && h > 0 && marched != VK_NULL_HANDLE) {
        // r32ui texels holding RGBA8 (or BGRA8) bytes into the swapchain's 32-bit format.
        VkImageCopy c{};
        c.srcSubresource = {VK_IMAGE_ASPECT_COLOR_BIT, 0, 0, 1};
        c.dstSubresource = {VK_IMAGE_ASPECT_COLOR_BIT, 0, 0, 1};
        c.extent = {w, h, 1};
        vkCmdCopyImage(cmd, marched, VK_IMAGE_LAYOUT_TRANSFER_SRC_OPTIMAL, m.images[index],
                       VK_IMAGE_LAYOUT_TRANSFER_DST_OPTIMAL, 1, &c);
    } else if (w > 0 && h > 0) {
        VkBufferImageCopy c{};
        c.bufferRowLength = src.row_length;
        c.bufferImageHeight = h;
        c.imageSubresource = {VK_IMAGE_ASPECT_COLOR_BIT, 0, 0, 1};
        c.imageExtent = {w, h, 1};
        vkCmdCopyBufferToImage(cmd, src.buffer, m.images[index],
                               VK_IMAGE_LAYOUT_TRANSFER_DST_OPTIMAL, 1, &c);
    }
    VkRenderPassBeginInfo rb{};
    rb.sType = VK_STRUCTURE_TYPE_RENDER_PASS_BEGIN_INFO;
    rb.renderPass = m.pass;
    rb.framebuffer = m.framebuffers[index];
    rb.renderArea.extent = m.extent;
    vkCmdBeginRenderPass(cmd, &rb, VK_SUBPASS_CONTENTS_INLINE);
    if (overlay) {
        overlay(cmd);
    }
    vkCmdEndRenderPass(cmd);
    if (m.capture_requested && m.can_capture) {
        m.record_capture(cmd, m.images[index]);
        m.capture_requested = false;
        m.captured = true;
        m.capture_slot = m.current;
    }
    check(vkEndCommandBuffer(cmd), "vkEndCommandBuffer");

    m.submit_to_present(cmd, index, "present");
}

void Presenter::Impl::abandon_frame(std::uint32_t index) noexcept {
    Impl& m = *this;
    Slot& slot = m.slots[m.current];
    try {
        const VkCommandBuffer cmd = slot.cmd;
        check(vkResetCommandBuffer(cmd, 0), "vkResetCommandBuffer", "abandoned frame");
        VkCommandBufferBeginInfo b{};
        b.sType = VK_STRUCTURE_TYPE_COMMAND_BUFFER_BEGIN_INFO;
        b.flags = VK_COMMAND_BUFFER_USAGE_ONE_TIME_SUBMIT_BIT;
        check(vkBeginCommandBuffer(cmd, &b), "vkBeginCommandBuffer", "abandoned frame");
        VkImageMemoryBarrier to_dst{};
        to_dst.sType = VK_STRUCTURE_TYPE_IMAGE_MEMORY_BARRIER;
        to_dst.dstAccessMask = VK_ACCESS_TRANSFER_WRITE_BIT;
        to_dst.oldLayout = VK_IMAGE_LAYOUT_UNDEFINED;
        to_dst.newLayout = VK_IMAGE_LAYOUT_TRANSFER_DST_OPTIMAL;
        to_dst.srcQueueFamilyIndex = VK_QUEUE_FAMILY_IGNORED;
        to_dst.dstQueueFamilyIndex = VK_QUEUE_FAMILY_IGNORED;
        to_dst.image = m.images[index];
        to_dst.subresourceRange = {VK_IMAGE_ASPECT_COLOR_BIT, 0, 1, 0, 1};
        vkCmdPipelineBarrier(cmd, VK_PIPELINE_STAGE_TRANSFER_BIT, VK_PIPELINE_STAGE_TRANSFER_BIT, 0,
                             0, nullptr, 0, nullptr, 1, &to_dst);
        const VkClearColorValue black{{0, 0, 0, 1}};
        vkCmdClearColorImage(cmd, m.images[index], VK_IMAGE_LAYOUT_TRANSFER_DST_OPTIMAL, &black, 1,
                             &to_dst.subresourceRange);
        VkImageMemoryBarrier to_present = to_dst;
        to_present.srcAccessMask = VK_ACCESS_TRANSFER_WRITE_BIT;
        to_present.dstAccessMask = 0;
        to_present.oldLayout = VK_IMAGE_LAYOUT_TRANSFER_DST_OPTIMAL;
        to_present.newLayout = VK_IMAGE_LAYOUT_PRESENT_SRC_KHR;
        vkCmdPipelineBarrier(cmd, VK_PIPELINE_STAGE_TRANSFER_BIT,
                             VK_PIPELINE_STAGE_BOTTOM_OF_PIPE_BIT, 0, 0, nullptr, 0, nullptr, 1,
                             &to_present);
        check(vkEndCommandBuffer(cmd), "vkEndCommandBuffer", "abandoned frame");
        m.submit_to_present(cmd, index, "abandoned frame");
    } catch (const std::exception&) {
        m.renew_slot_sync();
        return;  // the image stays acquired: nothing can return it without a submission
    }
    // Out of date or lost: the next begin_frame finds out again and recreates or throws.
    m.present(index);
}

void Presenter::Impl::renew_slot_sync() noexcept {
    Slot& slot = slots[current];
    // Neither is used by any pending submission (theirs failed), so both may go now.
    VkFenceCreateInfo fi{};
    fi.sType = VK_STRUCTURE_TYPE_FENCE_CREATE_INFO;
    fi.flags = VK_FENCE_CREATE_SIGNALED_BIT;
    VkFence fence = VK_NULL_HANDLE;
    if (vkCreateFence(device, &fi, nullptr, &fence) == VK_SUCCESS) {
        vkDestroyFence(device, slot.fence, nullptr);
        slot.fence = fence;
    }
    VkSemaphoreCreateInfo si{};
    si.sType = VK_STRUCTURE_TYPE_SEMAPHORE_CREATE_INFO;
    VkSemaphore semaphore = VK_NULL_HANDLE;
    if (vkCreateSemaphore(device, &si, nullptr, &semaphore) == VK_SUCCESS) {
        vkDestroySemaphore(device, slot.acquired, nullptr);
        slot.acquired = semaphore;
    }
}

bool Presenter::present(const std::uint8_t* rgba, std::uint32_t width, std::uint32_t height,
                        std::uint32_t fb_width, std::uint32_t fb_height,
                        const std::function<void(VkCommandBuffer)>& overlay) {
    Impl& m = *impl_;
    std::uint32_t index = 0;
    if (!m.begin_frame(fb_width, fb_height, index)) {
        return false;
    }

    // The image, cropped to the swapchain's extent, into the slot's staging buffer.
    Impl::Slot& slot = m.slots[m.current];
    const std::uint32_t w = std::min(width, m.extent.width);
    const std::uint32_t h = std::min(height, m.extent.height);
    m.ensure_staging(slot, VkDeviceSize{w} * h * 4 + 4);
    auto* dst = static_cast<std::uint8_t*>(slot.staging_map);
    for (std::uint32_t y = 0; y < h; ++y) {
        const std::uint8_t* src = rgba + (std::size_t{y} * width) * 4;
        std::uint8_t* row = dst + std::size_t{y} * w * 4;
        if (!m.swizzle) {
            std::memcpy(row, src, std::size_t{w} * 4);
        } else {
            for (std::uint32_t x = 0; x < w; ++x) {
                row[4 * x + 0] = src[4 * x + 2];
                row[4 * x + 1] = src[4 * x + 1];
                row[4 * x + 2] = src[4 * x + 0];
                row[4 * x + 3] = src[4 * x + 3];
            }
        }
    }
    Impl::Source source;
    source.buffer = slot.staging;
    source.row_length = w;
    return m.submit_frame(source, w, h, index, fb_width, fb_height, overlay);
}

bool Presenter::present_marched(Raymarcher& marcher, const RenderOptions& options,
                                std::uint32_t fb_width, std::uint32_t fb_height,
                                const std::function<void(VkCommandBuffer)>& overlay) {
    Impl& m = *impl_;
    if (m.ctx == nullptr) {
        throw std::logic_error("Presenter::present_marched needs a Presenter on the Context");
    }
    validate(options);
    std::uint32_t index = 0;
    if (!m.begin_frame(fb_width, fb_height, index)) {
        return false;
    }
    RenderOptions r = options;
    r.bgra = m.swizzle;
    Impl::Source source;
    source.march = [&](VkCommandBuffer cmd) { return marcher.record(cmd, r); };
    return m.submit_frame(source, std::min(r.width, m.extent.width),
                          std::min(r.height, m.extent.height), index, fb_width, fb_height, overlay);
}

bool Presenter::can_import_frames(const std::array<std::uint8_t, VK_UUID_SIZE>& uuid) const {
    return impl_->ctx == nullptr && impl_->external_memory_fd && impl_->uuid == uuid;
}

bool Presenter::bgra() const {
    return impl_->swizzle;
}

void Presenter::import_frame(int fd, VkDeviceSize size, std::uint32_t memory_type) {
    Impl& m = *impl_;
    // The fd is ours until the driver takes it (a successful import): closed on every other
    // way out, a throw included.
    struct OwnedFd {
        int fd;
        ~OwnedFd() {
            if (fd >= 0) {
                close(fd);
            }
        }
    } owned{fd};
    if (!m.external_memory_fd) {
        throw VkError("vkAllocateMemory", VK_ERROR_EXTENSION_NOT_PRESENT,
                      m.name + " (presentation) lacks VK_KHR_external_memory_fd");
    }
    m.wait_frames();  // frames in flight read the old import
    m.destroy_imported();
    VkExternalMemoryBufferCreateInfo eb{};
    eb.sType = VK_STRUCTURE_TYPE_EXTERNAL_MEMORY_BUFFER_CREATE_INFO;
    eb.handleTypes = VK_EXTERNAL_MEMORY_HANDLE_TYPE_OPAQUE_FD_BIT;
    VkBufferCreateInfo b{};
    b.sType = VK_STRUCTURE_TYPE_BUFFER_CREATE_INFO;
    b.pNext = &eb;
    b.size = size;
    b.usage = VK_BUFFER_USAGE_TRANSFER_SRC_BIT;
    b.sharingMode = VK_SHARING_MODE_EXCLUSIVE;
    VkBuffer buffer = VK_NULL_HANDLE;
    check(vkCreateBuffer(m.device, &b, nullptr, &buffer), "vkCreateBuffer", "imported frame");
    m.imported = buffer;
    VkImportMemoryFdInfoKHR import{};
    import.sType = VK_STRUCTURE_TYPE_IMPORT_MEMORY_FD_INFO_KHR;
    import.handleType = VK_EXTERNAL_MEMORY_HANDLE_TYPE_OPAQUE_FD_BIT;
    import.fd = fd;
    VkMemoryAllocateInfo a{};
    a.sType = VK_STRUCTURE_TYPE_MEMORY_ALLOCATE_INFO;
    a.pNext = &import;
    a.allocationSize = size;
    a.memoryTypeIndex = memory_type;
    // On success the driver owns the fd; on failure it is still ours.
    if (const VkResult r = vkAllocateMemory(m.device, &a, nullptr, &m.imported_memory);
        r != VK_SUCCESS) {
        m.imported_memory = VK_NULL_HANDLE;
        m.destroy_imported();
        check(r, "vkAllocateMemory", "importing a " + std::to_string(size) + "-byte frame");
    }
    owned.fd = -1;
    check(vkBindBufferMemory(m.device, m.imported, m.imported_memory, 0), "vkBindBufferMemory",
          "imported frame");
    m.imported_size = size;
}

void Presenter::wait_frame() {
    impl_->wait_frames();
}

bool Presenter::present_imported(std::uint32_t width, std::uint32_t height, std::uint32_t fb_width,
                                 std::uint32_t fb_height,
                                 const std::function<void(VkCommandBuffer)>& overlay) {
    Impl& m = *impl_;
    if (m.imported == VK_NULL_HANDLE || VkDeviceSize{width} * height * 4 > m.imported_size) {
        throw std::logic_error("Presenter::present_imported without a large enough import_frame");
    }
    std::uint32_t index = 0;
    if (!m.begin_frame(fb_width, fb_height, index)) {
        return false;
    }
    Impl::Source source;
    source.buffer = m.imported;
    source.external = true;
    source.row_length = width;
    return m.submit_frame(source, std::min(width, m.extent.width),
                          std::min(height, m.extent.height), index, fb_width, fb_height, overlay);
}

void Presenter::capture_next_frame() {
    impl_->capture_requested = true;
}

std::optional<Image> Presenter::captured_frame() {
    Impl& m = *impl_;
    if (!m.captured) {
        return std::nullopt;
    }
    m.wait(m.slots[m.capture_slot].fence);
    Image out;
    out.width = m.capture_extent.width;
    out.height = m.capture_extent.height;
    out.rgba.resize(std::size_t{out.width} * out.height * 4);
    std::memcpy(out.rgba.data(), m.capture_map, out.rgba.size());
    if (m.swizzle) {
        for (std::size_t i = 0; i < out.rgba.size(); i += 4) {
            std::swap(out.rgba[i], out.rgba[i + 2]);
        }
    }
    return out;
}

}  // namespace voxfield::vk
