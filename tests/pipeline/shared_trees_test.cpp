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

#include <algorithm>

#include <cstdint>
#include <random>
#include <stdexcept>
#include <string>
#include <vector>

#include "cl_test_util.hpp"
#include "sparse_brush.hpp"
#include "sparse_city.hpp"
#include "sparse_images.hpp"
#include "voxfield/cl/sparse_field.hpp"
#include "voxfield/cl/sparse_sand.hpp"
#include "voxfield/core/palette.hpp"
#include "voxfield/core/sand.hpp"
#include "voxfield/core/sparse.hpp"
#include "vulkan_env.hpp"

namespace voxfield::test {
namespace {

ocl::GeneratorOptions bounded(std::uint32_t d) {
    ocl::GeneratorOptions options;
    options.format = Format::u8;
    options.max_distance = d;
    return ocl::resolve_sparse_options(options, true);
}

// The shared tracer's views equal a fresh upload's of the world read back (inside a trace
// scope: path 2's buffers mapped for reading while Vulkan reads them).
void expect_shared_as_fresh(vk::Context& ctx, pipeline::SharedTrees& shared,
                            vk::SparseTracer& tracer, ocl::SparseField& field,
                            const Palette& palette, const std::string& when) {
    const SparseWorld& host = field.world();
    const pipeline::SharedTrees::TraceScope scope(shared);
    expect_as_fresh(ctx, tracer, host, palette, when);
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
    expect_shared_as_fresh(*ctx, shared, tracer, field, palette, "first upload");
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
    for (int e = 0; e < 30; ++e) {
        // Places in the air too (tiles made above the city), erases and paints: small brushes,
        // so that the slot buffers (16 slots at first) grow during one that leaves most slot
        // tiles outside its box.
        brushes.push_back(
            brush(static_cast<BrushOp>(op(rng)), e % 3 == 0 ? BrushShape::cube : BrushShape::sphere,
                  {px(rng), py(rng), pz(rng)}, radius(rng), static_cast<std::uint8_t>(1 + e)));
    }
    // A tile emptied whole (its tree on the device: a root without children), then a place.
    brushes.push_back(brush(BrushOp::erase, BrushShape::cube, {96, 32, 96}, 32, 1));
    brushes.push_back(brush(BrushOp::place, BrushShape::sphere, {200, 100, 40}, 8, 9));
    int e = 0;
    bool moved_outside_the_box = false;
    for (const Brush& b : brushes) {
        field.apply_brush(b);
        const vk::SparseTileUpdate u =
            shared.sync(tracer, field.device_world(), d, palette, brush_bounds(b, d));
        EXPECT_FALSE(u.whole);
        EXPECT_EQ(u.tiles_removed, 0u);  // the device keeps emptied tiles (empty trees)
        // Only directory entries move: a 32-byte record per tile written or moved (once for a
        // tile both moved and written), and a page entry per tile new to the directory (the
        // world is one directory block).
        if (u.tiles_moved == 0) {
            EXPECT_EQ(u.bytes, 32u * u.tiles_written + 4u * u.tiles_added) << "edit " << e;
        } else {
            // The tiles written went to slots, so the slot set's move lists them too, except
            // those new to the directory (records made after the move).
            EXPECT_EQ(u.bytes, 32u * (u.tiles_moved + u.tiles_added) + 4u * u.tiles_added)
                << "edit " << e << ": a record staged twice";
        }
        ++e;
        if (u.tiles_moved > 0) {
            // The slot buffers grew: every tile in them pointed at the new memory.
            moved_outside_the_box = moved_outside_the_box || u.tiles_moved > u.tiles_written;
            expect_shared_as_fresh(*ctx, shared, tracer, field, palette,
                                   "slot growth at edit " + std::to_string(e));
        } else if (e % 6 == 0 || e == static_cast<int>(brushes.size())) {
            expect_shared_as_fresh(*ctx, shared, tracer, field, palette,
                                   "device edit " + std::to_string(e));
        }
    }
    EXPECT_TRUE(moved_outside_the_box);
    EXPECT_GT(field.device_world().slots_used(), 16u);
    EXPECT_EQ(tracer.stats().arena_tiles, 0u);  // nothing went through the host world
}

// Host edits the device is told of (SparseField::update): tiles erased out of the directory, a
// whole directory block emptied (its page freed), then tiles made again in it (a page taken).
TEST(SharedTrees, TilesAndBlocksRemovedAndMadeAgain) {
    REQUIRE_VULKAN(ctx);
    REQUIRE_SHARING(shared, ctx);
    SparseWorld world = city(Dims{700, 100, 200}, 6);  // two directory blocks along x
    const Dims d = world.dims();
    const Palette palette = Palette::dissertation();
    ocl::SparseField field(pocl(), world, palette, bounded(4), shared.allocator());
    field.run();
    vk::SparseTracer tracer(*ctx);
    shared.sync(tracer, field.device_world(), d, palette, Box{});
    const std::uint64_t pages = tracer.stats().pages;
    ASSERT_EQ(pages, 2u);
    // Everything from x = 500 on erased: block 1 (x >= 512) emptied.
    field.world();
    const Box erased =
        apply_brush(world, brush(BrushOp::erase, BrushShape::cube, {600, 50, 100}, 100, 1));
    field.update(erased);
    vk::SparseTileUpdate u = shared.sync(tracer, field.device_world(), d, palette, erased);
    EXPECT_GT(u.tiles_removed, 0u);
    EXPECT_EQ(tracer.stats().pages, 1u);
    expect_shared_as_fresh(*ctx, shared, tracer, field, palette, "block emptied");
    // A sphere in block 1 again: new tiles, a page for the block.
    const Box placed =
        apply_brush(world, brush(BrushOp::place, BrushShape::sphere, {620, 40, 90}, 20, 12));
    field.update(placed);
    u = shared.sync(tracer, field.device_world(), d, palette, placed);
    EXPECT_GT(u.tiles_added, 0u);
    EXPECT_EQ(tracer.stats().pages, 2u);
    expect_shared_as_fresh(*ctx, shared, tracer, field, palette, "block made again");
    // And on the device, in the block made again.
    field.apply_brush(brush(BrushOp::paint, BrushShape::sphere, {620, 40, 90}, 12, 3));
    shared.sync(tracer, field.device_world(), d, palette,
                brush_bounds(brush(BrushOp::paint, BrushShape::sphere, {620, 40, 90}, 12, 3), d));
    expect_shared_as_fresh(*ctx, shared, tracer, field, palette, "painted on the device");
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
        ASSERT_EQ(st.tiles.size(), st.tiles_changed);
        // Only the tiles the step encoded again are pointed elsewhere.
        const vk::SparseTileUpdate u =
            shared.sync(tracer, field.device_world(), d, palette, st.tiles);
        EXPECT_EQ(u.tiles_written, st.tiles_changed);
        if (s == 5) {
            expect_shared_as_fresh(*ctx, shared, tracer, field, palette, "after 6 sand steps");
        }
    }
    EXPECT_GT(changed, 0u);
    expect_shared_as_fresh(*ctx, shared, tracer, field, palette, "after 12 sand steps");
}

TEST(SharedTrees, AWholeUploadIsTracedAgainAndTheOldMemoryFreed) {
    REQUIRE_VULKAN(ctx);
    REQUIRE_SHARING(shared, ctx);
    SparseWorld world = city(Dims{260, 120, 230}, 4);
    const Palette palette = Palette::dissertation();
    ocl::SparseField field(pocl(), world, palette, bounded(6), shared.allocator());
    field.run();
    vk::SparseTracer tracer(*ctx);
    shared.sync(tracer, field.device_world(), world.dims(), palette, Box{});
    // Kernels and an edit have used the main buffers before they are dropped.
    const Brush edit = brush(BrushOp::place, BrushShape::sphere, {60, 70, 60}, 9, 4);
    field.apply_brush(edit);
    shared.sync(tracer, field.device_world(), world.dims(), palette,
                brush_bounds(edit, world.dims()));
    field.world();
    const std::uint64_t before = shared.bytes();
    // A host edit the device was not told of: refresh() uploads the whole world again, into
    // new main buffers.
    apply_brush(world, brush(BrushOp::place, BrushShape::sphere, {130, 90, 115}, 30, 5));
    field.device_world().refresh();
    // The previous main buffers were freed before the new ones were allocated, and the tracer,
    // which read them, traces nothing until it is synced again.
    EXPECT_LT(shared.bytes(), before + world.bytes() / 2);
    vk::RenderOptions r;
    r.width = 8;
    r.height = 8;
    r.camera = vk::default_camera(world.dims());
    EXPECT_THROW(tracer.render(r), std::logic_error);
    const vk::SparseTileUpdate u =
        shared.sync(tracer, field.device_world(), world.dims(), palette, Box{});
    EXPECT_TRUE(u.whole);
    expect_shared_as_fresh(*ctx, shared, tracer, field, palette, "after a whole upload");
}

// A host edit over more than 256 tiles, told through SparseField::update, uploads the device
// world whole inside the edit: the next sync makes the tracer's directory whole again.
TEST(SharedTrees, AWholeUploadInsideAnEditIsTracedWhole) {
    REQUIRE_VULKAN(ctx);
    REQUIRE_SHARING(shared, ctx);
    SparseWorld world = city(Dims{1100, 64, 1100}, 3);  // 18 x 1 x 18 tiles
    const Dims d = world.dims();
    const Palette palette = Palette::dissertation();
    ocl::SparseField field(pocl(), world, palette, bounded(3), shared.allocator());
    field.run();
    vk::SparseTracer tracer(*ctx);
    shared.sync(tracer, field.device_world(), d, palette, Box{});
    field.world();
    const Box changed =
        apply_brush(world, brush(BrushOp::paint, BrushShape::cube, {550, 32, 550}, 549, 6));
    field.update(changed);
    const vk::SparseTileUpdate u = shared.sync(tracer, field.device_world(), d, palette, changed);
    EXPECT_TRUE(u.whole);
    expect_shared_as_fresh(*ctx, shared, tracer, field, palette, "after the whole upload");
    shared.forget(tracer);
}

TEST(SharedTrees, AnAllocationOverTheLimitIsRefusedWithItsReason) {
    REQUIRE_VULKAN(ctx);
    EXPECT_GT(ctx->info().max_buffer_size, 0u);
    SparseWorld world = city(Dims{260, 120, 230}, 4);
    const Palette palette = Palette::dissertation();
    // Below the world's node masks: the field cannot be made in shared memory.
    pipeline::SharedTrees small(pocl(), *ctx, vk::SharingPath::opaque_fd, 64 << 10);
    if (!small.shares()) {
        GTEST_SKIP() << "PoCL and " << ctx->info().name << " cannot share memory";
    }
    try {
        ocl::SparseField field(pocl(), world, palette, bounded(6), small.allocator());
        ADD_FAILURE() << "no AllocationError";
    } catch (const pipeline::SharedTrees::AllocationError& e) {
        const std::string what = e.what();
        EXPECT_NE(what.find("exceed one buffer of"), std::string::npos) << what;
        EXPECT_NE(what.find("65536 bytes"), std::string::npos) << what;
    }
    // A field without the allocator still works beside it (the viewer's fallback, path 3).
    ocl::SparseField plain(pocl(), world, palette, bounded(6));
    plain.run();
    vk::SparseTracer tracer(*ctx);
    tracer.upload(plain.world(), palette);
    EXPECT_EQ(tracer.stats().shared_bytes, 0u);
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
    // One trace scope at a time, and no sync inside one.
    ocl::SparseField field(pocl(), world, palette, bounded(4), shared.allocator());
    shared.sync(tracer, field.device_world(), world.dims(), palette, Box{});
    const pipeline::SharedTrees::TraceScope scope(shared);
    EXPECT_THROW(pipeline::SharedTrees::TraceScope again(shared), std::logic_error);
    EXPECT_THROW(shared.sync(tracer, field.device_world(), world.dims(), palette, Box{}),
                 std::logic_error);
    // A tile outside the grid, or listed twice, is refused.
    vk::SparseTracer other(*ctx);
    vk::SharedTile t;
    t.tile = {0, 0, 0};
    EXPECT_THROW(other.upload_shared(world.dims(), palette, {}, {t, t}), std::logic_error);
    t.tile = {5, 0, 0};
    EXPECT_THROW(other.upload_shared(world.dims(), palette, {}, {t}), std::logic_error);
}

}  // namespace
}  // namespace voxfield::test
