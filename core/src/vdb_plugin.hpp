#pragma once
// The OpenVDB plugin's table (libvoxfield_vdb.so, built from vdb_plugin.cpp): what of vdb.hpp
// needs OpenVDB itself. vdb.cpp loads it on first use (plugin.hpp) and forwards to it.
#include <filesystem>
#include <functional>
#include <string>

#include "voxfield/core/plugin.hpp"
#include "voxfield/core/vdb.hpp"

namespace voxfield::detail {

struct VdbPlugin {
    PluginHeader header;
    VoxModel (*read)(const std::filesystem::path& path, const std::string& grid);
    SparseWorld (*read_sparse)(const std::filesystem::path& path, const std::string& grid);
    Dims (*extent)(const std::filesystem::path& path, const std::string& grid);
    WorldInfo (*describe)(const std::filesystem::path& path, const std::string& grid,
                          double max_distance);
    // The .vdb file's bytes from boxes of the world and its field (write_vdb's grids).
    std::string (*bytes)(const std::function<bool(VdbBox&)>& next, Format format,
                         const VdbFieldSpec& spec);
};

}  // namespace voxfield::detail

// The plugin's entry.
extern "C" const voxfield::PluginHeader* voxfield_vdb_plugin();
