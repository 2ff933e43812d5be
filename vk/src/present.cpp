// Window presentation: swapchain, host image copy, overlay render pass (present.hpp). Every
// Vulkan object is held by an RAII handle (Owned, Buffer) and every submission and wait goes
// through a vk::Context: the ray marcher's, or one of the presenter's own made for presenting
// (its instance, device selection and $VOXFIELD_VK_DEVICE as every Context's).
#include "voxfield/vk/present.hpp"

#include <unistd.h>

#include <algorithm>
#include <array>
#include <cstring>
#include <optional>
#include <stdexcept>
#include <string>
#include <vector>

#include "compute_pipeline.hpp"

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

// A fence made signalled (a slot with no submission yet).
Owned<VkFence> make_fence(VkDevice device, const std::string& what) {
    VkFenceCreateInfo fi{};
    fi.sType = VK_STRUCTURE_TYPE_FENCE_CREATE_INFO;
    fi.flags = VK_FENCE_CREATE_SIGNALED_BIT;
    VkFence fence = VK_NULL_HANDLE;
    check(vkCreateFence(device, &fi, nullptr, &fence), "vkCreateFence", what);
    return Owned<VkFence>(device, fence, vkDestroyFence);
}

Owned<VkSemaphore> make_semaphore(VkDevice device, const std::string& what) {
    VkSemaphoreCreateInfo si{};
    si.sType = VK_STRUCTURE_TYPE_SEMAPHORE_CREATE_INFO;
    VkSemaphore semaphore = VK_NULL_HANDLE;
    check(vkCreateSemaphore(device, &si, nullptr, &semaphore), "vkCreateSemaphore", what);
    return Owned<VkSemaphore>(device, semaphore, vkDestroySemaphore);
}

}  // namespace

// Frames recorded and submitted while earlier ones still run on the GPU.
constexpr std::uint32_t kFramesInFlight = 2;

struct Presenter::Impl {
    // Declared first, destroyed last: the presenter's own Context (a device of its own), when
    // it does not present on the ray marcher's.
    std::unique_ptr<Context> own;
    // The Context it presents on (its instance, surface, device and queue; submissions and
    // waits through it, so that it tracks them for what the ray marcher retires).
    Context* ctx = nullptr;
    VkDevice device = VK_NULL_HANDLE;
    VkSurfaceFormatKHR format{};
    bool swizzle = false;  // BGRA swapchain: swap R and B when copying
    PresentMode mode = PresentMode::fifo;
    std::vector<PresentMode> wanted;

    Owned<VkRenderPass> pass;   // before the framebuffers made with it (destroyed after them)
    Owned<VkCommandPool> pool;  // frees the slots' command buffers

