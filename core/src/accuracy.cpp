#include "voxfield/core/accuracy.hpp"

#include <algorithm>
#include <cmath>
#include <stdexcept>

namespace voxfield {

Accuracy compare_to_exact(const std::vector<std::uint8_t>& field, Format f,
                          const std::vector<std::uint32_t>& exact) {
    if (field.size() != exact.size() * element_size(f)) {
        throw std::invalid_argument("compare_to_exact: field and exact sizes differ");
    }
    const std::uint32_t cap = max_distance(f);
    Accuracy a;
    double sum = 0;
    std::size_t over = 0, under = 0;
    for (std::size_t i = 0; i < exact.size(); ++i) {
        const std::uint32_t want = std::min(exact[i], cap);
        const std::uint32_t got = decode_distance(field, f, i);
        const std::uint32_t err = got > want ? got - want : want - got;
        over += got > want;
        under += got < want;
        a.max_error = std::max(a.max_error, err);
        sum += err;
    }
    if (!exact.empty()) {
        const auto n = static_cast<double>(exact.size());
        a.mean_error = sum / n;
        a.over_fraction = static_cast<double>(over) / n;
        a.under_fraction = static_cast<double>(under) / n;
    }
    return a;
}

Accuracy compare_fields(const std::vector<std::uint8_t>& got, const std::vector<std::uint8_t>& want,
                        Format f) {
    if (got.size() != want.size()) {
        throw std::invalid_argument("compare_fields: field sizes differ");
    }
    const std::size_t n = got.size() / element_size(f);
    Accuracy a;
    double sum = 0, max_err = 0;
    std::size_t over = 0, under = 0;
    for (std::size_t i = 0; i < n; ++i) {
        const double g = decode_value(got, f, i);
        const double w = decode_value(want, f, i);
        if (g == w) {
            continue;
        }
        const double err = std::isinf(g) || std::isinf(w) ? 1e300 : std::fabs(g - w);
        over += g > w;
        under += g < w;
        max_err = std::max(max_err, err);
        sum += std::min(err, 1e300 / static_cast<double>(n));
    }
    if (n != 0) {
        const auto count = static_cast<double>(n);
        a.max_error = static_cast<std::uint32_t>(std::min(std::ceil(max_err), 4294967295.0));
        a.mean_error = sum / count;
        a.over_fraction = static_cast<double>(over) / count;
        a.under_fraction = static_cast<double>(under) / count;
    }
    return a;
}

IndexAccuracy check_indices(const World& world, Metric metric, const Spacing& spacing,
                            std::span<const std::int32_t> planes, const std::vector<double>& exact,
                            const std::vector<std::int64_t>* scipy) {
    const Dims d = world.dims();
    const std::size_t n = d.count();
    if (planes.size() != 3 * n || exact.size() != n || (scipy != nullptr && scipy->size() != n)) {
        throw std::invalid_argument("check_indices: planes, distances and world sizes differ");
    }
    const bool any_solid = world.solid_count() != 0;
    IndexAccuracy a;
    a.checked = n;
    for (std::size_t i = 0; i < n; ++i) {
        const std::int64_t z = planes[i], y = planes[n + i], x = planes[2 * n + i];
        bool nearest = false;
        if (!any_solid) {
            nearest = x == -1 && y == -1 && z == -1;
        } else if (x >= 0 && y >= 0 && z >= 0 && x < d.x && y < d.y && z < d.z) {
            const std::size_t target =
                d.index(static_cast<std::uint32_t>(x), static_cast<std::uint32_t>(y),
                        static_cast<std::uint32_t>(z));
            const auto vx = static_cast<std::int64_t>(i % d.x);
            const auto vy = static_cast<std::int64_t>(i / d.x % d.y);
            const auto vz = static_cast<std::int64_t>(i / d.x / d.y);
            const double dist = metric_distance(metric, spacing, x - vx, y - vy, z - vz);
            nearest = world.voxels()[target] != 0 &&
                      std::fabs(dist - exact[i]) <= 1e-9 * std::max(1.0, exact[i]);
            if (nearest && scipy != nullptr && (*scipy)[i] != static_cast<std::int64_t>(target)) {
                ++a.not_scipy;
                a.first_wrong = a.first_wrong < 0 ? static_cast<std::int64_t>(i) : a.first_wrong;
            }
        }
        if (!nearest) {
            ++a.not_nearest;
            a.first_wrong = a.first_wrong < 0 ? static_cast<std::int64_t>(i) : a.first_wrong;
        }
    }
    return a;
}

}  // namespace voxfield
