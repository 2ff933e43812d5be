#pragma once
// Sparse voxel worlds: a tile grid of 64-trees (contrees), after the implicit-surface
// rendering blog (../shared/reference/implicit-surface-rendering-for-cad.txt, "Tile Grid").
//
// The world (up to 2^20 voxels per axis) is cut into tiles of 64^3 voxels; a tile is stored
// only where it holds a solid voxel. Inside a tile a 64-tree: the root (64^3) has a 64-bit
// occupancy mask of its 4x4x4 children of 16^3 voxels, each of those a mask of its 4^3
// children of 4^3 voxels, and each of those (a leaf node) a mask of its 64 voxels. Child bit
// of (x, y, z) in 0..3: z << 4 | y << 2 | x (the blog's Morton code). Everything lies in flat,
// structure-of-arrays buffers a GPU reads as they are:
//   nodes:     node_masks (u64) and node_offsets (u32), per tile contiguous from its
//              node_base: the root, then its 16^3 children in mask order, then their 4^3
//              children, grouped by parent in parent order. A non-leaf node's offset is the
//              tile-relative index of its first child; a leaf node's offset is the
//              tile-relative index of its first voxel's material.
//   materials: one byte per solid voxel, per leaf in mask order, per tile contiguous from its
//              material_base.
//   tiles:     coordinates (tile units), node_base, material_base (64-bit), and the tile
//              hash (open addressing, linear probing, key tile_key(t) + 1, 0 = free slot).
// Voxel counts and bases are 64-bit everywhere; offsets inside a tile are 32-bit.
#include <cstdint>
#include <functional>
#include <optional>
#include <span>
#include <vector>

#include "voxfield/core/brush.hpp"
#include "voxfield/core/chunks.hpp"
#include "voxfield/core/vox.hpp"
#include "voxfield/core/world.hpp"
#include "voxfield/core/world_info.hpp"  // kTileSize, 64 voxels per tile edge

namespace voxfield {

inline constexpr std::uint32_t kTileVoxels = 262144;  // 64^3
inline constexpr std::uint32_t kMaxSparseAxis = 1u << 20;
inline constexpr std::uint32_t kNoTile = 0xFFFFFFFFu;
// The most voxels a sparse world (or its field) is materialised into as one dense array.
inline constexpr std::uint64_t kMaxDenseVoxels = std::uint64_t{1} << 32;

// Tile grid coordinates are below 2^14 per axis: a key packs them into 42 bits.
inline std::uint64_t tile_key(std::uint32_t tx, std::uint32_t ty, std::uint32_t tz) {
    return (std::uint64_t{tz} << 28) | (std::uint64_t{ty} << 14) | tx;
}
// The tile grid coordinates a key packs (tile_key's inverse).
inline Int3 tile_of_key(std::uint64_t key) {
    constexpr std::uint64_t kCoord = (std::uint64_t{1} << 14) - 1;
    return {static_cast<std::int64_t>(key & kCoord), static_cast<std::int64_t>(key >> 14 & kCoord),
            static_cast<std::int64_t>(key >> 28 & kCoord)};
}
// The tiles (tile grid coordinates) a box of voxels with non-negative corners overlaps, x
// fastest, then y, then z; none for an empty box.
std::vector<Int3> tiles_overlapping(const Box& voxels);
// The voxels of tile `tile` (tile grid coordinates), whole: not clipped to any world.
inline Box tile_voxels(const Int3& tile) {
    const std::int64_t s = kTileSize;
    return {{tile.x * s, tile.y * s, tile.z * s},
            {(tile.x + 1) * s, (tile.y + 1) * s, (tile.z + 1) * s}};
}

// Fills `out` (box.volume() bytes, x fastest, then y, then z) with the voxels of `box`.
using BoxFill = std::function<void(const Box& box, std::span<std::uint8_t> out)>;
// Takes one voxel (x, y, z, value); a later voxel at the same place replaces an earlier one.
using VoxelSink = std::function<void(std::uint32_t, std::uint32_t, std::uint32_t, std::uint8_t)>;

class SparseWorld {
  public:
    // An empty world. Throws InputError when an axis is 0 or above 2^20.
    explicit SparseWorld(Dims dims);
    // From a dense world (its solid voxels).
    static SparseWorld from_dense(const World& world);
    // Tile by tile from `fill`, called once per column of tiles (a tile's x and z extents,
    // up to 16 tiles along y, clipped to the world: a fill that computes per (x, z) column
    // does so once per 16 tiles), so that no dense array of the world ever exists. Tiles are filled
    // and encoded on up to `threads` threads (0: one per hardware thread), so `fill` may be called
    // concurrently, each call with its own box and span; the world is the same for any thread
    // count.
    static SparseWorld from_fill(Dims dims, const BoxFill& fill, unsigned threads = 0);
    // From voxels handed to the sink one by one by `place` (a scene's instances, a grid's
    // active voxels), bucketed by tile (4 bytes per voxel placed): no dense array and no
    // visit of empty tiles. InputError for a voxel outside the world.
    static SparseWorld from_voxels(Dims dims, const std::function<void(const VoxelSink&)>& place);
    // The dense world (every voxel); throws InputError above kMaxDenseVoxels voxels.
    World to_dense() const;