    // A swapchain and what belongs to it; members destroyed in reverse order: the
    // render-finished semaphores, framebuffers, views, then the swapchain.
    struct Swapchain {
        Owned<VkSwapchainKHR> swapchain;
        std::vector<Owned<VkImageView>> views;
        std::vector<Owned<VkFramebuffer>> framebuffers;
        // One render-finished semaphore per swapchain image (what presenting it waits on): a
        // semaphore is signalled again only after its image was acquired again, i.e. after
        // the presentation that waited on it is done with it.
        std::vector<Owned<VkSemaphore>> rendered;
    };
    Swapchain chain;
    VkExtent2D extent{0, 0};
    std::uint32_t min_images = 2;
    std::vector<VkImage> images;  // the swapchain's (owned by it)
    // Replaced swapchains, kept until the presentation engine provably finished with them. A
    // present gives no signal when it has waited on its semaphore, so (as ANGLE does, "Queue
    // Present Wait Semaphore Management") they go once the image of the new swapchain's first
    // present was acquired again and the frame that waited on that acquire finished: the
    // presentation engine gave that image back, so it processed that present, and every
    // present queued before it.
    std::vector<Swapchain> old_swapchains;
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
        VkCommandBuffer cmd = VK_NULL_HANDLE;  // freed with `pool`
        Owned<VkFence> fence;
        Owned<VkSemaphore> acquired;
        Buffer staging;
    };
    std::array<Slot, kFramesInFlight> slots{};
    std::uint32_t current = 0;  // the slot of the next frame

    // Frames rendered by another VkDevice of this GPU (import_frame): the imported memory
    // (declared first: freed after the buffer bound to it) and that buffer.
    Owned<VkDeviceMemory> imported_memory;
    Buffer imported;

    // capture_next_frame(): the next presented image (overlay included) copied to the host.
    bool can_capture = false, capture_requested = false, captured = false;
    std::uint32_t capture_slot = 0;  // the slot whose submission copies it
    Buffer capture;
    VkExtent2D capture_extent{0, 0};

    Impl() = default;
    Impl(const Impl&) = delete;
    Impl& operator=(const Impl&) = delete;
    ~Impl() {
        if (device != VK_NULL_HANDLE) {
            // Teardown waits for the whole device: presents are not fenced, so the frames'
            // fences do not cover the semaphores a present still holds
            // (VUID-vkDestroySemaphore-semaphore-01137). Then the Context forgets the frames'
            // fences before the slots destroy them.
            wait_device();
        }
    }

    // Presents are not fenced: only a device wait covers the semaphores they hold. Then every
    // submission is known to have finished.
    void wait_device() noexcept {
        vkDeviceWaitIdle(device);
        try {
            ctx->wait_frames_in_flight();
        } catch (const std::exception&) {
            // The device is idle: a fence wait fails only for a lost device, which has
            // nothing left to wait for.
        }
    }
    void wait(const Owned<VkFence>& fence) { ctx->wait(fence.get(), "frame in flight"); }
    void wait_frames() {
        for (std::uint32_t i = 0; i < kFramesInFlight; ++i) {
            wait(slots[i].fence);
            release_old_swapchains_after(i);
        }
    }
    void wait_idle() {
        ctx->wait_frames_in_flight();
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
        const VkSemaphore acquired = slot.acquired.get();
        const VkSemaphore rendered = chain.rendered[index].get();
        VkSubmitInfo s{};
        s.sType = VK_STRUCTURE_TYPE_SUBMIT_INFO;
        s.waitSemaphoreCount = 1;
        s.pWaitSemaphores = &acquired;
        s.pWaitDstStageMask = &wait_stage;
        s.commandBufferCount = 1;
        s.pCommandBuffers = &cmd;
        s.signalSemaphoreCount = 1;
        s.pSignalSemaphores = &rendered;
        const VkFence fence = slot.fence.get();
        check(vkResetFences(device, 1, &fence), "vkResetFences", what);
        ctx->submit(s, fence, what);
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
        const VkSemaphore rendered = chain.rendered[index].get();
        const VkSwapchainKHR swapchain = chain.swapchain.get();
        VkPresentInfoKHR p{};
        p.sType = VK_STRUCTURE_TYPE_PRESENT_INFO_KHR;
        p.waitSemaphoreCount = 1;
        p.pWaitSemaphores = &rendered;
        p.swapchainCount = 1;
        p.pSwapchains = &swapchain;
        p.pImageIndices = &index;
        return vkQueuePresentKHR(ctx->queue(), &p);
    }
    // Replaces the current slot's fence (signalled) and acquire semaphore (unsignalled).
    void renew_slot_sync() noexcept;

    // The swapchain's format and the overlay's render pass, the command pool and the frame
    // slots (after the Context is known).
    void init_frames();

    // Records the copy of swapchain image `image` (after the overlay's pass) into a fresh
    // host-visible buffer, in `cmd`.
    void record_capture(VkCommandBuffer cmd, VkImage image);

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

    void destroy_old_swapchains() {
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

    // The slot's frame has finished (begin_frame waited for it).
    void ensure_staging(Slot& slot, VkDeviceSize size) {
        if (size <= slot.staging.size()) {
            return;
        }
        slot.staging = Buffer{};
        slot.staging = ctx->make_buffer(size, VK_BUFFER_USAGE_TRANSFER_SRC_BIT,
                                        MemoryIntent::upload, "present staging");
    }

    // Frames in flight may still use the current swapchain's framebuffers and the
    // presentation engine its semaphores: it is kept (old_swapchains) until both provably
    // finished, with no wait here.
    void create_swapchain(std::uint32_t w, std::uint32_t h);
};

