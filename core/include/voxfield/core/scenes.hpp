#pragma once
// Procedural worlds for tests, benchmarks and the viewer. Deterministic for a given seed.
#include <cstdint>
#include <span>
#include <string>
#include <vector>

#include "voxfield/core/chunks.hpp"
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

// A seeded terrain-and-city world of any size (up to 2^20 per axis): value-noise hills with
// lakes, and where a low-frequency "city" noise is high, 64-voxel blocks between roads holding
// up to four buildings each (facades with windows, roofs, some with a setback tower). Every
// voxel is a function of the seed, the world's dims and its position alone, so any box is
// filled independently: a 4096 x 512 x 4096 world can be written tile by tile without a dense
// array. Materials are the dissertation's colour ids (3 grey rock, 10 green grass, 2 white
// snow, 7 blue water, 1 black road, 4/5/6/11 walls, 8 cyan windows, 9 turquoise roofs).
class CityScene {
  public:
    CityScene(Dims dims, std::uint64_t seed);  // InputError for a zero axis or one over 2^20
    const Dims& dims() const { return dims_; }
    // Writes the voxels of `box` (half-open, non-empty, inside the world) into `out`, which
    // holds box.volume() bytes, x fastest, then y, then z. InputError otherwise.
    void fill(const Box& box, std::span<std::uint8_t> out) const;

  private:
    struct Column;
    struct Cache;
    Column column(std::uint32_t x, std::uint32_t z, Cache& cache) const;
    double terrain(double x, double z, Cache* cache) const;
    struct Corners;
    double noise(double x, double z, std::uint64_t salt, double cell, Corners* corners) const;
    std::uint64_t hash(std::uint64_t a, std::uint64_t b, std::uint64_t c) const;

    Dims dims_;
    std::uint64_t seed_;
    double cell_;  // the terrain's coarsest noise cell, in voxels
};

// The whole city world as one dense World (CityScene::fill over the world's box).
World scene_city(Dims dims, std::uint64_t seed);

// By name: "empty", "spheres", "terrain", "menger", "random" (density 0.1), "sand", "city".
World make_scene(const std::string& name, Dims dims, std::uint64_t seed);
std::vector<std::string> scene_names();

}  // namespace voxfield