    const Dims& dims() const { return dims_; }
    Dims tile_grid() const { return grid_; }  // ceil(dims / 64) per axis
    std::uint64_t solid_count() const { return materials_.size() - garbage_materials_; }

    std::uint8_t at(std::uint32_t x, std::uint32_t y, std::uint32_t z) const;
    // Sets one voxel (0 erases it).
    void set(std::uint32_t x, std::uint32_t y, std::uint32_t z, std::uint8_t v);
    // Rewrites the voxels of `box` (clipped to the world): `edit` gets each voxel's
    // coordinates and value and returns its new value. Each tile the box touches is rewritten
    // once. Returns the bounding box of the voxels whose value changed (Box{} when none).
    Box edit(const Box& box, const std::function<std::uint8_t(std::int64_t, std::int64_t,
                                                              std::int64_t, std::uint8_t)>& fn);
    // Every voxel of `box` into `out` (box.volume() bytes, x fastest): 0 outside the world
    // and in tiles that are not stored.
    void read_box(const Box& box, std::span<std::uint8_t> out) const;

    // Tiles: index 0..tile_count()-1 (an edit may reorder them).
    std::uint32_t tile_count() const { return static_cast<std::uint32_t>(tile_coords_.size() / 3); }
    Int3 tile_coord(std::uint32_t tile) const;  // in tile units
    Box tile_box(std::uint32_t tile) const;     // its voxels, clipped to the world
    // The tile at tile coordinates t, or kNoTile.
    std::uint32_t find_tile(std::int64_t tx, std::int64_t ty, std::int64_t tz) const;
    // The bounding box of the tile's solid voxels (world coordinates).
    Box solid_bounds(std::uint32_t tile) const;
    // One side of it: the least (`high`: greatest) coordinate along `axis` (0 x, 1 y, 2 z) of
    // the tile's solid voxels (world coordinates; the tile holds one).
    std::int64_t solid_extreme(std::uint32_t tile, int axis, bool high) const;
    // The tile's 64^3 voxels (tile-local, x fastest; beyond the world's edge 0).
    void decode_tile(std::uint32_t tile, std::span<std::uint8_t> out) const;