void Presenter::Impl::create_swapchain(std::uint32_t w, std::uint32_t h) {
    if (old_swapchains.size() >= kMaxOldSwapchains) {
        wait_device();
        destroy_old_swapchains();
    }
    const VkPhysicalDevice physical = ctx->physical();
    const VkSurfaceKHR surface = ctx->surface();
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
    s.oldSwapchain = chain.swapchain.get();
    VkSwapchainKHR created = VK_NULL_HANDLE;
    check(vkCreateSwapchainKHR(device, &s, nullptr, &created), "vkCreateSwapchainKHR",
          std::to_string(e.width) + "x" + std::to_string(e.height) + ", " + to_string(mode));
    Swapchain fresh;
    fresh.swapchain = Owned<VkSwapchainKHR>(device, created, vkDestroySwapchainKHR);
    if (chain.swapchain) {
        old_swapchains.push_back(std::move(chain));
    }
    chain = std::move(fresh);
    images.clear();
    first_present.reset();
    release_slot.reset();
    release_submitted = false;
    extent = e;
    vkGetSwapchainImagesKHR(device, created, &count, nullptr);
    images.resize(count);
    vkGetSwapchainImagesKHR(device, created, &count, images.data());
    for (VkImage image : images) {
        VkImageViewCreateInfo v{};
        v.sType = VK_STRUCTURE_TYPE_IMAGE_VIEW_CREATE_INFO;
        v.image = image;
        v.viewType = VK_IMAGE_VIEW_TYPE_2D;
        v.format = format.format;
        v.subresourceRange = {VK_IMAGE_ASPECT_COLOR_BIT, 0, 1, 0, 1};
        VkImageView view = VK_NULL_HANDLE;
        check(vkCreateImageView(device, &v, nullptr, &view), "vkCreateImageView");
        chain.views.emplace_back(device, view, vkDestroyImageView);
        VkFramebufferCreateInfo f{};
        f.sType = VK_STRUCTURE_TYPE_FRAMEBUFFER_CREATE_INFO;
        f.renderPass = pass.get();
        f.attachmentCount = 1;
        f.pAttachments = &view;
        f.width = e.width;
        f.height = e.height;
        f.layers = 1;
        VkFramebuffer fb = VK_NULL_HANDLE;
        check(vkCreateFramebuffer(device, &f, nullptr, &fb), "vkCreateFramebuffer");
        chain.framebuffers.emplace_back(device, fb, vkDestroyFramebuffer);
        chain.rendered.push_back(make_semaphore(device, "render finished"));
    }
}

Presenter::Presenter(Context& ctx, std::vector<PresentMode> modes)
    : impl_(std::make_unique<Impl>()) {
    Impl& m = *impl_;
    if (!ctx.presents()) {
        throw std::logic_error("Presenter on a Context that was not created to present");
    }
    m.ctx = &ctx;
    m.device = ctx.device();
    m.wanted = std::move(modes);
    m.init_frames();
}

Presenter::Presenter(const PresenterOptions& options) : impl_(std::make_unique<Impl>()) {
    Impl& m = *impl_;
    m.wanted = options.modes;
    // A device with a queue family that does graphics and presents to the surface, chosen as
    // every Vulkan device of voxfield is ($VOXFIELD_VK_DEVICE included); VK_KHR_swapchain and,
    // where the device has it, VK_KHR_external_memory_fd for frames the ray marcher's device
    // exported (same GPU, no host round trip).
    ContextOptions co;
    co.device = options.device;
    co.validation = options.validation;
    co.instance_extensions = options.instance_extensions;
    co.make_surface = options.make_surface;
    co.purpose = DevicePurpose::presenting;
    m.own = std::make_unique<Context>(co);
    m.ctx = m.own.get();
    m.device = m.ctx->device();
    m.init_frames();
}

