// .vdb input and output (vdb.hpp): what needs OpenVDB is in the plugin libvoxfield_vdb.so
// (vdb_plugin.cpp), loaded on the first call that needs it, so that a process that never reads
// or writes a .vdb never loads OpenVDB; the output spec and the file writing are here.
#include "voxfield/core/vdb.hpp"

#include <algorithm>
#include <cctype>
#include <string>

#include "output_file.hpp"
#include "vdb_plugin.hpp"
#include "voxfield/core/error.hpp"

namespace voxfield {

namespace {

// Loaded at the first call that needs it, once (a failure throws, and the next call tries again).
const detail::VdbPlugin& plugin() {
    static const detail::VdbPlugin& table = load_plugin_table<detail::VdbPlugin>(project_plugin(
        "the OpenVDB plugin", "libvoxfield_vdb.so", "VOXFIELD_VDB_PLUGIN", "voxfield_vdb_plugin"));
    return table;
}

// The whole world as one box.
std::function<bool(VdbBox&)> one_box(Dims dims, std::span<const std::uint8_t> voxels,
                                     std::span<const std::uint8_t> field) {
    return [dims, voxels, field, done = false](VdbBox& b) mutable {
        if (done) {
            return false;
        }
        done = true;
        b = VdbBox{Box{{0, 0, 0}, {dims.x, dims.y, dims.z}}, voxels, field};
        return true;
    };
}

std::span<const std::uint8_t> as_bytes(const std::string& s) {
    return {reinterpret_cast<const std::uint8_t*>(s.data()), s.size()};
}

}  // namespace

VoxModel read_vdb(const std::filesystem::path& path, const std::string& grid) {
    return plugin().read(path, grid);
}

SparseWorld read_vdb_sparse(const std::filesystem::path& path, const std::string& grid) {
    return plugin().read_sparse(path, grid);
}

Dims vdb_extent(const std::filesystem::path& path, const std::string& grid) {
    return plugin().extent(path, grid);
}

WorldInfo describe_vdb(const std::filesystem::path& path, const std::string& grid,
                       double max_distance) {
    return plugin().describe(path, grid, max_distance);
}

std::optional<VdbFieldSpec> vdb_output_spec(const std::filesystem::path& output,
                                            const Spacing& spacing,
                                            std::optional<double> max_distance, bool signed_field) {
    std::string ext = output.extension().string();
    std::transform(ext.begin(), ext.end(), ext.begin(),
                   [](unsigned char c) { return static_cast<char>(std::tolower(c)); });
    if (ext != ".vdb") {
        return std::nullopt;
    }
    if (spacing.x != spacing.y || spacing.x != spacing.z) {
        throw InputError("'" + output.string() + "': a .vdb output has cube voxels, so --spacing " +
                         spacing.to_string() +
                         " must be the same on every axis (write .npy for other spacings)");
    }
    VdbFieldSpec spec;
    spec.voxel_size = spacing.x;
    spec.background = max_distance.value_or(16.0);
    spec.level_set = signed_field;
    return spec;
}

void write_vdb(const std::filesystem::path& path, Dims dims, std::span<const std::uint8_t> voxels,
               std::span<const std::uint8_t> field, Format format, const VdbFieldSpec& spec) {
    const std::string bytes = plugin().bytes(one_box(dims, voxels, field), format, spec);
    detail::write_file_atomic(path, {as_bytes(bytes)});
}

void write_vdb(OutputBatch& batch, const std::filesystem::path& path, Dims dims,
               std::span<const std::uint8_t> voxels, std::span<const std::uint8_t> field,
               Format format, const VdbFieldSpec& spec) {
    const std::string bytes = plugin().bytes(one_box(dims, voxels, field), format, spec);
    batch.write(path, {as_bytes(bytes)});
}

void write_vdb(OutputBatch& batch, const std::filesystem::path& path,
               const std::function<bool(VdbBox&)>& next, Format format, const VdbFieldSpec& spec) {
    const std::string bytes = plugin().bytes(next, format, spec);
    batch.write(path, {as_bytes(bytes)});
}

}  // namespace voxfield
