#pragma once
// Mixed scenes (`.scene.json`): MagicaVoxel models and implicit parts placed in one world of
// one voxel size (DESIGN "Mixed scenes"):
//
//   {"version": 1, "voxel_size": h,
//    "items": [{"vox": "a.vox", "translate": [x, y, z]},
//              {"sdf": "part.sdf.json", "translate": [x, y, z], "material": m}]}
//
// Scene coordinates are the parts' units; voxel cell (i, j, k) of the scene grid covers
// [i h, (i + 1) h) per axis. A `.vox` item is its placed scene graph (read_vox: y up), one
// model voxel per scene voxel, its minimum corner at `translate` (a whole number of voxels).
// An `.sdf` item is the part's shape moved by `translate` and clipped to its own bounds (so a
// plane does not fill the scene), sampled on the scene's grid (its own voxel_size is not used);
// `material` (1..255) replaces every material of the part. The world is the grid's box around
// every item; its voxels: every part's solid voxels (f < 0 at the centre, parts in one union),
// then every `.vox` model's voxels over them in item order (a `.vox` voxel wins). Palette: the
// first `.vox` item's, else the default. Relative paths are relative to the scene file.
#include <array>
#include <cstdint>
#include <filesystem>
#include <optional>
#include <string>
#include <vector>

#include "voxfield/core/palette.hpp"
#include "voxfield/core/sdf.hpp"
#include "voxfield/core/vox.hpp"
#include "voxfield/core/world.hpp"

namespace voxfield::scene {

struct VoxItem {
    std::filesystem::path path;
    VoxModel model;
    std::array<std::uint32_t, 3> at{};  // the model's minimum corner, world voxel
};

struct Scene {
    double voxel_size = 0;
    std::array<double, 3> lo{};            // the world's minimum corner, scene coordinates
    std::array<std::int64_t, 3> origin{};  // the scene-grid cell at world voxel (0, 0, 0)
    Dims dims;                             // world voxels
    Palette palette;
    std::vector<VoxItem> vox;       // in item order
    std::optional<sdf::Part> part;  // every part in one union, gridded as the world
    std::size_t parts = 0;          // sdf items

    // The world's voxels: the parts' solid voxels, then the .vox models' (which win).
    World world(const std::string& name) const;
    // Calls f(x, y, z, material) for every .vox voxel in item order (world voxels).
    template <class F>
    void place_vox(F&& f) const {
        for (const VoxItem& item : vox) {
            const World& w = item.model.world;
            const Dims d = w.dims();
            for (std::uint32_t z = 0; z < d.z; ++z) {
                for (std::uint32_t y = 0; y < d.y; ++y) {
                    for (std::uint32_t x = 0; x < d.x; ++x) {
                        if (const std::uint8_t v = w.at(x, y, z)) {
                            f(item.at[0] + x, item.at[1] + y, item.at[2] + z, v);
                        }
                    }
                }
            }
        }
    }
};

// Whether `path` names a `.scene.json` file (by its name, case-insensitive).
bool is_scene_path(const std::filesystem::path& path);

// Parses scene text; `path` names it in messages and anchors relative item paths. One-line
// InputError on anything malformed: not JSON, a wrong version, a missing or non-positive
// voxel_size, no items, an unknown key, an item with neither or both of vox / sdf, a translate
// that is not 3 numbers (or, for a .vox item, not a whole number of voxels), a material
// outside 1..255 or on a .vox item, an item file that cannot be read (its own reader's message,
// prefixed by the item), a part nested too deeply to wrap, a world over 2^31 voxels.
Scene parse_scene(const std::string& text, const std::filesystem::path& path);
Scene load_scene(const std::filesystem::path& path);

}  // namespace voxfield::scene
