#pragma once
// Presenting to a window (the interactive viewer) through a swapchain that is recreated on
// resize. Built on a presenting Context (ContextOptions::make_surface), it uses that
// Context's instance, surface, device and queue: each frame records the Raymarcher's
// dispatch, the copy of its image into the acquired swapchain image and an overlay render pass
// (Dear ImGui draws there) into one command buffer, with no export, import or host round
// trip. Built on its own (PresenterOptions) it makes a Context of its own for presenting
// (ContextOptions::purpose; the same instance creation and device selection, $VOXFIELD_VK_DEVICE
// included), for when the ray marcher's device cannot present: frames then come from the host
// (present) or from memory the ray marcher's device exported on the same GPU
// (present_imported). Either way every submission and wait goes through that Context and
// every Vulkan object is held by an RAII handle (Owned, Buffer).
// Frames in flight: kFramesInFlight frame slots, each with a command buffer, a fence and an
// image-available semaphore, plus one render-finished semaphore per swapchain image; the CPU
// waits only when it reuses a slot (the frame before last). A frame that fails after its image
// was acquired (a throwing ray march or overlay, a failed submission) still returns the image
// (cleared) and consumes the acquire's semaphore before the error propagates, so the next frame
// starts clean. vk/ stays free of any window
// system API: the caller passes the required instance extensions and a function that makes
// the surface.
#include <vulkan/vulkan.h>

#include <array>
#include <cstdint>
#include <functional>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include "voxfield/vk/context.hpp"
#include "voxfield/vk/raymarcher.hpp"

namespace voxfield::vk {

enum class PresentMode { fifo, mailbox, immediate };
std::string to_string(PresentMode mode);

struct PresenterOptions {
    std::vector<std::string> instance_extensions;          // e.g. glfwGetRequiredInstanceExtensions
    std::function<VkSurfaceKHR(VkInstance)> make_surface;  // throws on failure
    // Preferred modes in order; FIFO (always available, vsync) is the fallback.
    std::vector<PresentMode> modes = {PresentMode::fifo};
    std::string device;  // as Context: "" ($VOXFIELD_VK_DEVICE or the best), gpu, cpu, N
    // Non-null: validation on for the presenter's instance, messages to this log (as
    // ContextOptions::validation).
    std::shared_ptr<ValidationLog> validation;
};

class Presenter {
  public:
    // On `ctx` (created with ContextOptions::make_surface; it must outlive the presenter),
    // preferring `modes` in order (FIFO is the fallback). Throws std::logic_error when `ctx`
    // does not present.
    explicit Presenter(Context& ctx, std::vector<PresentMode> modes = {PresentMode::fifo});
    // On a Context of its own (options.make_surface and instance_extensions), whose device only
    // needs to present. Throws DeviceSelectionError as Context does.
    explicit Presenter(const PresenterOptions& options);
    ~Presenter();
    Presenter(const Presenter&) = delete;
    Presenter& operator=(const Presenter&) = delete;

    VkInstance instance() const;
    // Whether it presents on the Context it was given (the ray marcher's) rather than its own.
    bool shares_context() const;
    // How many frames may be recorded and submitted before the CPU waits for the oldest.
    std::uint32_t frames_in_flight() const;
    VkPhysicalDevice physical() const;
    VkDevice device() const;
    VkQueue queue() const;
    std::uint32_t queue_family() const;
    VkRenderPass render_pass() const;  // the overlay's pass (one colour attachment, loaded)
    std::uint32_t image_count() const;
    std::uint32_t min_image_count() const;
    PresentMode mode() const;
    std::string device_name() const;
    VkFormat format() const;
    // What presenting each swapchain image waits on: one semaphore per image (a semaphore is
    // signalled again only once its image came back from the presentation engine).
    std::vector<VkSemaphore> render_finished_semaphores() const;
    // Swapchains replaced (resize, out of date) but kept with their semaphores, views and
    // framebuffers until the presentation engine provably finished with them: once the image
    // of the new swapchain's first present was acquired again and that frame finished (no
    // device wait on a resize).
    std::size_t retired_swapchains() const;

    // Presents `rgba` (width x height RGBA8 rows, top to bottom; the part outside the
    // swapchain's extent is dropped, uncovered parts are black) at framebuffer size
    // (fb_width, fb_height); recreates the swapchain when that size changed or the surface
    // reports it out of date. `overlay` records draw commands inside the render pass.
    // Returns false when the frame was skipped (a zero-size window, e.g. minimised).
    bool present(const std::uint8_t* rgba, std::uint32_t width, std::uint32_t height,
                 std::uint32_t fb_width, std::uint32_t fb_height,
                 const std::function<void(VkCommandBuffer)>& overlay);

    // On a Context only: records `marcher`'s ray march of `options` (the marcher must be on
    // the same Context; options.bgra is set to the swapchain's byte order) into the frame's
    // command buffer, followed by the copy of its image (cropped to the swapchain's extent,
    // uncovered parts black) into the swapchain image and the overlay; submits without
    // waiting and presents. The ray march's GPU time shows in
    // marcher.finished_raymarch_ms() once the frame has finished. Returns false when the
    // frame was skipped (a zero-size window, an out-of-date swapchain).
    bool present_marched(Raymarcher& marcher, const RenderOptions& options, std::uint32_t fb_width,
                         std::uint32_t fb_height,
                         const std::function<void(VkCommandBuffer)>& overlay);

    // With its own device: frames rendered on another VkDevice of the same GPU
    // (vk::Raymarcher::render_to into ExternalMemory::exportable memory) and presented with
    // no host round trip. can_import_frames: this presenter has its own device, which imports
    // opaque fds and whose deviceUUID is `uuid`.
    bool can_import_frames(const std::array<std::uint8_t, VK_UUID_SIZE>& uuid) const;
    // The swapchain wants B, G, R, A bytes (render with RenderOptions::bgra).
    bool bgra() const;
    // Imports the memory behind `fd` (ExternalMemory::export_fd; the presenter takes the fd)
    // of `size` bytes and `memory_type` (ExternalMemory::memory_type) as the source of
    // present_imported(), replacing the previous one; waits for the frames in flight first.
    void import_frame(int fd, VkDeviceSize size, std::uint32_t memory_type);
    // Waits until no frame in flight reads the imported memory: call before rendering the
    // next frame into it.
    void wait_frame();
    // As present(), from the imported memory holding width x height pixels (rows of `width`).
    bool present_imported(std::uint32_t width, std::uint32_t height, std::uint32_t fb_width,
                          std::uint32_t fb_height,
                          const std::function<void(VkCommandBuffer)>& overlay);

    // What the window shows, for scripted checks: the next presented frame (overlay
    // included) is also copied to the host; captured_frame() returns it as RGBA8 once it was
    // presented, nothing when the swapchain images cannot be copied from (no
    // VK_IMAGE_USAGE_TRANSFER_SRC_BIT) or no frame was presented since the request.
    void capture_next_frame();
    std::optional<Image> captured_frame();

    // Records into a command buffer, submits it and waits (e.g. the overlay's font upload).
    void submit_and_wait(const std::function<void(VkCommandBuffer)>& record);
    // Waits until every frame in flight has finished (on a Context:
    // Context::wait_frames_in_flight).
    void wait_idle();

  private:
    struct Impl;
    std::unique_ptr<Impl> impl_;
};

}  // namespace voxfield::vk
