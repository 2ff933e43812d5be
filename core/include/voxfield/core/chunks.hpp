#pragma once
// Chunk geometry: a world cut into cubes of C voxels per side (C a power of two); chunks
// at the far faces are clipped to the world.
#include <cstddef>
#include <cstdint>
#include <vector>

#include "voxfield/core/world.hpp"

namespace voxfield {

struct Int3 {
    std::int64_t x = 0, y = 0, z = 0;
    friend bool operator==(const Int3&, const Int3&) = default;
};

// Half-open integer box [min, max).
struct Box {
    Int3 min, max;
    bool empty() const { return min.x >= max.x || min.y >= max.y || min.z >= max.z; }
    std::int64_t volume() const;
    friend bool operator==(const Box&, const Box&) = default;
};

Box intersect(const Box& a, const Box& b);
// The smallest box holding both (an empty one adds nothing).
Box hull(const Box& a, const Box& b);

// Boxes to process one launch each, merged while a merge adds fewer voxels than a launch costs
// (`launch_voxels`: a launch's overhead in voxels of work) and always down to `max_boxes`: the
// result covers every voxel of `boxes` (and possibly more). Empty boxes are dropped. Greedy:
// the pair whose hull adds the fewest voxels first. More than 2 * max_boxes boxes give their
// hull at once.
std::vector<Box> merge_for_launches(std::vector<Box> boxes, std::int64_t launch_voxels,
                                    std::size_t max_boxes);

// Floor division for negative coordinates too (floor_div(-1, 8) == -1).
std::int64_t floor_div(std::int64_t a, std::int64_t b);

class ChunkGrid {
  public:
    // Throws InputError unless chunk is a power of two >= 1.
    ChunkGrid(Dims world, std::uint32_t chunk);

    std::uint32_t chunk() const { return chunk_; }
    const Dims& world() const { return world_; }
    Dims chunks() const { return chunks_; }  // ceil(world / chunk) per axis
    std::size_t chunk_count() const { return chunks_.count(); }

    Int3 chunk_of(Int3 voxel) const;            // floor division, may lie outside the grid
    Box voxels_of(Int3 chunk) const;            // clipped to the world
    std::size_t chunk_index(Int3 chunk) const;  // x fastest over the chunk grid
    // Chunks (inclusive min, exclusive max) overlapping a voxel box, clipped to the grid.
    Box chunks_overlapping(const Box& voxels) const;

  private:
    Dims world_;
    std::uint32_t chunk_;
    Dims chunks_;
};

// Throws InputError unless `chunk` is a power of two no larger than any axis of `world`
// (the checks a user-given --chunk must pass before chunk-local work starts).
void require_chunk_fits(Dims world, std::uint32_t chunk);

// The dissertation's level-of-detail focus (section 4.6): the chunks within `size` chunks of
// `centre` along every axis (inclusive), in chunk coordinates.
struct Focus {
    Int3 centre;
    std::int64_t size = 0;
};

// The focus as a half-open box of chunk coordinates, clipped to the grid. Throws InputError
// when the centre lies outside the chunk grid or the size is negative.
Box focus_chunks(const ChunkGrid& grid, const Focus& focus);

}  // namespace voxfield
