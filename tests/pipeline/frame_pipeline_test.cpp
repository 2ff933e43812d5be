// The frame pipeline (pipeline/) on PoCL + lavapipe, validated: the sharing-path choice and
// its fallbacks, one picture whatever path or render format carries the field, edits that
// reach the image, and switches that fail without changing anything.
#include <gtest/gtest.h>

#include <memory>
#include <stdexcept>
#include <string>
#include <vector>

#include "../cl/cl_test_util.hpp"
#include "../vk/vulkan_env.hpp"
#include "voxfield/cl/generator.hpp"
#include "voxfield/core/error.hpp"
#include "voxfield/core/sand.hpp"
#include "voxfield/core/scenes.hpp"
#include "voxfield/core/undo.hpp"
#include "voxfield/pipeline/frame_pipeline.hpp"

namespace voxfield::test {
namespace {

constexpr Dims kDims{40, 24, 32};

vk::RenderOptions view(const World& world) {
    vk::RenderOptions r;
    r.width = 64;
    r.height = 48;
    r.camera = vk::default_camera(world, r.width, r.height, r.camera.fov_deg);
    return r;
}

ocl::GeneratorOptions exact(Metric metric = Metric::manhattan) {
    ocl::GeneratorOptions g;
    g.format = Format::u16;
    g.metric = metric;
    return g;
}

std::vector<std::uint8_t> picture(pipeline::FramePipeline& p, const vk::RenderOptions& r) {
    vk::Image image;
    p.render(r, image);
    return image.rgba;
}

TEST(SharingPath, PoclAndLavapipeTakePathTwoAndSayWhyNotOne) {
    std::string why_not;
    EXPECT_EQ(pipeline::choose_sharing_path(pocl(), validated_vulkan(), why_not),
              vk::SharingPath::host_pointer);
    EXPECT_NE(why_not.find("path 1"), std::string::npos) << why_not;
    EXPECT_EQ(why_not.find("path 2"), std::string::npos) << why_not;
}

TEST(SharingPath, AskedForASlowerPathTakesIt) {
    std::string why_not;
    EXPECT_EQ(
        pipeline::choose_sharing_path(pocl(), validated_vulkan(), why_not, vk::SharingPath::copy),
        vk::SharingPath::copy);
    EXPECT_NE(why_not.find("path 2: not tried"), std::string::npos) << why_not;
    EXPECT_EQ(pipeline::choose_sharing_path(pocl(), validated_vulkan(), why_not,
                                            vk::SharingPath::host_pointer),
              vk::SharingPath::host_pointer);
}

// Paths 2 and 3 and the packed32 render field show the same picture, before and after edits
// (flat shading: the hit voxels' colours alone).
TEST(FramePipeline, EveryPathAndFormatShowsOnePicture) {
    const World world = make_scene("spheres", kDims, 7);
    vk::RenderOptions r = view(world);
    r.shading = vk::Shading::flat;
    pipeline::PipelineOptions shared, copied, packed;
    copied.fastest_path = vk::SharingPath::copy;
    packed.render_format = vk::FieldFormat::packed32;
    pipeline::FramePipeline a(pocl(), validated_vulkan(), Palette::magicavoxel_default(), kDims,
                              shared);
    pipeline::FramePipeline b(pocl(), validated_vulkan(), Palette::magicavoxel_default(), kDims,
                              copied);
    pipeline::FramePipeline c(pocl(), validated_vulkan(), Palette::magicavoxel_default(), kDims,
                              packed);
    EXPECT_EQ(a.sharing(), vk::SharingPath::host_pointer);
    EXPECT_EQ(b.sharing(), vk::SharingPath::copy);
    EXPECT_EQ(c.sharing(), vk::SharingPath::copy);
    EXPECT_EQ(c.why_not(), "packed32 is always copied (path 3)");
    for (pipeline::FramePipeline* p : {&a, &b, &c}) {
        p->rebuild(World(world), exact());
    }
    EXPECT_EQ(c.options().format, Format::packed32);
    const std::vector<std::uint8_t> before = picture(a, r);
    EXPECT_EQ(picture(b, r), before);
    EXPECT_EQ(picture(c, r), before);

    const std::vector<Brush> batch = {Brush{BrushOp::place, BrushShape::sphere, {20, 12, 10}, 5, 9},
                                      Brush{BrushOp::erase, BrushShape::cube, {8, 4, 20}, 3, 0}};
    for (pipeline::FramePipeline* p : {&a, &b, &c}) {
        const pipeline::UpdateTimings u = p->apply(batch);
        EXPECT_GT(u.voxels_recomputed, 0u);
        EXPECT_GT(u.field_ms, 0.0);  // device time of kernels that ran
    }
    const std::vector<std::uint8_t> after = picture(a, r);
    EXPECT_NE(after, before);
    EXPECT_EQ(picture(b, r), after);
    EXPECT_EQ(picture(c, r), after);
}

// An edited pipeline shows what a fresh one built from the edited world shows, lit shading
// included (occlusion and shadows read the updated field), and its field is exact.
TEST(FramePipeline, EditsReachTheFieldAndThePicture) {
    World world = make_scene("spheres", kDims, 11);
    const vk::RenderOptions r = view(world);
    pipeline::FramePipeline p(pocl(), validated_vulkan(), Palette::magicavoxel_default(), kDims);
    p.rebuild(World(world), exact());
    UndoStack undo;
    std::vector<EditResult> edits;
    for (const Brush& b : {Brush{BrushOp::place, BrushShape::sphere, {12, 16, 12}, 4, 5},
                           Brush{BrushOp::paint, BrushShape::cube, {12, 16, 12}, 2, 200}}) {
        p.apply({b}, &edits);
        ASSERT_EQ(edits.size(), 1u);
        EXPECT_TRUE(edits.front().changed());
        undo.record(edits.front());
        undo.end_stroke();
    }

    pipeline::FramePipeline fresh(pocl(), validated_vulkan(), Palette::magicavoxel_default(),
                                  kDims);
    fresh.rebuild(World(p.world()), exact());
    EXPECT_EQ(picture(p, r), picture(fresh, r));
    EXPECT_EQ(p.read_field(), fresh.read_field());

    p.apply_changes(undo.undo());  // the paint, then the sphere
    p.apply_changes(undo.undo());
    EXPECT_EQ(p.world().voxels(), world.voxels());
    fresh.rebuild(World(world), exact());
    EXPECT_EQ(picture(p, r), picture(fresh, r));
}

// Saturated distances, where the ray marcher strides by the block minima: a world 1024 voxels
// long whose only solid is the wall at x = 0, seen from x = 700 looking down +x (at first
// nothing but sky).
World saturated_world() {
    World world(Dims{1024, 16, 16});
    for (std::uint32_t z = 0; z < 16; ++z) {
        for (std::uint32_t y = 0; y < 16; ++y) {
            world.set(0, y, z, 5);
        }
    }
    return world;
}

vk::RenderOptions down_the_world() {
    vk::RenderOptions r;
    r.width = 48;
    r.height = 36;
    r.camera.position = {700.5, 8.5, 8.5};
    r.camera.target = {1023, 8, 8};
    r.camera.fov_deg = 5;
    r.shading = vk::Shading::flat;
    return r;
}

class FramePipelineBlockMin : public ::testing::TestWithParam<vk::SharingPath> {};

// A sphere placed near the far end, where the old block minima (about 700 from the wall)
// would carry rays straight past it: the edited pipeline shows what a fresh one built from the
// edited world shows. On path 2 OpenCL rewrote the table in place and nothing was copied; on
// path 3 only the minima of the blocks the edit changed travelled, not the whole table.
TEST_P(FramePipelineBlockMin, EditsRewriteOnlyTheChangedBlocks) {
    pipeline::PipelineOptions o;
    o.fastest_path = GetParam();
    const World world = saturated_world();
    pipeline::FramePipeline p(pocl(), validated_vulkan(), Palette::magicavoxel_default(),
                              world.dims(), o);
    p.rebuild(World(world), exact());
    ASSERT_EQ(p.sharing(), GetParam());
    const vk::RenderOptions r = down_the_world();
    const std::vector<std::uint8_t> before = picture(p, r);
    const std::uint64_t table = 4 * 128 * 2 * 2;  // ceil(dims / 8) blocks, 4 bytes each
    const bool copy = GetParam() == vk::SharingPath::copy;
    const std::uint64_t copied = p.marcher().block_min_bytes_copied();
    EXPECT_EQ(copied, copy ? table : 0u);

    const pipeline::UpdateTimings u =
        p.apply({Brush{BrushOp::place, BrushShape::sphere, {1000, 8, 8}, 6, 9}});
    EXPECT_FALSE(u.full_regeneration);
    const std::vector<std::uint8_t> after = picture(p, r);
    EXPECT_NE(after, before) << "the sphere does not show: the test would prove nothing";
    pipeline::FramePipeline fresh(pocl(), validated_vulkan(), Palette::magicavoxel_default(),
                                  world.dims(), o);
    fresh.rebuild(World(p.world()), exact());
    EXPECT_EQ(after, picture(fresh, r));
    const std::uint64_t moved = p.marcher().block_min_bytes_copied() - copied;
    if (copy) {
        EXPECT_GT(moved, 0u);
        EXPECT_LT(moved, table) << "the whole table was copied";
    } else {
        EXPECT_EQ(moved, 0u);
        EXPECT_EQ(p.marcher().bytes_copied(), 0u);
    }
}

INSTANTIATE_TEST_SUITE_P(Paths, FramePipelineBlockMin,
                         ::testing::Values(vk::SharingPath::host_pointer, vk::SharingPath::copy),
                         [](const ::testing::TestParamInfo<vk::SharingPath>& p) {
                             return p.param == vk::SharingPath::copy ? "path3" : "path2";
                         });

// A switch the updater refuses (a global algorithm it cannot update), or a world of another
// size, leaves the world, the options and the picture as they were.
TEST(FramePipeline, FailedSwitchChangesNothing) {
    const World world = make_scene("terrain", kDims, 3);
    const vk::RenderOptions r = view(world);
    pipeline::FramePipeline p(pocl(), validated_vulkan(), Palette::magicavoxel_default(), kDims);
    p.rebuild(World(world), exact());
    const std::vector<std::uint8_t> before = picture(p, r);
    ocl::GeneratorOptions refused = exact();
    refused.algorithm = ocl::Algorithm::jfa;  // global JFA: no incremental update
    EXPECT_THROW(p.switch_field(refused), InputError);
    EXPECT_THROW(p.rebuild(make_scene("terrain", Dims{16, 16, 16}, 3), exact()), InputError);
    EXPECT_EQ(p.options().algorithm, ocl::Algorithm::exact);
    EXPECT_EQ(p.world().voxels(), world.voxels());
    EXPECT_EQ(picture(p, r), before);
    // And it still works: a metric switch, then an edit.
    p.switch_field(exact(Metric::chebyshev));
    EXPECT_EQ(p.options().metric, Metric::chebyshev);
    p.apply({Brush{BrushOp::place, BrushShape::sphere, {20, 20, 16}, 3, 4}});
    pipeline::FramePipeline fresh(pocl(), validated_vulkan(), Palette::magicavoxel_default(),
                                  kDims);
    fresh.rebuild(World(p.world()), exact(Metric::chebyshev));
    EXPECT_EQ(p.read_field(), fresh.read_field());
    EXPECT_EQ(picture(p, r), picture(fresh, r));
}

// Until a rebuild succeeds there is no field: updates and reads say so instead of reaching a
// null one.
TEST(FramePipeline, NoFieldBeforeTheFirstSuccessfulRebuild) {
    pipeline::FramePipeline p(pocl(), validated_vulkan(), Palette::magicavoxel_default(), kDims);
    ocl::GeneratorOptions refused = exact();
    refused.algorithm = ocl::Algorithm::jfa;
    EXPECT_THROW(p.rebuild(make_scene("terrain", kDims, 3), refused), InputError);
    EXPECT_THROW(p.apply({Brush{BrushOp::place, BrushShape::sphere, {20, 12, 16}, 3, 4}}),
                 std::logic_error);
    EXPECT_THROW(p.world(), std::logic_error);
    EXPECT_THROW(p.read_field(), std::logic_error);
    p.rebuild(make_scene("terrain", kDims, 3), exact());
    EXPECT_GT(
        p.apply({Brush{BrushOp::place, BrushShape::sphere, {20, 12, 16}, 3, 4}}).voxels_recomputed,
        0u);
}

// A rebuild whose new field cannot be shown, and whose old one then cannot be shown again
// either, leaves the old scene unshown: the next update shows it first, and the picture and
// field are right.
TEST(FramePipeline, FailedRebuildThatCannotShowTheOldFieldRecovers) {
    for (const vk::SharingPath path : {vk::SharingPath::host_pointer, vk::SharingPath::copy}) {
        pipeline::PipelineOptions o;
        o.fastest_path = path;
        const World world = make_scene("spheres", kDims, 5);
        const vk::RenderOptions r = view(world);
        pipeline::FramePipeline p(pocl(), validated_vulkan(), Palette::magicavoxel_default(), kDims,
                                  o);
        p.rebuild(World(world), exact());
        p.fail_next_shows_for_testing(2);
        EXPECT_THROW(p.switch_field(exact(Metric::chebyshev)), ocl::ClError);
        EXPECT_EQ(p.options().metric, Metric::manhattan);
        const Brush brush{BrushOp::place, BrushShape::sphere, {20, 12, 16}, 4, 6};
        p.apply({brush});
        World edited = world;
        apply_brush(edited, brush);
        pipeline::FramePipeline fresh(pocl(), validated_vulkan(), Palette::magicavoxel_default(),
                                      kDims, o);
        fresh.rebuild(World(edited), exact());
        EXPECT_EQ(p.world().voxels(), edited.voxels());
        EXPECT_EQ(p.read_field(), fresh.read_field());
        EXPECT_EQ(picture(p, r), picture(fresh, r));
    }
}

// --simulate in the pipeline: sand steps in place on the scene's device voxels, their changes
// through the field and the render field on the device; the picture equals a fresh pipeline's
// of the stepped world.
TEST(FramePipeline, SandStepsReachTheFieldAndThePicture) {
    const World world = scene_sand(kDims, 4);
    const vk::RenderOptions r = view(world);
    pipeline::FramePipeline p(pocl(), validated_vulkan(), Palette::magicavoxel_default(), kDims);
    p.rebuild(World(world), exact());
    World ref = world;
    std::uint64_t changed = 0;
    for (std::uint64_t step = 0; step < 6; ++step) {
        const VoxelChanges want = sand_step(ref, SandRules{}, 9, step);
        const pipeline::UpdateTimings u = p.step_sand(SandRules{}, 9, step);
        EXPECT_EQ(u.voxels_changed, want.size());
        EXPECT_GT(u.simulate_ms, 0.0);
        changed += want.size();
    }
    ASSERT_GT(changed, 0u);
    EXPECT_EQ(p.world().voxels(), ref.voxels());
    pipeline::FramePipeline fresh(pocl(), validated_vulkan(), Palette::magicavoxel_default(),
                                  kDims);
    fresh.rebuild(World(ref), exact());
    EXPECT_EQ(p.read_field(), fresh.read_field());
    EXPECT_EQ(picture(p, r), picture(fresh, r));
}

}  // namespace
}  // namespace voxfield::test
