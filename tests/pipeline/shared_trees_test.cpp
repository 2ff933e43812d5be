// pipeline::SharedTrees on PoCL + lavapipe (path 2: one host allocation per buffer, used by
// OpenCL and imported by Vulkan) under the validation layer: the sparse tracer reads the OpenCL
// device world's 64-trees in place, and its images equal, pixel for pixel, those of a tracer
// uploaded from the host world: after the first upload, after device edits (tiles moved into
// slots, tiles made in empty space, a tile emptied, the slot buffers grown), after sand steps
// (tiles encoded from the automaton's windows) and after the device world was uploaded whole
// again. Nothing of the trees is the tracer's own. Without a Vulkan device, or where the two
// devices cannot share memory, the tests skip.
#include "voxfield/pipeline/shared_trees.hpp"

#include <gtest/gtest.h>

#include <cstdint>
#include <random>
#include <stdexcept>
#include <string>
#include <vector>

#include "cl_test_util.hpp"
#include "sparse_brush.hpp"
#include "sparse_images.hpp"
#include "voxfield/cl/sparse_field.hpp"
#include "voxfield/cl/sparse_sand.hpp"
#include "voxfield/core/palette.hpp"
#include "voxfield/core/sand.hpp"
#include "voxfield/core/scenes.hpp"
#include "voxfield/core/sparse.hpp"
#include "vulkan_env.hpp"

