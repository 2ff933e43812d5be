#pragma once
// The OpenVDB peer's plugin table (libvoxfield_openvdb_peer.so, built from
// openvdb_peer_plugin.cpp), loaded by openvdb_peer.cpp on first use (voxfield/core/plugin.hpp),
// so that the voxfield binary does not load OpenVDB at every start.
#include <vector>

#include "openvdb_peer.hpp"
#include "voxfield/core/plugin.hpp"

namespace voxfield::bench {

struct OpenVdbPeerPlugin {
    PluginHeader header;
    OpenVdbPeer (*run)(const SparseWorld& world, double bound, const std::vector<ExactTile>& exact);
};

}  // namespace voxfield::bench

// The plugin's entry.
extern "C" const voxfield::PluginHeader* voxfield_openvdb_peer_plugin();
