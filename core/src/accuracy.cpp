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

}  // namespace voxfield
