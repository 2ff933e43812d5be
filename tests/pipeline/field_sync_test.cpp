// How edits are ordered against the frames that read the render field (DESIGN §2
// "Synchronisation"): OpenCL <-> Vulkan semaphores on path 1 where both drivers have them
// (cl_khr_external_semaphore_opaque_fd, VK_KHR_external_semaphore_fd), else the CPU's wait for
// a frame's fence. Edit frames with frames in flight give the same pictures either way, the
// field equal to the CPU reference. PoCL + lavapipe have no such semaphores (path 2): the
// semaphore test skips there and says why; the NVIDIA drivers run it.
#include <gtest/gtest.h>

#include <fcntl.h>
#include <unistd.h>

#include <cstdlib>
#include <memory>
#include <optional>
#include <random>
#include <string>
#include <vector>

#include "../cl/cl_test_util.hpp"
#include "../scoped_env.hpp"
#include "../vk/vulkan_env.hpp"
#include "voxfield/cl/interop.hpp"
#include "voxfield/core/format.hpp"
#include "voxfield/core/reference.hpp"
#include "voxfield/core/scenes.hpp"
#include "voxfield/pipeline/frame_pipeline.hpp"
#include "voxfield/vk/shared.hpp"

namespace voxfield::test {
namespace {

constexpr Dims kDims{48, 32, 40};

// The OpenCL device `render` takes by default ($VOXFIELD_DEVICE, else the first GPU, ...):
// NVIDIA's where the lead runs this, PoCL here.
ocl::Context& default_opencl() {
    static std::unique_ptr<ocl::Context> ctx =
        std::make_unique<ocl::Context>(ocl::select_device(""));
    return *ctx;
}

std::unique_ptr<pipeline::FramePipeline> make_pipeline(ocl::Context& cl, bool semaphores) {
    std::optional<ScopedEnv> off;
    if (!semaphores) {
        off.emplace("VOXFIELD_NO_CL_SEMAPHORE", "1");
    }
    return std::make_unique<pipeline::FramePipeline>(cl, validated_vulkan(),
                                                     Palette::magicavoxel_default(), kDims);
}

ocl::GeneratorOptions exact() {
    ocl::GeneratorOptions g;
    g.format = Format::u16;
    g.metric = Metric::manhattan;
    return g;
}

vk::RenderOptions lit_view(const World& world) {
    vk::RenderOptions r;
    r.width = 96;
    r.height = 64;
    r.shading = vk::Shading::lit;  // shadows and occlusion read the field beyond the hits
    r.camera = vk::default_camera(world, r.width, r.height, r.camera.fov_deg);
    return r;
}

std::vector<std::uint8_t> picture(pipeline::FramePipeline& p, const vk::RenderOptions& r) {
    vk::Image image;
    p.render(r, image);
    return image.rgba;
}

// A batch of one to three brushes anywhere in the world.
std::vector<Brush> random_batch(std::mt19937_64& rng) {
    std::vector<Brush> batch(1 + rng() % 3);
    for (Brush& b : batch) {
        b.op = rng() % 3 == 0 ? BrushOp::erase : BrushOp::place;
        b.shape = rng() % 2 == 0 ? BrushShape::sphere : BrushShape::cube;
        b.centre = {static_cast<std::int64_t>(rng() % kDims.x),
                    static_cast<std::int64_t>(rng() % kDims.y),
                    static_cast<std::int64_t>(rng() % kDims.z)};
        b.radius = static_cast<std::int64_t>(rng() % 5);
        b.material = b.op == BrushOp::erase ? 0 : static_cast<std::uint8_t>(1 + rng() % 11);
    }
    return batch;
}

// `frames` edit frames on `pipelines` alike: two headless frames queued (unwaited, so that
// the edit meets frames in flight), then one batch; every fourth frame the pictures are
// compared. Returns the world the batches made on the CPU.
World edit_frames(const std::vector<pipeline::FramePipeline*>& pipelines, World world, int frames,
                  const vk::RenderOptions& r) {
    std::mt19937_64 rng(23);
    for (pipeline::FramePipeline* p : pipelines) {
        p->rebuild(World(world), exact());
    }
    for (int frame = 0; frame < frames; ++frame) {
        for (pipeline::FramePipeline* p : pipelines) {
            p->march(r);
            p->march(r);
        }
        const std::vector<Brush> batch = random_batch(rng);
        for (const Brush& b : batch) {
            apply_brush(world, b);
        }
        for (pipeline::FramePipeline* p : pipelines) {
            p->apply(batch);
        }
        if (frame % 4 == 3) {
            const std::vector<std::uint8_t> first = picture(*pipelines.front(), r);
            for (std::size_t i = 1; i < pipelines.size(); ++i) {
                EXPECT_EQ(picture(*pipelines[i], r), first) << "frame " << frame;
            }
        }
    }
    return world;
}

// The field of `p` equals the CPU reference of `world`, and its picture that of a pipeline
// built from `world` afresh (one whole conversion).
void expect_reference(ocl::Context& cl, pipeline::FramePipeline& p, const World& world,
                      const vk::RenderOptions& r) {
    EXPECT_TRUE(p.world().voxels() == world.voxels());
    const auto want = encode_field(reference_manhattan(world), world,
                                   Palette::magicavoxel_default(), Format::u16);
    EXPECT_EQ(first_difference(p.read_field(), want, Format::u16, world.dims()), "");
    pipeline::FramePipeline fresh(cl, validated_vulkan(), Palette::magicavoxel_default(), kDims);
    fresh.rebuild(World(world), exact());
    EXPECT_EQ(picture(p, r), picture(fresh, r));
}

TEST(FieldSync, NamesAndTheChoiceOnPoclAndLavapipe) {
    EXPECT_EQ(pipeline::to_string(pipeline::FieldSync::semaphore), "semaphore");
    EXPECT_EQ(pipeline::to_string(pipeline::FieldSync::fence), "fence");
    EXPECT_EQ(pipeline::to_string(pipeline::FieldSync::queue), "queue");
    // PoCL has no cl_khr_external_semaphore: path 2 waits for fences, path 3 is queue-ordered.
    EXPECT_FALSE(ocl::can_import_semaphore_fd(pocl()));
    std::string why;
    EXPECT_EQ(
        pipeline::choose_field_sync(pocl(), validated_vulkan(), vk::SharingPath::host_pointer, why),
        pipeline::FieldSync::fence);
    EXPECT_FALSE(why.empty());
    EXPECT_EQ(pipeline::choose_field_sync(pocl(), validated_vulkan(), vk::SharingPath::copy, why),
              pipeline::FieldSync::queue);
    EXPECT_EQ(
        pipeline::choose_field_sync(pocl(), validated_vulkan(), vk::SharingPath::opaque_fd, why),
        pipeline::FieldSync::fence);
    EXPECT_FALSE(why.empty());
    {
        ScopedEnv off("VOXFIELD_NO_CL_SEMAPHORE", "1");
        pipeline::choose_field_sync(pocl(), validated_vulkan(), vk::SharingPath::opaque_fd, why);
        EXPECT_EQ(why, "$VOXFIELD_NO_CL_SEMAPHORE is set");
    }
    pipeline::FramePipeline packed(pocl(), validated_vulkan(), Palette(), kDims,
                                   {vk::FieldFormat::packed32});
    EXPECT_EQ(packed.sync(), pipeline::FieldSync::queue);
}

TEST(FieldSync, AFailedSemaphoreImportClosesTheFd) {
    // cl_khr_external_semaphore: a successful import owns the fd; one that fails (here: PoCL
    // has no such import) leaves it ours, and ExternalSemaphore closes it, exactly once.
    int fds[2] = {-1, -1};
    ASSERT_EQ(pipe(fds), 0);
    ASSERT_FALSE(ocl::can_import_semaphore_fd(pocl()));
    EXPECT_THROW(ocl::ExternalSemaphore(pocl(), fds[0]), ocl::ClError);
    EXPECT_EQ(fcntl(fds[0], F_GETFD), -1);  // closed
    close(fds[1]);
}

// Signals then waits, twice, in Context's semaphore batches, with work around them.
void alternate(vk::Context& vk, VkSemaphore s) {
    for (int i = 0; i < 2; ++i) {
        vk.submit_unwaited([](VkCommandBuffer) {}, "work before the signal");
        vk.signal_semaphore(s, "a test signal");
        vk.wait_semaphore(s, "a test wait");
        vk.submit_unwaited([](VkCommandBuffer) {}, "work after the wait");
    }
    vk.wait_frames_in_flight();
    EXPECT_EQ(vk.retired_in_flight(), 0u);
}

TEST(FieldSync, VulkanSemaphoreBatchesAlternate) {
    // Vulkan's half alone, on a semaphore of Vulkan's own: the validation layer tracks it and
    // would report a wait without a signal or a signal of a signalled semaphore.
    vk::Context& vk = validated_vulkan();
    VkSemaphoreCreateInfo info{};
    info.sType = VK_STRUCTURE_TYPE_SEMAPHORE_CREATE_INFO;
    VkSemaphore plain = VK_NULL_HANDLE;
    ASSERT_EQ(vkCreateSemaphore(vk.device(), &info, nullptr, &plain), VK_SUCCESS);
    alternate(vk, plain);
    vkDestroySemaphore(vk.device(), plain, nullptr);
}

TEST(FieldSync, ExportedSemaphoreBatchesAlternate) {
    // An exportable semaphore, as path 1 uses (its state is OpenCL's too, so the layer no
    // longer tracks it once exported).
    vk::Context& vk = validated_vulkan();
    if (!vk::can_export_semaphore_fd(vk)) {
        GTEST_SKIP() << vk.info().name << " cannot export semaphores as opaque fds";
    }
    vk::ExportedSemaphore s(vk, "a test semaphore");
    const int fd = s.export_fd();
    ASSERT_GE(fd, 0);
    close(fd);  // exported, not imported anywhere: ours to close
    alternate(vk, s.get());
}

// The lead runs this on the H200 (NVIDIA OpenCL and Vulkan): path 1 ordered by semaphores,
// with frames in flight at every edit, against the fence path and the CPU reference.
TEST(FieldSync, SemaphoreEditsMatchTheFencePathAndTheReference) {
    ocl::Context& cl = default_opencl();
    const std::unique_ptr<pipeline::FramePipeline> sem = make_pipeline(cl, true);
    if (sem->sync() != pipeline::FieldSync::semaphore) {
        const auto yes = [](bool b) { return b ? "yes" : "no"; };
        GTEST_SKIP() << "no OpenCL <-> Vulkan semaphores here (expected without NVIDIA's "
                     << "drivers): OpenCL " << cl.info().name
                     << " imports opaque-fd semaphores: " << yes(ocl::can_import_semaphore_fd(cl))
                     << "; Vulkan " << validated_vulkan().info().name
                     << " exports them: " << yes(vk::can_export_semaphore_fd(validated_vulkan()))
                     << "; " << vk::describe(sem->sharing()) << "; " << sem->sync_why_not();
    }
    const std::unique_ptr<pipeline::FramePipeline> fence = make_pipeline(cl, false);
    ASSERT_EQ(fence->sync(), pipeline::FieldSync::fence);
    ASSERT_EQ(fence->sharing(), vk::SharingPath::opaque_fd);
    const World start = make_scene("spheres", kDims, 13);
    const vk::RenderOptions r = lit_view(start);
    const World edited = edit_frames({sem.get(), fence.get()}, start, 24, r);
    EXPECT_EQ(sem->sync(), pipeline::FieldSync::semaphore) << sem->sync_why_not();
    expect_reference(cl, *sem, edited, r);
    // An update's conversion time is reported by a later one: the picture above waited (on
    // the device) for the last conversion, so the next update counts it.
    World more = edited;
    const Brush b{BrushOp::place, BrushShape::sphere, {24, 16, 20}, 3, 7};
    apply_brush(more, b);
    EXPECT_GT(sem->apply({b}).convert_ms, 0.0);
    EXPECT_FALSE(picture(*sem, r).empty());
    expect_reference(cl, *sem, more, r);
    expect_reference(cl, *fence, edited, r);
}

// $VOXFIELD_NO_CL_SEMAPHORE forces the fallback: the same frames as the default ordering
// (here both wait for fences; on the H200 the default one uses the semaphores).
TEST(FieldSync, ForcedFallbackGivesIdenticalFrames) {
    ocl::Context& cl = default_opencl();
    const std::unique_ptr<pipeline::FramePipeline> plain = make_pipeline(cl, true);
    const std::unique_ptr<pipeline::FramePipeline> forced = make_pipeline(cl, false);
    EXPECT_NE(forced->sync(), pipeline::FieldSync::semaphore);
    EXPECT_EQ(forced->sharing(), plain->sharing());
    if (forced->sharing() == vk::SharingPath::opaque_fd) {
        EXPECT_EQ(forced->sync_why_not(), "$VOXFIELD_NO_CL_SEMAPHORE is set");
    }
    const World start = make_scene("spheres", kDims, 17);
    const vk::RenderOptions r = lit_view(start);
    const World edited = edit_frames({plain.get(), forced.get()}, start, 16, r);
    expect_reference(cl, *plain, edited, r);
}

}  // namespace
}  // namespace voxfield::test