namespace voxfield::test {
namespace {

SparseWorld city(Dims dims, std::uint64_t seed) {
    const CityScene scene(dims, seed);
    return SparseWorld::from_fill(
        dims, [&](const Box& box, std::span<std::uint8_t> out) { scene.fill(box, out); });
}

ocl::GeneratorOptions bounded(std::uint32_t d) {
    ocl::GeneratorOptions options;
    options.format = Format::u8;
    options.max_distance = d;
    return ocl::resolve_sparse_options(options, true);
}

// Declares `shared` for `ctx` and PoCL, or skips where they cannot share memory.
#define REQUIRE_SHARING(shared, ctx)                                    \
    pipeline::SharedTrees shared(pocl(), *(ctx));                       \
    if (!(shared).shares()) {                                           \
        GTEST_SKIP() << "PoCL and " << (ctx)->info().name               \
                     << " cannot share memory: " << (shared).why_not(); \
    }

TEST(SharedTrees, TheTracerReadsTheDeviceWorldInPlace) {
    REQUIRE_VULKAN(ctx);
    REQUIRE_SHARING(shared, ctx);
    EXPECT_EQ(shared.path(), vk::SharingPath::host_pointer);  // a CPU OpenCL device
    SparseWorld world = city(Dims{260, 120, 230}, 4);
    const Palette palette = Palette::dissertation();
    ocl::SparseField field(pocl(), world, palette, bounded(6), shared.allocator());
    field.run();
    vk::SparseTracer tracer(*ctx);
    const vk::SparseTileUpdate u =
        shared.sync(tracer, field.device_world(), world.dims(), palette, Box{});
    EXPECT_TRUE(u.whole);
    EXPECT_EQ(u.tiles_written, world.tile_count());
    expect_as_fresh(*ctx, tracer, field.world(), palette, "first upload");
    // The trees are not the tracer's: its own buffers are the directory, records and palette.
    vk::SparseTracer copy(*ctx);
    copy.upload(world, palette);
    const std::uint64_t trees = world.node_masks().size() * 12 + world.materials().size();
    EXPECT_GE(tracer.stats().shared_bytes, trees);
    EXPECT_LE(tracer.stats().bytes + trees, copy.stats().bytes);
    EXPECT_EQ(copy.stats().shared_bytes, 0u);
}

TEST(SharedTrees, DeviceEditsAreTracedWithoutTheHostWorld) {
    REQUIRE_VULKAN(ctx);
    REQUIRE_SHARING(shared, ctx);
    SparseWorld world = city(Dims{260, 120, 230}, 4);
    const Dims d = world.dims();
    const Palette palette = Palette::dissertation();
    ocl::SparseField field(pocl(), world, palette, bounded(6), shared.allocator());
    field.run();
    vk::SparseTracer tracer(*ctx);
    shared.sync(tracer, field.device_world(), d, palette, Box{});
    std::vector<Brush> brushes;
    std::mt19937_64 rng(8);
    std::uniform_int_distribution<std::int64_t> px(0, 259), py(0, 119), pz(0, 229), radius(0, 9),
        op(0, 2);
    for (int e = 0; e < 12; ++e) {
        // Places in the air too (tiles made above the city), erases and paints.
        brushes.push_back(
            brush(static_cast<BrushOp>(op(rng)), e % 3 == 0 ? BrushShape::cube : BrushShape::sphere,
                  {px(rng), py(rng), pz(rng)}, radius(rng), static_cast<std::uint8_t>(1 + e)));
    }
    // A tile emptied whole (its tree on the device: a root without children), and a paint over
    // every tile of the world, which outgrows the first 16 slots.
    brushes.push_back(brush(BrushOp::erase, BrushShape::cube, {96, 32, 96}, 32, 1));
    brushes.push_back(brush(BrushOp::paint, BrushShape::cube, {130, 60, 115}, 140, 7));
    brushes.push_back(brush(BrushOp::place, BrushShape::sphere, {200, 100, 40}, 8, 9));
    int e = 0;
    std::uint32_t moved = 0;
    for (const Brush& b : brushes) {
        const std::size_t slots_before = field.device_world().slots_used();
        field.apply_brush(b);
        const vk::SparseTileUpdate u =
            shared.sync(tracer, field.device_world(), d, palette, brush_bounds(b, d));
        EXPECT_FALSE(u.whole);
        moved += u.tiles_moved;
        // Only directory entries move: at most a record, a page entry and a block per tile, or
        // every record when the slot buffers were replaced.
        if (field.device_world().slots_used() == slots_before) {
            EXPECT_LE(u.bytes, u.tiles_written * 40u + 4096u * 4 * u.tiles_written);
        }
        if (++e % 4 == 0 || e == static_cast<int>(brushes.size())) {
            expect_as_fresh(*ctx, tracer, field.world(), palette,
                            "device edit " + std::to_string(e));
        }
    }
    // The slot buffers grew: the tiles in them were pointed at the new memory.
    EXPECT_GT(field.device_world().slots_used(), 16u);
    EXPECT_GT(moved, 0u);
    EXPECT_EQ(tracer.stats().arena_tiles, 0u);  // nothing went through the host world
}

TEST(SharedTrees, SandStepsAreTracedInPlace) {
    REQUIRE_VULKAN(ctx);
    REQUIRE_SHARING(shared, ctx);
    SparseWorld world = city(Dims{200, 140, 180}, 9);
    const Dims d = world.dims();
    Palette palette = Palette::dissertation();
    const SandRules rules;
    ocl::SparseField field(pocl(), world, palette, bounded(4), shared.allocator());
    field.run();
    ocl::SparseSand sand(pocl(), field, rules);
    vk::SparseTracer tracer(*ctx);
    shared.sync(tracer, field.device_world(), d, palette, Box{});
    const Brush pour = brush(BrushOp::place, BrushShape::cube, {100, 120, 90}, 12, rules.sand);
    field.apply_brush(pour);
    sand.touched(brush_bounds(pour, d));
    shared.sync(tracer, field.device_world(), d, palette, brush_bounds(pour, d));
    std::uint32_t changed = 0;
    for (std::uint64_t s = 0; s < 12; ++s) {
        const ocl::SparseSand::Step st = sand.step(3, s);
        changed += static_cast<std::uint32_t>(st.changed);
        if (!st.bounds.empty()) {
            shared.sync(tracer, field.device_world(), d, palette, st.bounds);
        }
    }
    EXPECT_GT(changed, 0u);
    expect_as_fresh(*ctx, tracer, field.world(), palette, "after 12 sand steps");
}

TEST(SharedTrees, AWholeUploadIsTracedAgainAndTheOldMemoryFreed) {
    REQUIRE_VULKAN(ctx);
    REQUIRE_SHARING(shared, ctx);
    SparseWorld world = city(Dims{260, 120, 230}, 4);
    const Palette palette = Palette::dissertation();
    ocl::SparseField field(pocl(), world, palette, bounded(6), shared.allocator());
    vk::SparseTracer tracer(*ctx);
    shared.sync(tracer, field.device_world(), world.dims(), palette, Box{});
    const std::uint64_t before = shared.bytes();
    // A host edit the device was not told of: refresh() uploads the whole world again, into
    // new main buffers.
    apply_brush(world, brush(BrushOp::place, BrushShape::sphere, {130, 90, 115}, 30, 5));
    field.device_world().refresh();
    const vk::SparseTileUpdate u =
        shared.sync(tracer, field.device_world(), world.dims(), palette, Box{});
    EXPECT_TRUE(u.whole);
    expect_as_fresh(*ctx, tracer, world, palette, "after a whole upload");
    // The previous main buffers are freed once the tracer reads the new ones.
    EXPECT_LT(shared.bytes(), before + world.bytes() / 2);
}

TEST(SharedTrees, RefusesWhatIsNotShared) {
    REQUIRE_VULKAN(ctx);
    SparseWorld world = city(Dims{130, 60, 70}, 2);
    const Palette palette = Palette::dissertation();
    vk::SparseTracer tracer(*ctx);
    pipeline::SharedTrees copying(pocl(), *ctx, vk::SharingPath::copy);
    EXPECT_FALSE(copying.shares());
    EXPECT_FALSE(static_cast<bool>(copying.allocator()));
    ocl::SparseField plain(pocl(), world, palette, bounded(4));
    EXPECT_THROW(copying.sync(tracer, plain.device_world(), world.dims(), palette, Box{}),
                 std::logic_error);
    REQUIRE_SHARING(shared, ctx);
    // A field whose trees are not in the shared memory.
    EXPECT_THROW(shared.sync(tracer, plain.device_world(), world.dims(), palette, Box{}),
                 std::logic_error);
    EXPECT_THROW(tracer.repoint({}, {}, {}), std::logic_error);
}

}  // namespace
}  // namespace voxfield::test
