// `voxfield view`: the interactive viewer (issue 6). A GLFW window with a Vulkan swapchain
// shows the world ray-marched through its distance field; edits go through the incremental
// updater every frame; Dear ImGui draws the overlay. Without a display it says so in one line
// and exits 2 (suggesting `voxfield render`), except in benchmark mode, which then runs
// headless (same loop, no window).
#include <vulkan/vulkan.h>

#define GLFW_INCLUDE_VULKAN
#include <GLFW/glfw3.h>
#include <imgui.h>
#include <imgui/backends/imgui_impl_glfw.h>
#include <imgui/backends/imgui_impl_vulkan.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <ctime>
#include <deque>
#include <filesystem>
#include <iostream>
#include <memory>
#include <optional>
#include <sstream>
#include <string>
#include <vector>

#include "cli_util.hpp"
#include "png.hpp"
#include "view_benchmark.hpp"
#include "view_options.hpp"
#include "view_script.hpp"
#include "voxfield/cl/generator.hpp"
#include "voxfield/cl/incremental.hpp"
#include "voxfield/cl/sand.hpp"
#include "voxfield/core/camera.hpp"
#include "voxfield/core/edits.hpp"
#include "voxfield/core/error.hpp"
#include "voxfield/core/npy.hpp"
#include "voxfield/core/pick.hpp"
#include "voxfield/core/sand.hpp"
#include "voxfield/core/scenes.hpp"
#include "voxfield/core/stats.hpp"
#include "voxfield/core/undo.hpp"
#include "voxfield/core/vox.hpp"
#include "voxfield/pipeline/frame_pipeline.hpp"
#include "voxfield/vk/present.hpp"
#include "voxfield/vk/raymarcher.hpp"

namespace voxfield::cli {
namespace {

using Clock = std::chrono::steady_clock;

double ms_since(Clock::time_point t) {
    return std::chrono::duration<double, std::milli>(Clock::now() - t).count();
}

std::string timestamp() {
    const std::time_t t = std::time(nullptr);
    std::tm tm{};
    localtime_r(&t, &tm);
    char buf[32];
    std::strftime(buf, sizeof buf, "%Y%m%d-%H%M%S", &tm);
    return buf;
}

bool display_present() {
    const char* x = std::getenv("DISPLAY");
    const char* w = std::getenv("WAYLAND_DISPLAY");
    return (x != nullptr && *x != '\0') || (w != nullptr && *w != '\0');
}

int no_display(const std::string& why) {
    std::cerr << "voxfield view: no display (" << why
              << "); render headless instead: voxfield render WORLD -o OUT.png\n";
    return 2;
}

// How frames reach the window: ray-marched into the swapchain image on the one device that
// presents, exported by the ray marcher's device and imported by the presenter's, or read back
// and uploaded.
enum class FramePath { one_device, imported, host };

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

bool has_focus(ocl::Algorithm a) {
    return a == ocl::Algorithm::lod || a == ocl::Algorithm::monolithic;
}

// The overlay's algorithm combo lists algorithm_names() (DESIGN §4 order, which is not the
// enum's): entries and algorithms are matched by name, never by the enum's value.
// The position of `name` in a combo's entries (entries.size() when it is not one).
int entry_of(const std::vector<std::string>& entries, const std::string& name) {
    return static_cast<int>(std::find(entries.begin(), entries.end(), name) - entries.begin());
}

int algorithm_entry(ocl::Algorithm a) {
    return entry_of(ocl::algorithm_names(), ocl::to_string(a));
}

int metric_entry(Metric m) {
    return entry_of(metric_names(), to_string(m));
}

ocl::Algorithm entry_algorithm(int entry) {
    return ocl::parse_algorithm(ocl::algorithm_names().at(static_cast<std::size_t>(entry)));
}

// The failures an algorithm or scene switch survives (the session keeps its field): refused
// options and device errors. Anything else ends the viewer.
bool switch_failure(const std::exception& e) {
    return dynamic_cast<const InputError*>(&e) != nullptr ||
           dynamic_cast<const ocl::ClError*>(&e) != nullptr ||
           dynamic_cast<const ocl::BuildError*>(&e) != nullptr ||
           dynamic_cast<const vk::VkError*>(&e) != nullptr;
}

// The sharing path in a few words (the compact overlay; the full panel has the whole story).
const char* sharing_summary(vk::SharingPath path) {
    switch (path) {
        case vk::SharingPath::opaque_fd:
            return "path 1 (opaque fd, no copy)";
        case vk::SharingPath::host_pointer:
            return "path 2 (host memory, no copy)";
        case vk::SharingPath::copy:
            break;
    }
    return "path 3 (copy)";
}

// The brush's target drawn over the image: a cube's box as 12 edges, a sphere as the circle
// of its projected radius (place: green, erase: red, paint: the brush's colour).
void draw_brush_preview(ImDrawList* draw, const Brush& b, const ViewCamera& camera,
                        std::uint32_t fb_w, std::uint32_t fb_h, ImVec2 display,
                        const Palette& palette) {
    const Vec3d eye = camera.position(), forward = camera.forward();
    const double fov = camera.settings.fov_deg;
    // Framebuffer pixels -> overlay units (they differ on HiDPI displays).
    const double sx = display.x / static_cast<double>(fb_w);
    const double sy = display.y / static_cast<double>(fb_h);
    const auto project = [&](const Vec3d& p) -> std::optional<ImVec2> {
        const auto ip = project_point(eye, forward, fov, fb_w, fb_h, p);
        if (!ip) {
            return std::nullopt;
        }
        return ImVec2(static_cast<float>(ip->x * sx), static_cast<float>(ip->y * sy));
    };
    ImU32 colour = IM_COL32(80, 255, 120, 230);
    if (b.op == BrushOp::erase) {
        colour = IM_COL32(255, 80, 80, 230);
    } else if (b.op == BrushOp::paint) {
        const Rgba c = palette[b.material];
        colour = IM_COL32(c.r, c.g, c.b, 255);
    }
    const double r = static_cast<double>(b.radius);
    const Vec3d c{static_cast<double>(b.centre.x) + 0.5, static_cast<double>(b.centre.y) + 0.5,
                  static_cast<double>(b.centre.z) + 0.5};
    if (b.shape == BrushShape::sphere) {
        const auto centre = project(c);
        const Vec3d right = view_basis(forward).right;
        const auto edge = project({c[0] + (r + 0.5) * right[0], c[1] + (r + 0.5) * right[1],
                                   c[2] + (r + 0.5) * right[2]});
        if (centre && edge) {
            const float radius = std::hypot(edge->x - centre->x, edge->y - centre->y);
            draw->AddCircle(*centre, std::max(radius, 2.0f), colour, 0, 2);
        }
        return;
    }
    const double lo[3] = {c[0] - r - 0.5, c[1] - r - 0.5, c[2] - r - 0.5};
    const double hi[3] = {c[0] + r + 0.5, c[1] + r + 0.5, c[2] + r + 0.5};
    std::optional<ImVec2> corner[8];
    for (int i = 0; i < 8; ++i) {
        corner[i] =
            project({(i & 1) ? hi[0] : lo[0], (i & 2) ? hi[1] : lo[1], (i & 4) ? hi[2] : lo[2]});
    }
    for (int i = 0; i < 8; ++i) {
        for (const int bit : {1, 2, 4}) {
            const int j = i | bit;
            if (j != i && corner[i] && corner[j]) {
                draw->AddLine(*corner[i], *corner[j], colour, 2);
            }
        }
    }
}

// Edge detection for keys polled once per frame.
class Keys {
  public:
    // script: held keys from `view --script` (nullptr: the keyboard alone).
    Keys(GLFWwindow* w, const ViewScript* script) : w_(w), script_(script) {}
    bool down(int key) const {
        return glfwGetKey(w_, key) == GLFW_PRESS || (script_ != nullptr && script_->key_down(key));
    }
    bool pressed(int key) {
        const bool now = down(key);
        bool& was = state_[key & 511];
        const bool edge = now && !was;
        was = now;
        return edge;
    }

