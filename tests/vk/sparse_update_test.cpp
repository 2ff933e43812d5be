// The sparse tracer's incremental update (vk::SparseTracer::update_tiles) on lavapipe with the
// validation layer: after every edit of a sequence (core's apply_brush on a SparseWorld: places,
// erases and paints, tiles made in empty space and in directory blocks that had none, tiles and
// whole blocks emptied by erasing), the updated tracer's image equals, pixel for pixel, the
// image of a tracer freshly uploaded from the edited world (flat and lit, several cameras); so
// does it through arena growth, with nodes and materials cut into several bindings, and where
// the arena cannot fit (the whole upload it falls back to). Without a Vulkan device the tests
// skip. The viewer's path too: edits on the OpenCL device (ocl::SparseField::apply_brush on
// PoCL), the edited tiles read back (SparseField::world), the tracer updated from them.
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
#include "voxfield/core/error.hpp"
#include "voxfield/core/palette.hpp"
#include "voxfield/core/sparse.hpp"
#include "voxfield/vk/sparse_trace_layout.h"
#include "voxfield/vk/sparse_tracer.hpp"
#include "vulkan_env.hpp"

namespace voxfield::test {
namespace {

TEST(SparseUpdate, RandomEditsEqualAFreshUpload) {
    REQUIRE_VULKAN(ctx);
    SparseWorld world = city(Dims{300, 150, 270}, 31);
    const Palette palette = Palette::magicavoxel_default();
    vk::SparseTracer tracer(*ctx);
    tracer.upload(world, palette);
    std::mt19937_64 rng(5);
    const Dims d = world.dims();
    std::uniform_int_distribution<std::int64_t> px(-10, d.x + 10), py(-10, d.y + 10),
        pz(-10, d.z + 10), radius(0, 12), material(1, 255), op(0, 2), shape(0, 1);
    std::uint32_t written = 0;
    for (int e = 0; e < 24; ++e) {
        const Brush b = brush(
            static_cast<BrushOp>(op(rng)), shape(rng) == 0 ? BrushShape::sphere : BrushShape::cube,
            {px(rng), py(rng), pz(rng)}, radius(rng), static_cast<std::uint8_t>(material(rng)));
        const Box changed = apply_brush(world, b);
        const vk::SparseTileUpdate u = tracer.update_tiles(world, changed);
        EXPECT_FALSE(u.whole);
        written += u.tiles_written;
        if (e % 6 == 5) {
            expect_as_fresh(*ctx, tracer, world, palette, "after edit " + std::to_string(e));
        }
    }
    EXPECT_GT(written, 0u);
    EXPECT_NE(tracer.stats().arena_node_chunk, VF_SPARSE_NONE);
    EXPECT_GT(tracer.stats().arena_tiles, 0u);
}

// An update submits nothing of its own: its copies go in the next trace's submission, before
// the dispatch; a second update before any trace submits the first's copies first (one
// submission), so that no submission copies to the same place twice.
TEST(SparseUpdate, CopiesGoWithTheNextTrace) {
    REQUIRE_VULKAN(ctx);
    SparseWorld world = city(Dims{200, 100, 180}, 12);
    const Palette palette = Palette::magicavoxel_default();
    vk::SparseTracer tracer(*ctx);
    tracer.upload(world, palette);
    const vk::RenderOptions view = views(world).front();
    tracer.trace(view);
    const auto edit = [&](std::int64_t x, std::uint8_t material) {
        return tracer.update_tiles(
            world, apply_brush(
                       world, brush(BrushOp::place, BrushShape::sphere, {x, 60, 90}, 9, material)));
    };
    const std::uint64_t first = ctx->next_serial();
    vk::SparseTileUpdate u = edit(40, 3);
    EXPECT_GT(u.bytes, 0u);
    EXPECT_EQ(ctx->next_serial(), first) << "the update submitted its copies itself";
    tracer.trace(view);
    EXPECT_EQ(ctx->next_serial(), first + 1) << "the copies and the trace: one submission";
    expect_as_fresh(*ctx, tracer, world, palette, "after one update");
    // The same tiles written twice before a trace, then more: their places in the arena and
    // their records staged again each time.
    const std::uint64_t second = ctx->next_serial();
    edit(40, 4);
    EXPECT_EQ(ctx->next_serial(), second);
    edit(40, 5);
    EXPECT_EQ(ctx->next_serial(), second + 1) << "the first update's copies, submitted first";
    edit(150, 6);
    EXPECT_EQ(ctx->next_serial(), second + 2);
    expect_as_fresh(*ctx, tracer, world, palette, "after three updates without a trace");
    // A whole upload drops copies staged for the buffers it replaces.
    edit(100, 7);
    tracer.upload(world, palette);
    expect_as_fresh(*ctx, tracer, world, palette, "after an update and a whole upload");
}

// An update that cannot be made throws, and then the tracer traces nothing, its staged copies
// dropped, until an upload makes it whole again: here the directory's pages outgrow one binding
// (64 KiB: 32 pages of 8^3 tiles) after the update's tiles were already written into the arena
// and the directory's host copy.
TEST(SparseUpdate, AFailedUpdateTracesNothingUntilAnUpload) {
    REQUIRE_VULKAN(ctx);
    const std::int64_t block = 8 * std::int64_t{kTileSize};  // a page's blocks of tiles
    SparseWorld world(Dims{34 * block, 64, 64});
    const Palette palette = Palette::magicavoxel_default();
    const std::uint64_t binding = 64 << 10;
    vk::SparseTracer tracer(*ctx, binding);
    apply_brush(world, brush(BrushOp::place, BrushShape::sphere, {5, 5, 5}, 2, 4));
    tracer.upload(world, palette);
    const vk::RenderOptions view = views(world).front();
    tracer.trace(view);
    // A voxel in each of the 33 other blocks: 34 pages.
    Box changed;
    for (std::int64_t b = 1; b < 34; ++b) {
        const Box one =
            apply_brush(world, brush(BrushOp::place, BrushShape::sphere, {b * block + 9, 9, 9}, 0,
                                     static_cast<std::uint8_t>(b)));
        changed = changed.empty() ? one : hull(changed, one);
    }
    EXPECT_THROW(tracer.update_tiles(world, changed), InputError);
    EXPECT_THROW(tracer.trace(view), std::logic_error);
    EXPECT_THROW(tracer.update_tiles(world, changed), std::logic_error);
    for (std::int64_t b = 1; b < 34; ++b) {
        apply_brush(world, brush(BrushOp::erase, BrushShape::sphere, {b * block + 9, 9, 9}, 0, 1));
    }
    tracer.upload(world, palette);
    expect_as_fresh(*ctx, tracer, world, palette, "uploaded again after a failed update", binding);
}

TEST(SparseUpdate, TilesMadeInEmptySpaceAndEmptiedByErasing) {
    REQUIRE_VULKAN(ctx);
    // Solid only near the origin: most directory blocks (512^3 voxels) hold no page.
    const Dims d{1100, 200, 700};
    SparseWorld world(d);
    world.edit(Box{{0, 0, 0}, {100, 20, 100}},
               [](std::int64_t x, std::int64_t, std::int64_t z, std::uint8_t) {
                   return static_cast<std::uint8_t>(1 + (x + z) % 7);
               });
    const Palette palette = Palette::magicavoxel_default();
    vk::SparseTracer tracer(*ctx);
    tracer.upload(world, palette);
    const std::uint64_t pages = tracer.stats().pages;

    // A sphere in empty space, in a block of its own: new tiles, a new page.
    vk::SparseTileUpdate u = tracer.update_tiles(
        world,
        apply_brush(world, brush(BrushOp::place, BrushShape::sphere, {900, 100, 600}, 20, 9)));
    EXPECT_GE(u.tiles_written, 1u);
    EXPECT_EQ(u.tiles_removed, 0u);
    EXPECT_EQ(tracer.stats().pages, pages + 1);
    expect_as_fresh(*ctx, tracer, world, palette, "sphere placed in empty space");

    // Painting it rewrites its tiles in place in the directory.
    u = tracer.update_tiles(
        world, apply_brush(world, brush(BrushOp::paint, BrushShape::cube, {900, 100, 600}, 10, 4)));
    EXPECT_GE(u.tiles_written, 1u);
    expect_as_fresh(*ctx, tracer, world, palette, "sphere painted");

    // Erasing it all: its tiles leave the directory and its page is freed.
    u = tracer.update_tiles(
        world, apply_brush(world, brush(BrushOp::erase, BrushShape::cube, {900, 100, 600}, 30, 1)));
    EXPECT_GE(u.tiles_removed, 1u);
    EXPECT_EQ(tracer.stats().pages, pages);
    expect_as_fresh(*ctx, tracer, world, palette, "sphere erased");

    // Erasing a tile the upload stored (not one of the arena's) and part of its neighbours.
    u = tracer.update_tiles(
        world, apply_brush(world, brush(BrushOp::erase, BrushShape::cube, {31, 10, 31}, 40, 1)));
    EXPECT_GE(u.tiles_removed, 1u);
    EXPECT_GE(u.tiles_written, 1u);
    expect_as_fresh(*ctx, tracer, world, palette, "an uploaded tile erased");

    // Everything erased: an empty world, all sky; then a voxel again (a freed page reused).
    u = tracer.update_tiles(world, apply_brush(world, brush(BrushOp::erase, BrushShape::cube,
                                                            {100, 100, 100}, 120, 1)));
    EXPECT_EQ(world.tile_count(), 0u);
    EXPECT_EQ(tracer.stats().pages, 0u);
    expect_as_fresh(*ctx, tracer, world, palette, "all erased");
    u = tracer.update_tiles(
        world, apply_brush(world, brush(BrushOp::place, BrushShape::sphere, {600, 50, 300}, 0, 6)));
    EXPECT_EQ(u.tiles_written, 1u);
    EXPECT_EQ(tracer.stats().pages, 1u);
    expect_as_fresh(*ctx, tracer, world, palette, "one voxel placed again");

    // An edit that changes nothing still leaves the image as it is.
    u = tracer.update_tiles(world, Box{});
    EXPECT_EQ(u.tiles_written + u.tiles_removed, 0u);
}

TEST(SparseUpdate, ArenaGrowsAndKeepsItsLiveTiles) {
    REQUIRE_VULKAN(ctx);
    const Dims d{520, 140, 520};
    SparseWorld world = city(d, 77);
    const Palette palette = Palette::magicavoxel_default();
    vk::SparseTracer tracer(*ctx);
    tracer.upload(world, palette);
    // Full tiles (4161 nodes, 256 KiB of materials each) overflow the arena's first capacity
    // (2^18 nodes, 16 MiB) after about 60 tiles; tiles written earlier must survive the growth.
    bool rebuilt_twice = false;
    int rebuilds = 0;
    for (int e = 0; e < 8; ++e) {
        const Int3 c{64 + (e % 4) * 128, 70, 64 + (e / 4) * 256};
        const vk::SparseTileUpdate u = tracer.update_tiles(
            world, apply_brush(world, brush(BrushOp::place, BrushShape::cube, c, 63,
                                            static_cast<std::uint8_t>(10 + e))));
        EXPECT_FALSE(u.whole);
        rebuilds += u.arena_rebuilt ? 1 : 0;
    }
    rebuilt_twice = rebuilds >= 2;  // made once, grown at least once
    EXPECT_TRUE(rebuilt_twice) << rebuilds;
    EXPECT_GT(tracer.stats().arena_material_capacity, std::uint64_t{16} << 20);
    expect_as_fresh(*ctx, tracer, world, palette, "after the arena grew");
    // Rewriting the same tiles again leaves superseded trees behind, dropped at the next growth.
    for (int e = 0; e < 8; ++e) {
        const Int3 c{64 + (e % 4) * 128, 70, 64 + (e / 4) * 256};
        tracer.update_tiles(world, apply_brush(world, brush(BrushOp::paint, BrushShape::cube, c, 63,
                                                            static_cast<std::uint8_t>(40 + e))));
    }
    expect_as_fresh(*ctx, tracer, world, palette, "after repainting");
}

// A world uploaded empty has no chunks: the arena becomes chunk 0, read through chunk 0's
// bindings (one node and one material chunk), which must follow it when it grows.
TEST(SparseUpdate, ArenaOfAWorldUploadedEmpty) {
    REQUIRE_VULKAN(ctx);
    SparseWorld world(Dims{520, 140, 520});
    const Palette palette = Palette::magicavoxel_default();
    vk::SparseTracer tracer(*ctx);
    tracer.upload(world, palette);
    vk::SparseTileUpdate u = tracer.update_tiles(
        world, apply_brush(world, brush(BrushOp::place, BrushShape::sphere, {100, 60, 90}, 9, 5)));
    EXPECT_TRUE(u.arena_rebuilt);
    EXPECT_EQ(tracer.stats().arena_node_chunk, 0u);
    expect_as_fresh(*ctx, tracer, world, palette, "a sphere in the arena, chunk 0");
    int rebuilds = 0;
    for (int e = 0; e < 8; ++e) {
        const Int3 c{64 + (e % 4) * 128, 70, 64 + (e / 4) * 256};
        u = tracer.update_tiles(world,
                                apply_brush(world, brush(BrushOp::place, BrushShape::cube, c, 63,
                                                         static_cast<std::uint8_t>(10 + e))));
        EXPECT_FALSE(u.whole);
        rebuilds += u.arena_rebuilt ? 1 : 0;
    }
    EXPECT_GE(rebuilds, 1);
    expect_as_fresh(*ctx, tracer, world, palette, "after the arena, chunk 0, grew");
}

TEST(SparseUpdate, SeveralBindingsAndTheWholeUploadFallback) {
    REQUIRE_VULKAN(ctx);
    SparseWorld world = city(Dims{300, 150, 270}, 12);
    const Palette palette = Palette::magicavoxel_default();
    std::uint64_t widest = 0;
    for (std::uint32_t t = 0; t < world.tile_count(); ++t) {
        widest = std::max<std::uint64_t>(
            {widest, std::uint64_t{world.node_counts()[t]} * 8, world.material_counts()[t]});
    }
    // Materials in about three bindings (a full tile fits one), the arena after them.
    const std::uint64_t binding =
        std::max<std::uint64_t>({widest, kTileVoxels, world.materials().size() / 3}) / 8 * 8 + 8;
    vk::SparseTracer cut(*ctx, binding);
    cut.upload(world, palette);
    ASSERT_GE(cut.stats().material_chunks, 2u);
    vk::SparseTileUpdate u = cut.update_tiles(
        world,
        apply_brush(world, brush(BrushOp::place, BrushShape::sphere, {100, 30, 90}, 12, 200)));
    EXPECT_FALSE(u.whole);
    EXPECT_EQ(cut.stats().arena_node_chunk, cut.stats().node_chunks);
    expect_as_fresh(*ctx, cut, world, palette, "a sphere, materials in several chunks", binding);

    // The arena cannot hold a cube of 18 mostly full tiles (about 4 MiB) in one binding
    // (a third of the world's materials): uploaded whole.
    ASSERT_LT(binding, std::uint64_t{4} << 20);
    vk::SparseTracer tight(*ctx, binding);
    tight.upload(world, palette);
    u = tight.update_tiles(
        world, apply_brush(world, brush(BrushOp::place, BrushShape::cube, {100, 30, 90}, 40, 3)));
    EXPECT_TRUE(u.whole);
    expect_as_fresh(*ctx, tight, world, palette, "uploaded whole", binding);
}

TEST(SparseUpdate, LongSequenceWithSmallBindings) {
    REQUIRE_VULKAN(ctx);
    // Bindings of a third of the materials: the arena is remade often and, once its live trees
    // outgrow a binding, the world is uploaded whole and the arena starts again.
    SparseWorld world = city(Dims{300, 150, 270}, 55);
    const Palette palette = Palette::magicavoxel_default();
    const std::uint64_t binding =
        std::max<std::uint64_t>(kTileVoxels, world.materials().size() / 3) / 8 * 8 + 8;
    vk::SparseTracer tracer(*ctx, binding);
    tracer.upload(world, palette);
    std::mt19937_64 rng(21);
    std::uniform_int_distribution<std::int64_t> px(0, 299), py(0, 149), pz(0, 269), radius(0, 40),
        op(0, 2);
    int rebuilt = 0, whole = 0;
    for (int e = 0; e < 48; ++e) {
        const auto o = static_cast<BrushOp>(op(rng));
        const Int3 c{px(rng), py(rng), pz(rng)};
        const std::int64_t r = radius(rng);
        const vk::SparseTileUpdate u = tracer.update_tiles(
            world, apply_brush(world, brush(o, BrushShape::cube, c, r,
                                            static_cast<std::uint8_t>(1 + e % 200))));
        rebuilt += u.arena_rebuilt ? 1 : 0;
        whole += u.whole ? 1 : 0;
        if (e % 12 == 11) {
            expect_as_fresh(*ctx, tracer, world, palette, "edit " + std::to_string(e), binding);
        }
    }
    EXPECT_GE(rebuilt, 2);
    EXPECT_GE(whole, 1);
}

TEST(SparseUpdate, DeviceEditsReadBackEqualAFreshUpload) {
    REQUIRE_VULKAN(ctx);
    SparseWorld world = city(Dims{260, 120, 230}, 4);
    const Palette palette = Palette::dissertation();
    ocl::GeneratorOptions options;
    options.format = Format::u8;
    options.max_distance = 6;
    ocl::SparseField field(pocl(), world, palette, ocl::resolve_sparse_options(options, true));
    field.run();
    vk::SparseTracer tracer(*ctx);
    tracer.upload(field.world(), palette);
    // The same brushes again for the host-side check below (draws in a fixed order).
    const auto brushes = [](std::uint64_t seed) {
        std::mt19937_64 rng(seed);
        std::uniform_int_distribution<std::int64_t> px(0, 259), py(0, 119), pz(0, 229),
            radius(0, 9), op(0, 2);
        std::vector<Brush> out;
        for (int e = 0; e < 12; ++e) {
            const auto o = static_cast<BrushOp>(op(rng));
            const Int3 c{px(rng), py(rng), pz(rng)};
            const std::int64_t r = radius(rng);
            // Places in the air too (tiles made above the city), erases and paints.
            out.push_back(brush(o, e % 3 == 0 ? BrushShape::cube : BrushShape::sphere, c, r,
                                static_cast<std::uint8_t>(1 + e)));
        }
        return out;
    };
    int e = 0;
    for (const Brush& b : brushes(8)) {
        field.apply_brush(b);
        const SparseWorld& edited = field.world();
        tracer.update_tiles(edited, brush_bounds(b, edited.dims()));
        if (++e % 4 == 0) {
            expect_as_fresh(*ctx, tracer, edited, palette, "device edit " + std::to_string(e));
        }
    }
    // The host world the tracer was updated from equals the host-side edits of the same brushes.
    SparseWorld host = city(Dims{260, 120, 230}, 4);
    for (const Brush& b : brushes(8)) {
        apply_brush(host, b);
    }
    EXPECT_EQ(host.to_dense().voxels(), field.world().to_dense().voxels());
}

TEST(SparseUpdate, RefusesBeforeUploadAndOtherWorlds) {
    REQUIRE_VULKAN(ctx);
    SparseWorld world(Dims{64, 64, 64});
    vk::SparseTracer tracer(*ctx);
    EXPECT_THROW(tracer.update_tiles(world, Box{{0, 0, 0}, {1, 1, 1}}), std::logic_error);
    tracer.upload(world, Palette());
    const SparseWorld other(Dims{65, 64, 64});
    EXPECT_THROW(tracer.update_tiles(other, Box{{0, 0, 0}, {1, 1, 1}}), std::logic_error);
    // trace() leaves the image on the device; render() after it reads its own image back.
    vk::RenderOptions r;
    r.width = 16;
    r.height = 8;
    r.sky = Rgba{9, 8, 7, 255};
    r.camera = vk::default_camera(world.dims());
    const double ms = tracer.trace(r);
    EXPECT_EQ(ms >= 0, ctx->info().timestamps);
    const vk::Image image = tracer.render(r);
    for (std::size_t p = 0; p < image.rgba.size(); p += 4) {
        ASSERT_EQ(image.rgba[p], 9);
        ASSERT_EQ(image.rgba[p + 1], 8);
        ASSERT_EQ(image.rgba[p + 2], 7);
    }
}

}  // namespace
}  // namespace voxfield::test
