#pragma once
// MagicaVoxel .vox reader and writer (version 150+). Models are SIZE/XYZI pairs; RGBA is the
// palette (missing -> MagicaVoxel's default); XYZI colour index i refers to palette entry i
// (RGBA chunk entry i-1). A file with a scene graph (nTRN / nGRP / nSHP) is every visible
// instance placed in one world (DESIGN §3); a file without one is its first model.
// MagicaVoxel is z-up: vox (x, y, z) -> world (x, z, y).
#include <array>
#include <cstdint>
#include <filesystem>
#include <functional>
#include <string>
#include <vector>

#include "voxfield/core/palette.hpp"
#include "voxfield/core/world.hpp"

namespace voxfield {

struct VoxModel {
    World world;
    Palette palette;
};

// Largest scene the reader places, per world axis (DESIGN §3).
inline constexpr std::uint32_t kVoxMaxSceneAxis = 1u << 20;

// One visible instance of a model, with its accumulated placement in vox coordinates (z up):
// the cube of model voxel v lands in cell `rotation * (v - pivot) + translation - flip`,
// where flip is 1 on the rows whose sign is negative (the cube [v, v + 1) turned round).
struct VoxInstance {
    std::uint32_t model = 0;
    std::array<std::int32_t, 9> rotation{1, 0, 0, 0, 1, 0, 0, 0, 1};  // rows, signed permutation
    std::array<std::int64_t, 3> translation{0, 0, 0};
};

// A .vox file as read: every model, the visible instances in depth-first order, the world box.
struct VoxScene {
    struct Model {
        Dims size;                                      // vox axes
        std::vector<std::array<std::uint8_t, 4>> xyzi;  // x, y, z (vox axes), colour index
    };
    std::vector<Model> models;
    std::vector<VoxInstance> instances;  // visible ones; one per file without a scene graph
    bool has_scene_graph = false;
    std::size_t hidden_instances = 0;  // shape nodes skipped (hidden node or layer)
    Dims dims;                         // world axes (y up), at most kVoxMaxSceneAxis each
    std::array<std::int64_t, 3> origin{0, 0, 0};  // vox-space cell at world (0, 0, 0)
    Palette palette;

    // Calls `f(x, y, z, colour)` (world axes, y up) for every voxel of every visible instance,
    // in depth-first instance order, so a later call for the same cell wins.
    void place(const std::function<void(std::uint32_t, std::uint32_t, std::uint32_t, std::uint8_t)>&
                   f) const;
};

// InputError on any malformed input: bad chunks, a version below 150, a node cycle, a missing
// child or model, a bad rotation, a scene over kVoxMaxSceneAxis per axis, or no visible
// instance.
VoxScene read_vox_scene(const std::filesystem::path& path);

// The scene placed in one dense world (origin at the scene's minimum corner; overlapping
// instances: the later in depth-first order wins). InputError also when the dense world would
// exceed 2^31 voxels.
VoxModel read_vox(const std::filesystem::path& path);

// Writes a MagicaVoxel .vox (version 150: MAIN with SIZE, XYZI, RGBA; one model, no scene
// graph) that read_vox reads back unchanged: world (x, y, z) -> vox (x, z, y), colour index =
// voxel value, RGBA entry i-1 = palette[i]. Atomic (temporary file + rename). Throws
// InputError when an axis exceeds 256 (the format's limit; MagicaVoxel's SIZE and XYZI hold
// one byte per coordinate) or the folder does not exist.
void write_vox(const std::filesystem::path& path, const World& world, const Palette& palette);

// What the readers may need beyond the path.
struct InputOptions {
    std::string grid;  // .vdb: the grid to read (empty: the first grid)
    // .npy label volumes: true when the caller uses values as palette indices (packed32
    // fields, rendering), so a value outside 0..255 is an InputError naming the voxel; false:
    // every nonzero value is solid (DESIGN §3, label arrays).
    bool palette_values = false;
};

// Loads a world by its file's extension (case-insensitive): .vox, .npy, .vdb. .npy gets the
// default palette. InputError naming the extensions accepted for any other.
VoxModel load_world(const std::filesystem::path& path, const InputOptions& options = {});

}  // namespace voxfield