  private:
    GLFWwindow* w_;
    const ViewScript* script_;
    bool state_[512] = {};
};

struct Window {
    GLFWwindow* handle = nullptr;
    ~Window() {
        if (handle != nullptr) {
            glfwDestroyWindow(handle);
        }
        glfwTerminate();
    }
};

// validation: non-null with --validate, for every Vulkan instance of the viewer.
int run_view(ViewCliOptions o, const std::shared_ptr<vk::ValidationLog>& validation) {
    ViewInputs inputs = check_view_options(o);
    const std::vector<Edit>& scripted = inputs.edits;
    std::optional<ViewScript>& script = inputs.script;
    // A window, or why there is none: then --benchmark runs headless, --fallback-png renders
    // one frame headless into that file, anything else exits 2.
    Window window;
    std::string why_no_window;
    if (!display_present()) {
        why_no_window = "neither $DISPLAY nor $WAYLAND_DISPLAY is set";
    } else {
        glfwInitHint(GLFW_JOYSTICK_HAT_BUTTONS, GLFW_FALSE);
        const char* desc = nullptr;
        if (glfwInit() != GLFW_TRUE) {
            glfwGetError(&desc);
            why_no_window =
                std::string("cannot open it: ") + (desc != nullptr ? desc : "glfwInit failed");
        } else if (glfwVulkanSupported() != GLFW_TRUE) {
            why_no_window = "GLFW finds no Vulkan loader able to present to it";
        } else {
            glfwWindowHint(GLFW_CLIENT_API, GLFW_NO_API);
            glfwWindowHint(GLFW_RESIZABLE, GLFW_TRUE);
            glfwWindowHint(GLFW_SCALE_TO_MONITOR, GLFW_TRUE);
            window.handle = glfwCreateWindow(static_cast<int>(o.width), static_cast<int>(o.height),
                                             "voxfield", nullptr, nullptr);
            if (window.handle == nullptr) {
                glfwGetError(&desc);
                why_no_window = std::string("cannot create a window: ") +
                                (desc != nullptr ? desc : "unknown GLFW error");
            }
        }
    }
    const bool windowed = window.handle != nullptr;
    if (!windowed) {
        if (o.benchmark) {
            std::cout << "view: no display (" << why_no_window << "), benchmark runs headless at "
                      << o.width << "x" << o.height << '\n';
        } else if (!o.fallback_png.empty() && !script) {
            std::cout << "view: no display (" << why_no_window
                      << "), rendering one frame headless to " << o.fallback_png << '\n';
            o.frames = 1;
            o.screenshot = o.fallback_png;
        } else {
            return no_display(why_no_window);
        }
    }

    // The world.
    VoxModel model{World(Dims{1, 1, 1}), Palette::dissertation()};
    std::string world_name;
    if (!o.input.empty()) {
        model = load_world(o.input);
        world_name = o.input;
    } else {
        const Dims dims = !o.dims.empty() ? parse_dims(o.dims)
                                          : Dims{o.world ? o.world : 128, o.world ? o.world : 128,
                                                 o.world ? o.world : 128};
        model.world = make_scene(o.scene, dims, o.scene_seed);
        world_name = "scene " + o.scene;
    }
    const Dims dims = model.world.dims();
    ocl::GeneratorOptions gopts = generator_options(o.gen, parse_format(o.format), dims);

    ocl::Context cl_ctx(ocl::select_device(o.device));
    // The ray marcher's device also presents the window where it can (one device, one queue);
    // else a presenter of its own does.
    std::unique_ptr<vk::Context> vk_owned;
    std::string why_not_one_device;
    if (windowed) {
        try {
            vk::ContextOptions co;
            co.device = std::to_string(vk::select_device("").index);
            co.validation = validation;
            window_surface(window.handle, co.instance_extensions, co.make_surface);
            vk_owned = std::make_unique<vk::Context>(co);
        } catch (const vk::DeviceSelectionError& e) {
            why_not_one_device = e.what();
        }
    }
    if (!vk_owned) {
        vk_owned = std::make_unique<vk::Context>(vk::ContextOptions{"", validation});
    }
    vk::Context& vk_ctx = *vk_owned;
    // Frames for the presenter's device, exported by the ray marcher's (declared before the
    // session: it outlives the ray marcher's buffer over it).
    vk::ExternalMemory frame_memory;
    pipeline::FramePipeline session(cl_ctx, vk_ctx, model.palette, dims);
    const Framing framing = solid_framing(model.world);  // the default camera's view
    const double build_ms = session.rebuild(std::move(model.world), gopts);
    std::cout << "opencl:  " << cl_ctx.info().name << " (" << cl_ctx.info().type << ")\n"
              << "vulkan:  " << vk_ctx.info().name << " (" << vk_ctx.info().type << ")\n"
              << "world:   " << world_name << " " << dims.to_string() << ", algorithm "
              << ocl::to_string(session.options().algorithm)
              << (session.options().chunk ? ", chunk " + std::to_string(session.options().chunk)
                                          : std::string(", global"))
              << ", field " << to_string(session.options().format) << " built in "
              << fixed(build_ms, 1) << " ms\n"
              << "sharing: " << session.marcher().sharing_path()
              << (session.why_not().empty() ? std::string() : " [" + session.why_not() + "]")
              << '\n';

    // Window, swapchain, overlay.
    std::unique_ptr<vk::Presenter> presenter;
    // One device where it presents; else frames go from the ray marcher's device to the
    // presenter's on the GPU (shared memory) when it can import them; else through the host.
    FramePath frame_path = FramePath::host;
    VkDescriptorPool imgui_pool = VK_NULL_HANDLE;
    bool imgui_ready = false;
    if (windowed) {
        vk::PresenterOptions po;
        if (o.benchmark) {
            po.modes = {vk::PresentMode::immediate, vk::PresentMode::mailbox,
                        vk::PresentMode::fifo};
        }
        if (vk_ctx.presents()) {
            presenter = std::make_unique<vk::Presenter>(vk_ctx, po.modes);
        } else {
            window_surface(window.handle, po.instance_extensions, po.make_surface);
            po.validation = validation;
            presenter = std::make_unique<vk::Presenter>(po);
        }
    }
    struct ImGuiGuard {
        bool* ready;
        vk::Presenter* p;
        VkDescriptorPool* pool;
        ~ImGuiGuard() {
            if (*ready) {
                p->wait_idle();
                ImGui_ImplVulkan_Shutdown();
                ImGui_ImplGlfw_Shutdown();
                ImGui::DestroyContext();
            }
            if (*pool != VK_NULL_HANDLE) {
                vkDestroyDescriptorPool(p->device(), *pool, nullptr);
            }
        }
    };
    std::optional<ImGuiGuard> imgui_guard;
    if (presenter) {
        imgui_guard.emplace(ImGuiGuard{&imgui_ready, presenter.get(), &imgui_pool});
        VkDescriptorPoolSize sizes[] = {{VK_DESCRIPTOR_TYPE_COMBINED_IMAGE_SAMPLER, 16}};
        VkDescriptorPoolCreateInfo dp{};
        dp.sType = VK_STRUCTURE_TYPE_DESCRIPTOR_POOL_CREATE_INFO;
        dp.flags = VK_DESCRIPTOR_POOL_CREATE_FREE_DESCRIPTOR_SET_BIT;
        dp.maxSets = 16;
        dp.poolSizeCount = 1;
        dp.pPoolSizes = sizes;
        vk::check(vkCreateDescriptorPool(presenter->device(), &dp, nullptr, &imgui_pool),
                  "vkCreateDescriptorPool", "overlay");
        ImGui::CreateContext();
        ImGui::GetIO().IniFilename = nullptr;
        ImGui::StyleColorsDark();
        ImGui_ImplGlfw_InitForVulkan(window.handle, true);
        ImGui_ImplVulkan_InitInfo ii{};
        ii.Instance = presenter->instance();
        ii.PhysicalDevice = presenter->physical();
        ii.Device = presenter->device();
        ii.QueueFamily = presenter->queue_family();
        ii.Queue = presenter->queue();
        ii.DescriptorPool = imgui_pool;
        ii.MinImageCount = 2;
        ii.ImageCount = 3;
        ii.MSAASamples = VK_SAMPLE_COUNT_1_BIT;
        ImGui_ImplVulkan_Init(&ii, presenter->render_pass());
        imgui_ready = true;
        presenter->submit_and_wait(
            [](VkCommandBuffer cmd) { ImGui_ImplVulkan_CreateFontsTexture(cmd); });
        ImGui_ImplVulkan_DestroyFontUploadObjects();
        glfwSetInputMode(window.handle, GLFW_CURSOR, GLFW_CURSOR_DISABLED);
        const bool import_possible = presenter->can_import_frames(vk_ctx.info().uuid) &&
                                     vk::supports(vk_ctx, vk::SharingPath::opaque_fd);
        if (o.present == "gpu" && !presenter->shares_context() && !import_possible) {
            throw InputError("--present gpu: the ray marcher's " + vk_ctx.info().name +
                             " cannot present (" + why_not_one_device +
                             ") and the presenting device " + presenter->device_name() +
                             " cannot import its frames (needs VK_KHR_external_memory_fd on "
                             "both and the same GPU)");
        }
        if (o.present != "host") {
            frame_path = presenter->shares_context() ? FramePath::one_device
                         : import_possible           ? FramePath::imported
                                                     : FramePath::host;
        }
        std::cout << "window:  " << presenter->device_name() << ", present mode "
                  << vk::to_string(vk::PresentMode::fifo) << " requested"
                  << (o.benchmark ? " (benchmark: immediate/mailbox preferred)" : "") << ", "
                  << present_path(frame_path) << "; F1 lists the keys\n";
    }

    // State of the interactive session.
    ViewCamera camera(dims, framing, double(o.width) / double(std::max(o.height, 1u)));
    vk::RenderOptions ropts;
    ropts.shading = o.shading == "flat" ? vk::Shading::flat : vk::Shading::lit;
    ropts.sky_gradient = ropts.shading == vk::Shading::lit;
    ropts.sky = Rgba{0, 0, 0, 255};
    BrushSettings brush;
    brush.size = 5;
    brush.material = 4;
    bool paint_mode = false, show_help = false, stroke_open = false;
    UndoStack undo;
    std::optional<Brush> last_stroke_brush;
    std::optional<BenchmarkEdits> bench;  // --benchmark: the protocol's edits
    if (o.benchmark) {
        bench.emplace(dims, gopts.chunk, o.seed, o.interval_ms);
    }
    std::vector<FrameRecord> records;
    std::deque<float> hist_frame, hist_update, hist_march;
    // --simulate: the automaton on the device, rebuilt from the session's world whenever
    // something else changed it (an edit, an undo, a new scene or algorithm).
    std::unique_ptr<ocl::SandSimulator> sim;
    bool sim_stale = true, sim_paused = false, sim_single = false;
    std::uint64_t sim_step = 0;
    double last_sim_ms = 0;
    std::size_t last_sim_changed = 0;
    pipeline::UpdateTimings last_update;
    std::optional<Brush> preview;
    bool focus_follows = false;
    int algorithm_index = algorithm_entry(session.options().algorithm);
    bool full_panel = false;   // F2: the full panel instead of the compact overlay
    std::string switch_error;  // why the last algorithm / scene switch failed
    int scene_index = 0;
    const std::vector<std::string> scenes = scene_names();
    for (std::size_t i = 0; i < scenes.size(); ++i) {
        if (scenes[i] == o.scene) {
            scene_index = static_cast<int>(i);
        }
    }
    int chunk_log2 = 4;
    // lod / monolithic: the focus the user gave (--focus) or the default, until changed.
    int focus_size = 1;
    Int3 focus_centre{0, 0, 0};
    if (const auto& f = session.options().focus) {
        focus_size = static_cast<int>(std::min<std::int64_t>(f->size, 8));
        focus_centre = f->centre;
    }
    Keys keys(window.handle, script ? &*script : nullptr);
    int metric_index = metric_entry(session.options().metric);
    // Ctrl+S and the script's `save`: the world as STEM.npy and STEM.vox.
    const auto save_world = [&session](const std::string& stem) {
        const NpyArray a = npy_from_world(session.world());
        write_npy(stem + ".npy", a.type, a.dims, a.data);
        std::cout << "saved " << stem << ".npy\n";
        try {
            write_vox(stem + ".vox", session.world(), session.palette());
            std::cout << "saved " << stem << ".vox\n";
        } catch (const InputError& e) {
            std::cout << "not saved as .vox: " << e.what() << '\n';
        }
    };
    double cursor_x = 0, cursor_y = 0;
    if (window.handle != nullptr) {
        glfwGetCursorPos(window.handle, &cursor_x, &cursor_y);
    }

    const auto start = Clock::now();
    auto last = start;
    std::uint64_t frame = 0;
    vk::Image image;
    double raymarch_ms = -1;
    bool rendered = false;
    // The last frame's pixels on the host: with GPU presenting they never left the GPU, so
    // the same view is ray-marched again (same field, same camera: the same image).
    const auto host_image = [&]() -> const vk::Image& {
        if (frame_path != FramePath::host && rendered) {
            vk::RenderOptions r = ropts;
            r.bgra = false;
            session.render(r, image);
        }
        return image;
    };
    bool running = true;
    int exit_code = 0;
    while (running) {
        const auto t0 = Clock::now();
        // Scripted frames advance by a fixed step: the same views on any machine.
        const double dt = script ? 1.0 / 60 : std::chrono::duration<double>(t0 - last).count();
        last = t0;
        const double time_s = std::chrono::duration<double>(t0 - start).count();
        std::vector<Brush> batch;
        bool stroke_batch = false;
        std::optional<VoxelChanges> undo_changes;

        std::uint32_t fb_w = o.width, fb_h = o.height;
        // --script: this frame's actions (keys, buttons, cursor and scroll are held in
        // `script`; the overlay's selections switch below, checks are written at the end).
        const std::vector<ScriptAction> actions =
            script ? script->begin_frame(frame) : std::vector<ScriptAction>{};
        bool script_regen = false, script_new_scene = false;
        for (const ScriptAction& a : actions) {
            if (a.kind != ScriptAction::Kind::select) {
                continue;
            }
            if (a.what == "algorithm") {
                algorithm_index = algorithm_entry(ocl::parse_algorithm(a.value));
                script_regen = true;
            } else if (a.what == "metric") {
                metric_index = metric_entry(parse_metric(a.value));
                script_regen = true;
            } else if (a.what == "scene") {
                scene_index = entry_of(scenes, a.value);
                script_new_scene = true;
            } else if (a.what == "shading") {
                ropts.shading = a.value == "lit" ? vk::Shading::lit : vk::Shading::flat;
                ropts.sky_gradient = ropts.shading == vk::Shading::lit;
            } else if (a.what == "colour") {
                brush.material = static_cast<std::uint8_t>(std::stoi(a.value));
            }
        }
        if (window.handle != nullptr) {
            glfwPollEvents();
            if (glfwWindowShouldClose(window.handle) != 0) {
                break;
            }
            int w = 0, h = 0;
            glfwGetFramebufferSize(window.handle, &w, &h);
            fb_w = static_cast<std::uint32_t>(std::max(w, 0));
            fb_h = static_cast<std::uint32_t>(std::max(h, 0));
            int ww = 0, wh = 0;
            glfwGetWindowSize(window.handle, &ww, &wh);
            const ImGuiIO& io = ImGui::GetIO();
            const bool ui_mode = keys.down(GLFW_KEY_LEFT_ALT);
            // The overlay takes the mouse only while the cursor is free (Left Alt); captured,
            // the crosshair picks even where the full panel lies under it.
            const bool overlay_has_mouse = ui_mode && io.WantCaptureMouse;
            const int cursor_mode = ui_mode ? GLFW_CURSOR_NORMAL : GLFW_CURSOR_DISABLED;
            // Capturing or freeing the cursor warps it: that jump is not a mouse movement.
            bool skip_look = frame == 0;
            if (glfwGetInputMode(window.handle, GLFW_CURSOR) != cursor_mode) {
                glfwSetInputMode(window.handle, GLFW_CURSOR, cursor_mode);
                skip_look = true;
            }
            double cx = 0, cy = 0;
            glfwGetCursorPos(window.handle, &cx, &cy);
            if (script && script->has_cursor()) {
                cx = script->cursor_x();
                cy = script->cursor_y();
            }
            if (skip_look) {
                cursor_x = cx;
                cursor_y = cy;
            }
            CameraInput in;
            const bool ctrl = keys.down(GLFW_KEY_LEFT_CONTROL) || keys.down(GLFW_KEY_RIGHT_CONTROL);
            if (!io.WantCaptureKeyboard) {
                in.forward = keys.down(GLFW_KEY_W) || keys.down(GLFW_KEY_UP);
                in.back = (keys.down(GLFW_KEY_S) && !ctrl) || keys.down(GLFW_KEY_DOWN);
                in.left = keys.down(GLFW_KEY_A) || keys.down(GLFW_KEY_LEFT);
                in.right = keys.down(GLFW_KEY_D) || keys.down(GLFW_KEY_RIGHT);
                in.up = keys.down(GLFW_KEY_SPACE);
                in.down = keys.down(GLFW_KEY_LEFT_SHIFT);
                in.fast = keys.down(GLFW_KEY_LEFT_CONTROL);
            }
            if (!ui_mode) {
                in.look_dx = cx - cursor_x;
                in.look_dy = cy - cursor_y;
            }
            cursor_x = cx;
            cursor_y = cy;
            camera.update(in, dt);

            if (keys.pressed(GLFW_KEY_ESCAPE)) {
                running = false;
            }
            if (keys.pressed(GLFW_KEY_F1)) {
                show_help = !show_help;
            }
            if (keys.pressed(GLFW_KEY_F2)) {
                full_panel = !full_panel;
            }
            if (keys.pressed(GLFW_KEY_TAB)) {
                camera.toggle_mode();
            }
            if (keys.pressed(GLFW_KEY_R) && !ctrl) {
                camera.reset();
            }
            if (keys.pressed(GLFW_KEY_P)) {
                paint_mode = !paint_mode;
            }
            if (keys.pressed(GLFW_KEY_G)) {
                sim_paused = !sim_paused;
            }
            if (keys.pressed(GLFW_KEY_N)) {
                sim_single = true;
            }
            if (keys.pressed(GLFW_KEY_B)) {
                brush.shape =
                    brush.shape == BrushShape::sphere ? BrushShape::cube : BrushShape::sphere;
            }
            for (int k = 0; k <= 9; ++k) {
                if (keys.pressed(GLFW_KEY_0 + k)) {
                    brush.material = static_cast<std::uint8_t>(k == 0 ? 10 : k);
                }
            }
            const double wheel =
                (overlay_has_mouse ? 0.0 : io.MouseWheel) + (script ? script->scroll() : 0.0);
            if (wheel != 0) {
                brush.size = scroll_brush_size(brush.size, wheel, kMaxBrushSize);
            }
            const bool z = keys.pressed(GLFW_KEY_Z), y = keys.pressed(GLFW_KEY_Y);
            const bool s = keys.pressed(GLFW_KEY_S), f12 = keys.pressed(GLFW_KEY_F12);
            if (ctrl && z) {
                undo_changes = undo.undo();
            } else if (ctrl && y) {
                undo_changes = undo.redo();
            }
            if (ctrl && s) {
                save_world("voxfield-world-" + timestamp());
            }
            if (f12 && rendered) {
                const std::string path = "voxfield-" + timestamp() + ".png";
                write_png(path, host_image());
                std::cout << "screenshot " << std::filesystem::absolute(path).string() << '\n';
            }

            // Editing: the pick ray through the crosshair (cursor captured) or the cursor;
            // the brush it would apply is previewed every frame.
            const auto button = [&](int b) {
                return glfwGetMouseButton(window.handle, b) == GLFW_PRESS ||
                       (script && script->button_down(b));
            };
            const bool lmb = button(GLFW_MOUSE_BUTTON_LEFT);
            const bool rmb = button(GLFW_MOUSE_BUTTON_RIGHT);
            preview.reset();
            if (!overlay_has_mouse && fb_w > 0 && fb_h > 0) {
                double px = fb_w / 2.0, py = fb_h / 2.0;
                if (ui_mode && ww > 0 && wh > 0) {
                    px = cx * fb_w / ww;
                    py = cy * fb_h / wh;
                }
                const Vec3d dir =
                    pixel_direction(camera.forward(), camera.settings.fov_deg, fb_w, fb_h, px, py);
                if (const auto hit = pick_voxel(session.world(), camera.position(), dir)) {
                    const Tool tool = rmb ? Tool::erase : (paint_mode ? Tool::paint : Tool::place);
                    preview = brush_for_pick(tool, brush, *hit);
                }
            }
            if ((lmb || rmb) && preview) {
                if (preview != last_stroke_brush) {
                    if (!stroke_open) {
                        undo.begin_stroke();
                        stroke_open = true;
                    }
                    batch.push_back(*preview);
                    stroke_batch = true;
                    last_stroke_brush = preview;
                }
            } else if (!lmb && !rmb && stroke_open) {
                undo.end_stroke();
                stroke_open = false;
                last_stroke_brush.reset();
            }
        }

        // Scripted and benchmark edits.
        if (frame < scripted.size()) {
            batch.push_back(scripted[frame].brush);
        }
        bool bench_edit = false;
        if (const auto edit = bench ? bench->due(time_s) : std::nullopt) {
            batch.push_back(*edit);
            bench_edit = true;
        }
        // Lod / monolithic: the focus is the centre chunk or, following the camera, the
        // camera's chunk; a changed focus recomputes the chunks that entered or left it.
        pipeline::UpdateTimings update;
        const auto add = [&update](const pipeline::UpdateTimings& u) {
            update.field_ms += u.field_ms;
            update.convert_ms += u.convert_ms;
        };
        if (has_focus(session.options().algorithm)) {
            const std::uint32_t chunk = session.options().chunk;
            const Int3 centre =
                focus_follows ? chunk_at(camera.position(), dims, chunk) : focus_centre;
            const Focus f{centre, focus_size};
            const auto& current = session.options().focus;
            if (!current || current->centre != f.centre || current->size != f.size) {
                add(session.set_focus(f));
            }
        }
        if (undo_changes && !undo_changes->empty()) {
            try {
                add(session.apply_changes(*undo_changes));
            } catch (const InputError& e) {
                // Voxels of the stroke were changed by edits the stack did not record.
                std::cout << "cannot undo/redo: " << e.what() << "; undo history cleared\n";
                undo.clear();
            }
        }
        if (!batch.empty()) {
            std::vector<EditResult> edits;
            const pipeline::UpdateTimings u = session.apply(batch, &edits);
            add(u);
            if (bench_edit && !edits.empty()) {
                // The protocol's edit is the batch's last brush; the batch's update is its cost.
                bench->record(batch.back(), u, edits.back());
            }
            if (stroke_batch && !edits.empty()) {
                // Only the stroke's brush (the first of the batch) is undoable.
                undo.record(edits.front());
            }
        }
        if (!batch.empty() || (undo_changes && !undo_changes->empty())) {
            sim_stale = true;
        }
        // One step of falling sand and water, its changes through the incremental update.
        double simulate_ms = -1;
        std::size_t sim_changed = 0;
        if (o.simulate && (!sim_paused || sim_single)) {
            sim_single = false;
            if (sim_stale || !sim) {
                sim = std::make_unique<ocl::SandSimulator>(cl_ctx, session.world(), SandRules{});
                sim_stale = false;
            }
            const ocl::SandStepResult r = sim->step(o.seed, sim_step++);
            simulate_ms = r.simulate_ms;
            sim_changed = r.changes.size();
            if (!r.changes.empty()) {
                add(session.apply_changes(r.changes));
            }
            last_sim_ms = simulate_ms;
            last_sim_changed = sim_changed;
        }
        const double update_ms = update.field_ms + update.convert_ms;
        if (update_ms > 0) {
            last_update = update;
        }

        // Render at the framebuffer's size (HiDPI: pixels, not window units).
        if (fb_w > 0 && fb_h > 0) {
            ropts.width = std::min(fb_w, vk::kMaxImageSize);
            ropts.height = std::min(fb_h, vk::kMaxImageSize);
            ropts.camera.position = camera.position();
            ropts.camera.target = camera.target();
            ropts.camera.fov_deg = camera.settings.fov_deg;
            if (frame_path == FramePath::one_device) {
                // Recorded with the frame (present_marched); its GPU time comes a frame or two
                // later.
                raymarch_ms = session.marcher().finished_raymarch_ms();
            } else if (frame_path == FramePath::imported) {
                ropts.bgra = presenter->bgra();
                presenter->wait_frame();  // the frame in flight reads frame_memory
                const VkDeviceSize bytes = VkDeviceSize{ropts.width} * ropts.height * 4;
                if (frame_memory.size() < bytes) {
                    frame_memory = vk::ExternalMemory::exportable(
                        vk_ctx, bytes, VK_BUFFER_USAGE_TRANSFER_DST_BIT, "frame");
                    presenter->import_frame(frame_memory.export_fd(), frame_memory.size(),
                                            frame_memory.memory_type());
                }
                raymarch_ms = session.render_to(ropts, frame_memory);
            } else {
                session.render(ropts, image);
                raymarch_ms = image.raymarch_ms;
            }
            rendered = true;
        }

        if (presenter) {
            ImGui_ImplVulkan_NewFrame();
            ImGui_ImplGlfw_NewFrame();
            ImGui::NewFrame();
            const ImGuiIO& io = ImGui::GetIO();
            // Crosshair.
            ImDrawList* fg = ImGui::GetForegroundDrawList();
            const ImVec2 c(io.DisplaySize.x / 2, io.DisplaySize.y / 2);
            fg->AddLine(ImVec2(c.x - 8, c.y), ImVec2(c.x + 9, c.y), IM_COL32(255, 255, 255, 220),
                        2);
            fg->AddLine(ImVec2(c.x, c.y - 8), ImVec2(c.x, c.y + 9), IM_COL32(255, 255, 255, 220),
                        2);

            if (preview && fb_w > 0 && fb_h > 0) {
                draw_brush_preview(fg, *preview, camera, fb_w, fb_h, io.DisplaySize,
                                   session.palette());
            }

            const auto push = [](std::deque<float>& h, double v) {
                h.push_back(static_cast<float>(v));
                if (h.size() > 120) {
                    h.pop_front();
                }
            };
            const double frame_ms = records.empty() ? 0 : records.back().frame_ms;
            push(hist_frame, frame_ms);
            push(hist_update, last_update.field_ms + last_update.convert_ms);
            push(hist_march, raymarch_ms);
            const ImVec4 red(1.0f, 0.45f, 0.4f, 1.0f);
            bool regen = script_regen, new_scene = script_new_scene;
            if (!full_panel) {
                // The compact overlay: one small box that takes no input.
                ImGui::SetNextWindowPos(ImVec2(8, 8), ImGuiCond_Always);
                ImGui::SetNextWindowBgAlpha(0.5f);
                ImGui::Begin("##compact", nullptr,
                             ImGuiWindowFlags_NoDecoration | ImGuiWindowFlags_AlwaysAutoResize |
                                 ImGuiWindowFlags_NoInputs | ImGuiWindowFlags_NoSavedSettings |
                                 ImGuiWindowFlags_NoFocusOnAppearing | ImGuiWindowFlags_NoNav);
                ImGui::Text("%.1f FPS  frame %.2f  update %.3f  march %.3f ms",
                            frame_ms > 0 ? 1000.0 / frame_ms : 0.0, frame_ms,
                            last_update.field_ms + last_update.convert_ms, raymarch_ms);
                if (o.simulate) {
                    ImGui::Text("sand: step %llu%s, simulate %.3f ms, %zu voxels moved",
                                static_cast<unsigned long long>(sim_step),
                                sim_paused ? " (paused: G runs, N steps)" : "", last_sim_ms,
                                last_sim_changed);
                }
                ImGui::Text("%s + %s", vk_ctx.info().name.c_str(), cl_ctx.info().name.c_str());
                ImGui::Text("%s, %s; F1 keys, F2 panel", sharing_summary(session.sharing()),
                            ocl::to_string(session.options().algorithm).c_str());
                if (!switch_error.empty()) {
                    ImGui::PushTextWrapPos(ImGui::GetFontSize() * 32);
                    ImGui::TextColored(red, "cannot switch: %s", switch_error.c_str());
                    ImGui::PopTextWrapPos();
                }
                ImGui::End();
            } else {
                ImGui::SetNextWindowPos(ImVec2(8, 8), ImGuiCond_FirstUseEver);
                ImGui::Begin("voxfield (F2: compact)");
                if (!switch_error.empty()) {
                    ImGui::PushTextWrapPos(ImGui::GetFontSize() * 40);
                    ImGui::TextColored(red, "cannot switch: %s", switch_error.c_str());
                    ImGui::PopTextWrapPos();
                }
                const std::vector<float> hf(hist_frame.begin(), hist_frame.end());
                const std::vector<float> hu(hist_update.begin(), hist_update.end());
                const std::vector<float> hm(hist_march.begin(), hist_march.end());
                ImGui::Text("%.1f FPS, frame %.2f ms", frame_ms > 0 ? 1000.0 / frame_ms : 0.0,
                            frame_ms);
                ImGui::PlotLines("frame ms", hf.data(), static_cast<int>(hf.size()));
                ImGui::Text("field update %.3f ms + render field %.3f ms (device)",
                            last_update.field_ms, last_update.convert_ms);
                ImGui::PlotLines("update ms", hu.data(), static_cast<int>(hu.size()));
                ImGui::Text("ray march %.3f ms (GPU timestamps)", raymarch_ms);
                ImGui::PlotLines("march ms", hm.data(), static_cast<int>(hm.size()));
                const World& w = session.world();
                ImGui::Text("world %s, %zu solid of %zu voxels", w.dims().to_string().c_str(),
                            w.solid_count(), w.size());
                ImGui::Text(
                    "memory/voxel: render 2 B (compact), OpenCL field %zu B (%s) + world 1 B",
                    element_size(session.options().format),
                    to_string(session.options().format).c_str());
                ImGui::Text("OpenCL: %s", cl_ctx.info().name.c_str());
                ImGui::Text("Vulkan: %s / present %s (%s)", vk_ctx.info().name.c_str(),
                            presenter->device_name().c_str(),
                            vk::to_string(presenter->mode()).c_str());
                ImGui::Text("frames: %s", present_path(frame_path));
                ImGui::Text("sharing: %s", session.marcher().sharing_path().c_str());
                if (!session.why_not().empty() && ImGui::IsItemHovered()) {
                    ImGui::SetTooltip("%s", session.why_not().c_str());
                }
                ImGui::Separator();
                const auto& names = ocl::algorithm_names();
                std::vector<const char*> cnames;
                for (const auto& n : names) {
                    cnames.push_back(n.c_str());
                }
                if (ImGui::Combo("algorithm", &algorithm_index, cnames.data(),
                                 static_cast<int>(cnames.size()))) {
                    regen = true;
                }
                std::vector<const char*> mnames;
                for (const auto& n : metric_names()) {
                    mnames.push_back(n.c_str());
                }
                if (ImGui::Combo("metric", &metric_index, mnames.data(),
                                 static_cast<int>(mnames.size()))) {
                    regen = true;
                }
                ImGui::SliderInt("chunk 2^k", &chunk_log2, 3, 7);
                if (has_focus(session.options().algorithm)) {
                    ImGui::SliderInt("focus size", &focus_size, 0, 8);
                    ImGui::Checkbox("focus follows camera", &focus_follows);
                    if (const auto& f = session.options().focus) {
                        ImGui::Text("focus: chunk (%lld, %lld, %lld), size %lld",
                                    static_cast<long long>(f->centre.x),
                                    static_cast<long long>(f->centre.y),
                                    static_cast<long long>(f->centre.z),
                                    static_cast<long long>(f->size));
                    }
                }
                std::vector<const char*> snames;
                for (const auto& n : scenes) {
                    snames.push_back(n.c_str());
                }
                ImGui::Combo("scene", &scene_index, snames.data(), static_cast<int>(snames.size()));
                new_scene = ImGui::Button("regenerate");
                ImGui::SameLine();
                regen = ImGui::Button("apply algorithm") || regen;
                int shading = ropts.shading == vk::Shading::lit ? 1 : 0;
                const char* shadings[] = {"flat", "lit"};
                if (ImGui::Combo("shading", &shading, shadings, 2)) {
                    ropts.shading = shading == 1 ? vk::Shading::lit : vk::Shading::flat;
                    ropts.sky_gradient = shading == 1;
                }
                ImGui::Text("brush: %s %s, size %lld, colour %d  (%s)",
                            paint_mode ? "paint" : "place", to_string(brush.shape).c_str(),
                            static_cast<long long>(brush.size), brush.material,
                            camera.mode() == ViewCamera::Mode::orbit ? "orbit" : "fly");
                ImGui::Text("undo %zu, redo %zu. F1: keys", undo.undo_count(), undo.redo_count());
                if (ImGui::CollapsingHeader("palette")) {
                    const Palette& pal = session.palette();
                    for (int m = 1; m < 256; ++m) {
                        const Rgba rgb = pal[static_cast<std::uint8_t>(m)];
                        ImGui::PushID(m);
                        if (ImGui::ColorButton(
                                "##colour",
                                ImVec4(rgb.r / 255.0f, rgb.g / 255.0f, rgb.b / 255.0f, 1),
                                ImGuiColorEditFlags_NoAlpha, ImVec2(14, 14))) {
                            brush.material = static_cast<std::uint8_t>(m);
                        }
                        if (m == brush.material) {
                            ImGui::GetWindowDrawList()->AddRect(
                                ImGui::GetItemRectMin(), ImGui::GetItemRectMax(),
                                IM_COL32(255, 255, 255, 255), 0, 0, 2);
                        }
                        ImGui::PopID();
                        if (m % 16 != 15) {
                            ImGui::SameLine(0, 2);
                        }
                    }
                    ImGui::NewLine();
                }
                ImGui::End();
            }
            if (show_help) {
                ImGui::SetNextWindowPos(ImVec2(io.DisplaySize.x / 2, io.DisplaySize.y / 2),
                                        ImGuiCond_Always, ImVec2(0.5f, 0.5f));
                ImGui::Begin("keys (F1)", &show_help, ImGuiWindowFlags_AlwaysAutoResize);
                for (const auto& k : kViewKeys) {
                    ImGui::Text("%-20s %s", k[0], k[1]);
                }
                ImGui::End();
            }
            ImGui::Render();
            if (regen || new_scene) {
                try {
                    // The dissertation's algorithms are updated per chunk (chunk-local);
                    // exact is global.
                    ocl::GeneratorOptions next = session.options();
                    next.algorithm = entry_algorithm(algorithm_index);
                    next.metric =
                        parse_metric(metric_names().at(static_cast<std::size_t>(metric_index)));
                    next.chunk = next.algorithm == ocl::Algorithm::exact ? 0 : 1u << chunk_log2;
                    next.focus.reset();
                    if (has_focus(next.algorithm)) {
                        // FIM in the chunks within `focus size` of the centre chunk.
                        require_chunk_fits(dims, next.chunk);
                        const Dims n = ChunkGrid(dims, next.chunk).chunks();
                        focus_centre = {n.x / 2, n.y / 2, n.z / 2};
                        next.focus = Focus{focus_centre, focus_size};
                    }
                    World world = new_scene
                                      ? make_scene(scenes[static_cast<std::size_t>(scene_index)],
                                                   dims, o.scene_seed)
                                      : World(session.world());
                    const double ms = session.rebuild(std::move(world), next);
                    sim_stale = true;
                    undo.clear();
                    switch_error.clear();
                    std::cout << "regenerated: " << ocl::to_string(next.algorithm)
                              << (next.chunk ? ", chunk " + std::to_string(next.chunk)
                                             : std::string(", global"))
                              << " in " << fixed(ms, 1) << " ms\n";
                } catch (const std::exception& e) {
                    // Refused options or a device failure (out of memory, a kernel that does
                    // not build): the session keeps its field, the overlay says why.
                    if (!switch_failure(e)) {
                        throw;
                    }
                    switch_error = e.what();
                    std::cout << "cannot switch: " << switch_error << '\n';
                }
                algorithm_index = algorithm_entry(session.options().algorithm);
                metric_index = metric_entry(session.options().metric);
            }
            const auto overlay = [](VkCommandBuffer cmd) {
                ImGui_ImplVulkan_RenderDrawData(ImGui::GetDrawData(), cmd);
            };
            if (!o.window_screenshot.empty() && frame + 1 >= o.frames) {
                presenter->capture_next_frame();
            }
            // Nothing is presented before the first frame was rendered (a zero-size window).
            if (rendered && frame_path == FramePath::one_device) {
                presenter->present_marched(session.marcher(), ropts, fb_w, fb_h, overlay);
            } else if (rendered && frame_path == FramePath::imported) {
                presenter->present_imported(ropts.width, ropts.height, fb_w, fb_h, overlay);
            } else if (rendered) {
                presenter->present(image.rgba.data(), image.width, image.height, fb_w, fb_h,
                                   overlay);
            }
        }

        FrameRecord rec;
        rec.time_s = time_s;
        rec.frame_ms = ms_since(t0);
        rec.update_ms = update_ms;
        rec.convert_ms = update.convert_ms;
        rec.raymarch_ms = raymarch_ms;
        rec.edit = bench_edit;
        rec.simulate_ms = simulate_ms;
        rec.sim_changed = sim_changed;
        records.push_back(rec);
        for (const ScriptAction& a : actions) {
            if (a.kind == ScriptAction::Kind::save) {
                save_world(a.value);
            } else if (a.kind == ScriptAction::Kind::check) {
                // What a scripted test checks after this frame: the world, the field and what
                // the overlay shows.
                const NpyArray w = npy_from_world(session.world());
                write_npy(a.value + "-world.npy", w.type, w.dims, w.data);
                write_npy(a.value + "-field.npy", npy_type(session.options().format), dims,
                          session.read_field());
                const Vec3d eye = camera.position();
                const nlohmann::json state = {
                    {"frame", frame},
                    {"algorithm",
                     ocl::algorithm_names().at(static_cast<std::size_t>(algorithm_index))},
                    {"field_algorithm", ocl::to_string(session.options().algorithm)},
                    {"metric", metric_names().at(static_cast<std::size_t>(metric_index))},
                    {"field_metric", to_string(session.options().metric)},
                    {"chunk", session.options().chunk},
                    {"panel", full_panel ? "full" : "compact"},
                    {"help", show_help},
                    {"switch_error", switch_error},
                    {"shading", ropts.shading == vk::Shading::lit ? "lit" : "flat"},
                    {"paint_mode", paint_mode},
                    {"brush",
                     {{"shape", to_string(brush.shape)},
                      {"size", brush.size},
                      {"material", brush.material}}},
                    {"undo", undo.undo_count()},
                    {"redo", undo.redo_count()},
                    {"solid_voxels", session.world().solid_count()},
                    {"camera",
                     {{"position", {eye[0], eye[1], eye[2]}},
                      {"mode", camera.mode() == ViewCamera::Mode::orbit ? "orbit" : "fly"}}},
                    {"simulate", {{"paused", sim_paused}, {"step", sim_step}}},
                    {"sharing", vk::describe(session.sharing())}};
                write_json_file(a.value + "-state.json", state);
                std::cout << "checked " << a.value << " (frame " << frame << ")\n";
            } else if (a.kind == ScriptAction::Kind::quit) {
                running = false;
            }
        }
        ++frame;
        if (o.frames != 0 && frame >= o.frames) {
            running = false;
        }
        if (o.benchmark && time_s >= o.duration_s) {
            running = false;
        }
    }
    if (stroke_open) {
        undo.end_stroke();
    }

    if (!o.screenshot.empty()) {
        if (!rendered) {
            throw std::runtime_error("no frame was rendered for --screenshot");
        }
        write_png(o.screenshot, host_image());
        std::cout << "screenshot " << o.screenshot << " (" << image.width << "x" << image.height
                  << ", frame " << frame << ")\n";
    }
    if (!o.window_screenshot.empty()) {
        const std::optional<vk::Image> shown =
            presenter ? presenter->captured_frame() : std::nullopt;
        if (!shown) {
            throw std::runtime_error(
                "--window-screenshot: no window frame was captured" +
                std::string(presenter ? " (the swapchain cannot be copied from: no TRANSFER_SRC "
                                        "usage)"
                                      : " (there is no window)"));
        }
        write_png(o.window_screenshot, *shown);
        std::cout << "window screenshot " << o.window_screenshot << " (" << shown->width << "x"
                  << shown->height << ", overlay included)\n";
    }
    if (!o.world_output.empty()) {
        const NpyArray a = npy_from_world(session.world());
        write_npy(o.world_output, a.type, a.dims, a.data);
    }
    if (!o.field_output.empty()) {
        write_npy(o.field_output, npy_type(session.options().format), dims, session.read_field());
    }
    std::cout << "frames:  " << frame << '\n';
    if (presenter) {
        // What the overlay showed last (scripted runs check it).
        std::cout << "overlay: algorithm "
                  << ocl::algorithm_names().at(static_cast<std::size_t>(algorithm_index)) << ", "
                  << (full_panel ? "full panel" : "compact") << '\n';
    }

    if (bench) {
        const BenchmarkSetup setup{world_name, cl_ctx.info(), vk_ctx.info().name,
                                   presenter ? std::optional(presenter->mode()) : std::nullopt};
        report_benchmark(o, setup, session, ropts, records, bench->log());
    }
    return exit_code;
}

}  // namespace

Command add_view(CLI::App& root) {
    auto o = std::make_shared<ViewCliOptions>();
    auto* app = root.add_subcommand(
        "view",
        "Interactive viewer: fly through the world, paint voxels, switch algorithms (needs a "
        "display; without one it exits 2 and suggests `render`, except with --benchmark, which "
        "then runs headless, or --fallback-png, which then renders the first frame into it)");
    add_view_options(*app, *o);
    return {app, [o] {
                std::shared_ptr<vk::ValidationLog> log;
                if (o->validate) {
                    log = std::make_shared<vk::ValidationLog>([](const std::string& m) {
                        std::cerr << "voxfield: Vulkan validation: " << m << '\n';
                    });
                }
                const int code = run_view(*o, log);  // every Vulkan object is gone afterwards
                if (log && log->count() > 0) {
                    std::cerr << "voxfield view: " << log->count()
                              << " Vulkan validation message(s) (--validate)\n";
                    return code == 0 ? 1 : code;
                }
                return code;
            }};
}

}  // namespace voxfield::cli
