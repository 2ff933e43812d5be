#pragma once
// Accuracy of a distance field against the exact one of the same semantics.
#include <cstdint>
#include <span>
#include <vector>

#include "voxfield/core/format.hpp"
#include "voxfield/core/metric.hpp"
#include "voxfield/core/world.hpp"

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

// A feature transform's index planes (3 * count int32: the z plane, then y, then x) checked
// voxel by voxel: each must name a solid voxel of `world` at the voxel's exact distance
// `exact[i]` (reference_distance of `metric` and `spacing`; equal within 1e-9 relative), or
// be -1 on every plane where the world has no solid voxel. With `scipy` (reference_features:
// SciPy's choice among equally near solids) each nearest one must also be that choice.
struct IndexAccuracy {
    std::uint64_t checked = 0;
    std::uint64_t not_nearest = 0;  // out of the world, not solid, or not at the exact distance
    std::uint64_t not_scipy = 0;    // a nearest solid, but not `scipy`'s (0 without it)
    std::int64_t first_wrong = -1;  // the first voxel counted in either, -1 when none
};
IndexAccuracy check_indices(const World& world, Metric metric, const Spacing& spacing,
                            std::span<const std::int32_t> planes, const std::vector<double>& exact,
                            const std::vector<std::int64_t>* scipy);

}  // namespace voxfield
