#pragma once
// The box field of an incremental L1 update (cl/include/voxfield/cl/incremental.hpp): the exact
// L1 distance, inside a box, to sources in the box, exact from the box's voxels alone since an
// L1 shortest path between two voxels of a box stays in the box; and the least value over each
// of the 27 parts of the box's boundary, with which the device bounds the reach of an edit.
#include <array>
#include <cstdint>

#include "voxfield/core/chunks.hpp"

namespace voxfield {

// No source within the box (the update's kernels' VF_FAR).
inline constexpr std::uint32_t kBoxFieldFar = 0xFFFFFFFFu;

// `f` holds n.x * n.y * n.z values (x fastest): 0 at the sources, kBoxFieldFar elsewhere.
// Replaces them by the L1 distance to the nearest source (kBoxFieldFar without any): forward
// and backward min-plus sweeps along x, y and z.
void box_field_transform(std::uint32_t* f, Int3 n);

// The least value of f over each part of the box's boundary, part (side.z * 3 + side.y) * 3 +
// side.x with per axis side 0: the low face, 1: any coordinate, 2: the high face.
std::array<std::uint32_t, 27> box_field_boundary_minima(const std::uint32_t* f, Int3 n);

}  // namespace voxfield
