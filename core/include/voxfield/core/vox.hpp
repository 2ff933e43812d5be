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

// Writes a MagicaVoxel .vox (version 150: MAIN with SIZE, XYZI, RGBA) that read_vox reads
// back unchanged: world (x, y, z) -> vox (x, z, y), colour index = voxel value, RGBA entry
// i-1 = palette[i]. Atomic (temporary file + rename). Throws InputError when an axis exceeds
// 256 (the format's limit; MagicaVoxel's SIZE and XYZI hold one byte per coordinate) or the
// folder does not exist.
void write_vox(const std::filesystem::path& path, const World& world, const Palette& palette);

// Loads a .vox or .npy world (by extension); .npy gets the default palette.
VoxModel load_world(const std::filesystem::path& path);

}  // namespace voxfield
