#pragma once
// Exact CPU reference transforms (global semantics, DESIGN §3): distance from each voxel to
// the nearest solid voxel, outside the world empty, kInfinite when the world has no solid.
#include <cstdint>
#include <vector>

#include "voxfield/core/world.hpp"

namespace voxfield {

// Manhattan (L1) distance by separable forward/backward sweeps along x, then y, then z.
std::vector<std::uint32_t> reference_manhattan(const World& world);

// O(N * solids) brute force, for checking the reference on tiny grids.
std::vector<std::uint32_t> brute_force_manhattan(const World& world);

// Chunk-local semantics (the dissertation's, section 4.2.1): each chunk of `chunk` voxels
// (clipped to the world) on its own, everything outside the chunk counted as solid. Every
// value is finite: at most the distance to the chunk's one-voxel shell.
std::vector<std::uint32_t> reference_manhattan_chunked(const World& world, std::uint32_t chunk);

// Algorithm 3 literally: each voxel scans its chunk plus the padding shell. Tiny grids only.
std::vector<std::uint32_t> brute_force_manhattan_chunked(const World& world, std::uint32_t chunk);

}  // namespace voxfield
