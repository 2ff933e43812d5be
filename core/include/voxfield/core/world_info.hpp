#pragma once
// What `voxfield info` reports about a world: its size, solid voxels, the 64^3 tiles a sparse
// world would store (DESIGN §3) and what a dense and a sparse field of it would take. Counted
// tile by tile (one bit per voxel of each tile holding a solid voxel), never as a dense array.
#include <cstdint>
#include <string>
#include <unordered_map>
#include <vector>

#include "voxfield/core/format.hpp"
#include "voxfield/core/vox.hpp"
#include "voxfield/core/world.hpp"

namespace voxfield {

inline constexpr std::uint32_t kTileSize = 64;  // voxels per tile axis (the blog's 64-tree)

struct WorldInfo {
    std::string kind;  // "vox", "npy", "vdb", ...
    Dims dims;
    std::uint64_t solid = 0;
    Dims tile_grid;                   // tiles per axis, ceil(dims / 64)
    std::uint64_t solid_tiles = 0;    // tiles holding a solid voxel
    std::uint64_t stored_tiles = 0;   // those, plus tiles within max_distance of a solid voxel
    std::uint64_t stored_voxels = 0;  // voxels of the stored tiles (cut by the world's edge)
    std::uint64_t blocks16 = 0;       // 16^3 blocks holding a solid voxel (64-tree level 1)
    std::uint64_t blocks4 = 0;        // 4^3 blocks holding a solid voxel (level 2)
    double max_distance = 16;         // the bound the stored tiles were counted for
    // .vox only
    bool scene_graph = false;
    std::uint64_t models = 0, instances = 0, hidden_instances = 0;
    // .vdb only
    std::string grid, grid_class;
};

// Bytes of a dense world and field: every voxel, one byte of material plus the field format.
std::uint64_t dense_field_bytes(const WorldInfo& info, Format f);
// Bytes of the sparse layout: a 32-bit offset per tile of the grid, per solid tile a 64-tree
// of 12-byte nodes (8-byte mask + 32-bit offset; the root and one node per populated 16^3
// and 4^3 block), one material byte per solid voxel, and the field format for every voxel of
// every stored tile.
std::uint64_t sparse_field_bytes(const WorldInfo& info, Format f);

// Collects solid voxels tile by tile, then fills the counts of a WorldInfo.
class TileCensus {
  public:
    explicit TileCensus(Dims dims);
    void add(std::uint32_t x, std::uint32_t y, std::uint32_t z);  // inside dims
    void add_world(const World& world);                           // every solid voxel
    // Sets dims, solid, tile_grid, solid_tiles, stored_tiles, stored_voxels, blocks16,
    // blocks4 and max_distance. A tile is counted as stored when one of its voxels is within
    // `max_distance` of a solid voxel's bounding box in its tile under L-inf (an upper bound of
    // the tiles any metric needs at unit spacing).
    void finish(WorldInfo& info, double max_distance) const;

  private:
    struct Tile {
        std::vector<std::uint64_t> bits;  // 64^3 bits, x fastest
        std::uint32_t lo[3], hi[3];       // bounding box of its solid voxels, in the tile
    };
    Tile& tile(std::uint64_t key);

    Dims dims_, grid_;
    std::unordered_map<std::uint64_t, Tile> tiles_;
    std::uint64_t last_key_ = ~std::uint64_t{0};
    Tile* last_ = nullptr;
};

// Reads the input file (by extension, as load_world) and counts it; .vox scenes are placed
// voxel by voxel into the census without a dense world.
WorldInfo describe_input(const std::filesystem::path& path, const InputOptions& options,
                         double max_distance);

}  // namespace voxfield