void Presenter::Impl::init_frames() {
    Impl& m = *this;
    // Surface format: 8-bit UNORM (the ray marcher's bytes are already display-encoded).
    std::uint32_t fc = 0;
    vkGetPhysicalDeviceSurfaceFormatsKHR(ctx->physical(), ctx->surface(), &fc, nullptr);
    std::vector<VkSurfaceFormatKHR> formats(fc);
    vkGetPhysicalDeviceSurfaceFormatsKHR(ctx->physical(), ctx->surface(), &fc, formats.data());
    if (formats.empty()) {
        throw DeviceSelectionError(ctx->info().name + " reports no surface format for the window");
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
    VkRenderPass render_pass = VK_NULL_HANDLE;
    check(vkCreateRenderPass(m.device, &rp, nullptr, &render_pass), "vkCreateRenderPass",
          "overlay");
    m.pass = Owned<VkRenderPass>(m.device, render_pass, vkDestroyRenderPass);

    VkCommandPoolCreateInfo pi{};
    pi.sType = VK_STRUCTURE_TYPE_COMMAND_POOL_CREATE_INFO;
    pi.flags = VK_COMMAND_POOL_CREATE_RESET_COMMAND_BUFFER_BIT;
    pi.queueFamilyIndex = ctx->queue_family();
    VkCommandPool command_pool = VK_NULL_HANDLE;
    check(vkCreateCommandPool(m.device, &pi, nullptr, &command_pool), "vkCreateCommandPool");
    m.pool = Owned<VkCommandPool>(m.device, command_pool, vkDestroyCommandPool);
    for (Slot& slot : m.slots) {
        VkCommandBufferAllocateInfo ai{};
        ai.sType = VK_STRUCTURE_TYPE_COMMAND_BUFFER_ALLOCATE_INFO;
        ai.commandPool = command_pool;
        ai.level = VK_COMMAND_BUFFER_LEVEL_PRIMARY;
        ai.commandBufferCount = 1;
        check(vkAllocateCommandBuffers(m.device, &ai, &slot.cmd), "vkAllocateCommandBuffers");
        slot.fence = make_fence(m.device, "frame slot");
        slot.acquired = make_semaphore(m.device, "image acquired");
    }
}

Presenter::~Presenter() = default;

VkInstance Presenter::instance() const {
    return impl_->ctx->instance();
}
bool Presenter::shares_context() const {
    return impl_->own == nullptr;
}
std::uint32_t Presenter::frames_in_flight() const {
    return kFramesInFlight;
}
VkPhysicalDevice Presenter::physical() const {
    return impl_->ctx->physical();
}
VkDevice Presenter::device() const {
    return impl_->device;
}
VkQueue Presenter::queue() const {
    return impl_->ctx->queue();
}
std::uint32_t Presenter::queue_family() const {
    return impl_->ctx->queue_family();
}
VkRenderPass Presenter::render_pass() const {
    return impl_->pass.get();
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
    return impl_->ctx->info().name;
}
VkFormat Presenter::format() const {
    return impl_->format.format;
}
std::vector<VkSemaphore> Presenter::render_finished_semaphores() const {
    std::vector<VkSemaphore> out;
    for (const Owned<VkSemaphore>& s : impl_->chain.rendered) {
        out.push_back(s.get());
    }
    return out;
}

std::size_t Presenter::retired_swapchains() const {
    return impl_->old_swapchains.size();
}

void Presenter::wait_idle() {
    impl_->wait_idle();
}

void Presenter::submit_and_wait(const std::function<void(VkCommandBuffer)>& record) {
    impl_->ctx->submit_and_wait(record, "presenter");
}

void Presenter::Impl::record_capture(VkCommandBuffer cmd, VkImage image) {
    if (capture.get() != VK_NULL_HANDLE) {
        wait(slots[capture_slot].fence);  // the last capture's copy may still run
    }
    capture = Buffer{};
    capture = ctx->make_buffer(VkDeviceSize{extent.width} * extent.height * 4,
                               VK_BUFFER_USAGE_TRANSFER_DST_BIT, MemoryIntent::readback,
                               "window capture");
    capture_extent = extent;

    const VkImageMemoryBarrier to_src =
        color_barrier(image, VK_ACCESS_COLOR_ATTACHMENT_WRITE_BIT, VK_ACCESS_TRANSFER_READ_BIT,
                      VK_IMAGE_LAYOUT_PRESENT_SRC_KHR, VK_IMAGE_LAYOUT_TRANSFER_SRC_OPTIMAL);
    vkCmdPipelineBarrier(cmd, VK_PIPELINE_STAGE_COLOR_ATTACHMENT_OUTPUT_BIT,
                         VK_PIPELINE_STAGE_TRANSFER_BIT, 0, 0, nullptr, 0, nullptr, 1, &to_src);
    VkBufferImageCopy c{};
    c.imageSubresource = {VK_IMAGE_ASPECT_COLOR_BIT, 0, 0, 1};
    c.imageExtent = {extent.width, extent.height, 1};
    vkCmdCopyImageToBuffer(cmd, image, VK_IMAGE_LAYOUT_TRANSFER_SRC_OPTIMAL, capture.get(), 1, &c);
    const VkImageMemoryBarrier to_present =
        color_barrier(image, VK_ACCESS_TRANSFER_READ_BIT, 0, VK_IMAGE_LAYOUT_TRANSFER_SRC_OPTIMAL,
                      VK_IMAGE_LAYOUT_PRESENT_SRC_KHR);
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
    if (!m.chain.swapchain || m.extent.width != fb_width || m.extent.height != fb_height) {
        m.create_swapchain(fb_width, fb_height);
    }
    VkResult r = vkAcquireNextImageKHR(m.device, m.chain.swapchain.get(), UINT64_MAX,
                                       m.slots[m.current].acquired.get(), VK_NULL_HANDLE, &index);
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
    const VkImageMemoryBarrier to_dst =
        color_barrier(m.images[index], 0, VK_ACCESS_TRANSFER_WRITE_BIT, VK_IMAGE_LAYOUT_UNDEFINED,
                      VK_IMAGE_LAYOUT_TRANSFER_DST_OPTIMAL);
    // An imported frame is acquired from the device that rendered it (it released it).
    VkBufferMemoryBarrier acquire{};
    acquire.sType = VK_STRUCTURE_TYPE_BUFFER_MEMORY_BARRIER;
    acquire.srcAccessMask = 0;
    acquire.dstAccessMask = VK_ACCESS_TRANSFER_READ_BIT;
    acquire.srcQueueFamilyIndex = VK_QUEUE_FAMILY_EXTERNAL;
    acquire.dstQueueFamilyIndex = m.ctx->queue_family();
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
    rb.renderPass = m.pass.get();
    rb.framebuffer = m.chain.framebuffers[index].get();
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
        const VkImageMemoryBarrier to_dst =
            color_barrier(m.images[index], 0, VK_ACCESS_TRANSFER_WRITE_BIT,
                          VK_IMAGE_LAYOUT_UNDEFINED, VK_IMAGE_LAYOUT_TRANSFER_DST_OPTIMAL);
        vkCmdPipelineBarrier(cmd, VK_PIPELINE_STAGE_TRANSFER_BIT, VK_PIPELINE_STAGE_TRANSFER_BIT, 0,
                             0, nullptr, 0, nullptr, 1, &to_dst);
        const VkClearColorValue black{{0, 0, 0, 1}};
        vkCmdClearColorImage(cmd, m.images[index], VK_IMAGE_LAYOUT_TRANSFER_DST_OPTIMAL, &black, 1,
                             &to_dst.subresourceRange);
        const VkImageMemoryBarrier to_present =
            color_barrier(m.images[index], VK_ACCESS_TRANSFER_WRITE_BIT, 0,
                          VK_IMAGE_LAYOUT_TRANSFER_DST_OPTIMAL, VK_IMAGE_LAYOUT_PRESENT_SRC_KHR);
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
    // Neither is used by any pending submission (theirs failed), so both may go now. Where
    // even a new one cannot be made (out of host memory), the old one stays: this is called
    // while another error propagates, which the caller reports.
    try {
        slot.fence = make_fence(device, "frame slot");
    } catch (const std::exception&) {
    }
    try {
        slot.acquired = make_semaphore(device, "image acquired");
    } catch (const std::exception&) {
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
    auto* dst = static_cast<std::uint8_t*>(slot.staging.data());
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
    source.buffer = slot.staging.get();
    source.row_length = w;
    return m.submit_frame(source, w, h, index, fb_width, fb_height, overlay);
}

bool Presenter::present_marched(Raymarcher& marcher, const RenderOptions& options,
                                std::uint32_t fb_width, std::uint32_t fb_height,
                                const std::function<void(VkCommandBuffer)>& overlay) {
    Impl& m = *impl_;
    if (m.own) {
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
    const Impl& m = *impl_;
    return m.own && m.ctx->enabled(VK_KHR_EXTERNAL_MEMORY_FD_EXTENSION_NAME) &&
           m.ctx->info().uuid == uuid;
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
    if (!m.ctx->enabled(VK_KHR_EXTERNAL_MEMORY_FD_EXTENSION_NAME)) {
        throw VkError("vkAllocateMemory", VK_ERROR_EXTENSION_NOT_PRESENT,
                      m.ctx->info().name + " (presentation) lacks VK_KHR_external_memory_fd");
    }
    m.wait_frames();  // frames in flight read the old import
    m.imported = Buffer{};
    m.imported_memory.reset();
    Buffer buffer =
        m.ctx->make_external_buffer(size, VK_BUFFER_USAGE_TRANSFER_SRC_BIT,
                                    VK_EXTERNAL_MEMORY_HANDLE_TYPE_OPAQUE_FD_BIT, "imported frame");
    VkImportMemoryFdInfoKHR import{};
    import.sType = VK_STRUCTURE_TYPE_IMPORT_MEMORY_FD_INFO_KHR;
    import.handleType = VK_EXTERNAL_MEMORY_HANDLE_TYPE_OPAQUE_FD_BIT;
    import.fd = fd;
    VkMemoryAllocateInfo a{};
    a.sType = VK_STRUCTURE_TYPE_MEMORY_ALLOCATE_INFO;
    a.pNext = &import;
    a.allocationSize = size;
    a.memoryTypeIndex = memory_type;
    VkDeviceMemory memory = VK_NULL_HANDLE;
    // On success the driver owns the fd; on failure it is still ours.
    check(vkAllocateMemory(m.device, &a, nullptr, &memory), "vkAllocateMemory",
          "importing a " + std::to_string(size) + "-byte frame");
    owned.fd = -1;
    Owned<VkDeviceMemory> imported_memory(m.device, memory, vkFreeMemory);
    m.ctx->bind(buffer, memory, 0, "imported frame");
    m.imported_memory = std::move(imported_memory);
    m.imported = std::move(buffer);
}

void Presenter::wait_frame() {
    impl_->wait_frames();
}

bool Presenter::present_imported(std::uint32_t width, std::uint32_t height, std::uint32_t fb_width,
                                 std::uint32_t fb_height,
                                 const std::function<void(VkCommandBuffer)>& overlay) {
    Impl& m = *impl_;
    if (!m.imported_memory || VkDeviceSize{width} * height * 4 > m.imported.size()) {
        throw std::logic_error("Presenter::present_imported without a large enough import_frame");
    }
    std::uint32_t index = 0;
    if (!m.begin_frame(fb_width, fb_height, index)) {
        return false;
    }
    Impl::Source source;
    source.buffer = m.imported.get();
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
    std::memcpy(out.rgba.data(), m.capture.data(), out.rgba.size());
    if (m.swizzle) {
        for (std::size_t i = 0; i < out.rgba.size(); i += 4) {
            std::swap(out.rgba[i], out.rgba[i + 2]);
        }
    }
    return out;
}

}  // namespace voxfield::vk
