#pragma once
// What one ray march hands raymarch.comp (private to vk/): its push constants, filled from the
// render options, the field's layout and whether block minima are bound. The camera vectors
// in them are vk::camera_basis's, i.e. core's image_basis (the one camera model, DESIGN §4).
#include <array>
#include <cstddef>
#include <cstdint>

#include "voxfield/vk/raymarcher.hpp"

namespace voxfield::vk {

// Mirrors the push-constant block `Params` of raymarch.comp (std430: vec4 / uvec4 members).
struct PushConstants {
    float origin[4];
    float forward[4];
    float right[4];
    float up[4];
    std::uint32_t dims[4];      // X, Y, Z, z-slices per slab
    std::uint32_t image[4];     // width, height, flags (VF_RAYMARCH_FLAG_*), flat sky RGBA8
    std::uint32_t implicit[4];  // the implicit surface's tiles x, y, z and tile depth
};
static_assert(sizeof(PushConstants) == 112);
static_assert(offsetof(PushConstants, dims) == 64);
static_assert(offsetof(PushConstants, image) == 80);
static_assert(offsetof(PushConstants, implicit) == 96);

// The push constants of a ray march of `options` over a field laid out as `layout`; `block_min`:
// the block-minimum table holds that field's minima; `implicit`: the implicit surface's tile
// grid (tiles x, y, z, tile depth; zeros without one). Throws InputError for bad options.
PushConstants push_constants(const RenderOptions& options, const FieldLayout& layout,
                             bool block_min, const std::array<std::uint32_t, 4>& implicit = {});

// RGBA8 as the shader reads it: r in the lowest byte.
std::uint32_t pack_rgba(Rgba c);

}  // namespace voxfield::vk
