// `voxfield generate INPUT -o OUT.npy`: one distance field, with a summary and optional stats.
#include <chrono>
#include <cstdio>
#include <cstring>
#include <iostream>

#include "cli_util.hpp"
#include "voxfield/cl/generator.hpp"
#include "voxfield/core/accuracy.hpp"
#include "voxfield/core/npy.hpp"
#include "voxfield/core/stats.hpp"
#include "voxfield/core/vox.hpp"

namespace voxfield::cli {
namespace {

struct GenerateOptions {
    GeneratorFlags generator;
    std::string input, output, device, format, json, indices;
    bool stats = false;
    std::uint32_t repeat = 1, warmup = 0;
};

bool uses_fim(ocl::Algorithm a) {
    using A = ocl::Algorithm;
    return a == A::fim || a == A::fim_host || a == A::jfa_fim || a == A::lod || a == A::monolithic;
}

int run_generate(const GenerateOptions& o) {
    const Format format = field_format(o.generator, o.format);
    require_output_folder(o.output);
    for (const std::string* extra : {&o.json, &o.indices}) {
        if (!extra->empty()) {
            require_output_folder(*extra);
        }
    }
    if (!o.indices.empty() && o.indices == o.output) {
        throw InputError("--indices and -o name the same file '" + o.output + "'");
    }
    const VoxModel model = load_world(o.input);
    const World& world = model.world;
    ocl::GeneratorOptions flags_options = generator_options(o.generator, format, world.dims());
    flags_options.indices = !o.indices.empty();
    const ocl::GeneratorOptions options = ocl::resolve_options(flags_options, world.dims());
    ocl::Context ctx(ocl::select_device(o.device));

    // End to end = upload + first run + download, wall clock (the first run pays page
    // faults and kernel set-up, as a one-off user would).
    using clock = std::chrono::steady_clock;
    const auto t0 = clock::now();
    const auto job = ocl::make_generator(ctx, world, model.palette, options);
    std::vector<double> samples;
    clock::duration first_run{};
    for (std::uint32_t i = 0; i < o.warmup + o.repeat; ++i) {
        const double ms = job->run();
        if (i == 0) {
            first_run = clock::now() - t0;
        }
        if (i >= o.warmup) {
            samples.push_back(ms);
        }
    }
    ocl::FieldResult field;
    const auto t1 = clock::now();
    field.bytes = job->read(&field.timing.download_ms);
    const double end_to_end_ms =
        std::chrono::duration<double, std::milli>(first_run + (clock::now() - t1)).count();
    field.timing.upload_ms = job->upload_ms();
    field.timing.kernel_ms = summarize(samples).median;
    std::vector<std::int32_t> indices;
    if (options.indices) {
        indices = job->read_indices();
    }
    write_npy(o.output, npy_type(format), world.dims(), field.bytes);
    if (options.indices) {
        const Dims d = world.dims();
        std::vector<std::uint8_t> bytes(indices.size() * 4);
        std::memcpy(bytes.data(), indices.data(), bytes.size());
        write_npy_shape(o.indices, NpyType::i32, {3, d.z, d.y, d.x}, bytes);
    }

    const double voxels = static_cast<double>(world.size());
    const double gvox = voxels / (field.timing.kernel_ms * 1e-3) / 1e9;
    std::cout << "device:  " << ctx.info().name << " (" << ctx.info().platform << ", "
              << ctx.info().type << ")\n"
              << "world:   " << o.input << "  " << world.dims().to_string() << " = " << world.size()
              << " voxels, " << world.solid_count() << " solid\n"
              << "field:   " << o.generator.algorithm << " (" << job->variant() << "), "
              << to_string(options.metric)
              << (options.spacing.unit() ? "" : " spacing " + options.spacing.to_string())
              << (options.signed_field ? ", signed" : "") << ", " << to_string(format) << " -> "
              << o.output << (options.indices ? ", indices -> " + o.indices : "") << '\n'
              << "time:    kernels " << fixed(field.timing.kernel_ms, 3) << " ms"
              << (samples.size() > 1 ? " median of " + std::to_string(samples.size()) : "") << " ("
              << fixed(gvox, 2) << " Gvox/s); end to end " << fixed(end_to_end_ms, 1)
              << " ms (upload " << fixed(field.timing.upload_ms, 2) << " ms, download "
              << fixed(field.timing.download_ms, 2) << " ms, incl. kernel build on first use)\n";

    nlohmann::json j = {
        {"device", device_json(ctx.info())},
        {"commit", commit()},
        {"input", o.input},
        {"size", {world.dims().x, world.dims().y, world.dims().z}},
        {"algorithm", o.generator.algorithm},
        {"chunk", options.chunk == 0 ? nlohmann::json() : nlohmann::json(options.chunk)},
        {"variant", job->variant()},
        {"jfa_extra", options.jfa_extra},
        {"metric", to_string(options.metric)},
        {"spacing", {options.spacing.x, options.spacing.y, options.spacing.z}},
        {"signed", options.signed_field},
        {"format", to_string(format)},
        {"kernel_ms", field.timing.kernel_ms},
        {"kernel_ms_samples", samples},
        {"warmup", o.warmup},
        {"upload_ms", field.timing.upload_ms},
        {"download_ms", field.timing.download_ms},
        {"end_to_end_ms", end_to_end_ms},
        {"gvox_per_s", gvox},
        {"iterations", job->iterations()}};
    if (options.focus) {
        const Focus& f = *options.focus;
        j["focus"] = {f.centre.x, f.centre.y, f.centre.z, f.size};
    }
    if (uses_fim(options.algorithm)) {
        std::cout << "fim:     " << job->iterations()
                  << " passes changed the field before one changed nothing"
                  << (options.chunk != 0 ? " (slowest chunk)" : "") << '\n';
    }
    if (o.stats) {
        const Accuracy a = accuracy_of(world, model.palette, options, field.bytes);
        std::cout << "stats:   " << fixed(voxels / (field.timing.kernel_ms * 1e-3) / 1e6, 1)
                  << " Mvox/s; vs the exact CPU reference ("
                  << (options.chunk != 0 ? "chunk-local, chunk " + std::to_string(options.chunk)
                                         : std::string("global"))
                  << "): max error " << a.max_error << ", mean error " << fixed(a.mean_error, 4)
                  << ", over-estimated " << fixed(100 * a.over_fraction, 3) << "%, under-estimated "
                  << fixed(100 * a.under_fraction, 3) << "%\n";
        j["max_error"] = a.max_error;
        j["mean_error"] = a.mean_error;
        j["over_fraction"] = a.over_fraction;
        j["under_fraction"] = a.under_fraction;
    }
    if (!o.json.empty()) {
        write_json_file(o.json, j);
    }
    return 0;
}

}  // namespace

Command add_generate(CLI::App& root) {
    auto o = std::make_shared<GenerateOptions>();
    auto* app = root.add_subcommand(
        "generate", "Generate the distance field of a .vox or .npy world into a .npy file");
    app->add_option("INPUT", o->input, "World: MagicaVoxel .vox or uint8/16/32 .npy (Z,Y,X)")
        ->required();
    app->add_option("-o,--output", o->output, "Output .npy of shape (Z,Y,X)")->required();
    add_generator_flags(*app, o->generator);
    add_signed_flag(*app, o->generator);
    app->add_option("--indices", o->indices,
                    "Also write the feature transform: int32 .npy of shape (3,Z,Y,X) holding the "
                    "(z,y,x) of a nearest solid voxel of every voxel (-1 without solids; "
                    "unsigned fields, --algorithm exact)");
    app->add_option("--device", o->device,
                    "cpu, gpu or an index from `voxfield devices` (default: $VOXFIELD_DEVICE, "
                    "else the first GPU, else the first CPU)");
    add_format_option(*app, o->format);
    app->add_flag("--stats", o->stats,
                  "Also report voxels/s and accuracy against the exact CPU reference of the "
                  "same semantics (global, or chunk-local with --chunk)");
    app->add_option("--json", o->json, "Write timings (and --stats accuracy) to this JSON file");
    app->add_option("--repeat", o->repeat,
                    "Run the transform this many times and report the median kernel time")
        ->check(CLI::PositiveNumber)
        ->capture_default_str();
    app->add_option("--warmup", o->warmup,
                    "Untimed runs first (the first run pays page faults and kernel set-up)")
        ->capture_default_str();
    return {app, [o] { return run_generate(*o); }};
}

}  // namespace voxfield::cli
