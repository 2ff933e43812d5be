// Reference fields of every metric by exact separable minimisation (the distance is the
// minimum over the nearest-on-each-line decomposition of Saito & Toriwaki 1994 for L2,
// and its min-plus / min-max analogues for L1 and L-inf), each voxel of a line searching
// outwards until the offset alone exceeds the best candidate (O(n^2) at worst).
#include <algorithm>
#include <cmath>
#include <cstdint>
#include <limits>
#include <vector>

#include "voxfield/core/reference.hpp"

namespace voxfield {
namespace {

constexpr double kInf = std::numeric_limits<double>::infinity();

// The partial distance carried between passes: L2 squared, L1 and L-inf plain.
double combine(Metric m, double partial, double offset) {
    switch (m) {
        case Metric::manhattan:
            return partial + offset;
        case Metric::chebyshev:
            return std::max(partial, offset);
        case Metric::euclidean:
            return partial + offset * offset;
    }
    return kInf;
}

// Partial distances from each voxel of `dims` to the nearest voxel with target[i] set.
std::vector<double> partial_field(Dims dims, const std::vector<char>& target, Metric m,
                                  const Spacing& s) {
    const std::size_t nx = dims.x, ny = dims.y, nz = dims.z;
    std::vector<double> g(dims.count());
    for (std::size_t i = 0; i < g.size(); ++i) {
        g[i] = target[i] ? 0.0 : kInf;
    }
    std::vector<double> line, out;
    // One pass along an axis: lines of length n, element stride `stride`, starting at every
    // index whose coordinate on that axis is 0.
    auto pass = [&](std::size_t n, std::size_t stride, double spacing) {
        line.resize(n);
        out.resize(n);
        for (std::size_t start = 0; start < g.size(); ++start) {
            if ((start / stride) % n != 0) {
                continue;
            }
            bool any = false;
            for (std::size_t i = 0; i < n; ++i) {
                line[i] = g[start + i * stride];
                any = any || line[i] != kInf;
            }
            if (!any) {
                continue;  // no target on the line: it stays infinite
            }
            // Every candidate at offset k costs at least the offset's own part, so the
            // search outwards from i stops once that reaches the best found.
            for (std::size_t i = 0; i < n; ++i) {
                double best = kInf;
                for (std::size_t k = 0; k < n; ++k) {
                    const double offset = spacing * static_cast<double>(k);
                    if (combine(m, 0.0, offset) >= best) {
                        break;
                    }
                    if (k <= i) {
                        best = std::min(best, combine(m, line[i - k], offset));
                    }
                    if (i + k < n) {
                        best = std::min(best, combine(m, line[i + k], offset));
                    }
                }
                out[i] = best;
            }
            for (std::size_t i = 0; i < n; ++i) {
                g[start + i * stride] = out[i];
            }
        }
    };
    pass(nx, 1, s.x);
    pass(ny, nx, s.y);
    pass(nz, nx * ny, s.z);
    if (m == Metric::euclidean) {
        for (double& v : g) {
            v = std::sqrt(v);
        }
    }
    return g;
}

std::vector<char> solids(const World& world) {
    std::vector<char> t(world.size());
    for (std::size_t i = 0; i < t.size(); ++i) {
        t[i] = world.voxels()[i] != 0;
    }
    return t;
}

// The world inside one layer of empty voxels, as a solid mask.
Dims padded(Dims d) {
    return {d.x + 2, d.y + 2, d.z + 2};
}

std::vector<char> padded_solids(const World& world) {
    const Dims d = world.dims();
    const Dims p = padded(d);
    std::vector<char> t(p.count(), 0);
    for (std::uint32_t z = 0; z < d.z; ++z) {
        for (std::uint32_t y = 0; y < d.y; ++y) {
            for (std::uint32_t x = 0; x < d.x; ++x) {
                t[p.index(x + 1, y + 1, z + 1)] = world.at(x, y, z) != 0;
            }
        }
    }
    return t;
}

// Combines the padded grid's distances to solids (for empties) and to empties (for solids).
std::vector<double> crop_signed(const World& world, const std::vector<char>& mask,
                                const std::vector<double>& to_solid,
                                const std::vector<double>& to_empty) {
    const Dims d = world.dims();
    const Dims p = padded(d);
    std::vector<double> out(world.size());
    for (std::uint32_t z = 0; z < d.z; ++z) {
        for (std::uint32_t y = 0; y < d.y; ++y) {
            for (std::uint32_t x = 0; x < d.x; ++x) {
                const std::size_t i = p.index(x + 1, y + 1, z + 1);
                out[d.index(x, y, z)] = mask[i] ? -to_empty[i] : to_solid[i];
            }
        }
    }
    return out;
}

std::vector<double> brute(Dims dims, const std::vector<char>& target, Metric m, const Spacing& s) {
    std::vector<std::size_t> sites;
    for (std::size_t i = 0; i < target.size(); ++i) {
        if (target[i]) {
            sites.push_back(i);
        }
    }
    std::vector<double> out(dims.count(), kInf);
    const std::size_t nx = dims.x, ny = dims.y;
    for (std::size_t i = 0; i < out.size(); ++i) {
        const long x = static_cast<long>(i % nx), y = static_cast<long>(i / nx % ny),
                   z = static_cast<long>(i / (nx * ny));
        for (std::size_t j : sites) {
            const long jx = static_cast<long>(j % nx), jy = static_cast<long>(j / nx % ny),
                       jz = static_cast<long>(j / (nx * ny));
            out[i] = std::min(out[i], metric_distance(m, s, x - jx, y - jy, z - jz));
        }
    }
    return out;
}

// SciPy's order of equally near targets: the lowest (x, y, z), x first.
std::uint64_t tie_key(Dims d, std::size_t i) {
    const std::uint64_t x = i % d.x, y = i / d.x % d.y, z = i / d.x / d.y;
    return (x * d.y + y) * d.z + z;
}

std::vector<std::int64_t> features(Dims dims, const std::vector<char>& target, Metric m,
                                   const Spacing& s) {
    const std::size_t nx = dims.x, ny = dims.y, nz = dims.z;
    // Per voxel (partial distance, tie key of its target, its target's index); -1: none.
    struct Best {
        double g;
        std::uint64_t key;
        std::int64_t at;
        bool operator<(const Best& o) const { return g < o.g || (g == o.g && key < o.key); }
    };
    std::vector<Best> g(dims.count());
    for (std::size_t i = 0; i < g.size(); ++i) {
        g[i] = target[i] ? Best{0.0, tie_key(dims, i), static_cast<std::int64_t>(i)}
                         : Best{kInf, 0, -1};
    }
    std::vector<Best> line, out;
    auto pass = [&](std::size_t n, std::size_t stride, double spacing) {
        line.resize(n);
        out.resize(n);
        for (std::size_t start = 0; start < g.size(); ++start) {
            if ((start / stride) % n != 0) {
                continue;
            }
            for (std::size_t i = 0; i < n; ++i) {
                line[i] = g[start + i * stride];
            }
            // Outwards from i until the offset alone passes the best (an offset equal to it
            // may still tie).
            for (std::size_t i = 0; i < n; ++i) {
                Best best{kInf, 0, -1};
                for (std::size_t k = 0; k < n; ++k) {
                    const double offset = spacing * static_cast<double>(k);
                    if (combine(m, 0.0, offset) > best.g) {
                        break;
                    }
                    for (std::size_t j : {i - k, i + k}) {
                        if (j < n && line[j].at >= 0) {
                            const Best c{combine(m, line[j].g, offset), line[j].key, line[j].at};
                            best = c < best ? c : best;
                        }
                    }
                }
                out[i] = best;
            }
            for (std::size_t i = 0; i < n; ++i) {
                g[start + i * stride] = out[i];
            }
        }
    };
    pass(nx, 1, s.x);
    pass(ny, nx, s.y);
    pass(nz, nx * ny, s.z);
    std::vector<std::int64_t> at(g.size());
    for (std::size_t i = 0; i < g.size(); ++i) {
        at[i] = g[i].at;
    }
    return at;
}

std::vector<char> inverted(const std::vector<char>& mask) {
    std::vector<char> t(mask.size());
    for (std::size_t i = 0; i < t.size(); ++i) {
        t[i] = !mask[i];
    }
    return t;
}

}  // namespace

std::vector<double> reference_distance(const World& world, Metric metric, const Spacing& spacing) {
    return partial_field(world.dims(), solids(world), metric, spacing);
}

std::vector<double> reference_signed(const World& world, Metric metric, const Spacing& spacing) {
    const Dims p = padded(world.dims());
    const std::vector<char> mask = padded_solids(world);
    return crop_signed(world, mask, partial_field(p, mask, metric, spacing),
                       partial_field(p, inverted(mask), metric, spacing));
}

std::vector<double> brute_force_distance(const World& world, Metric metric,
                                         const Spacing& spacing) {
    return brute(world.dims(), solids(world), metric, spacing);
}

std::vector<double> brute_force_signed(const World& world, Metric metric, const Spacing& spacing) {
    const Dims p = padded(world.dims());
    const std::vector<char> mask = padded_solids(world);
    return crop_signed(world, mask, brute(p, mask, metric, spacing),
                       brute(p, inverted(mask), metric, spacing));
}

std::vector<std::int64_t> reference_features(const World& world, Metric metric,
                                             const Spacing& spacing) {
    return features(world.dims(), solids(world), metric, spacing);
}

std::vector<std::int64_t> brute_force_features(const World& world, Metric metric,
                                               const Spacing& spacing) {
    const Dims d = world.dims();
    std::vector<std::size_t> sites;
    for (std::size_t j = 0; j < world.size(); ++j) {
        if (world.voxels()[j] != 0) {
            sites.push_back(j);
        }
    }
    std::vector<std::int64_t> out(world.size(), -1);
    for (std::size_t i = 0; i < out.size(); ++i) {
        const long x = static_cast<long>(i % d.x), y = static_cast<long>(i / d.x % d.y),
                   z = static_cast<long>(i / d.x / d.y);
        double best = kInf;
        std::uint64_t best_key = 0;
        for (std::size_t j : sites) {
            const double v = metric_distance(metric, spacing, x - static_cast<long>(j % d.x),
                                             y - static_cast<long>(j / d.x % d.y),
                                             z - static_cast<long>(j / d.x / d.y));
            const std::uint64_t key = tie_key(d, j);
            if (v < best || (v == best && key < best_key)) {
                best = v;
                best_key = key;
                out[i] = static_cast<std::int64_t>(j);
            }
        }
    }
    return out;
}

}  // namespace voxfield
