// Brushes: place / erase / paint a sphere or a cube, clipped to the world (DESIGN §4).
#include "voxfield/core/brush.hpp"

#include <algorithm>
#include <cmath>
#include <cstddef>
#include <cstdint>
#include <limits>
#include <string>

#include "voxfield/core/error.hpp"

namespace voxfield {

std::string to_string(BrushOp op) {
    switch (op) {
        case BrushOp::place:
            return "place";
        case BrushOp::erase:
            return "erase";
        case BrushOp::paint:
            return "paint";
    }
    return "unknown";
}

std::string to_string(BrushShape shape) {
    switch (shape) {
        case BrushShape::sphere:
            return "sphere";
        case BrushShape::cube:
            return "cube";
    }
    return "unknown";
}

namespace {

void check_radius(std::int64_t radius) {
    if (radius < 0 || radius > kMaxBrushRadius) {
        throw InputError("invalid brush radius " + std::to_string(radius) + ": must be 0.." +
                         std::to_string(kMaxBrushRadius));
    }
}

// [c - r, c + r] intersected with [0, size), as a half-open range; lo >= hi when empty.
// Safe from overflow for every int64 centre (r >= 0).
void clip_axis(std::int64_t c, std::int64_t r, std::uint32_t size, std::int64_t& lo,
               std::int64_t& hi) {
    const std::int64_t last = std::int64_t{size} - 1;
    // c < 0: c - r may overflow, but the clipped low end is 0 anyway.
    lo = c < 0 ? 0 : std::max<std::int64_t>(0, c - r);
    // c > last: c + r may overflow, but the clipped high end is `last` anyway.
    hi = (c > last ? last : std::min(last, c + r)) + 1;
    if (hi < lo) {
        hi = lo;  // the range lies entirely before or beyond the world
    }
}

// |v| without overflow, also for INT64_MIN.
std::uint64_t magnitude(std::int64_t v) {
    const auto u = static_cast<std::uint64_t>(v);
    return v < 0 ? std::uint64_t{0} - u : u;
}

// floor(sqrt(n)) exactly, for n < 2^62.
std::int64_t isqrt(std::int64_t n) {
    auto r = static_cast<std::int64_t>(std::sqrt(static_cast<double>(n)));
    while (r > 0 && r * r > n) {
        --r;
    }
    while ((r + 1) * (r + 1) <= n) {
        ++r;
    }
    return r;
}

}  // namespace

Box brush_bounds(const Brush& brush, Dims dims) {
    check_radius(brush.radius);
    Box b;
    clip_axis(brush.centre.x, brush.radius, dims.x, b.min.x, b.max.x);
    clip_axis(brush.centre.y, brush.radius, dims.y, b.min.y, b.max.y);
    clip_axis(brush.centre.z, brush.radius, dims.z, b.min.z, b.max.z);
    return b.empty() ? Box{} : b;
}

bool brush_contains(BrushShape shape, std::int64_t radius, std::int64_t dx, std::int64_t dy,
                    std::int64_t dz) {
    check_radius(radius);
    const auto r = static_cast<std::uint64_t>(radius);
    const std::uint64_t ax = magnitude(dx), ay = magnitude(dy), az = magnitude(dz);
    if (ax > r || ay > r || az > r) {
        return false;  // outside the cube, hence outside the sphere too
    }
    if (shape == BrushShape::cube) {
        return true;
    }
    // Every offset is <= r < 2^31 here, so the sum of squares is exact in 64 bits.
    return ax * ax + ay * ay + az * az <= r * r;
}

EditResult apply_brush(World& world, const Brush& brush) {
    check_radius(brush.radius);
    if (brush.op != BrushOp::erase && brush.material == 0) {
        throw InputError("invalid material 0 for " + to_string(brush.op) +
                         ": must be 1..255 (use erase to clear voxels)");
    }
    EditResult result;
    const Dims dims = world.dims();
    const Box box = brush_bounds(brush, dims);
    if (box.empty()) {
        return result;
    }
    const std::uint8_t target = brush.op == BrushOp::erase ? std::uint8_t{0} : brush.material;
    const std::int64_t r = brush.radius;
    const Int3 c = brush.centre;  // within r of the world on every axis, as box is non-empty
    std::vector<std::uint8_t>& voxels = world.voxels();

    constexpr std::int64_t kBig = std::numeric_limits<std::int64_t>::max();
    Int3 lo{kBig, kBig, kBig}, hi{-kBig, -kBig, -kBig};
    Int3 occ_lo = lo, occ_hi = hi;
    auto grow = [](Int3& mn, Int3& mx, std::int64_t x, std::int64_t y, std::int64_t z) {
        mn = {std::min(mn.x, x), std::min(mn.y, y), std::min(mn.z, z)};
        mx = {std::max(mx.x, x + 1), std::max(mx.y, y + 1), std::max(mx.z, z + 1)};
    };

    for (std::int64_t z = box.min.z; z < box.max.z; ++z) {
        const std::int64_t dz = z - c.z;
        for (std::int64_t y = box.min.y; y < box.max.y; ++y) {
            const std::int64_t dy = y - c.y;
            std::int64_t x0 = box.min.x, x1 = box.max.x;
            if (brush.shape == BrushShape::sphere) {
                const std::int64_t rem = r * r - dy * dy - dz * dz;
                if (rem < 0) {
                    continue;
                }
                const std::int64_t half = isqrt(rem);
                x0 = std::max(x0, c.x - half);
                x1 = std::min(x1, c.x + half + 1);
            }
            const std::size_t row =
                dims.index(0, static_cast<std::uint32_t>(y), static_cast<std::uint32_t>(z));
            for (std::int64_t x = x0; x < x1; ++x) {
                const std::size_t i = row + static_cast<std::size_t>(x);
                const std::uint8_t before = voxels[i];
                if (before == target || (brush.op == BrushOp::paint && before == 0)) {
                    continue;
                }
                voxels[i] = target;
                result.changes.push_back({i, before, target});
                grow(lo, hi, x, y, z);
                if (before == 0) {
                    ++result.became_solid;
                    grow(occ_lo, occ_hi, x, y, z);
                } else if (target == 0) {
                    ++result.became_empty;
                    grow(occ_lo, occ_hi, x, y, z);
                } else {
                    ++result.recoloured;
                }
            }
        }
    }
    if (!result.changes.empty()) {
        result.bounds = Box{lo, hi};
    }
    if (result.occupancy_changed()) {
        result.occupancy_bounds = Box{occ_lo, occ_hi};
    }
    return result;
}

}  // namespace voxfield
