#pragma once
// OpenVDB .vdb input and output through Debian's libopenvdb (DESIGN §3). core/ only: no GPU
// API. Index (i, j, k) of a grid is our voxel (x, y, z).
#include <cstdint>
#include <filesystem>
#include <functional>
#include <optional>
#include <span>
#include <string>

#include "voxfield/core/format.hpp"
#include "voxfield/core/metric.hpp"
#include "voxfield/core/output.hpp"
#include "voxfield/core/sparse.hpp"
#include "voxfield/core/vox.hpp"
#include "voxfield/core/world_info.hpp"

namespace voxfield {

// Reads the grid named `grid` (empty: the first grid of the file) as a world whose origin is
// the grid's active bounding box's minimum corner. A level set's interior (value < 0, found
// by OpenVDB's sdfInteriorMask, inactive interior tiles included) is solid, material 1; any
// other grid's active voxels and tiles with a nonzero value are solid: an integer value 1..255
// is the material, any other value material 1 (as label volumes). InputError for a
// file OpenVDB cannot read, no grids, a missing grid name, a grid type that holds no values
// (points, strings), no active voxels, over kVoxMaxSceneAxis per axis, or a dense world over
// 2^31 voxels.
VoxModel read_vdb(const std::filesystem::path& path, const std::string& grid);
// The same grid into sparse storage, voxel by voxel (no dense world: up to kVoxMaxSceneAxis per
// axis); the same InputErrors except the dense limit.
SparseWorld read_vdb_sparse(const std::filesystem::path& path, const std::string& grid);
// The extent of the grid's active voxels (the world read_vdb makes), without reading them.
Dims vdb_extent(const std::filesystem::path& path, const std::string& grid);

// The same grid counted into a TileCensus without a dense world (kind "vdb", grid, class).
WorldInfo describe_vdb(const std::filesystem::path& path, const std::string& grid,
                       double max_distance);

// How a field is written as .vdb: cube voxels of `voxel_size`, background `background` (the
// bound D), a level set when signed.
struct VdbFieldSpec {
    double voxel_size = 1;
    double background = 16;
    bool level_set = false;
};

// The .vdb output spec for `output`, or nullopt when it does not end in .vdb (any case). The
// background is `max_distance` when given, else 16 (the sparse default). InputError when the
// spacing is not the same on every axis (OpenVDB's linear transform here has cube voxels).
std::optional<VdbFieldSpec> vdb_output_spec(const std::filesystem::path& output,
                                            const Spacing& spacing,
                                            std::optional<double> max_distance, bool signed_field);

// Writes an Int32Grid "material" (active on solid voxels, value = palette index, background
// 0) and a FloatGrid "distance" (the field decoded from `format`, active exactly where
// |d| < background, background D; a level set: class GRID_LEVEL_SET, inactive inside values
// -D), both with `spec.voxel_size`, in that order, so that reading the file's first grid gives
// the world back. `voxels` and `field` are the world's and the field's arrays (x fastest).
// Written through the output writer (voxfield/core/output.hpp): on its own, or into `batch`
// with a command's other outputs.
void write_vdb(const std::filesystem::path& path, Dims dims, std::span<const std::uint8_t> voxels,
               std::span<const std::uint8_t> field, Format format, const VdbFieldSpec& spec);
void write_vdb(OutputBatch& batch, const std::filesystem::path& path, Dims dims,
               std::span<const std::uint8_t> voxels, std::span<const std::uint8_t> field,
               Format format, const VdbFieldSpec& spec);

// One box of a world and of its field (box.volume() values each, x fastest), for the box-wise
// write_vdb.
struct VdbBox {
    Box box;
    std::span<const std::uint8_t> voxels;
    std::span<const std::uint8_t> field;
};
// write_vdb of a world handed out box by box: `next` fills in the next box and returns true,
// or returns false when there are no more (each call may reuse the previous box's storage).
// Voxels in no box are empty and their field is the background (beyond the bound): a sparse
// world's field is written tile by tile, never as one dense array.
void write_vdb(OutputBatch& batch, const std::filesystem::path& path,
               const std::function<bool(VdbBox&)>& next, Format format, const VdbFieldSpec& spec);

}  // namespace voxfield
