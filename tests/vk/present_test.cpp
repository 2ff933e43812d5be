// vk::Presenter in a real window (GLFW on X11), with validation on (synchronisation included):
// host frames and frames the ray marcher's device exports reach the swapchain unchanged, and
// every swapchain image has its own render-finished semaphore. Without a display the test runs
// itself again under xvfb-run (reported as skipped, with CTest's skip, only when xvfb-run is
// missing).
#include <gtest/gtest.h>
#include <sys/wait.h>

#define GLFW_INCLUDE_VULKAN
#include <GLFW/glfw3.h>

#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <set>
#include <sstream>
#include <string>
#include <vector>

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
    const std::string cmd = "xvfb-run -a -s '-screen 0 640x480x24' '" + self.string() +
                            "' --gtest_filter='" + info->test_suite_name() + "." + info->name() +
                            "' >'" + log.string() + "' 2>&1";
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

// The pixels two RGBA8 images of kWidth x kHeight differ in (RGB only).
std::size_t differing(const std::vector<std::uint8_t>& a, const std::vector<std::uint8_t>& b) {
    std::size_t n = 0;
    for (std::size_t i = 0; i + 3 < a.size() && i + 3 < b.size(); i += 4) {
        n += (a[i] != b[i] || a[i + 1] != b[i + 1] || a[i + 2] != b[i + 2]) ? 1 : 0;
    }
    return n + (a.size() != b.size() ? 1 : 0);
}

TEST(Presenter, PresentsHostAndImportedFramesWithASemaphorePerImage) {
    if (!have_display()) {
        rerun_under_xvfb();
        return;
    }
    Window window;
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
    vk::Presenter presenter(presenter_options(window.handle));

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
    {
        std::vector<std::uint16_t> compact(world.size());
        for (std::size_t i = 0; i < compact.size(); ++i) {
            compact[i] =
                static_cast<std::uint16_t>(world.voxels()[i] == 0 ? 1u << 8 : world.voxels()[i]);
        }
        marcher.upload_compact(world.dims(), Palette::dissertation(), compact);
    }
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

}  // namespace
}  // namespace voxfield::test
