// `voxfield generate` on sparse worlds (issue 24): load, tile, bounded field per tile, .npy.
#include "generate_sparse.hpp"

#include <algorithm>
#include <cctype>
#include <chrono>
#include <filesystem>
#include <iostream>
#include <optional>
#include <set>

#include "voxfield/cl/sparse_field.hpp"
#include "voxfield/core/accuracy.hpp"
#include "voxfield/core/clock.hpp"
#include "voxfield/core/error.hpp"
#include "voxfield/core/npy.hpp"
#include "voxfield/core/output.hpp"
#include "voxfield/core/sparse.hpp"
#include "voxfield/core/stats.hpp"
#include "voxfield/core/vdb.hpp"
#include "voxfield/core/vox.hpp"

namespace voxfield::cli {
namespace {

bool has_extension(const std::string& input, const char* ext) {
    std::string e = std::filesystem::path(input).extension().string();
    std::transform(e.begin(), e.end(), e.begin(),
                   [](unsigned char c) { return static_cast<char>(std::tolower(c)); });
    return e == ext;
}

bool is_npy(const std::string& input) {
    return has_extension(input, ".npy");
}

}  // namespace

void write_vdb_tiles(OutputBatch& outputs, const std::string& path, const SparseWorld& world,
                     ocl::SparseField& field, Format format, const VdbFieldSpec& spec) {
    const Dims grid = world.tile_grid();
    const std::int64_t reach = std::max({field.halo(0), field.halo(1), field.halo(2)});
    const std::int64_t ring = (reach + kTileSize - 1) / kTileSize;
    std::set<std::uint64_t> keys;
    for (std::uint32_t t = 0; t < world.tile_count(); ++t) {
        const Int3 c = world.tile_coord(t);
        for (std::int64_t z = std::max<std::int64_t>(0, c.z - ring);
             z <= std::min<std::int64_t>(grid.z - 1, c.z + ring); ++z) {
            for (std::int64_t y = std::max<std::int64_t>(0, c.y - ring);
                 y <= std::min<std::int64_t>(grid.y - 1, c.y + ring); ++y) {
                for (std::int64_t x = std::max<std::int64_t>(0, c.x - ring);
                     x <= std::min<std::int64_t>(grid.x - 1, c.x + ring); ++x) {
                    keys.insert(tile_key(static_cast<std::uint32_t>(x),
                                         static_cast<std::uint32_t>(y),
                                         static_cast<std::uint32_t>(z)));
                }
            }
        }
    }
    auto key = keys.begin();
    std::vector<std::uint8_t> voxels, values;
    const Dims d = world.dims();
    write_vdb(
        outputs, path,
        [&](VdbBox& b) {
            if (key == keys.end()) {
                return false;
            }
            const Int3 t = tile_of_key(*key++);
            const std::int64_t s = kTileSize;
            const Box box{{t.x * s, t.y * s, t.z * s},
                          {std::min<std::int64_t>((t.x + 1) * s, d.x),
                           std::min<std::int64_t>((t.y + 1) * s, d.y),
                           std::min<std::int64_t>((t.z + 1) * s, d.z)}};
            voxels.resize(static_cast<std::size_t>(box.volume()));
            world.read_box(box, voxels);
            values = field.read_box(box);
            b = VdbBox{box, voxels, values};
            return true;
        },
        format, spec);
}

namespace {

void require_dense_output(Dims dims, const std::string& output) {
    if (dims.count() > kMaxDenseVoxels) {
        throw InputError("the field of the sparse world " + dims.to_string() + " (" +
                         std::to_string(dims.count()) +
                         " voxels) is too large for one .npy "
                         "array (at most " +
                         std::to_string(kMaxDenseVoxels) +
                         " voxels): write it as a sparse .vdb instead (-o " +
                         std::filesystem::path(output).replace_extension(".vdb").string() + ")");
    }
}

}  // namespace

bool needs_sparse(const std::string& input, const std::string& grid) {
    if (is_npy(input)) {
        return NpyReader(input).dims().count() > kSparseAutoVoxels;
    }
    if (has_extension(input, ".vox")) {
        return read_vox_scene(input).dims.count() > kSparseAutoVoxels;
    }
    if (has_extension(input, ".vdb")) {
        return vdb_extent(input, grid).count() > kSparseAutoVoxels;
    }
    return false;
}

int run_generate_sparse(const SparseGenerateArgs& a) {
    // The caller (run_generate) has checked every output path with check_outputs.
    const Format format = field_format(a.flags, a.format);
    if (is_npy(a.input)) {
        require_dense_output(NpyReader(a.input).dims(), a.output);
    }
    // .vox scenes and .vdb grids are placed voxel by voxel into the tiles: no dense world.
    const auto t_read = Clock::now();
    const SparseModel model =
        load_sparse_world(a.input, InputOptions{a.grid, format == Format::packed32});
    const SparseWorld& world = model.world;
    const Dims dims = world.dims();
    ocl::GeneratorOptions flags_options = generator_options(a.flags, format, dims);
    flags_options.indices = a.indices;
    const ocl::GeneratorOptions options = ocl::resolve_sparse_options(flags_options, true);
    const std::optional<VdbFieldSpec> vdb =
        vdb_output_spec(a.output, options.spacing, options.max_distance, options.signed_field);
    if (!vdb) {
        require_dense_output(dims, a.output);
    }
    const double read_ms = ms_since(t_read);

    ocl::Context ctx(ocl::select_device(a.device));
    ocl::SparseField field(ctx, world, model.palette, options);
    std::vector<double> samples;
    const auto t_first = Clock::now();
    double first_ms = 0;
    for (std::uint32_t i = 0; i < a.warmup + a.repeat; ++i) {
        const double ms = field.run();
        if (i == 0) {
            first_ms = ms_since(t_first);
        }
        if (i >= a.warmup) {
            samples.push_back(ms);
        }
    }
    const double kernel_ms = summarize(samples).median;
    // The field and --json go into one batch: a failure leaves neither.
    OutputBatch outputs;
    const auto t_read_back = Clock::now();
    if (vdb) {
        write_vdb_tiles(outputs, a.output, world, field, format, *vdb);
    } else {
        write_npy(outputs, a.output, npy_type(format), dims, field.read_dense());
    }
    const double read_back_ms = ms_since(t_read_back);

    std::cout << "device:  " << ctx.info().name << " (" << ctx.info().platform << ", "
              << ctx.info().type << ")\n"
              << "world:   " << a.input << "  " << dims.to_string() << " = " << dims.count()
              << " voxels, " << world.solid_count() << " solid; sparse: " << world.tile_count()
              << " tiles of 64^3 stored, " << world.bytes() << " bytes (64-trees, built in "
              << fixed(read_ms, 1) << " ms)\n"
              << "field:   exact bounded (sparse, D " << *options.max_distance << ", halo "
              << field.halo(0) << "," << field.halo(1) << "," << field.halo(2) << "), "
              << to_string(options.metric)
              << (options.spacing.unit() ? "" : " spacing " + options.spacing.to_string())
              << (options.signed_field ? ", signed" : "") << ", " << to_string(format) << " -> "
              << a.output << "; " << field.dense_tiles() << " field tiles stored\n"
              << "time:    kernels " << fixed(kernel_ms, 3) << " ms"
              << (samples.size() > 1 ? " median of " + std::to_string(samples.size()) : "")
              << "; first run end to end " << fixed(first_ms, 1) << " ms, read back and "
              << "encoded " << fixed(read_back_ms, 1) << " ms\n";
    nlohmann::json j = {
        {"device", device_json(ctx.info())},
        {"commit", commit()},
        {"input", a.input},
        {"size", {dims.x, dims.y, dims.z}},
        {"sparse", true},
        {"tiles", world.tile_count()},
        {"sparse_bytes", world.bytes()},
        {"field_tiles", field.dense_tiles()},
        {"max_distance", *options.max_distance},
        {"metric", to_string(options.metric)},
        {"spacing", {options.spacing.x, options.spacing.y, options.spacing.z}},
        {"signed", options.signed_field},
        {"format", to_string(format)},
        {"kernel_ms", kernel_ms},
        {"kernel_ms_samples", samples},
        {"warmup", a.warmup},
        {"phases_ms", {{"read", read_ms}, {"first_run", first_ms}, {"read_back", read_back_ms}}}};
    if (a.stats) {
        const Accuracy acc =
            accuracy_of(world.to_dense(), model.palette, options, field.read_dense());
        std::cout << "stats:   vs the exact CPU reference (bounded): max error " << acc.max_error
                  << ", mean error " << fixed(acc.mean_error, 4) << ", over-estimated "
                  << fixed(100 * acc.over_fraction, 3) << "%, under-estimated "
                  << fixed(100 * acc.under_fraction, 3) << "%\n";
        j["max_error"] = acc.max_error;
        j["mean_error"] = acc.mean_error;
        j["over_fraction"] = acc.over_fraction;
        j["under_fraction"] = acc.under_fraction;
    }
    if (!a.json.empty()) {
        outputs.write(a.json, j.dump(2) + "\n");
    }
    outputs.commit();
    exit_after_outputs(0);
}

}  // namespace voxfield::cli
