// The sparse suite's peer (openvdb_peer.hpp): the sampled tiles here, OpenVDB's sweep in the
// plugin libvoxfield_openvdb_peer.so (openvdb_peer_plugin.cpp), loaded on the first run.
#include "openvdb_peer.hpp"

#include <algorithm>

#include "openvdb_peer_plugin.hpp"

namespace voxfield::bench {

std::vector<std::uint32_t> peer_sample_tiles(const SparseWorld& world, std::uint32_t count) {
    const std::uint32_t tiles = world.tile_count();
    const std::uint32_t step = std::max<std::uint32_t>(1, tiles / std::max(1u, count));
    std::vector<std::uint32_t> out;
    for (std::uint32_t t = 0; t < tiles && out.size() < count; t += step) {
        out.push_back(t);
    }
    return out;
}

OpenVdbPeer run_openvdb_peer(const SparseWorld& world, double bound,
                             const std::vector<ExactTile>& exact) {
    // Loaded at the first run, once.
    static const OpenVdbPeerPlugin& plugin = load_plugin_table<OpenVdbPeerPlugin>(
        project_plugin("the OpenVDB peer's plugin", "libvoxfield_openvdb_peer.so",
                       "VOXFIELD_OPENVDB_PEER_PLUGIN", "voxfield_openvdb_peer_plugin"));
    return plugin.run(world, bound, exact);
}

}  // namespace voxfield::bench
