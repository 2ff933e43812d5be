#pragma once
// Editing logic of the viewer, free of any windowing API: the brush a click makes from a
// pick, brush size from the scroll wheel, undo/redo of whole strokes, and the reproducible
// random edits of the dissertation's benchmark mode.
#include <cstddef>
#include <cstdint>
#include <deque>
#include <map>
#include <optional>
#include <string>
#include <vector>

#include "voxfield/core/brush.hpp"
#include "voxfield/core/pick.hpp"

namespace voxfield {

// What a click does: place (left mouse) at the hit voxel + its face normal, erase (right
// mouse) at the hit voxel, paint (paint mode) recolours around the hit voxel.
enum class Tool { place, erase, paint };
std::string to_string(Tool tool);

struct BrushSettings {
    BrushShape shape = BrushShape::sphere;
    std::int64_t size = 1;      // >= 1; radius = size / 2 (the dissertation's), so 1 and 2 are
                                // a single voxel and a radius-1 brush respectively
    std::uint8_t material = 1;  // 1..255 for place and paint
};

inline constexpr std::int64_t kMaxBrushSize = 256;

// The brush for `tool` at `hit`. Place is centred on hit.voxel + hit.normal (the empty
// voxel in front of the face looked at; nullopt when the normal is {0,0,0}, i.e. the camera
// is inside the solid), erase and paint on hit.voxel.
std::optional<Brush> brush_for_pick(Tool tool, const BrushSettings& settings, const PickHit& hit);

// The size after `scroll` wheel notches (positive grows), clamped to 1..max_size.
std::int64_t scroll_brush_size(std::int64_t size, double scroll, std::int64_t max_size);

// A stroke's net effect: every voxel it changed once, with its value before the stroke and
// after it (voxels it changed back to their original value are dropped), ascending index.
using VoxelChanges = std::vector<VoxelChange>;

// Sets every listed voxel to `after` and returns what changed, as apply_brush does (changes
// with before == after are skipped; bounds over the rest). Throws InputError (leaving the
// world untouched) when a voxel does not hold `before` or an index is outside the world.
EditResult apply_changes(World& world, const VoxelChanges& changes);

// Undo/redo of whole strokes (a stroke: everything from mouse down to mouse up). Recording
// merges the EditResults of the stroke's brushes per voxel (first `before`, last `after`).
// undo() returns the changes that restore the state before the newest stroke (before and
// after swapped), redo() those that reapply it; apply them to the world (apply_changes, or
// IncrementalField::apply_changes for the world and its field). A new stroke clears the redo list.
// At most `max_strokes` strokes and `max_voxels` recorded voxel changes are kept (the oldest
// strokes are dropped first).
class UndoStack {
  public:
    explicit UndoStack(std::size_t max_strokes = 256, std::size_t max_voxels = 64u << 20);

    void begin_stroke();
    // Adds one brush's result to the current stroke (begins one when none is open).
    void record(const EditResult& result);
    // Closes the stroke; returns true when it changed anything (it is then undoable).
    bool end_stroke();
    bool in_stroke() const { return open_; }

    bool can_undo() const { return !undo_.empty(); }
    bool can_redo() const { return !redo_.empty(); }
    std::size_t undo_count() const { return undo_.size(); }
    std::size_t redo_count() const { return redo_.size(); }
    // Closes an open stroke first. Empty when there is nothing to undo / redo.
    VoxelChanges undo();
    VoxelChanges redo();
    void clear();

  private:
    void trim();

    std::size_t max_strokes_, max_voxels_;
    bool open_ = false;
    std::map<std::size_t, VoxelChange> current_;
    std::deque<VoxelChanges> undo_, redo_;
    std::size_t voxels_ = 0;  // recorded in undo_ and redo_
};

// The dissertation's benchmark edits, reproducible: a sphere at a uniformly random voxel
// centre of the world, size uniform in 1..chunk-1 (radius = size / 2), material uniform in
// 0..11 where 0 (about 1 in 12) erases and 1..11 place the dissertation's colours. The same
// seed gives the same sequence on every run and platform (splitmix64, no std distributions).
// `view --benchmark` and `bench --suite edits` both draw their edits from it.
class RandomEdits {
  public:
    // chunk >= 2.
    RandomEdits(Dims dims, std::uint32_t chunk, std::uint64_t seed);
    Brush next();
    // The protocol's size (1..chunk-1) of the last edit next() gave; its radius is size / 2.
    std::int64_t last_size() const { return last_size_; }

  private:
    std::uint64_t below(std::uint64_t n);  // uniform in [0, n)

    Dims dims_;
    std::uint32_t chunk_;
    std::uint64_t state_;
    std::int64_t last_size_ = 0;
};

}  // namespace voxfield
