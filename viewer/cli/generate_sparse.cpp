// `voxfield generate` on sparse worlds (issue 24): load, tile, bounded field per tile, .npy.
#include "generate_sparse.hpp"

#include <algorithm>
#include <cctype>
#include <chrono>
#include <filesystem>
#include <iostream>
#include <optional>

#include "voxfield/cl/sparse_field.hpp"
#include "voxfield/core/accuracy.hpp"
#include "voxfield/core/error.hpp"
#include "voxfield/core/npy.hpp"
#include "voxfield/core/output.hpp"
#include "voxfield/core/sparse.hpp"
#include "voxfield/core/stats.hpp"
#include "voxfield/core/vdb.hpp"
#include "voxfield/core/vox.hpp"

namespace voxfield::cli {
namespace {

using Clock = std::chrono::steady_clock;

double ms_since(Clock::time_point t) {
    return std::chrono::duration<double, std::milli>(Clock::now() - t).count();
}

bool is_npy(const std::string& input) {
    std::string ext = std::filesystem::path(input).extension().string();
    std::transform(ext.begin(), ext.end(), ext.begin(),
                   [](unsigned char c) { return static_cast<char>(std::tolower(c)); });
    return ext == ".npy";
}

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

bool needs_sparse(const std::string& input) {
    return is_npy(input) && NpyReader(input).dims().count() > kSparseAutoVoxels;
}

int run_generate_sparse(const SparseGenerateArgs& a) {
    // The caller (run_generate) has checked every output path with check_outputs.
    const Format format = field_format(a.flags, a.format);
    if (is_npy(a.input)) {
        require_dense_output(NpyReader(a.input).dims(), a.output);
    }
    const auto t_read = Clock::now();
    VoxModel model = load_world(a.input, InputOptions{a.grid, format == Format::packed32});
    const Dims dims = model.world.dims();
    require_dense_output(dims, a.output);
    ocl::GeneratorOptions flags_options = generator_options(a.flags, format, dims);
    flags_options.indices = a.indices;
    const ocl::GeneratorOptions options = ocl::resolve_sparse_options(flags_options, true);
    const std::optional<VdbFieldSpec> vdb =
        vdb_output_spec(a.output, options.spacing, options.max_distance, options.signed_field);
    const double read_ms = ms_since(t_read);
    const auto t_build = Clock::now();
    const SparseWorld world = SparseWorld::from_dense(model.world);
    const double build_ms = ms_since(t_build);

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
    const auto t_read_back = Clock::now();
    const std::vector<std::uint8_t> bytes = field.read_dense();
    const double read_back_ms = ms_since(t_read_back);
    // The field and --json go into one batch: a failure leaves neither.
    OutputBatch outputs;
    if (vdb) {
        write_vdb(outputs, a.output, dims, model.world.voxels(), bytes, format, *vdb);
    } else {
        write_npy(outputs, a.output, npy_type(format), dims, bytes);
    }

    std::cout << "device:  " << ctx.info().name << " (" << ctx.info().platform << ", "
              << ctx.info().type << ")\n"
              << "world:   " << a.input << "  " << dims.to_string() << " = " << dims.count()
              << " voxels, " << world.solid_count() << " solid; sparse: " << world.tile_count()
              << " tiles of 64^3 stored, " << world.bytes() << " bytes (64-trees, built in "
              << fixed(build_ms, 1) << " ms)\n"
              << "field:   exact bounded (sparse, D " << *options.max_distance << ", halo "
              << field.halo(0) << "," << field.halo(1) << "," << field.halo(2) << "), "
              << to_string(options.metric)
              << (options.spacing.unit() ? "" : " spacing " + options.spacing.to_string())
              << (options.signed_field ? ", signed" : "") << ", " << to_string(format) << " -> "
              << a.output << "; " << field.dense_tiles() << " field tiles stored\n"
              << "time:    kernels " << fixed(kernel_ms, 3) << " ms"
              << (samples.size() > 1 ? " median of " + std::to_string(samples.size()) : "")
              << "; first run end to end " << fixed(first_ms, 1) << " ms, read back "
              << fixed(read_back_ms, 1) << " ms\n";
    nlohmann::json j = {{"device", device_json(ctx.info())},
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
                        {"phases_ms",
                         {{"read", read_ms},
                          {"build", build_ms},
                          {"first_run", first_ms},
                          {"read_back", read_back_ms}}}};
    if (a.stats) {
        const Accuracy acc = accuracy_of(model.world, model.palette, options, bytes);
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
    return 0;
}

}  // namespace voxfield::cli
