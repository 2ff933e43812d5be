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

}  // namespace voxfield
