#pragma once
// Brushes that edit a world (DESIGN §4, `replay`): place / erase / paint with a sphere or a
// cube, clipped to the world, reporting exactly which voxels changed.
#include <cstddef>
#include <cstdint>
#include <string>
#include <vector>

#include "voxfield/core/chunks.hpp"
#include "voxfield/core/world.hpp"

namespace voxfield {

enum class BrushOp {
    place,  // sets every voxel of the shape to `material` (1..255)
    erase,  // sets every voxel of the shape to 0 (air); `material` is ignored
    paint,  // sets solid voxels of the shape to `material` (1..255); air stays air
};
enum class BrushShape {
    sphere,  // dx² + dy² + dz² <= R²
    cube,    // max(|dx|, |dy|, |dz|) <= R, i.e. (2R+1)³ voxels
};

std::string to_string(BrushOp op);        // "place", "erase", "paint"
std::string to_string(BrushShape shape);  // "sphere", "cube"

// The largest radius a brush may have (the edit file's int32 limit; keeps R² exact).
inline constexpr std::int64_t kMaxBrushRadius = 2147483647;

// dx, dy, dz are the offsets of a voxel (x, y, z) from `centre`. The centre may lie outside
// the world; only voxels inside the world are ever touched.
struct Brush {
    BrushOp op = BrushOp::place;
    BrushShape shape = BrushShape::sphere;
    Int3 centre;
    std::int64_t radius = 0;  // 0..kMaxBrushRadius; 0 is the centre voxel alone
    std::uint8_t material = 1;
    friend bool operator==(const Brush&, const Brush&) = default;
};

// One voxel whose value an edit changed (before != after).
struct VoxelChange {
    std::size_t index = 0;  // linear index, x fastest (Dims::index)
    std::uint8_t before = 0;
    std::uint8_t after = 0;
    friend bool operator==(const VoxelChange&, const VoxelChange&) = default;
};

struct EditResult {
    std::vector<VoxelChange> changes;  // ascending index; only voxels whose value changed
    std::size_t became_solid = 0;      // 0 -> non-zero
    std::size_t became_empty = 0;      // non-zero -> 0
    std::size_t recoloured = 0;        // non-zero -> another non-zero
    Box bounds;            // half-open bounding box of `changes`; Box{} (empty) when none
    Box occupancy_bounds;  // same, of the voxels that became solid or empty only

    bool changed() const { return !changes.empty(); }
    // True when the solid/empty pattern changed, i.e. distances may change; a recolour-only
    // edit changes only the colour byte of packed32 fields.
    bool occupancy_changed() const { return became_solid + became_empty != 0; }
};

// The box of voxels the brush can touch: [centre - R, centre + R] on each axis (the cube,
// which is also the sphere's bounding box) clipped to the world [0, dims). Box{} when the
// brush lies entirely outside the world. Throws InputError for a radius outside
// 0..kMaxBrushRadius.
Box brush_bounds(const Brush& brush, Dims dims);

// True if the voxel at offset (dx, dy, dz) from the centre is inside the shape (ignoring the
// world). Throws InputError for a radius outside 0..kMaxBrushRadius.
bool brush_contains(BrushShape shape, std::int64_t radius, std::int64_t dx, std::int64_t dy,
                    std::int64_t dz);

// Applies the brush to the world and returns what changed. Throws InputError (and leaves the
// world untouched) for a radius outside 0..kMaxBrushRadius, or for material 0 with place or
// paint.
EditResult apply_brush(World& world, const Brush& brush);

}  // namespace voxfield
