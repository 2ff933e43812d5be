// pipeline::Scene on PoCL: the one owner of a world, its device copy, its field, the history
// and the simulation. Sand steps in place on the device keep the field equal to a full
// regeneration and the host world (read back lazily) equal to the CPU reference; brushes,
// undo and redo go through the same protocol.
#include <gtest/gtest.h>

#include <array>
#include <cstdint>
#include <random>
#include <string>
#include <vector>

#include "../cl/cl_test_util.hpp"
#include "voxfield/cl/generator.hpp"
#include "voxfield/core/error.hpp"
#include "voxfield/core/format.hpp"
#include "voxfield/core/palette.hpp"
#include "voxfield/core/reference.hpp"
#include "voxfield/core/sand.hpp"
#include "voxfield/core/scenes.hpp"
#include "voxfield/pipeline/scene.hpp"

namespace voxfield::test {
namespace {

ocl::GeneratorOptions options_for(Metric metric, Format format, Dims dims) {
    ocl::GeneratorOptions o;
    o.metric = metric;
    o.format = format;
    return ocl::resolve_options(o, dims);
}

std::array<std::size_t, 256> histogram(const World& w) {
    std::array<std::size_t, 256> h{};
    for (const std::uint8_t v : w.voxels()) {
        ++h[v];
    }
    return h;
}

// Sand falling onto terrain, in a world small enough to check after every step.
World sandy_terrain(Dims dims, std::uint64_t seed) {
    World w = make_scene("terrain", dims, seed);
    std::mt19937_64 rng(seed);
    for (std::uint32_t z = 0; z < dims.z; ++z) {
        for (std::uint32_t y = dims.y / 2; y < dims.y; ++y) {
            for (std::uint32_t x = 0; x < dims.x; ++x) {
                if (w.at(x, y, z) == 0 && rng() % 5 == 0) {
                    w.set(x, y, z, rng() % 3 == 0 ? SandRules{}.water : SandRules{}.sand);
                }
            }
        }
    }
    return w;
}

TEST(Scene, SandStepsKeepTheFieldAndTheWorldExact) {
    const Palette palette = Palette::magicavoxel_default();
    for (const auto& [metric, format] :
         {std::pair{Metric::manhattan, Format::u16}, std::pair{Metric::chebyshev, Format::u8},
          std::pair{Metric::euclidean, Format::f32}}) {
        const World start = sandy_terrain(Dims{30, 26, 22}, 3);
        const ocl::GeneratorOptions o = options_for(metric, format, start.dims());
        pipeline::Scene scene(pocl(), start, palette, o);
        World ref = start;
        for (std::uint64_t step = 0; step < 20; ++step) {
            const VoxelChanges want = sand_step(ref, SandRules{}, 11, step);
            const pipeline::SceneUpdate u = scene.step_sand(SandRules{}, 11, step);
            ASSERT_EQ(u.voxels_changed, want.size()) << to_string(metric) << ", step " << step;
            EXPECT_GE(u.simulate_ms, 0.0);
            const auto full = ocl::generate(pocl(), ref, palette, o).bytes;
            ASSERT_EQ(first_difference(scene.read_field(), full, format, start.dims()), "")
                << to_string(metric) << ", after step " << step;
        }
        EXPECT_EQ(scene.world().voxels(), ref.voxels()) << to_string(metric);
        EXPECT_EQ(histogram(scene.world()), histogram(start)) << to_string(metric);
    }
}

TEST(Scene, StrokesUndoAndRedoThroughTheScene) {
    const World start = make_scene("spheres", Dims{32, 24, 28}, 2);
    const ocl::GeneratorOptions o = options_for(Metric::manhattan, Format::u16, start.dims());
    pipeline::Scene scene(pocl(), start, Palette(), o);
    const Brush a{BrushOp::place, BrushShape::sphere, {10, 12, 10}, 4, 7};
    const Brush b{BrushOp::erase, BrushShape::cube, {12, 12, 12}, 2, 0};
    scene.history().begin_stroke();
    scene.apply({a}, true);
    scene.apply({b}, true);
    EXPECT_TRUE(scene.history().end_stroke());
    World edited = start;
    apply_brush(edited, a);
    apply_brush(edited, b);
    EXPECT_EQ(scene.world().voxels(), edited.voxels());
    EXPECT_FALSE(scene.undo().changed.empty());
    EXPECT_EQ(scene.world().voxels(), start.voxels());
    EXPECT_EQ(scene.read_field(), ocl::generate(pocl(), start, Palette(), o).bytes);
    scene.redo();
    EXPECT_EQ(scene.world().voxels(), edited.voxels());
    EXPECT_EQ(scene.read_field(), ocl::generate(pocl(), edited, Palette(), o).bytes);
    EXPECT_TRUE(scene.redo().changed.empty());  // nothing left to redo
}

TEST(Scene, OneUndoRevertsAWholeBatch) {
    // Three brushes far apart in one undoable batch (one field update): one undo restores the
    // world and the field the batch found, for every metric, checked against the CPU reference;
    // redo brings the whole batch back.
    const Palette palette = Palette::magicavoxel_default();
    const World start = make_scene("spheres", Dims{48, 40, 44}, 5);
    std::vector<Brush> batch{{BrushOp::place, BrushShape::sphere, {6, 30, 6}, 4, 201},
                             {BrushOp::place, BrushShape::cube, {41, 8, 38}, 3, 202}};
    // The middle brush erases around a solid voxel of the scene.
    for (std::size_t i = start.voxels().size() / 2; i < start.voxels().size(); ++i) {
        if (start.voxels()[i] != 0) {
            const Dims d = start.dims();
            const auto at = [](std::size_t v) { return static_cast<std::int64_t>(v); };
            const Int3 p{at(i % d.x), at(i / d.x % d.y), at(i / d.x / d.y)};
            batch.insert(batch.begin() + 1, Brush{BrushOp::erase, BrushShape::cube, p, 3, 0});
            break;
        }
    }
    ASSERT_EQ(batch.size(), 3u);
    World edited = start;
    for (const Brush& b : batch) {
        ASSERT_TRUE(apply_brush(edited, b).changed());
    }
    for (const auto& [metric, format] :
         {std::pair{Metric::manhattan, Format::u16}, std::pair{Metric::chebyshev, Format::u8},
          std::pair{Metric::euclidean, Format::f32}}) {
        const ocl::GeneratorOptions o = options_for(metric, format, start.dims());
        const auto reference = [&](const World& w) {
            return encode_real_field(reference_distance(w, metric, o.spacing), w, palette, format);
        };
        pipeline::Scene scene(pocl(), start, palette, o);
        scene.history().begin_stroke();
        scene.apply(batch, true);
        EXPECT_TRUE(scene.history().end_stroke());
        ASSERT_TRUE(scene.world().voxels() == edited.voxels()) << to_string(metric);
        EXPECT_FALSE(scene.undo().changed.empty());
        EXPECT_TRUE(scene.world().voxels() == start.voxels()) << to_string(metric);
        EXPECT_EQ(first_difference(scene.read_field(), reference(start), format, start.dims()), "")
            << to_string(metric) << ", after the undo";
        EXPECT_FALSE(scene.history().can_undo());
        scene.redo();
        EXPECT_TRUE(scene.world().voxels() == edited.voxels()) << to_string(metric);
        EXPECT_EQ(first_difference(scene.read_field(), reference(edited), format, start.dims()), "")
            << to_string(metric) << ", after the redo";
    }
}

TEST(Scene, OnlyTheStrokesBrushesOfABatchAreRecorded) {
    // apply_stroke: the first brush is the stroke's, the second a scripted edit of the same
    // frame; the undo reverts the first alone.
    const World start = make_scene("spheres", Dims{32, 24, 28}, 2);
    const ocl::GeneratorOptions o = options_for(Metric::manhattan, Format::u16, start.dims());
    pipeline::Scene scene(pocl(), start, Palette(), o);
    const Brush stroke{BrushOp::place, BrushShape::cube, {5, 18, 5}, 3, 4};
    const Brush scripted{BrushOp::place, BrushShape::cube, {26, 4, 22}, 3, 6};
    scene.history().begin_stroke();
    scene.apply_stroke({stroke, scripted}, 1);
    scene.history().end_stroke();
    World want = start;
    apply_brush(want, scripted);
    scene.undo();
    EXPECT_TRUE(scene.world().voxels() == want.voxels());
    EXPECT_EQ(first_difference(scene.read_field(),
                               encode_field(reference_manhattan(want), want, Palette(), o.format),
                               o.format, want.dims()),
              "");
}

TEST(Scene, UndoOfAStrokeTheSandMovedClearsTheHistory) {
    // A stroke places sand in the air; the simulation then moves it (changes the history did
    // not record): its undo no longer applies, says so, and the history is cleared.
    World start(Dims{16, 16, 16});
    for (std::uint32_t z = 0; z < 16; ++z) {
        for (std::uint32_t x = 0; x < 16; ++x) {
            start.set(x, 0, z, 1);
        }
    }
    const ocl::GeneratorOptions o = options_for(Metric::manhattan, Format::u16, start.dims());
    pipeline::Scene scene(pocl(), start, Palette(), o);
    scene.apply({{BrushOp::place, BrushShape::cube, {8, 10, 8}, 1, SandRules{}.sand}}, true);
    scene.history().end_stroke();
    World ref = scene.world();
    for (std::uint64_t step = 0; step < 4; ++step) {
        sand_step(ref, SandRules{}, 1, step);
        scene.step_sand(SandRules{}, 1, step);
    }
    EXPECT_THROW(scene.undo(), InputError);
    EXPECT_FALSE(scene.history().can_undo());
    EXPECT_EQ(scene.world().voxels(), ref.voxels());
    EXPECT_EQ(scene.read_field(), ocl::generate(pocl(), ref, Palette(), o).bytes);
}

TEST(Scene, TheHostWorldIsReadBackOnlyWhenRead) {
    const World start = sandy_terrain(Dims{20, 18, 16}, 4);
    const ocl::GeneratorOptions o = options_for(Metric::manhattan, Format::u16, start.dims());
    pipeline::Scene scene(pocl(), start, Palette(), o);
    World ref = start;
    for (std::uint64_t step = 0; step < 6; ++step) {
        sand_step(ref, SandRules{}, 3, step);
        scene.step_sand(SandRules{}, 3, step);
    }
    ASSERT_NE(ref.voxels(), start.voxels());
    EXPECT_EQ(scene.last_read_world().voxels(), start.voxels());  // not read back yet
    EXPECT_EQ(scene.world().voxels(), ref.voxels());
    EXPECT_EQ(scene.last_read_world().voxels(), ref.voxels());
}

TEST(Scene, BrushesBetweenStepsSeeTheSteppedWorld) {
    // The host world is read back only when something reads it: a brush between steps starts
    // from the world the steps left, and the steps after it from the brush's.
    const World start = sandy_terrain(Dims{24, 20, 18}, 8);
    const ocl::GeneratorOptions o = options_for(Metric::manhattan, Format::packed32, start.dims());
    const Palette palette = Palette::magicavoxel_default();
    pipeline::Scene scene(pocl(), start, palette, o);
    World ref = start;
    std::mt19937_64 rng(5);
    for (std::uint64_t step = 0; step < 16; ++step) {
        sand_step(ref, SandRules{}, 2, step);
        scene.step_sand(SandRules{}, 2, step);
        if (step % 4 == 3) {
            const Brush brush{
                rng() % 2 == 0 ? BrushOp::place : BrushOp::erase,
                BrushShape::sphere,
                {static_cast<std::int64_t>(rng() % 24), 12, static_cast<std::int64_t>(rng() % 18)},
                3,
                SandRules{}.sand};
            const pipeline::SceneUpdate u = scene.apply({brush});
            const EditResult want = apply_brush(ref, brush);
            ASSERT_EQ(u.stats.edits.size(), 1u);
            EXPECT_EQ(u.stats.edits[0].changes, want.changes) << "step " << step;
        }
        ASSERT_EQ(first_difference(scene.read_field(), ocl::generate(pocl(), ref, palette, o).bytes,
                                   o.format, ref.dims()),
                  "")
            << "after step " << step;
    }
    EXPECT_EQ(scene.world().voxels(), ref.voxels());
}

}  // namespace
}  // namespace voxfield::test
