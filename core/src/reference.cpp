// Exact Manhattan distance transform by separable 1-D sweeps (L1 is separable: the
// distance is the min over axes' independent 1-D offsets; Rosenfeld & Pfaltz, 1966).
#include "voxfield/core/reference.hpp"

#include <algorithm>
#include <cstdint>
#include <cstdlib>
#include <limits>
#include <vector>

#include "voxfield/core/chunks.hpp"
#include "voxfield/core/format.hpp"

namespace voxfield {

namespace {

// v + 1, except that kInfinite stays kInfinite.
inline std::uint32_t inc_sat(std::uint32_t v) {
    return v + (v != kInfinite ? 1u : 0u);
}

}  // namespace

std::vector<std::uint32_t> reference_manhattan(const World& world) {
    const Dims d = world.dims();
    const std::size_t nx = d.x, ny = d.y, nz = d.z;
    const std::size_t row = nx, slice = nx * ny;
    const auto& vox = world.voxels();
    std::vector<std::uint32_t> f(world.size());

    // x pass: distance to the nearest solid in the same row.
    for (std::size_t r = 0; r < ny * nz; ++r) {
        const std::size_t base = r * row;
        std::uint32_t prev = kInfinite;
        for (std::size_t x = 0; x < nx; ++x) {
            prev = vox[base + x] != 0 ? 0u : inc_sat(prev);
            f[base + x] = prev;
        }
        prev = kInfinite;
        for (std::size_t x = nx; x-- > 0;) {
            prev = std::min(f[base + x], inc_sat(prev));
            f[base + x] = prev;
        }
    }

    // y pass: forward and backward, the inner loop over contiguous x.
    for (std::size_t z = 0; z < nz; ++z) {
        std::uint32_t* s = f.data() + z * slice;
        for (std::size_t y = 1; y < ny; ++y) {
            std::uint32_t* cur = s + y * row;
            const std::uint32_t* prev = cur - row;
            for (std::size_t x = 0; x < nx; ++x) {
                cur[x] = std::min(cur[x], inc_sat(prev[x]));
            }
        }
        for (std::size_t y = ny - 1; y-- > 0;) {
            std::uint32_t* cur = s + y * row;
            const std::uint32_t* next = cur + row;
            for (std::size_t x = 0; x < nx; ++x) {
                cur[x] = std::min(cur[x], inc_sat(next[x]));
            }
        }
    }

    // z pass: forward and backward over whole slices, the inner loop over contiguous x.
    for (std::size_t z = 1; z < nz; ++z) {
        std::uint32_t* cur = f.data() + z * slice;
        const std::uint32_t* prev = cur - slice;
        for (std::size_t i = 0; i < slice; ++i) {
            cur[i] = std::min(cur[i], inc_sat(prev[i]));
        }
    }
    for (std::size_t z = nz - 1; z-- > 0;) {
        std::uint32_t* cur = f.data() + z * slice;
        const std::uint32_t* next = cur + slice;
        for (std::size_t i = 0; i < slice; ++i) {
            cur[i] = std::min(cur[i], inc_sat(next[i]));
        }
    }
    return f;
}

std::vector<std::uint32_t> brute_force_manhattan(const World& world) {
    const Dims d = world.dims();
    struct P {
        std::int64_t x, y, z;
    };
    std::vector<P> solids;
    for (std::uint32_t z = 0; z < d.z; ++z) {
        for (std::uint32_t y = 0; y < d.y; ++y) {
            for (std::uint32_t x = 0; x < d.x; ++x) {
                if (world.at(x, y, z) != 0) {
                    solids.push_back({x, y, z});
                }
            }
        }
    }
    std::vector<std::uint32_t> f(world.size(), kInfinite);
    for (std::uint32_t z = 0; z < d.z; ++z) {
        for (std::uint32_t y = 0; y < d.y; ++y) {
            for (std::uint32_t x = 0; x < d.x; ++x) {
                std::uint32_t best = kInfinite;
                for (const P& p : solids) {
                    const std::int64_t dist =
                        std::llabs(p.x - x) + std::llabs(p.y - y) + std::llabs(p.z - z);
                    best = std::min(best, static_cast<std::uint32_t>(dist));
                }
                f[d.index(x, y, z)] = best;
            }
        }
    }
    return f;
}

namespace {

// Calls f(box) for every chunk of `grid`.
template <class F>
void for_each_chunk(const ChunkGrid& grid, F&& f) {
    const Dims n = grid.chunks();
    for (std::uint32_t cz = 0; cz < n.z; ++cz) {
        for (std::uint32_t cy = 0; cy < n.y; ++cy) {
            for (std::uint32_t cx = 0; cx < n.x; ++cx) {
                f(grid.voxels_of({cx, cy, cz}));
            }
        }
    }
}

// Manhattan distance from (x,y,z) in `b` to the nearest voxel of b's one-voxel shell.
std::uint32_t shell_distance(const Box& b, std::int64_t x, std::int64_t y, std::int64_t z) {
    return static_cast<std::uint32_t>(std::min({x - b.min.x + 1, b.max.x - x, y - b.min.y + 1,
                                                b.max.y - y, z - b.min.z + 1, b.max.z - z}));
}

}  // namespace

std::vector<std::uint32_t> reference_manhattan_chunked(const World& world, std::uint32_t chunk) {
    const ChunkGrid grid(world.dims(), chunk);
    const Dims d = world.dims();
    std::vector<std::uint32_t> f(world.size());
    for_each_chunk(grid, [&](const Box& b) {
        // The chunk alone, outside empty (global semantics), then the shell as extra solid.
        const Dims cd{static_cast<std::uint32_t>(b.max.x - b.min.x),
                      static_cast<std::uint32_t>(b.max.y - b.min.y),
                      static_cast<std::uint32_t>(b.max.z - b.min.z)};
        World sub(cd);
        for (std::uint32_t z = 0; z < cd.z; ++z) {
            for (std::uint32_t y = 0; y < cd.y; ++y) {
                for (std::uint32_t x = 0; x < cd.x; ++x) {
                    sub.set(x, y, z,
                            world.at(static_cast<std::uint32_t>(b.min.x + x),
                                     static_cast<std::uint32_t>(b.min.y + y),
                                     static_cast<std::uint32_t>(b.min.z + z)));
                }
            }
        }
        const auto local = reference_manhattan(sub);
        for (std::uint32_t z = 0; z < cd.z; ++z) {
            for (std::uint32_t y = 0; y < cd.y; ++y) {
                for (std::uint32_t x = 0; x < cd.x; ++x) {
                    const std::int64_t gx = b.min.x + x, gy = b.min.y + y, gz = b.min.z + z;
                    f[d.index(static_cast<std::uint32_t>(gx), static_cast<std::uint32_t>(gy),
                              static_cast<std::uint32_t>(gz))] =
                        std::min(local[cd.index(x, y, z)], shell_distance(b, gx, gy, gz));
                }
            }
        }
    });
    return f;
}

std::vector<std::uint32_t> brute_force_manhattan_chunked(const World& world, std::uint32_t chunk) {
    const ChunkGrid grid(world.dims(), chunk);
    const Dims d = world.dims();
    std::vector<std::uint32_t> f(world.size(), kInfinite);
    for_each_chunk(grid, [&](const Box& b) {
        // Algorithm 2: inside the chunk the world's voxel, on the padding shell a solid.
        auto solid = [&](std::int64_t x, std::int64_t y, std::int64_t z) {
            const bool inside = x >= b.min.x && x < b.max.x && y >= b.min.y && y < b.max.y &&
                                z >= b.min.z && z < b.max.z;
            return !inside || world.at(static_cast<std::uint32_t>(x), static_cast<std::uint32_t>(y),
                                       static_cast<std::uint32_t>(z)) != 0;
        };
        for (std::int64_t z = b.min.z; z < b.max.z; ++z) {
            for (std::int64_t y = b.min.y; y < b.max.y; ++y) {
                for (std::int64_t x = b.min.x; x < b.max.x; ++x) {
                    std::int64_t best = std::numeric_limits<std::int64_t>::max();
                    for (std::int64_t k = b.min.z - 1; k <= b.max.z; ++k) {
                        for (std::int64_t j = b.min.y - 1; j <= b.max.y; ++j) {
                            for (std::int64_t i = b.min.x - 1; i <= b.max.x; ++i) {
                                if (solid(i, j, k)) {
                                    best = std::min<std::int64_t>(
                                        best,
                                        std::llabs(i - x) + std::llabs(j - y) + std::llabs(k - z));
                                }
                            }
                        }
                    }
                    f[d.index(static_cast<std::uint32_t>(x), static_cast<std::uint32_t>(y),
                              static_cast<std::uint32_t>(z))] = static_cast<std::uint32_t>(best);
                }
            }
        }
    });
    return f;
}

}  // namespace voxfield
