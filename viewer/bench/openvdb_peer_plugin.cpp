// OpenVDB's fast sweeping as the sparse suite's peer (see openvdb_peer.hpp): the plugin
// libvoxfield_openvdb_peer.so (openvdb_peer_plugin.hpp), loaded by openvdb_peer.cpp on first use.
#include "openvdb_peer_plugin.hpp"

#include <openvdb/openvdb.h>
#include <openvdb/tools/FastSweeping.h>
#include <openvdb/tools/Morphology.h>
#include <openvdb/tools/ValueTransformer.h>

#include <algorithm>
#include <cmath>
#include <string>

#include "process_memory.hpp"
#include "voxfield/core/clock.hpp"

namespace voxfield::bench {
namespace {

// Sets each active fog voxel to 1 where the world is solid, else 0.
struct FogValue {
    explicit FogValue(const openvdb::BoolTree& tree) : solid(tree) {}
    void operator()(const openvdb::FloatGrid::ValueOnIter& it) const {
        it.setValue(solid.isValueOn(it.getCoord()) ? 1.0f : 0.0f);
    }
    mutable openvdb::tree::ValueAccessor<const openvdb::BoolTree> solid;
};

// The world's solid voxels.
void add_solids(const SparseWorld& world, openvdb::BoolTree& tree) {
    openvdb::tree::ValueAccessor<openvdb::BoolTree> acc(tree);
    std::vector<std::uint8_t> voxels(kTileVoxels);
    for (std::uint32_t t = 0; t < world.tile_count(); ++t) {
        const Box b = world.tile_box(t);
        world.decode_tile(t, voxels);
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

OpenVdbPeer run(const SparseWorld& world, double bound, const std::vector<ExactTile>& exact) {
    openvdb::initialize();
    OpenVdbPeer peer;
    peer.version = openvdb::getLibraryVersionString();
    peer.peak_is_own = reset_peak_rss();
    peer.rss_before_bytes = rss_now_bytes();
    const Dims d = world.dims();
    const int reach = static_cast<int>(std::ceil(bound));
    const auto t_topology = Clock::now();
    openvdb::FloatGrid fog(0.0f);
    {
        openvdb::BoolTree solid(false);
        add_solids(world, solid);
        openvdb::BoolTree band(solid);
        openvdb::tools::dilateActiveValues(band, reach, openvdb::tools::NN_FACE_EDGE_VERTEX,
                                           openvdb::tools::EXPAND_TILES);
        {
            openvdb::BoolTree deep(solid);
            openvdb::tools::erodeActiveValues(deep, 1, openvdb::tools::NN_FACE_EDGE_VERTEX,
                                              openvdb::tools::IGNORE_TILES);
            band.topologyDifference(deep);
        }
        band.clip(
            openvdb::CoordBBox(openvdb::Coord(0, 0, 0),
                               openvdb::Coord(static_cast<int>(d.x) - 1, static_cast<int>(d.y) - 1,
                                              static_cast<int>(d.z) - 1)));
        fog.tree().topologyUnion(band);
        band.clear();
        // The dilation leaves 8^3 blocks wholly in the band as active tiles: each voxel is
        // valued on its own below.
        fog.tree().voxelizeActiveTiles();
        // On one thread: valued by tools::foreach on several, some voxels of the 1024 x 256 x
        // 1024 city took wrong values (errors of up to 9 voxels that varied run to run and
        // vanished on one thread), and one thread was no slower there.
        openvdb::tools::foreach (fog.beginValueOn(), FogValue(solid), false);
    }
    peer.band_voxels = fog.activeVoxelCount();
    peer.leaf_nodes = fog.tree().leafCount();
    peer.topology_ms = ms_since(t_topology);

    // tools::fogToSdf(fog, 0.5f, 1), with the fog grid released once the sweep has its copy.
    auto t_sweep = Clock::now();
    openvdb::tools::FastSweeping<openvdb::FloatGrid> sweep;
    const bool valid = sweep.initSdf(fog, 0.5f, false);
    peer.sweep_ms = ms_since(t_sweep);
    fog.clear();
    t_sweep = Clock::now();
    if (valid) {
        sweep.sweep(1);
    }
    const openvdb::FloatGrid::Ptr sdf = sweep.sdfGrid();
    peer.sweep_ms += ms_since(t_sweep);
    peer.peak_rss_bytes = peak_rss_bytes();
    sweep.clear();

    double sum = 0;
    std::vector<std::uint8_t> voxels(kTileVoxels);
    auto acc = sdf->getConstAccessor();
    for (const ExactTile& tile : exact) {
        const Box b = world.tile_box(tile.tile);
        world.decode_tile(tile.tile, voxels);
        const auto nx = b.max.x - b.min.x, ny = b.max.y - b.min.y;
        for (std::int64_t z = b.min.z; z < b.max.z; ++z) {
            for (std::int64_t y = b.min.y; y < b.max.y; ++y) {
                for (std::int64_t x = b.min.x; x < b.max.x; ++x) {
                    const auto local = static_cast<std::size_t>(
                        ((z - b.min.z) * std::int64_t{kTileSize} + (y - b.min.y)) *
                            std::int64_t{kTileSize} +
                        (x - b.min.x));
                    const float e = tile.values[static_cast<std::size_t>(
                        ((z - b.min.z) * ny + (y - b.min.y)) * nx + (x - b.min.x))];
                    const openvdb::Coord c(static_cast<int>(x), static_cast<int>(y),
                                           static_cast<int>(z));
                    if (voxels[local] != 0 || e > bound - 1 || !valid || !acc.isValueOn(c)) {
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

const OpenVdbPeerPlugin plugin{{VOXFIELD_PLUGIN_BUILD_ID}, run};

}  // namespace
}  // namespace voxfield::bench

const voxfield::PluginHeader* voxfield_openvdb_peer_plugin() {
    return &voxfield::bench::plugin.header;
}
