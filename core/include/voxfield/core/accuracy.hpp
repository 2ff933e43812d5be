#pragma once
// Accuracy of a distance field against the exact one of the same semantics.
#include <cstdint>
#include <vector>

#include "voxfield/core/format.hpp"

namespace voxfield {

struct Accuracy {
    std::uint32_t max_error = 0;  // max |field - exact|
    double mean_error = 0;        // mean |field - exact| over all voxels
    double over_fraction = 0;     // fraction of voxels with field > exact
    double under_fraction = 0;    // fraction of voxels with field < exact
};

// `field` is encoded in `f`; `exact` holds unsaturated distances (kInfinite allowed), which
// are saturated to max_distance(f) before comparing.
Accuracy compare_to_exact(const std::vector<std::uint8_t>& field, Format f,
                          const std::vector<std::uint32_t>& exact);

// Two fields of any format, `want` the exact one encoded in `f` (encode_real_field); the
// max error is rounded up to a whole number, the mean is kept as is. Infinities are equal.
Accuracy compare_fields(const std::vector<std::uint8_t>& got, const std::vector<std::uint8_t>& want,
                        Format f);

}  // namespace voxfield
