#pragma once
// Exact CPU reference transforms (global semantics, DESIGN §3): distance from each voxel to
// the nearest solid voxel, outside the world empty, kInfinite when the world has no solid.
#include <cstdint>
#include <vector>

#include "voxfield/core/metric.hpp"
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

// Every metric and spacing (DESIGN §3), in double precision: the distance from each voxel to
// the nearest solid voxel, +inf when the world has none. Separable, axis by axis, each 1-D
// step a plain minimum over the line searched outwards (no lower-envelope scan), so that it
// shares no logic with the kernels. For unit spacing every L1/L-inf value and every L2
// squared distance is an exact integer, and the L2 value is sqrt of it in double (which
// rounds to the correctly rounded float as well).
std::vector<double> reference_distance(const World& world, Metric metric, const Spacing& spacing);

// The signed field: +distance to the nearest solid for empty voxels, -distance to the
// nearest empty voxel for solid ones, the world surrounded by one layer of empty voxels.
std::vector<double> reference_signed(const World& world, Metric metric, const Spacing& spacing);

// O(N * targets) brute force of both, for checking the reference on tiny grids.
std::vector<double> brute_force_distance(const World& world, Metric metric, const Spacing& spacing);
std::vector<double> brute_force_signed(const World& world, Metric metric, const Spacing& spacing);

// The feature transform with SciPy's ties (distance_transform_edt's): each voxel's nearest
// solid voxel as its Dims::index, -1 when the world has none. Separable as
// reference_distance is, along x, y, then z, each pass taking of its candidates the least
// (partial distance, target's (x, y, z)), x compared first; exact for unit spacing. For L1
// and L2 that is the nearest solid of lowest (x, y, z); for L-inf, where a line's partial
// distance hides its other equally near targets, the passes' choice (the kernels' L-inf
// ties go by position instead).
std::vector<std::int64_t> reference_features(const World& world, Metric metric,
                                             const Spacing& spacing);

// O(N * solids) brute force: the nearest solid of lowest (x, y, z), for checking the
// reference on tiny grids.
std::vector<std::int64_t> brute_force_features(const World& world, Metric metric,
                                               const Spacing& spacing);

}  // namespace voxfield
