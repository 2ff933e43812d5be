#pragma once
// Distance metrics and voxel spacing (DESIGN §3): L1, L-inf and L2 between voxel centres,
// each axis offset scaled by its spacing first.
#include <algorithm>
#include <string>
#include <vector>

#include "voxfield/core/world.hpp"

namespace voxfield {

enum class Metric { manhattan, chebyshev, euclidean };

// "manhattan", "chebyshev", "euclidean"; throws InputError listing them otherwise.
Metric parse_metric(const std::string& name);
std::string to_string(Metric m);
const std::vector<std::string>& metric_names();

// Spacing of the voxel grid per world axis (x, y, z), all positive and finite.
struct Spacing {
    double x = 1, y = 1, z = 1;
    bool unit() const { return x == 1 && y == 1 && z == 1; }
    double largest() const { return std::max({x, y, z}); }
    std::string to_string() const;  // "X,Y,Z"
    friend bool operator==(const Spacing&, const Spacing&) = default;
};

// Parses "X,Y,Z" (world axis order); throws InputError on a malformed, non-positive or
// non-finite value.
Spacing parse_spacing(const std::string& text);

// Most steps of the smallest spacing that a distance across the world may span with a
// non-unit spacing: the float scans resolve one step up to 2^24 of them.
inline constexpr double kSpacingStepsLimit = 16777216.0;

// Throws InputError unless the kernels represent `s` on a world of `dims` exactly: every value
// positive and within float range, distances across the world within float range (squared,
// for euclidean) and at most kSpacingStepsLimit times the smallest spacing. The limit and the
// numbers are in the message.
void check_spacing_range(const Spacing& s, Metric m, Dims world);

// The metric's distance for axis offsets (dx, dy, dz) in voxels, scaled by `s`.
double metric_distance(Metric m, const Spacing& s, long dx, long dy, long dz);

}  // namespace voxfield
