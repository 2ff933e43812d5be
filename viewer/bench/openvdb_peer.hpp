#pragma once
// The peer a user of sparse volumes would pick for a bounded distance field (issue 24):
// OpenVDB's fast sweeping (tools::FastSweeping, what tools::fogToSdf runs) on the same sparse
// world, timed in the same run as voxfield's exact field, with its error against voxfield's
// exact Euclidean distances. One implementation for `voxfield bench --suite sparse --peer` and
// bench/sparse_bench --peer.
#include <cstdint>
#include <string>
#include <vector>

#include "voxfield/core/sparse.hpp"

namespace voxfield::bench {

// voxfield's exact unsigned Euclidean f32 field of one tile (x fastest over the tile's box,
// clipped to the world; values beyond the bound are the bound), read before the peer runs so
// that the device's world and field can be released first.
struct ExactTile {
    std::uint32_t tile = 0;
    std::vector<float> values;
};

// The tiles compared: `count` of the world's tiles, evenly spread.
std::vector<std::uint32_t> peer_sample_tiles(const SparseWorld& world, std::uint32_t count);

struct OpenVdbPeer {
    std::string version;            // OpenVDB's library version
    double topology_ms = 0;         // the fog grid: solids, dilated to the band, valued
    double sweep_ms = 0;            // FastSweeping::initSdf + sweep(1), as fogToSdf runs them
    std::uint64_t band_voxels = 0;  // active voxels of the fog grid (the band)
    std::uint64_t leaf_nodes = 0;   // its 8^3 leaf nodes
    double rss_before_bytes = 0;    // resident memory when the peer started
    // The peak resident memory while the peer ran (peak_is_own), else the process's peak.
    double peak_rss_bytes = 0;
    bool peak_is_own = false;
    // Over the empty voxels of the sampled tiles whose exact distance is at most D - 1: the
    // OpenVDB distance plus half a voxel (its iso-surface lies halfway between a solid and an
    // empty centre) against the exact distance between voxel centres.
    std::uint64_t compared = 0;
    double mean_abs_error = 0, max_abs_error = 0;
};

// The band: empty voxels within ceil(`bound`) of a solid one and the solid voxels with an
// empty 26-neighbour (the surface the sweep starts from; the field compared is unsigned, so
// deeper solids are not swept), clipped to the world, as a FloatGrid fog (1 solid, 0 empty)
// built from the world's tiles; then FastSweeping with iso-value 0.5 and one iteration
// (fogToSdf's), the fog grid released once the sweep has its copy (OpenVDB's sweep holds its
// copy and the voxel slices of its four sweep directions at once). `exact` holds the tiles to
// compare.
OpenVdbPeer run_openvdb_peer(const SparseWorld& world, double bound,
                             const std::vector<ExactTile>& exact);

}  // namespace voxfield::bench
