#include <gtest/gtest.h>

#include <algorithm>
#include <set>
#include <vector>

#include "voxfield/core/error.hpp"
#include "voxfield/core/scenes.hpp"
#include "voxfield/core/undo.hpp"

namespace voxfield {
namespace {

TEST(BrushForPick, PlaceEraseAndPaint) {
    PickHit hit;
    hit.voxel = {5, 0, 7};
    hit.normal = {0, 1, 0};
    BrushSettings s;
    s.size = 5;  // radius 2
    s.material = 9;
    auto b = brush_for_pick(Tool::place, s, hit);
    ASSERT_TRUE(b);
    EXPECT_EQ(b->op, BrushOp::place);
    EXPECT_EQ(b->centre, (Int3{5, 1, 7}));  // on top of the face looked at
    EXPECT_EQ(b->radius, 2);
    EXPECT_EQ(b->material, 9);
    EXPECT_EQ(b->shape, BrushShape::sphere);
    b = brush_for_pick(Tool::erase, s, hit);
    ASSERT_TRUE(b);
    EXPECT_EQ(b->op, BrushOp::erase);
    EXPECT_EQ(b->centre, (Int3{5, 0, 7}));
    s.shape = BrushShape::cube;
    s.size = 1;
    b = brush_for_pick(Tool::paint, s, hit);
    ASSERT_TRUE(b);
    EXPECT_EQ(b->op, BrushOp::paint);
    EXPECT_EQ(b->centre, (Int3{5, 0, 7}));
    EXPECT_EQ(b->radius, 0);
    EXPECT_EQ(b->shape, BrushShape::cube);
    // Inside a solid there is no face to place against.
    hit.normal = {0, 0, 0};
    EXPECT_FALSE(brush_for_pick(Tool::place, s, hit));
    EXPECT_TRUE(brush_for_pick(Tool::erase, s, hit));
}

TEST(BrushForPick, ScrollSize) {
    EXPECT_EQ(scroll_brush_size(4, 1, 32), 5);
    EXPECT_EQ(scroll_brush_size(4, -2, 32), 2);
    EXPECT_EQ(scroll_brush_size(1, -5, 32), 1);
    EXPECT_EQ(scroll_brush_size(31, 4, 32), 32);
    EXPECT_EQ(scroll_brush_size(4, 0.4, 32), 4);  // a fraction of a notch (touchpads)
}

TEST(UndoStack, StrokesUndoAndRedoExactly) {
    World w = scene_floor_spheres(Dims{24, 16, 20}, 3, 4);
    const World original = w;
    UndoStack stack;
    // Stroke 1: a drag of three overlapping place brushes.
    stack.begin_stroke();
    for (int i = 0; i < 3; ++i) {
        Brush b{BrushOp::place, BrushShape::sphere, {6 + 2 * i, 4, 8}, 3, std::uint8_t(20 + i)};
        stack.record(apply_brush(w, b));
    }
    EXPECT_TRUE(stack.end_stroke());
    const World after1 = w;
    // Stroke 2: an erase cube.
    stack.begin_stroke();
    stack.record(apply_brush(w, Brush{BrushOp::erase, BrushShape::cube, {8, 1, 8}, 2, 1}));
    EXPECT_TRUE(stack.end_stroke());
    const World after2 = w;
    EXPECT_EQ(stack.undo_count(), 2u);

    VoxelChanges inv = stack.undo();
    ASSERT_FALSE(inv.empty());
    apply_changes(w, inv);
    EXPECT_EQ(w.voxels(), after1.voxels());
    inv = stack.undo();
    apply_changes(w, inv);
    EXPECT_EQ(w.voxels(), original.voxels());
    EXPECT_FALSE(stack.can_undo());
    EXPECT_TRUE(stack.undo().empty());
    EXPECT_EQ(stack.redo_count(), 2u);

    apply_changes(w, stack.redo());
    EXPECT_EQ(w.voxels(), after1.voxels());
    // A new stroke drops the redo list.
    stack.record(apply_brush(w, Brush{BrushOp::paint, BrushShape::sphere, {8, 0, 8}, 4, 77}));
    EXPECT_TRUE(stack.end_stroke());
    EXPECT_FALSE(stack.can_redo());
    apply_changes(w, stack.undo());
    EXPECT_EQ(w.voxels(), after1.voxels());
    (void)after2;
}

TEST(UndoStack, MergesPerVoxelAndDropsNoOps) {
    World w(Dims{8, 8, 8});
    UndoStack stack;
    stack.begin_stroke();
    stack.record(apply_brush(w, Brush{BrushOp::place, BrushShape::cube, {3, 3, 3}, 1, 5}));
    stack.record(apply_brush(w, Brush{BrushOp::place, BrushShape::cube, {3, 3, 3}, 0, 6}));
    stack.record(apply_brush(w, Brush{BrushOp::erase, BrushShape::cube, {4, 4, 4}, 0, 1}));
    EXPECT_TRUE(stack.end_stroke());
    const VoxelChanges inv = stack.undo();
    ASSERT_EQ(inv.size(), 26u);  // 27 placed, one erased again within the stroke
    for (const VoxelChange& c : inv) {
        EXPECT_EQ(c.after, 0);
        EXPECT_TRUE(c.before == 5 || c.before == 6);
        EXPECT_NE(c.index, w.dims().index(4, 4, 4));
    }
    EXPECT_EQ(inv[13 - 0].before, 6);  // the centre (3,3,3) is the 14th index of the cube
    // A stroke that changed nothing is not undoable.
    stack.begin_stroke();
    stack.record(apply_brush(w, Brush{BrushOp::erase, BrushShape::cube, {0, 0, 0}, 0, 1}));
    EXPECT_FALSE(stack.end_stroke());
    EXPECT_FALSE(stack.can_undo());
}

TEST(UndoStack, ApplyChangesReportsLikeABrush) {
    World w = scene_random(Dims{10, 12, 9}, 0.3, 4);
    const World original = w;
    UndoStack stack;
    stack.record(apply_brush(w, Brush{BrushOp::place, BrushShape::sphere, {5, 5, 5}, 3, 200}));
    stack.record(apply_brush(w, Brush{BrushOp::erase, BrushShape::sphere, {3, 6, 4}, 2, 1}));
    stack.record(apply_brush(w, Brush{BrushOp::paint, BrushShape::cube, {7, 2, 2}, 1, 9}));
    stack.end_stroke();
    const World edited = w;
    const VoxelChanges inv = stack.undo();
    const EditResult r = apply_changes(w, inv);
    EXPECT_EQ(w.voxels(), original.voxels());
    // The summary agrees with the world: every change, counted by kind, inside its bounds.
    EXPECT_EQ(r.changes.size(), inv.size());
    EXPECT_EQ(r.became_solid + r.became_empty + r.recoloured, r.changes.size());
    EXPECT_GT(r.became_solid, 0u);
    EXPECT_GT(r.became_empty, 0u);
    EXPECT_GT(r.recoloured, 0u);
    Int3 lo{99, 99, 99}, hi{0, 0, 0};
    for (const VoxelChange& c : r.changes) {
        const Int3 p{static_cast<std::int64_t>(c.index % 10),
                     static_cast<std::int64_t>(c.index / 10 % 12),
                     static_cast<std::int64_t>(c.index / 120)};
        lo = {std::min(lo.x, p.x), std::min(lo.y, p.y), std::min(lo.z, p.z)};
        hi = {std::max(hi.x, p.x + 1), std::max(hi.y, p.y + 1), std::max(hi.z, p.z + 1)};
        EXPECT_EQ(original.voxels()[c.index], c.after);
        EXPECT_EQ(edited.voxels()[c.index], c.before);
    }
    EXPECT_EQ(r.bounds, (Box{lo, hi}));
    EXPECT_TRUE(r.occupancy_changed());
    EXPECT_TRUE(std::is_sorted(
        r.changes.begin(), r.changes.end(),
        [](const VoxelChange& a, const VoxelChange& b) { return a.index < b.index; }));
    apply_changes(w, stack.redo());
    EXPECT_EQ(w.voxels(), edited.voxels());
    // No-op entries are dropped.
    EXPECT_FALSE(apply_changes(w, {{0, w.voxels()[0], w.voxels()[0]}}).changed());
}

TEST(UndoStack, ApplyChangesChecksTheWorld) {
    World w(Dims{4, 4, 4});
    EXPECT_THROW(apply_changes(w, {{3, 1, 0}}), InputError);  // voxel 3 holds 0, not 1
    EXPECT_THROW(apply_changes(w, {{64, 0, 1}}), InputError);
    EXPECT_EQ(w.solid_count(), 0u);
}

TEST(UndoStack, KeepsAtMostMaxStrokes) {
    World w(Dims{8, 8, 8});
    UndoStack stack(3);
    for (int i = 0; i < 5; ++i) {
        stack.record(apply_brush(
            w, Brush{BrushOp::place, BrushShape::cube, {i, 0, 0}, 0, std::uint8_t(i + 1)}));
        stack.end_stroke();
    }
    EXPECT_EQ(stack.undo_count(), 3u);
    for (int i = 0; i < 3; ++i) {
        apply_changes(w, stack.undo());
    }
    EXPECT_EQ(w.solid_count(), 2u);  // the two oldest strokes can no longer be undone
}

TEST(RandomEdits, ReproducibleDissertationProtocol) {
    const Dims dims{64, 32, 48};
    RandomEdits a(dims, 16, 6683787), b(dims, 16, 6683787), c(dims, 16, 1);
    std::set<std::int64_t> radii;
    int erases = 0, differ = 0;
    const int n = 6000;
    for (int i = 0; i < n; ++i) {
        const Brush x = a.next(), y = b.next(), z = c.next();
        EXPECT_EQ(x, y);
        differ += x == z ? 0 : 1;
        EXPECT_EQ(x.shape, BrushShape::sphere);
        EXPECT_TRUE(dims.contains(x.centre.x, x.centre.y, x.centre.z));
        EXPECT_GE(x.radius, 0);
        EXPECT_LE(x.radius, 7);  // size 1..15, radius = size / 2
        radii.insert(x.radius);
        if (x.op == BrushOp::erase) {
            ++erases;
        } else {
            EXPECT_EQ(x.op, BrushOp::place);
            EXPECT_GE(x.material, 1);
            EXPECT_LE(x.material, 11);
        }
    }
    EXPECT_EQ(radii.size(), 8u);
    EXPECT_NEAR(double(erases) / n, 1.0 / 12, 0.015);
    EXPECT_GT(differ, n - 10);
    // A fresh generator with the same seed starts the same sequence again.
    RandomEdits first(dims, 16, 6683787);
    const Brush f = first.next();
    RandomEdits again(dims, 16, 6683787);
    EXPECT_EQ(again.next(), f);
    EXPECT_THROW(RandomEdits(dims, 1, 0), InputError);
}

}  // namespace
}  // namespace voxfield
