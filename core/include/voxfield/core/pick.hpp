#pragma once
// Picking: the exact voxel hit by a ray, by an Amanatides-Woo DDA in double precision that
// starts at the ray's origin (never behind it) and recomputes every boundary crossing from
// the integer cell (no accumulated error, no rounded inverse direction: the dissertation's
// picking bugs).
#include <cstdint>
#include <functional>
#include <limits>
#include <optional>

#include "voxfield/core/camera.hpp"
#include "voxfield/core/chunks.hpp"
#include "voxfield/core/world.hpp"

namespace voxfield {

struct PickHit {
    Int3 voxel;           // the first solid voxel along the ray
    Int3 normal;          // the face the ray entered it through (unit axis vector, pointing
                          // back toward the ray); {0,0,0} when the origin is inside it
    double distance = 0;  // ray parameter of the entry point (|direction| units)
    friend bool operator==(const PickHit&, const PickHit&) = default;
};

// The first solid voxel (value != 0) that the ray origin + t * direction, t >= 0, enters,
// within t <= max_distance. Voxel (x, y, z) is the cube [x, x+1) x [y, y+1) x [z, z+1).
// Origins outside the world are clipped to the world box first. A ray that touches a voxel
// only along an edge or a corner steps through one of its neighbours first (ties step x,
// then y, then z). nullopt for a zero or non-finite direction, a non-finite origin, or no
// hit.
std::optional<PickHit> pick_voxel(const World& world, const Vec3d& origin, const Vec3d& direction,
                                  double max_distance = std::numeric_limits<double>::infinity());

// The voxel lookup a pick walks: true when voxel (x, y, z), inside the box, is solid.
using SolidVoxel = std::function<bool(std::uint32_t x, std::uint32_t y, std::uint32_t z)>;

// pick_voxel over any voxel storage of dimensions `dims`: the same walk, clipping and ties,
// asking `solid` about each cell it enters (dense World, SparseWorld, ...).
std::optional<PickHit> pick_solid_voxel(
    const Dims& dims, const SolidVoxel& solid, const Vec3d& origin, const Vec3d& direction,
    double max_distance = std::numeric_limits<double>::infinity());

}  // namespace voxfield
