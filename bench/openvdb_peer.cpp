// OpenVDB's fast sweeping as the sparse suite's peer (see openvdb_peer.hpp).
#include "openvdb_peer.hpp"

#include <openvdb/openvdb.h>
#include <openvdb/tools/FastSweeping.h>
#include <openvdb/tools/Morphology.h>
#include <openvdb/tools/ValueTransformer.h>

#include <algorithm>
#include <cmath>

#include "voxfield/core/clock.hpp"

namespace voxfield::bench {
namespace {

// Sets each active fog voxel to 1 where the world is solid, else 0 (one accessor per thread).
struct FogValue {
    explicit FogValue(const openvdb::BoolTree& tree) : solid(tree) {}
    FogValue(const FogValue& other) : solid(other.solid.tree()) {}
    void operator()(const openvdb::FloatGrid::ValueOnIter& it) const {
        it.setValue(solid.isValueOn(it.getCoord()) ? 1.0f : 0.0f);
    }
    mutable openvdb::tree::ValueAccessor<const openvdb::BoolTree> solid;
};

}  // namespace

OpenVdbPeer run_openvdb_peer(const SparseWorld& world, double bound,
                             const std::function<std::vector<float>(const Box&)>& exact,
                             std::uint32_t sample_tiles) {
    openvdb::initialize();
    OpenVdbPeer peer;
    peer.version = openvdb::getLibraryVersionString();
    const auto t_topology = Clock::now();
    const int reach = static_cast<int>(std::ceil(bound));
    openvdb::BoolGrid solid(false);
    {
        auto acc = solid.getAccessor();
        std::vector<std::uint8_t> voxels(kTileVoxels);
        for (std::uint32_t t = 0; t < world.tile_count(); ++t) {
            world.decode_tile(t, voxels);
            const Box b = world.tile_box(t);
            std::size_t i = 0;
            for (std::int64_t z = 0; z < std::int64_t{kTileSize}; ++z) {
                for (std::int64_t y = 0; y < std::int64_t{kTileSize}; ++y) {
                    for (std::int64_t x = 0; x < std::int64_t{kTileSize}; ++x, ++i) {
                        if (voxels[i] != 0) {
                            acc.setValueOn(openvdb::Coord(static_cast<int>(b.min.x + x),
                                                          static_cast<int>(b.min.y + y),
                                                          static_cast<int>(b.min.z + z)),
                                           true);
                        }
                    }
                }
            }
        }
    }
    openvdb::BoolTree band(solid.tree());
    openvdb::tools::dilateActiveValues(band, reach, openvdb::tools::NN_FACE_EDGE_VERTEX,
                                       openvdb::tools::EXPAND_TILES);
    openvdb::BoolTree deep(solid.tree());
    openvdb::tools::erodeActiveValues(deep, reach + 2, openvdb::tools::NN_FACE_EDGE_VERTEX,
                                      openvdb::tools::IGNORE_TILES);
    band.topologyDifference(deep);
    openvdb::FloatGrid fog(0.0f);
    fog.tree().topologyUnion(band);
    openvdb::tools::foreach (fog.beginValueOn(), FogValue(solid.tree()), true, false);
    peer.band_voxels = fog.activeVoxelCount();
    peer.topology_ms = ms_since(t_topology);

    const auto t_sweep = Clock::now();
    const openvdb::FloatGrid::Ptr sdf = openvdb::tools::fogToSdf(fog, 0.5f);
    peer.sweep_ms = ms_since(t_sweep);

    // Error on evenly spread tiles.
    const std::uint32_t tiles = world.tile_count();
    const std::uint32_t step = std::max<std::uint32_t>(1, tiles / std::max(1u, sample_tiles));
    auto acc = sdf->getConstAccessor();
    std::vector<std::uint8_t> voxels(kTileVoxels);
    double sum = 0;
    for (std::uint32_t t = 0; t < tiles; t += step) {
        const Box b = world.tile_box(t);
        const std::vector<float> ex = exact(b);
        world.decode_tile(t, voxels);
        const auto nx = b.max.x - b.min.x, ny = b.max.y - b.min.y;
        for (std::int64_t z = b.min.z; z < b.max.z; ++z) {
            for (std::int64_t y = b.min.y; y < b.max.y; ++y) {
                for (std::int64_t x = b.min.x; x < b.max.x; ++x) {
                    const auto local = static_cast<std::size_t>(
                        ((z - b.min.z) * std::int64_t{kTileSize} + (y - b.min.y)) *
                            std::int64_t{kTileSize} +
                        (x - b.min.x));
                    const float e = ex[static_cast<std::size_t>(
                        ((z - b.min.z) * ny + (y - b.min.y)) * nx + (x - b.min.x))];
                    const openvdb::Coord c(static_cast<int>(x), static_cast<int>(y),
                                           static_cast<int>(z));
                    if (voxels[local] != 0 || e > bound - 1 || !acc.isValueOn(c)) {
                        continue;
                    }
                    const double err = std::abs(static_cast<double>(acc.getValue(c)) + 0.5 - e);
                    sum += err;
                    peer.max_abs_error = std::max(peer.max_abs_error, err);
                    ++peer.compared;
                }
            }
        }
    }
    peer.mean_abs_error = peer.compared > 0 ? sum / static_cast<double>(peer.compared) : 0;
    return peer;
}

}  // namespace voxfield::bench