    // The flat buffers (see the top of this header).
    const std::vector<std::uint64_t>& node_masks() const { return node_masks_; }
    const std::vector<std::uint32_t>& node_offsets() const { return node_offsets_; }
    const std::vector<std::uint8_t>& materials() const { return materials_; }
    const std::vector<std::uint32_t>& tile_coords() const { return tile_coords_; }  // x,y,z
    const std::vector<std::uint64_t>& node_bases() const { return node_bases_; }
    const std::vector<std::uint64_t>& material_bases() const { return material_bases_; }
    const std::vector<std::uint64_t>& hash_keys() const { return hash_keys_; }
    const std::vector<std::uint32_t>& hash_values() const { return hash_values_; }
    // Nodes and materials of tile t: node_counts()[t] and material_counts()[t].
    const std::vector<std::uint32_t>& node_counts() const { return node_counts_; }
    const std::vector<std::uint32_t>& material_counts() const { return material_counts_; }
    // Bytes of all of the above (what a device copy takes).
    std::uint64_t bytes() const;
    // Counts the compactions that moved nodes and materials (a device copy is then stale as a
    // whole; between two compactions edits only append to the node and material buffers).
    std::uint64_t layout_generation() const { return generation_; }

    // One tile's 64-tree: its nodes (masks, tile-relative offsets) and materials, as they lie
    // from the tile's node_base and material_base; empty when every voxel is 0.
    struct EncodedTile {
        std::vector<std::uint64_t> masks;
        std::vector<std::uint32_t> offsets;
        std::vector<std::uint8_t> materials;
        friend bool operator==(const EncodedTile&, const EncodedTile&) = default;
    };
    // The 64-tree of 64^3 voxels (tile-local, x fastest); needs nothing of a world (from_fill
    // encodes tiles on several threads; cl/sparse_device_world.hpp's kernels equal it).
    static EncodedTile encode_tile(std::span<const std::uint8_t> voxels);
    // Stores an encoded tile as tile (tx, ty, tz) (in tile units, inside the tile grid):
    // appends its nodes and materials, inserts or replaces its tile entry; removes the tile
    // when `e` is empty.
    void put_tile(std::uint32_t tx, std::uint32_t ty, std::uint32_t tz, const EncodedTile& e);

  private:
    // Encodes 64^3 voxels (tile-local) as tile (tx, ty, tz): encode_tile, then put_tile.
    void store_tile(std::uint32_t tx, std::uint32_t ty, std::uint32_t tz,
                    std::span<const std::uint8_t> voxels);
    void remove_tile(std::uint32_t tile);
    void hash_insert(std::uint64_t key, std::uint32_t tile);
    std::size_t hash_slot(std::uint64_t key) const;  // the key's slot or the free slot
    void rehash(std::size_t capacity);
    void compact_if_needed();

    Dims dims_;
    Dims grid_;
    std::vector<std::uint64_t> node_masks_;
    std::vector<std::uint32_t> node_offsets_;
    std::vector<std::uint8_t> materials_;
    std::vector<std::uint32_t> tile_coords_;
    std::vector<std::uint64_t> node_bases_, material_bases_;
    std::vector<std::uint32_t> node_counts_, material_counts_;
    std::vector<std::uint64_t> hash_keys_;
    std::vector<std::uint32_t> hash_values_;
    std::uint64_t hash_used_ = 0;  // occupied slots, removed ones included
    // Nodes and materials of rewritten tiles, reclaimed by compaction.
    std::uint64_t garbage_nodes_ = 0, garbage_materials_ = 0;
    std::uint64_t generation_ = 0;
};

// Applies a brush (core/brush.hpp semantics, clipped to the world) to a sparse world and
// returns the bounding box of the voxels it changed (Box{} when none). Throws InputError as
// apply_brush does (radius out of range, material 0 with place or paint).
Box apply_brush(SparseWorld& world, const Brush& brush);

// A world in sparse storage and its palette, as load_sparse_world returns it.
struct SparseModel {
    SparseWorld world;
    Palette palette;
};

// Loads a world as load_world (vox.hpp) does, into sparse storage. A .vox scene and a .vdb grid
// are placed voxel by voxel (SparseWorld::from_voxels), never as one dense array, so their
// extent may reach kMaxSparseAxis per axis; .npy arrays and .sdf.json parts are read dense first
// (their limits apply). InputError as load_world.
SparseModel load_sparse_world(const std::filesystem::path& path, const InputOptions& options = {});

}  // namespace voxfield
