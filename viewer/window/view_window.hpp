#pragma once
// `view`'s window and what shows frames in it: the GLFW window (or why there is none, and
// then the headless fallbacks), the Vulkan context the ray marcher runs on (the one that
// presents where it can), the presenter with Dear ImGui on it, how frames reach the swapchain,
// and one frame's input polled from GLFW, the overlay and `--script`.
#include <vulkan/vulkan.h>

#define GLFW_INCLUDE_VULKAN
#include <GLFW/glfw3.h>

#include <cstdint>
#include <memory>
#include <optional>
#include <string>

#include "view_input.hpp"
#include "view_options.hpp"
#include "view_script.hpp"
#include "voxfield/pipeline/frame_pipeline.hpp"
#include "voxfield/vk/present.hpp"

namespace voxfield::cli {

class Window {
  public:
    // Opens a width x height window, or records why there is none (no display, GLFW or a
    // Vulkan loader that presents).
    Window(std::uint32_t width, std::uint32_t height);
    ~Window();
    Window(const Window&) = delete;
    Window& operator=(const Window&) = delete;
    GLFWwindow* handle() const { return handle_; }
    const std::string& why_none() const { return why_none_; }
    // Processes the window's events; false once the user closed it.
    bool poll();
    // This frame's input: the keyboard, mouse and overlay, with the script's on top; the
    // cursor is captured or freed here (first_frame: it has just been captured).
    RawInput input(const ViewScript* script, bool first_frame);

  private:
    GLFWwindow* handle_ = nullptr;
    std::string why_none_;
};

// Without a window: --benchmark runs headless, --fallback-png renders one frame headless into
// that file (o.frames and o.screenshot are set for it), each said in a line. False for
// anything else, or with a script (it needs the window).
bool go_headless(ViewCliOptions& o, bool scripted, const std::string& why);
// The exit when there is no display and nothing to do headless: says so and suggests render.
int no_display(const std::string& why);

// The ray marcher's context: on a device that presents to `window` where there is one (else
// why_not_one_device says why), else headless.
std::unique_ptr<vk::Context> marcher_context(GLFWwindow* window,
                                             const std::shared_ptr<vk::ValidationLog>& validation,
                                             std::string& why_not_one_device);

// How frames reach the window: ray-marched into the swapchain image on the one device that
// presents, exported by the ray marcher's device and imported by the presenter's, or read back
// and uploaded.
enum class FramePath { one_device, imported, host };
const char* present_path(FramePath path);

// Dear ImGui's GLFW and Vulkan backends on a presenter.
class ImGuiBackend {
  public:
    ImGuiBackend(GLFWwindow* window, vk::Presenter& presenter);
    ~ImGuiBackend();
    ImGuiBackend(const ImGuiBackend&) = delete;
    ImGuiBackend& operator=(const ImGuiBackend&) = delete;
    void new_frame();
    // Records the overlay drawn since new_frame (after ImGui::Render).
    static void record(VkCommandBuffer cmd);

  private:
    void release();

    vk::Presenter& presenter_;
    VkDescriptorPool pool_ = VK_NULL_HANDLE;
    bool ready_ = false;
};

// The window's presenter (on the ray marcher's context where that presents, else on a device
// of its own) and the overlay's backends; made after the frame pipeline, gone before it.
class Screen {
  public:
    // --present gpu that cannot be honoured is an InputError.
    Screen(GLFWwindow* window, vk::Context& marcher, const ViewCliOptions& o,
           const std::shared_ptr<vk::ValidationLog>& validation,
           const std::string& why_not_one_device);
    vk::Presenter& presenter() { return *presenter_; }
    FramePath path() const { return path_; }
    ImGuiBackend& overlay() { return *overlay_; }

  private:
    std::unique_ptr<vk::Presenter> presenter_;
    std::unique_ptr<ImGuiBackend> overlay_;
    FramePath path_ = FramePath::host;
};

// A frame's image on its way out: ray-marched into the swapchain image, into memory the
// presenter imports, or into host pixels (uploaded to the window, or written as PNG).
// Declared before the frame pipeline: the exported frame memory outlives the ray marcher's
// buffer over it.
class Frames {
  public:
    explicit Frames(vk::Context& marcher) : ctx_(marcher) {}
    // Sets the render options' size (framebuffer pixels; an empty one renders nothing) and
    // camera, and ray-marches the frame on `screen`'s path (headless without one: on the device
    // only, nothing read back unless host_image asks); one device:
    // it is recorded with the present and its time comes a frame or two later.
    void render(pipeline::FramePipeline& session, Screen* screen, vk::RenderOptions& r,
                const ViewCamera& camera, std::uint32_t fb_width, std::uint32_t fb_height);
    // Presents the last rendered frame with the overlay (nothing before the first).
    void present(pipeline::FramePipeline& session, Screen& screen, const vk::RenderOptions& r,
                 std::uint32_t fb_width, std::uint32_t fb_height);
    // The last frame's pixels on the host: where they never left the GPU, the same view is
    // ray-marched again (same field, same camera: the same image).
    const vk::Image& host_image(pipeline::FramePipeline& session, const Screen* screen,
                                const vk::RenderOptions& r);
    bool rendered() const { return rendered_; }
    double raymarch_ms() const { return raymarch_ms_; }  // -1: none yet

  private:
    vk::Context& ctx_;
    vk::ExternalMemory memory_;  // the imported path's frame
    vk::Image image_;
    // The options of the last headless frame while image_ does not hold it yet.
    std::optional<vk::RenderOptions> marched_;
    bool rendered_ = false;
    double raymarch_ms_ = -1;
};

}  // namespace voxfield::cli
