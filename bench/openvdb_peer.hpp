#pragma once
// The peer a user of sparse volumes would pick for a bounded distance field (issue 24):
// OpenVDB's fast sweeping (tools::fogToSdf) on the same sparse world, timed in the same run as
// voxfield's exact field, with its error against voxfield's exact Euclidean distances.
#include <cstdint>
#include <functional>
#include <string>
#include <vector>

#include "voxfield/core/sparse.hpp"

namespace voxfield::bench {

struct OpenVdbPeer {
    std::string version;            // OpenVDB's library version
    double topology_ms = 0;         // the fog grid: solids, dilated and eroded to the band, valued
    double sweep_ms = 0;            // tools::fogToSdf (the transform a user would time)
    std::uint64_t band_voxels = 0;  // active voxels of the fog grid (the band)
    // Over the empty voxels of the sampled tiles whose exact distance is at most D - 1: the
    // OpenVDB distance plus half a voxel (its iso-surface lies halfway between a solid and an
    // empty centre) against the exact distance between voxel centres.
    std::uint64_t compared = 0;
    double mean_abs_error = 0, max_abs_error = 0;
};

// `exact(box)` returns voxfield's Euclidean f32 field of `box` (x fastest; values beyond the
// bound are D). The band: solid voxels within `bound` + 2 of an empty one and empty voxels
// within `bound` of a solid one (26-neighbour dilation/erosion), so the sweep covers at least
// what the bounded field does. `sample_tiles` of the world's tiles (evenly spread) are
// compared.
OpenVdbPeer run_openvdb_peer(const SparseWorld& world, double bound,
                             const std::function<std::vector<float>(const Box&)>& exact,
                             std::uint32_t sample_tiles);

}  // namespace voxfield::bench
