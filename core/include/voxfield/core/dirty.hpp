#pragma once
// Dirty tracking: the voxel boxes that changed since the last take() (an incremental field's
// host world uses it for the boxes the device changed and it has yet to read back), and the
// chunks they overlap.
//
// Semantics:
// - add(box) records a box of voxels (the caller decides what it covers: usually an edit's
//   changed voxels grown by the distance they can influence). The box is clipped to the world
//   first; a box that is empty after clipping is ignored entirely.
// - The pending regions are pairwise disjoint (no voxel is listed twice) and their union
//   covers every voxel of every box added since the last take(). Regions may cover a few more
//   voxels than that union, bounded by `merge_slack` per merge:
//     * a new box and a pending region that overlap or touch (share a face, an edge or a
//       corner) are replaced by their bounding box when that bounding box has at most
//       (1 + merge_slack) times the voxels of their union; this repeats until no pending
//       region qualifies. merge_slack = 0 merges only when the union is exactly a box;
//       merge_slack = infinity always merges overlapping or touching boxes into bounding boxes.
//     * what remains of the new box outside the pending regions is cut into disjoint boxes
//       (at most 6 per overlapped region) and added;
//     * finally, disjoint regions whose union is exactly a box are joined into it.
// - dirty_chunks() are the chunks (ChunkGrid::chunk_index) that overlap a pending region,
//   found by floor division of the region's corners; partial chunks at the world's far faces
//   count like any other.
// - take() returns the pending regions and the dirty chunks at that moment, and clears the
//   pending set.
#include <cstddef>
#include <cstdint>
#include <vector>

#include "voxfield/core/chunks.hpp"

namespace voxfield {

class DirtyTracker {
  public:
    struct Snapshot {
        std::vector<Box> regions;         // as regions()
        std::vector<std::size_t> chunks;  // as dirty_chunks()
    };

    // Throws std::invalid_argument unless merge_slack >= 0 (infinity allowed).
    explicit DirtyTracker(const ChunkGrid& grid, double merge_slack = 0.25);

    const ChunkGrid& grid() const { return grid_; }
    double merge_slack() const { return merge_slack_; }

    void add(const Box& voxels);

    bool empty() const { return pending_.empty(); }
    // The pending regions: disjoint, non-empty, inside the world, sorted by min (z, then y,
    // then x), then by max.
    std::vector<Box> regions() const;
    std::int64_t pending_voxels() const;  // sum of the regions' volumes
    // Ascending indices of the chunks that overlap a pending region.
    std::vector<std::size_t> dirty_chunks() const;

    Snapshot take();

  private:
    bool should_merge(const Box& a, const Box& b) const;
    void insert(Box box);

    ChunkGrid grid_;
    double merge_slack_;
    std::vector<Box> pending_;
};

}  // namespace voxfield
