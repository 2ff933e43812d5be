#pragma once
// MagicaVoxel .vox reader (version 150+): first model's SIZE/XYZI, RGBA palette (missing ->
// MagicaVoxel default). XYZI colour index i refers to palette entry i (RGBA chunk entry
// i-1). MagicaVoxel is z-up: vox (x, y, z) -> world (x, z, y).
#include <filesystem>

#include "voxfield/core/palette.hpp"
#include "voxfield/core/world.hpp"

namespace voxfield {

struct VoxModel {
    World world;
    Palette palette;
};

VoxModel read_vox(const std::filesystem::path& path);  // InputError on any malformed input

// Loads a .vox or .npy world (by extension); .npy gets the default palette.
VoxModel load_world(const std::filesystem::path& path);

}  // namespace voxfield
