// Falling sand and water, CPU reference: a 3-D block cellular automaton (rules in sand.hpp).
// Source: Toffoli & Margolus, "Cellular Automata Machines" (1987), ch. 12 (Margolus blocks).
#include "voxfield/core/sand.hpp"

#include <algorithm>
#include <string>
#include <vector>

#include "voxfield/core/error.hpp"

namespace voxfield {

namespace {

constexpr int kAir = 0;
constexpr int kOutside = 256;  // a cell outside the world: a wall nothing enters

}  // namespace

void check_sand_rules(const SandRules& rules) {
    if (rules.sand == 0 || rules.water == 0) {
        throw InputError("the sand and water materials must be 1..255 (0 is air), got sand " +
                         std::to_string(rules.sand) + ", water " + std::to_string(rules.water));
    }
    if (rules.sand == rules.water) {
        throw InputError("the sand and water materials must differ, both are " +
                         std::to_string(rules.sand));
    }
}

std::uint64_t sand_hash(std::uint64_t x) {
    std::uint64_t z = x + 0x9E3779B97F4A7C15ull;
    z = (z ^ (z >> 30)) * 0xBF58476D1CE4E5B9ull;
    z = (z ^ (z >> 27)) * 0x94D049BB133111EBull;
    return z ^ (z >> 31);
}

std::uint64_t sand_step_key(std::uint64_t seed, std::uint64_t step) {
    return sand_hash(sand_hash(seed) ^ step);
}

Int3 sand_block_offset(std::uint64_t step) {
    return {static_cast<std::int64_t>((step >> 1) & 1), static_cast<std::int64_t>(step & 1),
            static_cast<std::int64_t>((step >> 2) & 1)};
}

VoxelChanges sand_step(World& world, const SandRules& rules, std::uint64_t seed,
                       std::uint64_t step) {
    check_sand_rules(rules);
    const Dims d = world.dims();
    const Int3 o = sand_block_offset(step);
    const std::int64_t nbx = (d.x + o.x + 1) / 2;
    const std::int64_t nby = (d.y + o.y + 1) / 2;
    const std::int64_t nbz = (d.z + o.z + 1) / 2;
    const std::uint64_t key = sand_step_key(seed, step);
    const int sand = rules.sand;
    const int water = rules.water;
    // Blocks read the world before the step (the cell below a block belongs to another).
    const std::vector<std::uint8_t> before = world.voxels();
    std::vector<std::uint8_t>& voxels = world.voxels();
    const auto at = [&](std::int64_t x, std::int64_t y, std::int64_t z) {
        return d.contains(x, y, z) ? int{before[d.index(static_cast<std::uint32_t>(x),
                                                        static_cast<std::uint32_t>(y),
                                                        static_cast<std::uint32_t>(z))]}
                                   : kOutside;
    };
    VoxelChanges changes;
    for (std::int64_t k = 0; k < nbz; ++k) {
        for (std::int64_t j = 0; j < nby; ++j) {
            for (std::int64_t i = 0; i < nbx; ++i) {
                const std::int64_t x0 = 2 * i - o.x, y0 = 2 * j - o.y, z0 = 2 * k - o.z;
                int cell[2][4];  // [layer: 0 bottom, 1 top][column dx + 2 * dz]
                bool active = false;
                for (int l = 0; l < 2; ++l) {
                    for (int c = 0; c < 4; ++c) {
                        cell[l][c] = at(x0 + (c & 1), y0 + l, z0 + (c >> 1));
                        active |= cell[l][c] == sand || cell[l][c] == water;
                    }
                }
                if (!active) {
                    continue;
                }
                const std::uint64_t block = static_cast<std::uint64_t>((k * nby + j) * nbx + i);
                const std::uint64_t h = sand_hash(key ^ block);
                const int r = static_cast<int>(h & 3);
                bool moved[2][4] = {};
                // 1. Falling: top-layer sand and water, down or diagonally down.
                for (int n = 0; n < 4; ++n) {
                    const int c = (n + r) & 3;
                    const int v = cell[1][c];
                    if (v != sand && v != water) {
                        continue;
                    }
                    const int below = cell[0][c];
                    if (below == kAir || (v == sand && below == water && !moved[0][c])) {
                        cell[0][c] = v;
                        cell[1][c] = below;
                        moved[0][c] = true;
                        moved[1][c] = below != kAir;
                        continue;
                    }
                    const int a = c ^ 1, b = c ^ 2;
                    const bool free_a = cell[0][a] == kAir, free_b = cell[0][b] == kAir;
                    if (!free_a && !free_b) {
                        continue;
                    }
                    const int t =
                        free_a && free_b ? (((h >> (8 + c)) & 1) != 0 ? b : a) : (free_a ? a : b);
                    cell[0][t] = v;
                    cell[1][c] = kAir;
                    moved[0][t] = true;
                }
                // 2. Sideways: water that has not moved, top layer first.
                for (int l = 1; l >= 0; --l) {
                    for (int n = 0; n < 4; ++n) {
                        const int c = (n + r) & 3;
                        if (cell[l][c] != water || moved[l][c]) {
                            continue;
                        }
                        if (l == 0 && at(x0 + (c & 1), y0 - 1, z0 + (c >> 1)) == kAir) {
                            continue;
                        }
                        const int a = c ^ 1, b = c ^ 2;
                        const bool free_a = cell[l][a] == kAir, free_b = cell[l][b] == kAir;
                        if (!free_a && !free_b) {
                            continue;
                        }
                        const int t = free_a && free_b
                                          ? (((h >> (16 + c + 4 * l)) & 1) != 0 ? b : a)
                                          : (free_a ? a : b);
                        cell[l][t] = water;
                        cell[l][c] = kAir;
                        moved[l][t] = true;
                    }
                }
                for (int l = 0; l < 2; ++l) {
                    for (int c = 0; c < 4; ++c) {
                        const std::int64_t x = x0 + (c & 1), y = y0 + l, z = z0 + (c >> 1);
                        if (!d.contains(x, y, z)) {
                            continue;
                        }
                        const std::size_t index =
                            d.index(static_cast<std::uint32_t>(x), static_cast<std::uint32_t>(y),
                                    static_cast<std::uint32_t>(z));
                        if (cell[l][c] != before[index]) {
                            voxels[index] = static_cast<std::uint8_t>(cell[l][c]);
                            changes.push_back({index, before[index], voxels[index]});
                        }
                    }
                }
            }
        }
    }
    std::sort(changes.begin(), changes.end(),
              [](const VoxelChange& a, const VoxelChange& b) { return a.index < b.index; });
    return changes;
}

World scene_sand(Dims dims, std::uint64_t seed) {
    World w(dims);
    const SandRules rules;
    constexpr std::uint8_t kFloor = 1, kWall = 4;
    const std::int64_t nx = dims.x, ny = dims.y, nz = dims.z;
    const auto set = [&](std::int64_t x, std::int64_t y, std::int64_t z, std::uint8_t v) {
        w.set(static_cast<std::uint32_t>(x), static_cast<std::uint32_t>(y),
              static_cast<std::uint32_t>(z), v);
    };
    for (std::int64_t z = 0; z < nz; ++z) {
        for (std::int64_t x = 0; x < nx; ++x) {
            set(x, 0, z, kFloor);
        }
    }
    // The basin: walls around x in [bx0, bx1), z in [bz0, bz1), y in 1..wall_top; water up
    // to two thirds of the walls.
    const std::int64_t bx0 = nx / 2, bx1 = nx - nx / 8, bz0 = nz / 8, bz1 = nz - nz / 8;
    const std::int64_t wall_top = std::min(ny - 1, ny / 4), water_top = 2 * wall_top / 3;
    for (std::int64_t z = bz0; z < bz1; ++z) {
        for (std::int64_t x = bx0; x < bx1; ++x) {
            const bool wall = x == bx0 || x == bx1 - 1 || z == bz0 || z == bz1 - 1;
            for (std::int64_t y = 1; y <= wall_top; ++y) {
                if (wall) {
                    set(x, y, z, kWall);
                } else if (y <= water_top) {
                    set(x, y, z, rules.water);
                }
            }
        }
    }
    // A sand cone of radius R and height 2R (twice as steep as sand rests), on the floor:
    // h^2 (dx^2 + dz^2) < R^2 (h - (y - 1))^2.
    const std::int64_t cx = nx / 4, cz = nz / 2, radius = std::min(nx, nz) / 6;
    const std::int64_t height = std::min(ny / 2, 2 * radius);
    for (std::int64_t z = cz - radius; z <= cz + radius; ++z) {
        for (std::int64_t x = cx - radius; x <= cx + radius; ++x) {
            const std::int64_t r2 = (x - cx) * (x - cx) + (z - cz) * (z - cz);
            for (std::int64_t y = 1; y <= height; ++y) {
                const std::int64_t above = height - (y - 1);
                if (w.dims().contains(x, y, z) &&
                    height * height * r2 < radius * radius * above * above) {
                    set(x, y, z, rules.sand);
                }
            }
        }
    }
    // Grains in the air of the upper half.
    const std::uint64_t grain_key = sand_hash(~seed);
    for (std::int64_t z = 0; z < nz; ++z) {
        for (std::int64_t y = std::max<std::int64_t>(1, ny / 2); y < ny; ++y) {
            for (std::int64_t x = 0; x < nx; ++x) {
                const std::size_t index =
                    dims.index(static_cast<std::uint32_t>(x), static_cast<std::uint32_t>(y),
                               static_cast<std::uint32_t>(z));
                if (w.voxels()[index] == 0 && sand_hash(grain_key ^ index) % 64 == 0) {
                    w.voxels()[index] = rules.sand;
                }
            }
        }
    }
    return w;
}

}  // namespace voxfield
