// vk::Presenter in a real window (GLFW on X11), with validation on (synchronisation included):
// on one presenting Context the ray-marched image reaches the swapchain unchanged, also with
// frames in flight while the field is replaced, rebound and the image resized between them;
// on a presenter's own device host frames and frames the ray marcher's device exports reach
// the swapchain unchanged, and every swapchain image has its own render-finished semaphore. Without
// a display the test runs itself again under xvfb-run (reported as skipped, with CTest's skip, only
// when xvfb-run is missing).
#include <gtest/gtest.h>
#include <sys/wait.h>

#define GLFW_INCLUDE_VULKAN
#include <GLFW/glfw3.h>

#include <algorithm>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <memory>
#include <set>
#include <sstream>
#include <stdexcept>
#include <string>
#include <vector>

#include "../xvfb_run.hpp"
#include "voxfield/core/scenes.hpp"
#include "voxfield/vk/present.hpp"
#include "voxfield/vk/raymarcher.hpp"
#include "voxfield/vk/shared.hpp"
#include "vulkan_env.hpp"

namespace voxfield::test {
namespace {

namespace fs = std::filesystem;

constexpr std::uint32_t kWidth = 160, kHeight = 120;

bool have_display() {
    const char* x = std::getenv("DISPLAY");
    return x != nullptr && *x != '\0';
}

// Runs the current test again in this executable under a fresh Xvfb server.
void rerun_under_xvfb() {
    if (std::system("command -v xvfb-run >/dev/null 2>&1") != 0) {
        GTEST_SKIP() << "no display and xvfb-run is not installed (setup.sh installs it)";
    }
    const auto* info = ::testing::UnitTest::GetInstance()->current_test_info();
    const fs::path self = fs::read_symlink("/proc/self/exe");
    const fs::path log = fs::temp_directory_path() /
                         ("voxfield_present_test_" + std::to_string(::getpid()) + ".log");
    const std::string cmd = xvfb_run("640x480x24") + " '" + self.string() + "' --gtest_filter='" +
                            info->test_suite_name() + "." + info->name() + "' >'" + log.string() +
                            "' 2>&1";
    const int status = std::system(cmd.c_str());
    std::stringstream out;
    out << std::ifstream(log).rdbuf();
    fs::remove(log);
    EXPECT_TRUE(WIFEXITED(status) && WEXITSTATUS(status) == 0) << out.str();
    EXPECT_NE(out.str().find("[  PASSED  ] 1 test"), std::string::npos) << out.str();
}

struct Window {
    GLFWwindow* handle = nullptr;
    ~Window() {
        if (handle != nullptr) {
            glfwDestroyWindow(handle);
        }
        glfwTerminate();
    }
};

vk::PresenterOptions presenter_options(GLFWwindow* window) {
    vk::PresenterOptions po;
    std::uint32_t n = 0;
    const char** exts = glfwGetRequiredInstanceExtensions(&n);
    for (std::uint32_t i = 0; i < n; ++i) {
        po.instance_extensions.emplace_back(exts[i]);
    }
    po.make_surface = [window](VkInstance instance) {
        VkSurfaceKHR surface = VK_NULL_HANDLE;
        vk::check(glfwCreateWindowSurface(instance, window, nullptr, &surface),
                  "glfwCreateWindowSurface");
        return surface;
    };
    po.device = std::to_string(validated_vulkan().info().index);
    po.validation = failing_validation_log();
    return po;
}

// A presenting context on the window (validation failing the test on any message).
std::unique_ptr<vk::Context> presenting_context(GLFWwindow* window) {
    vk::ContextOptions co;
    co.validation = failing_validation_log();
    const vk::PresenterOptions po = presenter_options(window);
    co.instance_extensions = po.instance_extensions;
    co.make_surface = po.make_surface;
    return std::make_unique<vk::Context>(co);
}

// A window of kWidth x kHeight framebuffer pixels (fails the test when there is none).
void open_window(Window& window) {
    ASSERT_EQ(glfwInit(), GLFW_TRUE);
    ASSERT_EQ(glfwVulkanSupported(), GLFW_TRUE);
    glfwWindowHint(GLFW_CLIENT_API, GLFW_NO_API);
    glfwWindowHint(GLFW_RESIZABLE, GLFW_FALSE);
    window.handle = glfwCreateWindow(kWidth, kHeight, "voxfield present test", nullptr, nullptr);
    ASSERT_NE(window.handle, nullptr);
    int fw = 0, fh = 0;
    glfwGetFramebufferSize(window.handle, &fw, &fh);
    ASSERT_EQ(fw, static_cast<int>(kWidth));
    ASSERT_EQ(fh, static_cast<int>(kHeight));
}

// The compact field of `world` with every empty voxel at distance 1 (exact enough for the
// marcher: it only steps by one).
std::vector<std::uint16_t> compact_field(const World& world) {
    std::vector<std::uint16_t> compact(world.size());
    for (std::size_t i = 0; i < compact.size(); ++i) {
        compact[i] =
            static_cast<std::uint16_t>(world.voxels()[i] == 0 ? 1u << 8 : world.voxels()[i]);
    }
    return compact;
}

// The pixels two RGBA8 images of kWidth x kHeight differ in (RGB only).
std::size_t differing(const std::vector<std::uint8_t>& a, const std::vector<std::uint8_t>& b) {
    std::size_t n = 0;
    for (std::size_t i = 0; i + 3 < a.size() && i + 3 < b.size(); i += 4) {
        n += (a[i] != b[i] || a[i + 1] != b[i + 1] || a[i + 2] != b[i + 2]) ? 1 : 0;
    }
    return n + (a.size() != b.size() ? 1 : 0);
}

// Opens the test's window. False when the test body must not run here: it was run again under
// Xvfb (no display), skipped (no xvfb-run), or the window failed to open (a fatal failure).
bool open_test_window(Window& window) {
    if (!have_display()) {
        rerun_under_xvfb();
        return false;
    }
    open_window(window);
    return !::testing::Test::HasFatalFailure();
}

TEST(Presenter, PresentsHostAndImportedFramesWithASemaphorePerImage) {
    Window window;
    if (!open_test_window(window)) {
        return;
    }
    vk::Presenter presenter(presenter_options(window.handle));
    EXPECT_FALSE(presenter.shares_context());

    // Host frames: a gradient, several frames per swapchain image.
    std::vector<std::uint8_t> rgba(std::size_t{kWidth} * kHeight * 4);
    for (std::uint32_t y = 0; y < kHeight; ++y) {
        for (std::uint32_t x = 0; x < kWidth; ++x) {
            std::uint8_t* p = &rgba[(std::size_t{y} * kWidth + x) * 4];
            p[0] = static_cast<std::uint8_t>(x);
            p[1] = static_cast<std::uint8_t>(y * 2);
            p[2] = static_cast<std::uint8_t>(255 - x);
            p[3] = 255;
        }
    }
    for (int i = 0; i < 12; ++i) {
        glfwPollEvents();
        if (i == 11) {
            presenter.capture_next_frame();
        }
        ASSERT_TRUE(presenter.present(rgba.data(), kWidth, kHeight, kWidth, kHeight, {}));
    }
    const std::vector<VkSemaphore> done = presenter.render_finished_semaphores();
    EXPECT_GE(done.size(), 2u);
    EXPECT_EQ(done.size(), presenter.image_count());
    EXPECT_EQ(std::set<VkSemaphore>(done.begin(), done.end()).size(), done.size())
        << "swapchain images share a render-finished semaphore";
    EXPECT_EQ(std::set<VkSemaphore>(done.begin(), done.end()).count(VK_NULL_HANDLE), 0u);
    const auto shown = presenter.captured_frame();
    ASSERT_TRUE(shown.has_value()) << "the swapchain cannot be copied from";
    EXPECT_EQ(differing(shown->rgba, rgba), 0u);

    // Frames the ray marcher renders into memory its device exports (the viewer's --present
    // gpu path), imported by the presenter's device.
    vk::Context& ctx = validated_vulkan();
    if (!presenter.can_import_frames(ctx.info().uuid) ||
        !vk::supports(ctx, vk::SharingPath::opaque_fd)) {
        GTEST_SKIP() << ctx.info().name << " cannot export frames to the presenter";
    }
    const World world = make_scene("spheres", Dims{24, 24, 24}, 7);
    vk::Raymarcher marcher(ctx);
    marcher.upload_compact(world.dims(), Palette::dissertation(), compact_field(world));
    vk::RenderOptions r;
    r.width = kWidth;
    r.height = kHeight;
    r.camera = vk::default_camera(world.dims());
    r.shading = vk::Shading::lit;
    r.sky_gradient = true;
    const vk::Image want = marcher.render(r);
    vk::ExternalMemory frame = vk::ExternalMemory::exportable(
        ctx, VkDeviceSize{kWidth} * kHeight * 4, VK_BUFFER_USAGE_TRANSFER_DST_BIT, "frame");
    presenter.import_frame(frame.export_fd(), frame.size(), frame.memory_type());
    r.bgra = presenter.bgra();
    for (int i = 0; i < 6; ++i) {
        glfwPollEvents();
        presenter.wait_frame();  // the frame in flight reads `frame`
        marcher.render_to(r, frame);
        if (i == 5) {
            presenter.capture_next_frame();
        }
        ASSERT_TRUE(presenter.present_imported(kWidth, kHeight, kWidth, kHeight, {}));
    }
    const auto imported = presenter.captured_frame();
    ASSERT_TRUE(imported.has_value());
    EXPECT_EQ(differing(imported->rgba, want.rgba), 0u);
    presenter.wait_idle();
}

vk::RenderOptions lit_view(const World& world) {
    vk::RenderOptions r;
    r.width = kWidth;
    r.height = kHeight;
    r.camera = vk::default_camera(world.dims());
    r.shading = vk::Shading::lit;
    r.sky_gradient = true;
    return r;
}

TEST(Presenter, OneDeviceShowsExactlyTheRayMarchedImage) {
    Window window;
    if (!open_test_window(window)) {
        return;
    }
    const std::unique_ptr<vk::Context> ctx = presenting_context(window.handle);
    ASSERT_TRUE(ctx->presents());
    EXPECT_TRUE(ctx->enabled(VK_KHR_SWAPCHAIN_EXTENSION_NAME));
    vk::Presenter presenter(*ctx);
    EXPECT_TRUE(presenter.shares_context());
    EXPECT_EQ(presenter.instance(), ctx->instance());
    EXPECT_EQ(presenter.device(), ctx->device());
    EXPECT_EQ(presenter.queue(), ctx->queue());
    EXPECT_EQ(presenter.frames_in_flight(), 2u);
    EXPECT_FALSE(presenter.can_import_frames(ctx->info().uuid)) << "one device imports nothing";

    const World world = make_scene("spheres", Dims{24, 24, 24}, 7);
    vk::Raymarcher marcher(*ctx);
    marcher.upload_compact(world.dims(), Palette::dissertation(), compact_field(world));
    const vk::RenderOptions r = lit_view(world);
    const vk::Image want = marcher.render(r);
    for (int i = 0; i < 8; ++i) {
        glfwPollEvents();
        if (i == 7) {
            presenter.capture_next_frame();
        }
        ASSERT_TRUE(presenter.present_marched(marcher, r, kWidth, kHeight, {}));
    }
    const auto shown = presenter.captured_frame();
    ASSERT_TRUE(shown.has_value()) << "the swapchain cannot be copied from";
    EXPECT_EQ(differing(shown->rgba, want.rgba), 0u);
    presenter.wait_idle();
    if (ctx->info().timestamps) {
        EXPECT_GE(marcher.finished_raymarch_ms(), 0.0);
    }
}

TEST(Presenter, FramesInFlightSurviveFieldChangesRebindingAndResizes) {
    Window window;
    if (!open_test_window(window)) {
        return;
    }
    const std::unique_ptr<vk::Context> ctx = presenting_context(window.handle);
    // Worlds large enough that a frame is usually still running when the next one is recorded
    // (RaymarchFrames.ReplacedResourcesAreRetiredUntilTheFrameFinished forces it).
    const World a = make_scene("spheres", Dims{64, 64, 64}, 7);
    const World b = make_scene("terrain", Dims{64, 64, 64}, 3);
    // Path 1 where the device exports memory the host can write: the field in place, acquired
    // from and released to VK_QUEUE_FAMILY_EXTERNAL by every frame (declared before the
    // marcher, which reads it until it is gone).
    vk::ExternalMemory shared;
    vk::FieldLayout shared_layout;
    vk::Raymarcher marcher(*ctx);
    if (vk::supports(*ctx, vk::SharingPath::opaque_fd)) {
        shared_layout = marcher.plan(b.dims(), vk::FieldFormat::compact);
        shared = vk::ExternalMemory::exportable(*ctx, shared_layout.total_bytes,
                                                VK_BUFFER_USAGE_STORAGE_BUFFER_BIT, "field");
        const auto flags = ctx->memory_properties().memoryTypes[shared.memory_type()].propertyFlags;
        if ((flags & VK_MEMORY_PROPERTY_HOST_VISIBLE_BIT) != 0) {
            void* map = nullptr;
            ASSERT_EQ(vkMapMemory(ctx->device(), shared.memory(), 0, VK_WHOLE_SIZE, 0, &map),
                      VK_SUCCESS);
            const std::vector<std::uint16_t> field = compact_field(b);
            ASSERT_EQ(shared_layout.slabs, 1u);
            std::memcpy(map, field.data(), field.size() * 2);
            vkUnmapMemory(ctx->device(), shared.memory());
        } else {
            shared = vk::ExternalMemory();
        }
    }
    vk::Presenter presenter(*ctx);
    vk::RenderOptions r = lit_view(a);
    vk::SharingPath last_path = vk::SharingPath::copy;
    const World* last = &a;
    for (int i = 0; i < 30; ++i) {
        glfwPollEvents();
        // A new field every other frame (new buffers; the old ones may still be read by the
        // frame in flight), bound in place from shared memory in frames 12..17, and the image
        // smaller than the window (a new offscreen target) in frames 20..24.
        if (i % 2 == 0) {
            last = (i / 2) % 2 == 0 ? &a : &b;
            if (i >= 12 && i < 18 && shared.memory() != VK_NULL_HANDLE) {
                marcher.bind_shared(shared, shared_layout, Palette::dissertation());
                last = &b;
            } else {
                marcher.upload_compact(last->dims(), Palette::dissertation(), compact_field(*last));
            }
            last_path = marcher.sharing();
        }
        r.width = i >= 20 && i < 25 ? kWidth - 40 : kWidth;
        r.height = i >= 20 && i < 25 ? kHeight - 30 : kHeight;
        if (i == 29) {
            presenter.capture_next_frame();
        }
        ASSERT_TRUE(presenter.present_marched(marcher, r, kWidth, kHeight, {}));
    }
    const auto shown = presenter.captured_frame();
    ASSERT_TRUE(shown.has_value());
    EXPECT_EQ(last_path, vk::SharingPath::copy);
    const vk::Image want = marcher.render(r);
    EXPECT_EQ(differing(shown->rgba, want.rgba), 0u);
    // The shared field renders as the uploaded one (what path 1's frames showed).
    if (shared.memory() != VK_NULL_HANDLE) {
        marcher.upload_compact(b.dims(), Palette::dissertation(), compact_field(b));
        const vk::Image uploaded = marcher.render(r);
        marcher.bind_shared(shared, shared_layout, Palette::dissertation());
        EXPECT_EQ(marcher.sharing(), vk::SharingPath::opaque_fd);
        EXPECT_EQ(differing(marcher.render(r).rgba, uploaded.rgba), 0u);
    }
    presenter.wait_idle();
    EXPECT_EQ(ctx->retired_in_flight(), 0u);
}

// A frame that fails after its image was acquired (a ray march that throws while recording, a
// failed submission) returns the image and consumes the acquire's semaphore before the error
// propagates: the frames after it acquire into that slot's semaphore and wait on its fence
// with no validation message and no hang, and show the ray-marched image.
TEST(Presenter, AFrameThatFailsAfterItsAcquireLeavesTheSlotUsable) {
    Window window;
    if (!open_test_window(window)) {
        return;
    }
    const std::unique_ptr<vk::Context> ctx = presenting_context(window.handle);
    vk::Presenter presenter(*ctx);
    const World world = make_scene("spheres", Dims{24, 24, 24}, 7);
    vk::Raymarcher marcher(*ctx);
    const vk::RenderOptions r = lit_view(world);
    // No field yet: record() throws std::logic_error after the acquire.
    EXPECT_THROW(presenter.present_marched(marcher, r, kWidth, kHeight, {}), std::logic_error);
    marcher.upload_compact(world.dims(), Palette::dissertation(), compact_field(world));
    const vk::Image want = marcher.render(r);
    for (int i = 0; i < 5; ++i) {
        glfwPollEvents();
        ASSERT_TRUE(presenter.present_marched(marcher, r, kWidth, kHeight, {}));
    }
    // A throwing overlay, then a failed submission, each in turn on both slots.
    for (int i = 0; i < 2; ++i) {
        const auto throwing = [](VkCommandBuffer) { throw std::runtime_error("overlay failed"); };
        EXPECT_THROW(presenter.present_marched(marcher, r, kWidth, kHeight, throwing),
                     std::runtime_error);
        ASSERT_TRUE(presenter.present_marched(marcher, r, kWidth, kHeight, {}));
        ctx->fail_next_submit(VK_ERROR_OUT_OF_DEVICE_MEMORY);
        EXPECT_THROW(presenter.present_marched(marcher, r, kWidth, kHeight, {}), vk::VkError);
    }
    for (int i = 0; i < 5; ++i) {
        glfwPollEvents();
        if (i == 4) {
            presenter.capture_next_frame();
        }
        ASSERT_TRUE(presenter.present_marched(marcher, r, kWidth, kHeight, {}));
    }
    const auto shown = presenter.captured_frame();
    ASSERT_TRUE(shown.has_value());
    EXPECT_EQ(differing(shown->rgba, want.rgba), 0u);
    presenter.wait_idle();
}

// A resize replaces the swapchain without a device wait, keeping the old swapchain and its
// render-finished semaphores (which a queued present may still wait on) until the image of the
// new swapchain's first present came back and that frame finished.
TEST(Presenter, AReplacedSwapchainLivesUntilThePresentationEngineIsDone) {
    Window window;
    if (!open_test_window(window)) {
        return;
    }
    const std::unique_ptr<vk::Context> ctx = presenting_context(window.handle);
    vk::Presenter presenter(*ctx);
    const World world = make_scene("spheres", Dims{24, 24, 24}, 7);
    vk::Raymarcher marcher(*ctx);
    marcher.upload_compact(world.dims(), Palette::dissertation(), compact_field(world));
    vk::RenderOptions r = lit_view(world);
    for (int i = 0; i < 4; ++i) {
        glfwPollEvents();
        ASSERT_TRUE(presenter.present_marched(marcher, r, kWidth, kHeight, {}));
    }
    EXPECT_EQ(presenter.retired_swapchains(), 0u);
    const std::vector<VkSemaphore> before = presenter.render_finished_semaphores();
    glfwSetWindowSize(window.handle, kWidth + 40, kHeight + 30);
    int fw = 0, fh = 0;
    for (int i = 0; i < 200 && (fw != int(kWidth) + 40 || fh != int(kHeight) + 30); ++i) {
        glfwWaitEventsTimeout(0.01);
        glfwGetFramebufferSize(window.handle, &fw, &fh);
    }
    ASSERT_EQ(fw, int(kWidth) + 40) << "the window was not resized";
    r.width = static_cast<std::uint32_t>(fw);
    r.height = static_cast<std::uint32_t>(fh);
    ASSERT_TRUE(presenter.present_marched(marcher, r, r.width, r.height, {}));
    EXPECT_EQ(presenter.retired_swapchains(), 1u) << "the old swapchain went with no proof";
    const std::vector<VkSemaphore> after = presenter.render_finished_semaphores();
    for (const VkSemaphore s : before) {
        EXPECT_EQ(std::count(after.begin(), after.end(), s), 0) << "an old semaphore was reused";
    }
    for (int i = 0; i < 3 * static_cast<int>(presenter.image_count()) + 4 &&
                    presenter.retired_swapchains() != 0;
         ++i) {
        glfwPollEvents();
        if (i == 0) {
            presenter.capture_next_frame();
        }
        ASSERT_TRUE(presenter.present_marched(marcher, r, r.width, r.height, {}));
    }
    EXPECT_EQ(presenter.retired_swapchains(), 0u) << "the old swapchain was never freed";
    const auto shown = presenter.captured_frame();
    ASSERT_TRUE(shown.has_value());
    EXPECT_EQ(differing(shown->rgba, marcher.render(r).rgba), 0u);
    presenter.wait_idle();
}

// One device selection for every Vulkan device: a presenter with a device of its own takes
// $VOXFIELD_VK_DEVICE as the ray marcher's Context does.
TEST(Presenter, ItsOwnDeviceHonoursVoxfieldVkDevice) {
    Window window;
    if (!open_test_window(window)) {
        return;
    }
    vk::PresenterOptions po = presenter_options(window.handle);
    po.device = "";
    ::setenv("VOXFIELD_VK_DEVICE", "99", 1);
    EXPECT_THROW(vk::Presenter{po}, vk::DeviceSelectionError);
    const std::string index = std::to_string(validated_vulkan().info().index);
    ::setenv("VOXFIELD_VK_DEVICE", index.c_str(), 1);
    {
        vk::Presenter presenter(po);
        EXPECT_EQ(presenter.device_name(), validated_vulkan().info().name);
    }
    ::unsetenv("VOXFIELD_VK_DEVICE");
}

}  // namespace
}  // namespace voxfield::test
