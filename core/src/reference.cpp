// Exact Manhattan distance transform by separable 1-D sweeps (L1 is separable: the
// distance is the min over axes' independent 1-D offsets; Rosenfeld & Pfaltz, 1966).
#include "voxfield/core/reference.hpp"

#include <algorithm>
#include <cstdint>
#include <cstdlib>
#include <vector>

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

}  // namespace voxfield
