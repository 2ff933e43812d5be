#pragma once
// `voxfield generate --sparse` (and worlds over kSparseAutoVoxels voxels): the world as a tile
// grid of 64-trees (core/sparse.hpp), its exact bounded field per tile (cl/sparse_field.hpp),
// written as one dense .npy where it fits one array, or as .vdb grids.
#include <cstdint>
#include <string>

#include "cli_util.hpp"
#include "voxfield/cl/sparse_field.hpp"
#include "voxfield/core/output.hpp"
#include "voxfield/core/sparse.hpp"
#include "voxfield/core/vdb.hpp"

namespace voxfield::cli {

// Worlds with more voxels than this are generated sparse without --sparse.
inline constexpr std::uint64_t kSparseAutoVoxels = std::uint64_t{1} << 31;

// Whether `input` holds more than kSparseAutoVoxels voxels: a .npy's header, a .vox scene's
// extent or a .vdb grid's (`grid`: its name, empty for the first) says so; .sdf.json parts are
// generated dense.
bool needs_sparse(const std::string& input, const std::string& grid);

struct SparseGenerateArgs {
    GeneratorFlags flags;
    std::string input, output, device, format, json, grid;
    bool indices = false, stats = false;
    std::uint32_t repeat = 1, warmup = 0;
};

// The world and its field as .vdb grids (core's box-wise write_vdb: a material Int32Grid and a
// distance FloatGrid), read from the device tile by tile: every tile of the world and the tiles
// within the bound of one (rings of ceil(halo / 64) tiles), never one dense array. `world`: the
// field's world, brought up to date (SparseField::world()).
void write_vdb_tiles(OutputBatch& outputs, const std::string& path, const SparseWorld& world,
                     ocl::SparseField& field, Format format, const VdbFieldSpec& spec);

// Prints the summary (and writes --json); InputError for what sparse worlds refuse
// (--indices, other algorithms, a field too large for one .npy). The outputs' names were
// checked by the caller (check_outputs).
int run_generate_sparse(const SparseGenerateArgs& a);

}  // namespace voxfield::cli
