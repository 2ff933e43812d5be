#include "voxfield/core/accuracy.hpp"

#include <algorithm>
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

}  // namespace voxfield
