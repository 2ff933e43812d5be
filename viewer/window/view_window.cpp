// `view`'s window and what shows frames in it (see view_window.hpp).
#include "view_window.hpp"

#include <imgui.h>
#include <imgui/backends/imgui_impl_glfw.h>
#include <imgui/backends/imgui_impl_vulkan.h>

#include <algorithm>
#include <cstdlib>
#include <functional>
#include <iostream>
#include <vector>

#include "voxfield/core/error.hpp"

namespace voxfield::cli {
namespace {

bool display_present() {
    const char* x = std::getenv("DISPLAY");
    const char* w = std::getenv("WAYLAND_DISPLAY");
    return (x != nullptr && *x != '\0') || (w != nullptr && *w != '\0');
}

// The window system's instance extensions and a maker of `window`'s Vulkan surface.
void window_surface(GLFWwindow* window, std::vector<std::string>& extensions,
                    std::function<VkSurfaceKHR(VkInstance)>& make_surface) {
    std::uint32_t n = 0;
    const char** exts = glfwGetRequiredInstanceExtensions(&n);
    for (std::uint32_t i = 0; i < n; ++i) {
        extensions.emplace_back(exts[i]);
    }
    make_surface = [window](VkInstance instance) {
        VkSurfaceKHR surface = VK_NULL_HANDLE;
        vk::check(glfwCreateWindowSurface(instance, window, nullptr, &surface),
                  "glfwCreateWindowSurface");
        return surface;
    };
}

}  // namespace

Window::Window(std::uint32_t width, std::uint32_t height) {
    if (!display_present()) {
        why_none_ = "neither $DISPLAY nor $WAYLAND_DISPLAY is set";
        return;
    }
    glfwInitHint(GLFW_JOYSTICK_HAT_BUTTONS, GLFW_FALSE);
    const char* desc = nullptr;
    if (glfwInit() != GLFW_TRUE) {
        glfwGetError(&desc);
        why_none_ = std::string("cannot open it: ") + (desc != nullptr ? desc : "glfwInit failed");
    } else if (glfwVulkanSupported() != GLFW_TRUE) {
        why_none_ = "GLFW finds no Vulkan loader able to present to it";
    } else {
        glfwWindowHint(GLFW_CLIENT_API, GLFW_NO_API);
        glfwWindowHint(GLFW_RESIZABLE, GLFW_TRUE);
        glfwWindowHint(GLFW_SCALE_TO_MONITOR, GLFW_TRUE);
        handle_ = glfwCreateWindow(static_cast<int>(width), static_cast<int>(height), "voxfield",
                                   nullptr, nullptr);
        if (handle_ == nullptr) {
            glfwGetError(&desc);
            why_none_ = std::string("cannot create a window: ") +
                        (desc != nullptr ? desc : "unknown GLFW error");
        }
    }
}

Window::~Window() {
    if (handle_ != nullptr) {
        glfwDestroyWindow(handle_);
    }
    glfwTerminate();
}

bool Window::poll() {
    glfwPollEvents();
    return glfwWindowShouldClose(handle_) == 0;
}

RawInput Window::input(const ViewScript* script, bool first_frame) {
    RawInput in;
    for (const int k : mapped_keys()) {
        if (glfwGetKey(handle_, k) == GLFW_PRESS) {
            in.keys.insert(k);
        }
    }
    in.left = glfwGetMouseButton(handle_, GLFW_MOUSE_BUTTON_LEFT) == GLFW_PRESS;
    in.right = glfwGetMouseButton(handle_, GLFW_MOUSE_BUTTON_RIGHT) == GLFW_PRESS;
    const ImGuiIO& io = ImGui::GetIO();
    in.wheel = io.MouseWheel;
    in.overlay_keyboard = io.WantCaptureKeyboard;
    in.overlay_mouse = io.WantCaptureMouse;
    int w = 0, h = 0;
    glfwGetFramebufferSize(handle_, &w, &h);
    in.fb_width = static_cast<std::uint32_t>(std::max(w, 0));
    in.fb_height = static_cast<std::uint32_t>(std::max(h, 0));
    glfwGetWindowSize(handle_, &in.window_width, &in.window_height);
    if (script != nullptr) {
        add_script_input(in, *script);
    }
    // Capturing or freeing the cursor warps it.
    const int cursor_mode =
        InputMapper::cursor_free(in) ? GLFW_CURSOR_NORMAL : GLFW_CURSOR_DISABLED;
    in.cursor_warped = first_frame;
    if (glfwGetInputMode(handle_, GLFW_CURSOR) != cursor_mode) {
        glfwSetInputMode(handle_, GLFW_CURSOR, cursor_mode);
        in.cursor_warped = true;
    }
    if (script == nullptr || !script->has_cursor()) {
        glfwGetCursorPos(handle_, &in.cursor_x, &in.cursor_y);
    }
    return in;
}

bool go_headless(ViewCliOptions& o, bool scripted, const std::string& why) {
    if (o.benchmark) {
        std::cout << "view: no display (" << why << "), benchmark runs headless at " << o.width
                  << "x" << o.height << '\n';
        return true;
    }
    if (!o.fallback_png.empty() && !scripted) {
        std::cout << "view: no display (" << why << "), rendering one frame headless to "
                  << o.fallback_png << '\n';
        o.frames = 1;
        o.screenshot = o.fallback_png;
        return true;
    }
    return false;
}

int no_display(const std::string& why) {
    std::cerr << "voxfield view: no display (" << why
              << "); render headless instead: voxfield render WORLD -o OUT.png\n";
    return 2;
}

std::unique_ptr<vk::Context> marcher_context(GLFWwindow* window,
                                             const std::shared_ptr<vk::ValidationLog>& validation,
                                             std::string& why_not_one_device) {
    if (window != nullptr) {
        try {
            vk::ContextOptions co;
            co.device = std::to_string(vk::select_device("").index);
            co.validation = validation;
            window_surface(window, co.instance_extensions, co.make_surface);
            return std::make_unique<vk::Context>(co);
        } catch (const vk::DeviceSelectionError& e) {
            why_not_one_device = e.what();
        }
    }
    return std::make_unique<vk::Context>(vk::ContextOptions{"", validation});
}

const char* present_path(FramePath path) {
    switch (path) {
        case FramePath::one_device:
            return "one device: frames stay on the GPU (ray-marched, then copied into the "
                   "swapchain image)";
        case FramePath::imported:
            return "two devices: frames stay on the GPU (exported by the ray marcher, imported "
                   "by the presenter)";
        case FramePath::host:
            break;
    }
    return "frames go through the host (read back, uploaded)";
}

ImGuiBackend::ImGuiBackend(GLFWwindow* window, vk::Presenter& presenter) : presenter_(presenter) {
    try {
        VkDescriptorPoolSize sizes[] = {{VK_DESCRIPTOR_TYPE_COMBINED_IMAGE_SAMPLER, 16}};
        VkDescriptorPoolCreateInfo dp{};
        dp.sType = VK_STRUCTURE_TYPE_DESCRIPTOR_POOL_CREATE_INFO;
        dp.flags = VK_DESCRIPTOR_POOL_CREATE_FREE_DESCRIPTOR_SET_BIT;
        dp.maxSets = 16;
        dp.poolSizeCount = 1;
        dp.pPoolSizes = sizes;
        vk::check(vkCreateDescriptorPool(presenter.device(), &dp, nullptr, &pool_),
                  "vkCreateDescriptorPool", "overlay");
        ImGui::CreateContext();
        ImGui::GetIO().IniFilename = nullptr;
        ImGui::StyleColorsDark();
        ImGui_ImplGlfw_InitForVulkan(window, true);
        ImGui_ImplVulkan_InitInfo ii{};
        ii.Instance = presenter.instance();
        ii.PhysicalDevice = presenter.physical();
        ii.Device = presenter.device();
        ii.QueueFamily = presenter.queue_family();
        ii.Queue = presenter.queue();
        ii.DescriptorPool = pool_;
        ii.MinImageCount = 2;
        ii.ImageCount = 3;
        ii.MSAASamples = VK_SAMPLE_COUNT_1_BIT;
        ImGui_ImplVulkan_Init(&ii, presenter.render_pass());
        ready_ = true;
        presenter.submit_and_wait(
            [](VkCommandBuffer cmd) { ImGui_ImplVulkan_CreateFontsTexture(cmd); });
        ImGui_ImplVulkan_DestroyFontUploadObjects();
    } catch (...) {
        release();
        throw;
    }
}

ImGuiBackend::~ImGuiBackend() {
    release();
}

void ImGuiBackend::release() {
    if (ready_) {
        presenter_.wait_idle();
        ImGui_ImplVulkan_Shutdown();
        ImGui_ImplGlfw_Shutdown();
        ImGui::DestroyContext();
        ready_ = false;
    }
    if (pool_ != VK_NULL_HANDLE) {
        vkDestroyDescriptorPool(presenter_.device(), pool_, nullptr);
        pool_ = VK_NULL_HANDLE;
    }
}

void ImGuiBackend::new_frame() {
    ImGui_ImplVulkan_NewFrame();
    ImGui_ImplGlfw_NewFrame();
    ImGui::NewFrame();
}

void ImGuiBackend::record(VkCommandBuffer cmd) {
    ImGui_ImplVulkan_RenderDrawData(ImGui::GetDrawData(), cmd);
}

Screen::Screen(GLFWwindow* window, vk::Context& marcher, const ViewCliOptions& o,
               const std::shared_ptr<vk::ValidationLog>& validation,
               const std::string& why_not_one_device) {
    vk::PresenterOptions po;
    if (o.benchmark) {
        po.modes = {vk::PresentMode::immediate, vk::PresentMode::mailbox, vk::PresentMode::fifo};
    }
    if (marcher.presents()) {
        presenter_ = std::make_unique<vk::Presenter>(marcher, po.modes);
    } else {
        window_surface(window, po.instance_extensions, po.make_surface);
        po.validation = validation;
        presenter_ = std::make_unique<vk::Presenter>(po);
    }
    overlay_ = std::make_unique<ImGuiBackend>(window, *presenter_);
    glfwSetInputMode(window, GLFW_CURSOR, GLFW_CURSOR_DISABLED);
    // One device where it presents; else frames go from the ray marcher's device to the
    // presenter's on the GPU (shared memory) when it can import them; else through the host.
    const bool import_possible = presenter_->can_import_frames(marcher.info().uuid) &&
                                 vk::supports(marcher, vk::SharingPath::opaque_fd);
    if (o.present == "gpu" && !presenter_->shares_context() && !import_possible) {
        throw InputError("--present gpu: the ray marcher's " + marcher.info().name +
                         " cannot present (" + why_not_one_device + ") and the presenting device " +
                         presenter_->device_name() +
                         " cannot import its frames (needs VK_KHR_external_memory_fd on "
                         "both and the same GPU)");
    }
    if (o.present != "host") {
        path_ = presenter_->shares_context() ? FramePath::one_device
                : import_possible            ? FramePath::imported
                                             : FramePath::host;
    }
    std::cout << "window:  " << presenter_->device_name() << ", present mode "
              << vk::to_string(vk::PresentMode::fifo) << " requested"
              << (o.benchmark ? " (benchmark: immediate/mailbox preferred)" : "") << ", "
              << present_path(path_) << "; F1 lists the keys\n";
}

void Frames::render(pipeline::FramePipeline& session, Screen* screen, vk::RenderOptions& r,
                    const ViewCamera& camera, std::uint32_t fb_width, std::uint32_t fb_height) {
    if (fb_width == 0 || fb_height == 0) {
        return;
    }
    // At the framebuffer's size (HiDPI: pixels, not window units).
    r.width = std::min(fb_width, vk::kMaxImageSize);
    r.height = std::min(fb_height, vk::kMaxImageSize);
    r.camera.position = camera.position();
    r.camera.target = camera.target();
    r.camera.fov_deg = camera.settings.fov_deg;
    const FramePath path = screen != nullptr ? screen->path() : FramePath::host;
    if (path == FramePath::one_device) {
        raymarch_ms_ = session.marcher().finished_raymarch_ms();
    } else if (path == FramePath::imported) {
        vk::Presenter& presenter = screen->presenter();
        r.bgra = presenter.bgra();
        presenter.wait_frame();  // the frame in flight reads the frame memory
        const VkDeviceSize bytes = VkDeviceSize{r.width} * r.height * 4;
        if (memory_.size() < bytes) {
            memory_ = vk::ExternalMemory::exportable(ctx_, bytes, VK_BUFFER_USAGE_TRANSFER_DST_BIT,
                                                     "frame");
            presenter.import_frame(memory_.export_fd(), memory_.size(), memory_.memory_type());
        }
        raymarch_ms_ = session.render_to(r, memory_);
    } else if (screen == nullptr) {
        raymarch_ms_ = session.march(r);  // headless: the frame stays on the device
        marched_ = r;
    } else {
        session.render(r, image_);
        raymarch_ms_ = image_.raymarch_ms;
    }
    rendered_ = true;
}

void Frames::present(pipeline::FramePipeline& session, Screen& screen, const vk::RenderOptions& r,
                     std::uint32_t fb_width, std::uint32_t fb_height) {
    if (!rendered_) {
        return;  // a zero-size window so far
    }
    vk::Presenter& presenter = screen.presenter();
    if (screen.path() == FramePath::one_device) {
        presenter.present_marched(session.marcher(), r, fb_width, fb_height, ImGuiBackend::record);
    } else if (screen.path() == FramePath::imported) {
        presenter.present_imported(r.width, r.height, fb_width, fb_height, ImGuiBackend::record);
    } else {
        presenter.present(image_.rgba.data(), image_.width, image_.height, fb_width, fb_height,
                          ImGuiBackend::record);
    }
}

const vk::Image& Frames::host_image(pipeline::FramePipeline& session, const Screen* screen,
                                    const vk::RenderOptions& r) {
    if (screen == nullptr && marched_) {
        session.render(*marched_, image_);  // the last headless frame, marched again
        marched_.reset();
    } else if (screen != nullptr && screen->path() != FramePath::host && rendered_) {
        vk::RenderOptions host = r;
        host.bgra = false;
        session.render(host, image_);
    }
    return image_;
}

}  // namespace voxfield::cli
