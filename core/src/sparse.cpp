// Sparse worlds as a tile grid of 64-trees (the implicit-surface rendering blog's "Tile Grid"
// and "Serializing the contree"): encoding, lookup, edits and the flat buffers.
#include "voxfield/core/sparse.hpp"

#include <algorithm>
#include <atomic>
#include <bit>
#include <exception>
#include <limits>
#include <mutex>
#include <stdexcept>
#include <string>
#include <thread>
#include <unordered_map>

#include "voxfield/core/error.hpp"

namespace voxfield {

std::vector<Int3> tiles_overlapping(const Box& voxels) {
    std::vector<Int3> tiles;
    if (voxels.empty()) {
        return tiles;
    }
    const std::int64_t ts = kTileSize;
    for (std::int64_t tz = voxels.min.z / ts; tz <= (voxels.max.z - 1) / ts; ++tz) {
        for (std::int64_t ty = voxels.min.y / ts; ty <= (voxels.max.y - 1) / ts; ++ty) {
            for (std::int64_t tx = voxels.min.x / ts; tx <= (voxels.max.x - 1) / ts; ++tx) {
                tiles.push_back({tx, ty, tz});
            }
        }
    }
    return tiles;
}
namespace {

constexpr std::uint64_t kFreeSlot = 0;
constexpr std::uint64_t kRemovedSlot = std::numeric_limits<std::uint64_t>::max();

// Child bit of (x, y, z) in 0..3 (the blog's Morton code).
constexpr std::uint32_t child_bit(std::uint32_t x, std::uint32_t y, std::uint32_t z) {
    return (z << 4) | (y << 2) | x;
}

// Set bits of `mask` below `bit`: the rank of child `bit` among its siblings.
std::uint32_t rank_below(std::uint64_t mask, std::uint32_t bit) {
    return static_cast<std::uint32_t>(std::popcount(mask & ((std::uint64_t{1} << bit) - 1)));
}

// The coordinates along `axis` (0 x, 1 y, 2 z) of a 4^3 mask's set bits (bit z << 4 | y << 2 |
// x): bit k for coordinate k.
unsigned mask_coords(std::uint64_t m, int axis) {
    unsigned s = 0;
    if (axis == 2) {
        for (unsigned k = 0; k < 4; ++k) {
            s |= unsigned{(m >> (16 * k) & 0xFFFF) != 0} << k;
        }
        return s;
    }
    const std::uint64_t yx = (m | m >> 16 | m >> 32 | m >> 48) & 0xFFFF;
    if (axis == 1) {
        for (unsigned k = 0; k < 4; ++k) {
            s |= unsigned{(yx >> (4 * k) & 0xF) != 0} << k;
        }
        return s;
    }
    return static_cast<unsigned>((yx | yx >> 4 | yx >> 8 | yx >> 12) & 0xF);
}

// The bits of a 4^3 mask whose coordinate along `axis` is c.
std::uint64_t mask_plane(int axis, int c) {
    constexpr std::uint64_t kFirst[3] = {0x1111111111111111, 0x000F000F000F000F, 0xFFFF};
    return kFirst[axis] << (c << (2 * axis));
}

// The least (`high`: greatest) tile-local coordinate along `axis` of the solid voxels of the
// non-empty 64-tree at `base`: only the 16^3 nodes on the root's extreme plane are folded, then
// only their 4^3 leaves on the extreme plane of those nodes, stopping at the tile's edge.
std::int64_t tree_extreme(const std::vector<std::uint64_t>& masks,
                          const std::vector<std::uint32_t>& offsets, std::uint64_t base, int axis,
                          bool high) {
    const int edge = high ? 3 : 0;
    const auto pick = [high](unsigned s) {
        return high ? static_cast<int>(std::bit_width(s)) - 1 : std::countr_zero(s);
    };
    const auto better = [high](int a, int b) { return high ? std::max(a, b) : std::min(a, b); };
    const std::uint64_t root = masks[base];
    const std::uint64_t first_child = base + offsets[base];
    const int c16 = pick(mask_coords(root, axis));
    const std::uint64_t plane16 = root & mask_plane(axis, c16);
    int c4 = high ? -1 : 4;
    for (std::uint64_t r = plane16; r != 0 && c4 != edge; r &= r - 1) {
        const std::uint64_t child =
            first_child + rank_below(root, static_cast<std::uint32_t>(std::countr_zero(r)));
        c4 = better(c4, pick(mask_coords(masks[child], axis)));
    }
    int c1 = high ? -1 : 4;
    for (std::uint64_t r = plane16; r != 0 && c1 != edge; r &= r - 1) {
        const std::uint64_t child =
            first_child + rank_below(root, static_cast<std::uint32_t>(std::countr_zero(r)));
        const std::uint64_t mid = masks[child];
        const std::uint64_t first_leaf = base + offsets[child];
        for (std::uint64_t m = mid & mask_plane(axis, c4); m != 0 && c1 != edge; m &= m - 1) {
            const std::uint64_t leaf =
                first_leaf + rank_below(mid, static_cast<std::uint32_t>(std::countr_zero(m)));
            c1 = better(c1, pick(mask_coords(masks[leaf], axis)));
        }
    }
    return std::int64_t{c16} * 16 + std::int64_t{c4} * 4 + c1;
}

std::uint64_t mix(std::uint64_t k) {
    k ^= k >> 33;
    k *= 0xff51afd7ed558ccdULL;
    k ^= k >> 33;
    k *= 0xc4ceb9fe1a85ec53ULL;
    k ^= k >> 33;
    return k;
}

std::uint32_t tiles_along(std::uint32_t n) {
    return (n + kTileSize - 1) / kTileSize;
}

// Tile-local linear index of voxel (x, y, z) in 0..63.
std::size_t local_index(std::uint32_t x, std::uint32_t y, std::uint32_t z) {
    return (std::size_t{z} * kTileSize + y) * kTileSize + x;
}

// Calls fn(x, y, z, material) for every solid voxel of `tile` (tile-local coordinates), in
// storage order.
template <class Fn>
void for_each_solid(const SparseWorld& world, std::uint32_t tile, Fn&& fn) {
    const auto& masks = world.node_masks();
    const auto& offsets = world.node_offsets();
    const std::uint64_t base = world.node_bases()[tile];
    const std::uint8_t* mat = world.materials().data() + world.material_bases()[tile];
    std::uint64_t n16 = base + offsets[base];
    for (std::uint64_t m = masks[base]; m != 0; m &= m - 1, ++n16) {
        const auto b16 = static_cast<std::uint32_t>(std::countr_zero(m));
        const std::uint32_t x16 = (b16 & 3) * 16, y16 = (b16 >> 2 & 3) * 16, z16 = (b16 >> 4) * 16;
        std::uint64_t n4 = base + offsets[n16];
        for (std::uint64_t m2 = masks[n16]; m2 != 0; m2 &= m2 - 1, ++n4) {
            const auto b4 = static_cast<std::uint32_t>(std::countr_zero(m2));
            const std::uint32_t x4 = x16 + (b4 & 3) * 4, y4 = y16 + (b4 >> 2 & 3) * 4,
                                z4 = z16 + (b4 >> 4) * 4;
            const std::uint8_t* leaf = mat + offsets[n4];
            for (std::uint64_t m3 = masks[n4]; m3 != 0; m3 &= m3 - 1, ++leaf) {
                const auto bv = static_cast<std::uint32_t>(std::countr_zero(m3));
                fn(x4 + (bv & 3), y4 + (bv >> 2 & 3), z4 + (bv >> 4), *leaf);
            }
        }
    }
}

}  // namespace

SparseWorld::SparseWorld(Dims dims) : dims_(dims) {
    if (dims.x == 0 || dims.y == 0 || dims.z == 0 || dims.x > kMaxSparseAxis ||
        dims.y > kMaxSparseAxis || dims.z > kMaxSparseAxis) {
        throw InputError("invalid sparse world dims " + dims.to_string() +
                         ": every axis must be 1..1048576 (2^20)");
    }
    grid_ = {tiles_along(dims.x), tiles_along(dims.y), tiles_along(dims.z)};
    rehash(64);
}

SparseWorld SparseWorld::from_dense(const World& world) {
    const Dims d = world.dims();
    return from_fill(d, [&](const Box& box, std::span<std::uint8_t> out) {
        std::size_t i = 0;
        for (std::int64_t z = box.min.z; z < box.max.z; ++z) {
            for (std::int64_t y = box.min.y; y < box.max.y; ++y) {
                const std::size_t row =
                    d.index(static_cast<std::uint32_t>(box.min.x), static_cast<std::uint32_t>(y),
                            static_cast<std::uint32_t>(z));
                const auto n = static_cast<std::size_t>(box.max.x - box.min.x);
                std::copy_n(world.voxels().begin() + static_cast<std::ptrdiff_t>(row), n,
                            out.begin() + static_cast<std::ptrdiff_t>(i));
                i += n;
            }
        }
    });
}

SparseWorld SparseWorld::from_fill(Dims dims, const BoxFill& fill, unsigned threads) {
    SparseWorld s(dims);
    if (threads == 0) {
        threads = std::max(1u, std::thread::hardware_concurrency());
    }
    // Work units: a column of tiles (fixed tz, tx) over up to kStack tiles along y, filled as
    // one box (a fill computing per (x, z) column, such as the city's, computes each once per
    // kStack tiles instead of once per tile). Slabs of tiles (fixed tz) in batches: the
    // threads fill and encode a batch's units, then its tiles are stored in (tz, ty, tx)
    // order, so tiles are numbered as one thread would.
    constexpr std::uint32_t kStack = 16;
    const std::uint32_t stacks = (s.grid_.y + kStack - 1) / kStack;
    const std::uint64_t per_slab = std::uint64_t{s.grid_.x} * stacks;
    const auto slabs_per_batch = static_cast<std::uint32_t>(
        std::max<std::uint64_t>(1, (std::uint64_t{threads} * 4 + per_slab - 1) / per_slab));
    const std::uint64_t slab_tiles = std::uint64_t{s.grid_.x} * s.grid_.y;
    std::vector<EncodedTile> encoded;
    for (std::uint32_t first = 0; first < s.grid_.z; first += slabs_per_batch) {
        const std::uint32_t slabs = std::min(slabs_per_batch, s.grid_.z - first);
        const std::uint64_t count = per_slab * slabs;
        encoded.assign(slab_tiles * slabs, EncodedTile{});
        std::atomic<std::uint64_t> next{0};
        std::exception_ptr failure;
        std::mutex failure_mutex;
        auto work = [&] {
            std::vector<std::uint8_t> box_voxels, tile(kTileVoxels);
            for (std::uint64_t u = next++; u < count; u = next++) {
                const auto slab = static_cast<std::uint32_t>(u / per_slab);
                const auto tz = first + slab;
                const auto tx = static_cast<std::uint32_t>(u % per_slab % s.grid_.x);
                const auto ty0 = static_cast<std::uint32_t>(u % per_slab / s.grid_.x) * kStack;
                const std::uint32_t ty1 = std::min(ty0 + kStack, s.grid_.y);
                try {
                    const Box box{
                        {std::int64_t{tx} * kTileSize, std::int64_t{ty0} * kTileSize,
                         std::int64_t{tz} * kTileSize},
                        {std::min<std::int64_t>(std::int64_t{tx + 1} * kTileSize, dims.x),
                         std::min<std::int64_t>(std::int64_t{ty1} * kTileSize, dims.y),
                         std::min<std::int64_t>(std::int64_t{tz + 1} * kTileSize, dims.z)}};
                    box_voxels.resize(static_cast<std::size_t>(box.volume()));
                    fill(box, box_voxels);
                    const auto bx = static_cast<std::size_t>(box.max.x - box.min.x);
                    const auto by = static_cast<std::size_t>(box.max.y - box.min.y);
                    const auto bz = static_cast<std::uint32_t>(box.max.z - box.min.z);
                    for (std::uint32_t ty = ty0; ty < ty1; ++ty) {
                        // Tile ty's rows: y in [y0, y1) of the box.
                        const std::size_t y0 = std::size_t{ty - ty0} * kTileSize;
                        const std::size_t y1 = std::min(y0 + kTileSize, by);
                        bool any = false;
                        for (std::uint32_t z = 0; z < bz && !any; ++z) {
                            const auto row = box_voxels.begin() +
                                             static_cast<std::ptrdiff_t>((z * by + y0) * bx);
                            any =
                                std::any_of(row, row + static_cast<std::ptrdiff_t>((y1 - y0) * bx),
                                            [](std::uint8_t v) { return v != 0; });
                        }
                        if (!any) {
                            continue;
                        }
                        if (bx != kTileSize || y1 - y0 != kTileSize || bz != kTileSize) {
                            std::fill(tile.begin(), tile.end(), std::uint8_t{0});
                        }
                        for (std::uint32_t z = 0; z < bz; ++z) {
                            for (std::size_t y = y0; y < y1; ++y) {
                                std::copy_n(
                                    box_voxels.begin() +
                                        static_cast<std::ptrdiff_t>((z * by + y) * bx),
                                    bx,
                                    tile.begin() + static_cast<long>(local_index(
                                                       0, static_cast<std::uint32_t>(y - y0), z)));
                            }
                        }
                        encoded[slab * slab_tiles + std::uint64_t{ty} * s.grid_.x + tx] =
                            encode_tile(tile);
                    }
                } catch (...) {
                    const std::lock_guard<std::mutex> lock(failure_mutex);
                    if (!failure) {
                        failure = std::current_exception();
                    }
                    next = count;  // the other threads stop at their next unit
                }
            }
        };
        std::vector<std::thread> pool;
        const auto helpers = static_cast<unsigned>(std::min<std::uint64_t>(threads, count)) - 1;
        for (unsigned t = 0; t < helpers; ++t) {
            pool.emplace_back(work);
        }
        work();
        for (std::thread& t : pool) {
            t.join();
        }
        if (failure) {
            std::rethrow_exception(failure);
        }
        for (std::uint64_t i = 0; i < encoded.size(); ++i) {
            if (!encoded[i].masks.empty()) {
                const std::uint64_t in_slab = i % slab_tiles;
                s.put_tile(static_cast<std::uint32_t>(in_slab % s.grid_.x),
                           static_cast<std::uint32_t>(in_slab / s.grid_.x),
                           first + static_cast<std::uint32_t>(i / slab_tiles), encoded[i]);
            }
        }
    }
    return s;
}

SparseWorld SparseWorld::from_voxels(Dims dims,
                                     const std::function<void(const VoxelSink&)>& place) {
    SparseWorld s(dims);
    // Per tile key, its voxels in the order placed: local index (18 bits), value above it.
    std::unordered_map<std::uint64_t, std::vector<std::uint32_t>> buckets;
    place([&](std::uint32_t x, std::uint32_t y, std::uint32_t z, std::uint8_t v) {
        if (!dims.contains(x, y, z)) {
            throw InputError("voxel (" + std::to_string(x) + "," + std::to_string(y) + "," +
                             std::to_string(z) + ") lies outside the world " + dims.to_string());
        }
        const auto local =
            static_cast<std::uint32_t>(local_index(x % kTileSize, y % kTileSize, z % kTileSize));
        buckets[tile_key(x / kTileSize, y / kTileSize, z / kTileSize)].push_back(
            local | std::uint32_t{v} << 18);
    });
    std::vector<std::uint64_t> keys;
    keys.reserve(buckets.size());
    for (const auto& [key, voxels] : buckets) {
        keys.push_back(key);
    }
    std::sort(keys.begin(), keys.end());
    std::vector<std::uint8_t> tile(kTileVoxels);
    for (const std::uint64_t key : keys) {
        std::fill(tile.begin(), tile.end(), std::uint8_t{0});
        std::vector<std::uint32_t>& voxels = buckets[key];
        for (const std::uint32_t e : voxels) {
            tile[e & (kTileVoxels - 1)] = static_cast<std::uint8_t>(e >> 18);
        }
        std::vector<std::uint32_t>().swap(voxels);
        const Int3 t = tile_of_key(key);
        s.store_tile(static_cast<std::uint32_t>(t.x), static_cast<std::uint32_t>(t.y),
                     static_cast<std::uint32_t>(t.z), tile);
    }
    return s;
}

World SparseWorld::to_dense() const {
    if (dims_.count() > kMaxDenseVoxels) {
        throw InputError("the sparse world " + dims_.to_string() + " has " +
                         std::to_string(dims_.count()) + " voxels, more than one dense array " +
                         "holds (" + std::to_string(kMaxDenseVoxels) + ")");
    }
    World w(dims_);
    std::vector<std::uint8_t> tile(kTileVoxels);
    for (std::uint32_t t = 0; t < tile_count(); ++t) {
        decode_tile(t, tile);
        const Box b = tile_box(t);
        for (std::int64_t z = b.min.z; z < b.max.z; ++z) {
            for (std::int64_t y = b.min.y; y < b.max.y; ++y) {
                const auto lz = static_cast<std::uint32_t>(z - b.min.z);
                const auto ly = static_cast<std::uint32_t>(y - b.min.y);
                std::copy_n(tile.begin() + static_cast<long>(local_index(0, ly, lz)),
                            b.max.x - b.min.x,
                            w.voxels().begin() +
                                static_cast<long>(dims_.index(static_cast<std::uint32_t>(b.min.x),
                                                              static_cast<std::uint32_t>(y),
                                                              static_cast<std::uint32_t>(z))));
            }
        }
    }
    return w;
}

Int3 SparseWorld::tile_coord(std::uint32_t tile) const {
    return {tile_coords_[3 * std::size_t{tile}], tile_coords_[3 * std::size_t{tile} + 1],
            tile_coords_[3 * std::size_t{tile} + 2]};
}

Box SparseWorld::tile_box(std::uint32_t tile) const {
    return intersect(tile_voxels(tile_coord(tile)), Box{{0, 0, 0}, {dims_.x, dims_.y, dims_.z}});
}

std::size_t SparseWorld::hash_slot(std::uint64_t key) const {
    const std::size_t mask = hash_keys_.size() - 1;
    std::size_t slot = static_cast<std::size_t>(mix(key)) & mask;
    while (hash_keys_[slot] != kFreeSlot && hash_keys_[slot] != key + 1) {
        slot = (slot + 1) & mask;
    }
    return slot;
}

std::uint32_t SparseWorld::find_tile(std::int64_t tx, std::int64_t ty, std::int64_t tz) const {
    if (tx < 0 || ty < 0 || tz < 0 || tx >= grid_.x || ty >= grid_.y || tz >= grid_.z) {
        return kNoTile;
    }
    const std::size_t slot =
        hash_slot(tile_key(static_cast<std::uint32_t>(tx), static_cast<std::uint32_t>(ty),
                           static_cast<std::uint32_t>(tz)));
    return hash_keys_[slot] == kFreeSlot ? kNoTile : hash_values_[slot];
}

void SparseWorld::rehash(std::size_t capacity) {
    std::vector<std::uint64_t> keys(capacity, kFreeSlot);
    std::vector<std::uint32_t> values(capacity, kNoTile);
    hash_keys_.swap(keys);
    hash_values_.swap(values);
    hash_used_ = 0;
    for (std::uint32_t t = 0; t < tile_count(); ++t) {
        const Int3 c = tile_coord(t);
        hash_insert(tile_key(static_cast<std::uint32_t>(c.x), static_cast<std::uint32_t>(c.y),
                             static_cast<std::uint32_t>(c.z)),
                    t);
    }
}

void SparseWorld::hash_insert(std::uint64_t key, std::uint32_t tile) {
    if (2 * (hash_used_ + 1) > hash_keys_.size()) {
        // Removed slots are dropped by the rehash; grow only when live tiles need it.
        rehash(2 * (tile_count() + 1) > hash_keys_.size() / 2 ? 2 * hash_keys_.size()
                                                              : hash_keys_.size());
    }
    const std::size_t mask = hash_keys_.size() - 1;
    std::size_t slot = static_cast<std::size_t>(mix(key)) & mask;
    while (hash_keys_[slot] != kFreeSlot && hash_keys_[slot] != kRemovedSlot &&
           hash_keys_[slot] != key + 1) {
        slot = (slot + 1) & mask;
    }
    if (hash_keys_[slot] == kFreeSlot) {
        ++hash_used_;
    }
    hash_keys_[slot] = key + 1;
    hash_values_[slot] = tile;
}

std::uint8_t SparseWorld::at(std::uint32_t x, std::uint32_t y, std::uint32_t z) const {
    const std::uint32_t t = find_tile(x / kTileSize, y / kTileSize, z / kTileSize);
    if (t == kNoTile) {
        return 0;
    }
    const std::uint32_t lx = x % kTileSize, ly = y % kTileSize, lz = z % kTileSize;
    const std::uint64_t base = node_bases_[t];
    const std::uint32_t b16 = child_bit(lx >> 4, ly >> 4, lz >> 4);
    const std::uint64_t root = node_masks_[base];
    if ((root >> b16 & 1) == 0) {
        return 0;
    }
    const std::uint64_t n16 = base + node_offsets_[base] + rank_below(root, b16);
    const std::uint32_t b4 = child_bit((lx >> 2) & 3, (ly >> 2) & 3, (lz >> 2) & 3);
    const std::uint64_t m16 = node_masks_[n16];
    if ((m16 >> b4 & 1) == 0) {
        return 0;
    }
    const std::uint64_t n4 = base + node_offsets_[n16] + rank_below(m16, b4);
    const std::uint32_t bv = child_bit(lx & 3, ly & 3, lz & 3);
    const std::uint64_t m4 = node_masks_[n4];
    if ((m4 >> bv & 1) == 0) {
        return 0;
    }
    return materials_[material_bases_[t] + node_offsets_[n4] + rank_below(m4, bv)];
}

void SparseWorld::decode_tile(std::uint32_t tile, std::span<std::uint8_t> out) const {
    std::fill(out.begin(), out.end(), std::uint8_t{0});
    for_each_solid(*this, tile,
                   [&](std::uint32_t x, std::uint32_t y, std::uint32_t z, std::uint8_t material) {
                       out[local_index(x, y, z)] = material;
                   });
}

Box SparseWorld::solid_bounds(std::uint32_t tile) const {
    const Int3 t = tile_coord(tile);
    const Int3 o{t.x * kTileSize, t.y * kTileSize, t.z * kTileSize};
    if (node_masks_[node_bases_[tile]] == 0) {
        return {{o.x + kTileSize, o.y + kTileSize, o.z + kTileSize}, o};
    }
    return {{solid_extreme(tile, 0, false), solid_extreme(tile, 1, false),
             solid_extreme(tile, 2, false)},
            {solid_extreme(tile, 0, true) + 1, solid_extreme(tile, 1, true) + 1,
             solid_extreme(tile, 2, true) + 1}};
}

std::int64_t SparseWorld::solid_extreme(std::uint32_t tile, int axis, bool high) const {
    const Int3 t = tile_coord(tile);
    const std::int64_t origin = (axis == 0 ? t.x : axis == 1 ? t.y : t.z) * kTileSize;
    return origin + tree_extreme(node_masks_, node_offsets_, node_bases_[tile], axis, high);
}

SparseWorld::EncodedTile SparseWorld::encode_tile(std::span<const std::uint8_t> voxels) {
    // Leaf masks per (16^3 child, 4^3 child), and the 16^3 children's masks.
    std::uint64_t leaf[64][64];
    std::uint64_t mid[64];
    std::uint64_t root = 0;
    EncodedTile e;
    for (std::uint32_t b16 = 0; b16 < 64; ++b16) {
        const std::uint32_t x16 = (b16 & 3) * 16, y16 = (b16 >> 2 & 3) * 16, z16 = (b16 >> 4) * 16;
        mid[b16] = 0;
        for (std::uint32_t b4 = 0; b4 < 64; ++b4) {
            const std::uint32_t x4 = x16 + (b4 & 3) * 4, y4 = y16 + (b4 >> 2 & 3) * 4,
                                z4 = z16 + (b4 >> 4) * 4;
            std::uint64_t m = 0;
            for (std::uint32_t z = 0; z < 4; ++z) {
                for (std::uint32_t y = 0; y < 4; ++y) {
                    const std::uint8_t* row = voxels.data() + local_index(x4, y4 + y, z4 + z);
                    for (std::uint32_t x = 0; x < 4; ++x) {
                        m |= std::uint64_t{row[x] != 0} << child_bit(x, y, z);
                    }
                }
            }
            leaf[b16][b4] = m;
            mid[b16] |= std::uint64_t{m != 0} << b4;
        }
        root |= std::uint64_t{mid[b16] != 0} << b16;
    }
    if (root == 0) {
        return e;
    }
    const auto n16 = static_cast<std::uint32_t>(std::popcount(root));
    // Root, then the 16^3 children, then their 4^3 children grouped by parent.
    e.masks.push_back(root);
    e.offsets.push_back(1);
    std::uint32_t next4 = 1 + n16;
    for (std::uint64_t m = root; m != 0; m &= m - 1) {
        const auto b16 = static_cast<std::uint32_t>(std::countr_zero(m));
        e.masks.push_back(mid[b16]);
        e.offsets.push_back(next4);
        next4 += static_cast<std::uint32_t>(std::popcount(mid[b16]));
    }
    std::uint32_t next_material = 0;
    for (std::uint64_t m = root; m != 0; m &= m - 1) {
        const auto b16 = static_cast<std::uint32_t>(std::countr_zero(m));
        const std::uint32_t x16 = (b16 & 3) * 16, y16 = (b16 >> 2 & 3) * 16, z16 = (b16 >> 4) * 16;
        for (std::uint64_t m2 = mid[b16]; m2 != 0; m2 &= m2 - 1) {
            const auto b4 = static_cast<std::uint32_t>(std::countr_zero(m2));
            const std::uint32_t x4 = x16 + (b4 & 3) * 4, y4 = y16 + (b4 >> 2 & 3) * 4,
                                z4 = z16 + (b4 >> 4) * 4;
            e.masks.push_back(leaf[b16][b4]);
            e.offsets.push_back(next_material);
            for (std::uint64_t m3 = leaf[b16][b4]; m3 != 0; m3 &= m3 - 1) {
                const auto bv = static_cast<std::uint32_t>(std::countr_zero(m3));
                e.materials.push_back(
                    voxels[local_index(x4 + (bv & 3), y4 + (bv >> 2 & 3), z4 + (bv >> 4))]);
                ++next_material;
            }
        }
    }
    return e;
}

void SparseWorld::store_tile(std::uint32_t tx, std::uint32_t ty, std::uint32_t tz,
                             std::span<const std::uint8_t> voxels) {
    put_tile(tx, ty, tz, encode_tile(voxels));
}

void SparseWorld::put_tile(std::uint32_t tx, std::uint32_t ty, std::uint32_t tz,
                           const EncodedTile& e) {
    if (tx >= grid_.x || ty >= grid_.y || tz >= grid_.z || e.masks.size() != e.offsets.size()) {
        throw std::invalid_argument("SparseWorld::put_tile: tile outside the grid " +
                                    grid_.to_string() + " or nodes without offsets");
    }
    const bool empty = e.masks.empty();
    const std::uint64_t key = tile_key(tx, ty, tz);
    std::uint32_t tile = find_tile(tx, ty, tz);
    if (tile != kNoTile) {
        garbage_nodes_ += node_counts_[tile];
        garbage_materials_ += material_counts_[tile];
        if (empty) {
            remove_tile(tile);
            compact_if_needed();
            return;
        }
    } else if (empty) {
        return;
    }
    if (tile == kNoTile) {
        tile = tile_count();
        tile_coords_.insert(tile_coords_.end(), {tx, ty, tz});
        node_bases_.push_back(0);
        material_bases_.push_back(0);
        node_counts_.push_back(0);
        material_counts_.push_back(0);
        hash_insert(key, tile);
    }
    node_bases_[tile] = node_masks_.size();
    material_bases_[tile] = materials_.size();
    node_masks_.insert(node_masks_.end(), e.masks.begin(), e.masks.end());
    node_offsets_.insert(node_offsets_.end(), e.offsets.begin(), e.offsets.end());
    materials_.insert(materials_.end(), e.materials.begin(), e.materials.end());
    node_counts_[tile] = static_cast<std::uint32_t>(e.masks.size());
    material_counts_[tile] = static_cast<std::uint32_t>(e.materials.size());
    compact_if_needed();
}

void SparseWorld::remove_tile(std::uint32_t tile) {
    const Int3 c = tile_coord(tile);
    std::size_t slot =
        hash_slot(tile_key(static_cast<std::uint32_t>(c.x), static_cast<std::uint32_t>(c.y),
                           static_cast<std::uint32_t>(c.z)));
    hash_keys_[slot] = kRemovedSlot;
    hash_values_[slot] = kNoTile;
    const std::uint32_t last = tile_count() - 1;
    if (tile != last) {
        // The last tile takes the removed one's index.
        const Int3 l = tile_coord(last);
        slot = hash_slot(tile_key(static_cast<std::uint32_t>(l.x), static_cast<std::uint32_t>(l.y),
                                  static_cast<std::uint32_t>(l.z)));
        hash_values_[slot] = tile;
        std::copy_n(tile_coords_.begin() + 3 * std::ptrdiff_t{last}, 3,
                    tile_coords_.begin() + 3 * std::ptrdiff_t{tile});
        node_bases_[tile] = node_bases_[last];
        material_bases_[tile] = material_bases_[last];
        node_counts_[tile] = node_counts_[last];
        material_counts_[tile] = material_counts_[last];
    }
    tile_coords_.resize(3 * std::size_t{last});
    node_bases_.pop_back();
    material_bases_.pop_back();
    node_counts_.pop_back();
    material_counts_.pop_back();
}

void SparseWorld::compact_if_needed() {
    const std::uint64_t live_nodes = node_masks_.size() - garbage_nodes_;
    const std::uint64_t live_materials = materials_.size() - garbage_materials_;
    constexpr std::uint64_t kSlack = 1u << 16;
    if (garbage_nodes_ <= live_nodes + kSlack && garbage_materials_ <= live_materials + kSlack) {
        return;
    }
    std::vector<std::uint64_t> masks;
    std::vector<std::uint32_t> offsets;
    std::vector<std::uint8_t> materials;
    masks.reserve(live_nodes);
    offsets.reserve(live_nodes);
    materials.reserve(live_materials);
    for (std::uint32_t t = 0; t < tile_count(); ++t) {
        const auto nb = static_cast<std::ptrdiff_t>(node_bases_[t]);
        const auto mb = static_cast<std::ptrdiff_t>(material_bases_[t]);
        node_bases_[t] = masks.size();
        material_bases_[t] = materials.size();
        masks.insert(masks.end(), node_masks_.begin() + nb,
                     node_masks_.begin() + nb + node_counts_[t]);
        offsets.insert(offsets.end(), node_offsets_.begin() + nb,
                       node_offsets_.begin() + nb + node_counts_[t]);
        materials.insert(materials.end(), materials_.begin() + mb,
                         materials_.begin() + mb + material_counts_[t]);
    }
    node_masks_.swap(masks);
    node_offsets_.swap(offsets);
    materials_.swap(materials);
    garbage_nodes_ = garbage_materials_ = 0;
    ++generation_;
}

Box SparseWorld::edit(
    const Box& box,
    const std::function<std::uint8_t(std::int64_t, std::int64_t, std::int64_t, std::uint8_t)>& fn) {
    const Box b = intersect(box, Box{{0, 0, 0}, {dims_.x, dims_.y, dims_.z}});
    Box changed{};
    if (b.empty()) {
        return changed;
    }
    std::vector<std::uint8_t> tile(kTileVoxels);
    const std::int64_t s = kTileSize;
    for (std::int64_t tz = b.min.z / s; tz <= (b.max.z - 1) / s; ++tz) {
        for (std::int64_t ty = b.min.y / s; ty <= (b.max.y - 1) / s; ++ty) {
            for (std::int64_t tx = b.min.x / s; tx <= (b.max.x - 1) / s; ++tx) {
                const std::uint32_t t = find_tile(tx, ty, tz);
                if (t == kNoTile) {
                    std::fill(tile.begin(), tile.end(), std::uint8_t{0});
                } else {
                    decode_tile(t, tile);
                }
                const Box part = intersect(
                    b, Box{{tx * s, ty * s, tz * s}, {(tx + 1) * s, (ty + 1) * s, (tz + 1) * s}});
                Box part_changed{};
                for (std::int64_t z = part.min.z; z < part.max.z; ++z) {
                    for (std::int64_t y = part.min.y; y < part.max.y; ++y) {
                        for (std::int64_t x = part.min.x; x < part.max.x; ++x) {
                            std::uint8_t& v =
                                tile[local_index(static_cast<std::uint32_t>(x - tx * s),
                                                 static_cast<std::uint32_t>(y - ty * s),
                                                 static_cast<std::uint32_t>(z - tz * s))];
                            const std::uint8_t after = fn(x, y, z, v);
                            if (after != v) {
                                v = after;
                                part_changed =
                                    hull(part_changed, Box{{x, y, z}, {x + 1, y + 1, z + 1}});
                            }
                        }
                    }
                }
                if (!part_changed.empty()) {
                    store_tile(static_cast<std::uint32_t>(tx), static_cast<std::uint32_t>(ty),
                               static_cast<std::uint32_t>(tz), tile);
                    changed = hull(changed, part_changed);
                }
            }
        }
    }
    return changed;
}

void SparseWorld::set(std::uint32_t x, std::uint32_t y, std::uint32_t z, std::uint8_t v) {
    if (!dims_.contains(x, y, z)) {
        throw InputError("voxel (" + std::to_string(x) + "," + std::to_string(y) + "," +
                         std::to_string(z) + ") lies outside the world " + dims_.to_string());
    }
    const std::int64_t px = x, py = y, pz = z;
    edit(Box{{px, py, pz}, {px + 1, py + 1, pz + 1}},
         [v](std::int64_t, std::int64_t, std::int64_t, std::uint8_t) { return v; });
}

void SparseWorld::read_box(const Box& box, std::span<std::uint8_t> out) const {
    const Box b = intersect(box, Box{{0, 0, 0}, {dims_.x, dims_.y, dims_.z}});
    std::fill(out.begin(), out.end(), std::uint8_t{0});
    if (b.empty()) {
        return;
    }
    std::vector<std::uint8_t> tile(kTileVoxels);
    const std::int64_t s = kTileSize;
    const std::int64_t nx = box.max.x - box.min.x, ny = box.max.y - box.min.y;
    for (std::int64_t tz = b.min.z / s; tz <= (b.max.z - 1) / s; ++tz) {
        for (std::int64_t ty = b.min.y / s; ty <= (b.max.y - 1) / s; ++ty) {
            for (std::int64_t tx = b.min.x / s; tx <= (b.max.x - 1) / s; ++tx) {
                const std::uint32_t t = find_tile(tx, ty, tz);
                if (t == kNoTile) {
                    continue;
                }
                decode_tile(t, tile);
                const Box part = intersect(
                    b, Box{{tx * s, ty * s, tz * s}, {(tx + 1) * s, (ty + 1) * s, (tz + 1) * s}});
                for (std::int64_t z = part.min.z; z < part.max.z; ++z) {
                    for (std::int64_t y = part.min.y; y < part.max.y; ++y) {
                        std::copy_n(
                            tile.begin() + static_cast<long>(local_index(
                                               static_cast<std::uint32_t>(part.min.x - tx * s),
                                               static_cast<std::uint32_t>(y - ty * s),
                                               static_cast<std::uint32_t>(z - tz * s))),
                            part.max.x - part.min.x,
                            out.begin() + ((z - box.min.z) * ny + (y - box.min.y)) * nx +
                                (part.min.x - box.min.x));
                    }
                }
            }
        }
    }
}

std::uint64_t SparseWorld::bytes() const {
    return node_masks_.size() * 8 + node_offsets_.size() * 4 + materials_.size() +
           tile_coords_.size() * 4 + (node_bases_.size() + material_bases_.size()) * 8 +
           (node_counts_.size() + material_counts_.size()) * 4 + hash_keys_.size() * 8 +
           hash_values_.size() * 4;
}

Box apply_brush(SparseWorld& world, const Brush& brush) {
    if ((brush.op == BrushOp::place || brush.op == BrushOp::paint) && brush.material == 0) {
        throw InputError(to_string(brush.op) + " needs a material 1..255, not 0");
    }
    const Box bounds = brush_bounds(brush, world.dims());  // checks the radius
    return world.edit(
        bounds,
        [&](std::int64_t x, std::int64_t y, std::int64_t z, std::uint8_t v) -> std::uint8_t {
            if (!brush_contains(brush.shape, brush.radius, x - brush.centre.x, y - brush.centre.y,
                                z - brush.centre.z)) {
                return v;
            }
            switch (brush.op) {
                case BrushOp::place:
                    return brush.material;
                case BrushOp::erase:
                    return 0;
                case BrushOp::paint:
                    return v != 0 ? brush.material : v;
            }
            return v;
        });
}

}  // namespace voxfield
