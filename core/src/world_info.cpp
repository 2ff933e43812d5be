// Tile census of a world for `voxfield info` (tiles of 64^3 as in the implicit-surface
// rendering blog's tile grid of 64-trees, ../shared/reference).
#include "voxfield/core/world_info.hpp"

#include <algorithm>
#include <bit>
#include <cmath>
#include <cstdint>
#include <unordered_set>

namespace voxfield {

namespace {

std::uint32_t tiles_for(std::uint32_t n) {
    return (n + kTileSize - 1) / kTileSize;
}

}  // namespace

std::uint64_t dense_field_bytes(const WorldInfo& info, Format f) {
    return std::uint64_t{info.dims.x} * info.dims.y * info.dims.z * (1 + element_size(f));
}

std::uint64_t sparse_field_bytes(const WorldInfo& info, Format f) {
    const std::uint64_t grid =
        std::uint64_t{info.tile_grid.x} * info.tile_grid.y * info.tile_grid.z;
    const std::uint64_t nodes = info.solid_tiles + info.blocks16 + info.blocks4;
    return grid * 4 + nodes * 12 + info.solid + info.stored_voxels * element_size(f);
}

TileCensus::TileCensus(Dims dims)
    : dims_(dims), grid_{tiles_for(dims.x), tiles_for(dims.y), tiles_for(dims.z)} {}

TileCensus::Tile& TileCensus::tile(std::uint64_t key) {
    if (key != last_key_) {
        auto [it, fresh] = tiles_.try_emplace(key);
        if (fresh) {
            it->second.bits.assign(std::size_t{kTileSize} * kTileSize * kTileSize / 64, 0);
            for (int a = 0; a < 3; ++a) {
                it->second.lo[a] = kTileSize;
                it->second.hi[a] = 0;
            }
        }
        last_key_ = key;
        last_ = &it->second;
    }
    return *last_;
}

void TileCensus::add(std::uint32_t x, std::uint32_t y, std::uint32_t z) {
    const std::uint64_t key =
        (std::uint64_t{z / kTileSize} * grid_.y + y / kTileSize) * grid_.x + x / kTileSize;
    Tile& t = tile(key);
    const std::uint32_t l[3] = {x % kTileSize, y % kTileSize, z % kTileSize};
    const std::uint32_t i = (l[2] * kTileSize + l[1]) * kTileSize + l[0];
    t.bits[i / 64] |= std::uint64_t{1} << (i % 64);
    for (int a = 0; a < 3; ++a) {
        t.lo[a] = std::min(t.lo[a], l[a]);
        t.hi[a] = std::max(t.hi[a], l[a]);
    }
}

void TileCensus::add_world(const World& world) {
    const Dims d = world.dims();
    const std::uint8_t* v = world.voxels().data();
    for (std::uint32_t z = 0; z < d.z; ++z) {
        for (std::uint32_t y = 0; y < d.y; ++y) {
            const std::uint8_t* row = v + d.index(0, y, z);
            for (std::uint32_t x = 0; x < d.x; ++x) {
                if (row[x] != 0) {
                    add(x, y, z);
                }
            }
        }
    }
}

void TileCensus::finish(WorldInfo& info, double max_distance) const {
    info.dims = dims_;
    info.tile_grid = grid_;
    info.max_distance = max_distance;
    info.solid = 0;
    info.blocks16 = 0;
    info.blocks4 = 0;
    info.solid_tiles = tiles_.size();
    std::unordered_set<std::uint64_t> stored;
    const auto reach = static_cast<std::int64_t>(std::ceil(max_distance / kTileSize));
    for (const auto& [key, t] : tiles_) {
        // A row of 64 voxels along x is one word (x fastest): OR the words of 4 rows by 4
        // layers and test nibbles for the 4^3 blocks, 16 by 16 and 16-bit groups for 16^3.
        for (const std::uint64_t w : t.bits) {
            info.solid += static_cast<std::uint64_t>(std::popcount(w));
        }
        std::uint64_t acc16[4][4] = {};
        for (std::uint32_t bz = 0; bz < 16; ++bz) {
            for (std::uint32_t by = 0; by < 16; ++by) {
                std::uint64_t acc = 0;
                for (std::uint32_t z = bz * 4; z < bz * 4 + 4; ++z) {
                    for (std::uint32_t y = by * 4; y < by * 4 + 4; ++y) {
                        acc |= t.bits[z * kTileSize + y];
                    }
                }
                acc16[bz / 4][by / 4] |= acc;
                for (std::uint32_t bx = 0; bx < 16; ++bx) {
                    info.blocks4 += ((acc >> (4 * bx)) & 0xF) != 0;
                }
            }
        }
        for (const auto& plane : acc16) {
            for (const std::uint64_t acc : plane) {
                for (std::uint32_t bx = 0; bx < 4; ++bx) {
                    info.blocks16 += ((acc >> (16 * bx)) & 0xFFFF) != 0;
                }
            }
        }
        const std::int64_t t_pos[3] = {static_cast<std::int64_t>(key % grid_.x),
                                       static_cast<std::int64_t>(key / grid_.x % grid_.y),
                                       static_cast<std::int64_t>(key / grid_.x / grid_.y)};
        const std::int64_t n[3] = {grid_.x, grid_.y, grid_.z};
        const std::int64_t dim[3] = {dims_.x, dims_.y, dims_.z};
        std::int64_t lo[3], hi[3];
        for (int a = 0; a < 3; ++a) {
            lo[a] = t_pos[a] * kTileSize + t.lo[a];
            hi[a] = t_pos[a] * kTileSize + t.hi[a];
        }
        for (std::int64_t dz = -reach; dz <= reach; ++dz) {
            for (std::int64_t dy = -reach; dy <= reach; ++dy) {
                for (std::int64_t dx = -reach; dx <= reach; ++dx) {
                    const std::int64_t c[3] = {t_pos[0] + dx, t_pos[1] + dy, t_pos[2] + dz};
                    double gap = 0;
                    bool inside = true;
                    for (int a = 0; a < 3; ++a) {
                        inside = inside && c[a] >= 0 && c[a] < n[a];
                        const std::int64_t b0 = c[a] * kTileSize;
                        const std::int64_t b1 = std::min(b0 + kTileSize, dim[a]) - 1;
                        const std::int64_t g = std::max<std::int64_t>({0, b0 - hi[a], lo[a] - b1});
                        gap = std::max(gap, static_cast<double>(g));
                    }
                    if (inside && (gap < max_distance || (dx == 0 && dy == 0 && dz == 0))) {
                        stored.insert(
                            static_cast<std::uint64_t>((c[2] * n[1] + c[1]) * n[0] + c[0]));
                    }
                }
            }
        }
    }
    info.stored_tiles = stored.size();
    info.stored_voxels = 0;
    for (const std::uint64_t key : stored) {
        const std::uint64_t c[3] = {key % grid_.x, key / grid_.x % grid_.y,
                                    key / grid_.x / grid_.y};
        const std::uint64_t dim[3] = {dims_.x, dims_.y, dims_.z};
        std::uint64_t v = 1;
        for (int a = 0; a < 3; ++a) {
            v *= std::min<std::uint64_t>(kTileSize, dim[a] - c[a] * kTileSize);
        }
        info.stored_voxels += v;
    }
}

}  // namespace voxfield
