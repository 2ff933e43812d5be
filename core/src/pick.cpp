// Exact picking by a double-precision voxel DDA (Amanatides & Woo 1987, "A Fast Voxel
// Traversal Algorithm for Ray Tracing"), starting at the camera.
#include "voxfield/core/pick.hpp"

#include <algorithm>
#include <cmath>
#include <cstdint>

namespace voxfield {

std::optional<PickHit> pick_voxel(const World& world, const Vec3d& origin, const Vec3d& direction,
                                  double max_distance) {
    return pick_solid_voxel(
        world.dims(),
        [&world](std::uint32_t x, std::uint32_t y, std::uint32_t z) {
            return world.at(x, y, z) != 0;
        },
        origin, direction, max_distance);
}

std::optional<PickHit> pick_solid_voxel(const Dims& dims, const SolidVoxel& solid,
                                        const Vec3d& origin, const Vec3d& direction,
                                        double max_distance) {
    const Dims d = dims;
    const double size[3] = {double(d.x), double(d.y), double(d.z)};
    for (int a = 0; a < 3; ++a) {
        if (!std::isfinite(origin[a]) || !std::isfinite(direction[a])) {
            return std::nullopt;
        }
    }
    if (direction[0] == 0 && direction[1] == 0 && direction[2] == 0) {
        return std::nullopt;
    }
    // Clip [0, max_distance] to the world box (slab test); remember the entry axis.
    double t0 = 0, t1 = max_distance;
    int entry_axis = -1;
    for (int a = 0; a < 3; ++a) {
        if (direction[a] == 0) {
            if (origin[a] < 0 || origin[a] >= size[a]) {
                return std::nullopt;
            }
            continue;
        }
        double lo = (0 - origin[a]) / direction[a];
        double hi = (size[a] - origin[a]) / direction[a];
        if (lo > hi) {
            std::swap(lo, hi);
        }
        if (lo > t0) {
            t0 = lo;
            entry_axis = a;
        }
        t1 = std::min(t1, hi);
    }
    if (t0 > t1 || (t0 == t1 && entry_axis >= 0)) {
        return std::nullopt;
    }

    // The starting cell: the origin's cell, or the boundary cell the ray enters through.
    std::int64_t cell[3];
    int step[3];
    double t_max[3];
    for (int a = 0; a < 3; ++a) {
        step[a] = direction[a] > 0 ? 1 : (direction[a] < 0 ? -1 : 0);
        double p = origin[a] + t0 * direction[a];
        std::int64_t c = static_cast<std::int64_t>(std::floor(p));
        if (a == entry_axis) {
            c = step[a] > 0 ? 0 : static_cast<std::int64_t>(size[a]) - 1;
        }
        const std::int64_t limit = static_cast<std::int64_t>(size[a]) - 1;
        cell[a] = std::clamp<std::int64_t>(c, 0, limit);
    }
    auto next_crossing = [&](int a) {
        if (step[a] == 0) {
            return std::numeric_limits<double>::infinity();
        }
        const double boundary = double(cell[a] + (step[a] > 0 ? 1 : 0));
        return (boundary - origin[a]) / direction[a];
    };
    for (int a = 0; a < 3; ++a) {
        t_max[a] = next_crossing(a);
    }

    Int3 normal{0, 0, 0};
    if (entry_axis >= 0) {
        std::int64_t n[3] = {0, 0, 0};
        n[entry_axis] = -step[entry_axis];
        normal = {n[0], n[1], n[2]};
    }
    double t = t0;
    while (true) {
        if (solid(static_cast<std::uint32_t>(cell[0]), static_cast<std::uint32_t>(cell[1]),
                  static_cast<std::uint32_t>(cell[2]))) {
            return PickHit{{cell[0], cell[1], cell[2]}, normal, t};
        }
        int a = 0;
        if (t_max[1] < t_max[a]) {
            a = 1;
        }
        if (t_max[2] < t_max[a]) {
            a = 2;
        }
        t = t_max[a];
        if (!(t <= t1) || step[a] == 0) {
            return std::nullopt;
        }
        cell[a] += step[a];
        if (cell[a] < 0 || cell[a] >= static_cast<std::int64_t>(size[a])) {
            return std::nullopt;
        }
        std::int64_t n[3] = {0, 0, 0};
        n[a] = -step[a];
        normal = {n[0], n[1], n[2]};
        t_max[a] = next_crossing(a);
    }
}

}  // namespace voxfield
