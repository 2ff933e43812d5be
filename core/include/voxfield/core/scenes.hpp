#pragma once
// Procedural worlds for tests, benchmarks and the viewer. Deterministic for a given seed.
#include <cstdint>
#include <string>
#include <vector>

#include "voxfield/core/world.hpp"

namespace voxfield {

World scene_empty(Dims dims);
// The dissertation's scene: a one-voxel floor at y = 0 plus `spheres` random spheres.
World scene_floor_spheres(Dims dims, std::uint64_t seed, std::uint32_t spheres = 16);
// A heightmap terrain from summed sines with random phases, solid below the height.
World scene_terrain(Dims dims, std::uint64_t seed);
// A Menger sponge fitted to the world (level chosen from the smallest axis).
World scene_menger(Dims dims);
// Each voxel solid with probability `density` (0..1), palette index 1..255.
World scene_random(Dims dims, double density, std::uint64_t seed);

// By name: "empty", "spheres", "terrain", "menger", "random" (density 0.1).
World make_scene(const std::string& name, Dims dims, std::uint64_t seed);
std::vector<std::string> scene_names();

}  // namespace voxfield
