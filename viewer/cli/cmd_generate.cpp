// `voxfield generate INPUT -o OUT.npy`: one distance field, with a summary and optional stats.
#include <algorithm>
#include <cctype>
#include <chrono>
#include <cstdio>
#include <future>
#include <iostream>
#include <memory>
#include <optional>
#include <span>

#include "cli_util.hpp"
#include "generate_sparse.hpp"
#include "progress.hpp"
#include "voxfield/cl/exact.hpp"
#include "voxfield/cl/generator.hpp"
#include "voxfield/cl/separable.hpp"
#include "voxfield/core/accuracy.hpp"
#include "voxfield/core/clock.hpp"
#include "voxfield/core/npy.hpp"
#include "voxfield/core/output.hpp"
#include "voxfield/core/reference.hpp"
#include "voxfield/core/stats.hpp"
#include "voxfield/core/vdb.hpp"
#include "voxfield/core/vox.hpp"

namespace voxfield::cli {
namespace {

// When the program started (static initialisation, before main): the origin of the wall time.
const Clock::time_point kProgramStart = Clock::now();

struct GenerateOptions {
    GeneratorFlags generator;
    std::string input, output, device, format, json, indices, grid;
    bool stats = false, sparse = false;
    std::uint32_t repeat = 1, warmup = 0;
};

// Wall-clock phases of one generate, in ms (DESIGN §4 --stats).
struct Phases {
    double read = 0, setup = 0, upload = 0, kernels = 0, download = 0, write = 0, wall = 0;
};

bool uses_fim(ocl::Algorithm a) {
    using A = ocl::Algorithm;
    return a == A::fim || a == A::fim_host || a == A::jfa_fim || a == A::lod || a == A::monolithic;
}

// A uint8 .npy input, its header read and checked; nullopt for anything else (.vox, wider
// types), which load_world reads.
std::optional<NpyReader> open_u8_npy(const std::string& input) {
    std::string ext = std::filesystem::path(input).extension().string();
    std::transform(ext.begin(), ext.end(), ext.begin(),
                   [](unsigned char c) { return static_cast<char>(std::tolower(c)); });
    if (ext != ".npy") {
        return std::nullopt;
    }
    NpyReader npy(input);
    if (npy.type() != NpyType::u8) {
        return std::nullopt;
    }
    return npy;
}

std::size_t count_solid(std::span<const std::uint8_t> voxels) {
    return voxels.size() -
           static_cast<std::size_t>(std::count(voxels.begin(), voxels.end(), std::uint8_t{0}));
}

int run_generate(const GenerateOptions& o) {
    check_outputs({{"-o", o.output}, {"--indices", o.indices}, {"--json", o.json}},
                  {{"INPUT", o.input}});
    if (o.sparse || needs_sparse(o.input, o.grid)) {
        return run_generate_sparse({o.generator, o.input, o.output, o.device, o.format, o.json,
                                    o.grid, !o.indices.empty(), o.stats, o.repeat, o.warmup});
    }
    const Format format = field_format(o.generator, o.format);
    Phases phases;
    Progress progress("generate");
    progress.set("reading " + o.input);
    // The main job (exact Manhattan, unit spacing, unsigned, from a uint8 .npy) reads the
    // world straight into the host memory the kernels read, on a second thread while the
    // device and its kernels are set up; everything else loads a World first.
    std::optional<NpyReader> npy = open_u8_npy(o.input);
    std::optional<VoxModel> model;
    auto load_model = [&] {
        const auto t = Clock::now();
        model = load_world(o.input, InputOptions{o.grid, format == Format::packed32});
        phases.read = ms_since(t);
    };
    if (!npy) {
        load_model();
    }
    const Dims dims = npy ? npy->dims() : model->world.dims();
    ocl::GeneratorOptions flags_options = generator_options(o.generator, format, dims);
    flags_options.indices = !o.indices.empty();
    const ocl::GeneratorOptions options = ocl::resolve_options(flags_options, dims);
    const std::optional<VdbFieldSpec> vdb =
        vdb_output_spec(o.output, options.spacing, options.max_distance, options.signed_field);
    // In place where the sweeps of exact_manhattan.cl compute the field in some layout; a
    // device whose layout they lack for it (chebyshev on a GPU) gets a World after the read.
    bool in_place = npy && options.algorithm == ocl::Algorithm::exact &&
                    ocl::ExactManhattan::handles(options, options.layout == ocl::Layout::gpu);
    // The outputs' files are made, and their room taken, on another thread while the device
    // is set up, so that writing them later only copies (OutputBatch::reserve); a .vdb's size
    // is not known before its tree is built.
    OutputBatch outputs;
    std::future<void> reserving;
    if (!vdb) {
        reserving = std::async(std::launch::async, [&, dims] {
            outputs.reserve(o.output, dims.count() * element_size(format));
            if (options.indices) {
                outputs.reserve(o.indices, dims.count() * 3 * sizeof(std::int32_t));
            }
        });
    }
    ocl::HostMemory voxels;
    std::size_t solid = 0;
    std::future<double> reading;
    // A uint8 .npy that the kernels do not read in place is loaded as a World on a second
    // thread too, while the device is set up.
    std::future<void> loading;
    if (npy && !in_place) {
        npy.reset();
        loading = std::async(std::launch::async, load_model);
    }
    if (in_place) {
        voxels = ocl::HostMemory(dims.count());
        reading = std::async(std::launch::async, [&] {
            const auto t = Clock::now();
            npy->read_data(voxels.span());
            solid = count_solid(voxels.span());
            return ms_since(t);
        });
    }
    progress.set("setting up the device");
    const auto t_setup = Clock::now();
    // (An exception here leaves through `loading`'s destructor, which waits for the read.)
    ocl::Context ctx(ocl::select_device(o.device));
    double build_ms = 0;  // kernel build, where it is not part of the upload
    if (in_place && !ocl::ExactManhattan::handles(ctx, options, dims)) {
        phases.read = reading.get();
        model = VoxModel{
            World(dims, std::vector<std::uint8_t>(voxels.span().begin(), voxels.span().end())),
            Palette()};
        voxels = ocl::HostMemory();
        in_place = false;
    }
    if (in_place) {
        const auto t_build = Clock::now();
        ocl::ExactManhattan::prepare(ctx, dims, format, options.layout, options.metric,
                                     options.max_distance);
        build_ms = ms_since(t_build);
        phases.setup = ms_since(t_setup);
        phases.read = reading.get();
    } else {
        phases.setup = ms_since(t_setup);
    }
    if (loading.valid()) {
        loading.get();  // phases.read: the load, beside setup
    }
    const Palette palette = model ? model->palette : Palette();

    // End to end = kernel build + upload + first run + download (the first run pays page
    // faults and kernel set-up, as a one-off user would).
    progress.set("uploading the world");
    const auto t_upload = Clock::now();
    // The world outlives the job, so an exact separable transform reads it in place where the
    // device computes in host memory (no copy of the world: DESIGN's memory floor).
    const ocl::GeneratorOptions resolved = in_place ? options : ocl::resolve_options(options, dims);
    const std::unique_ptr<ocl::Generator> job =
        in_place ? std::make_unique<ocl::ExactManhattan>(
                       ctx, dims, voxels.span(), palette, format, options.layout, options.metric,
                       std::span<std::uint8_t>(), options.max_distance)
        : resolved.algorithm == ocl::Algorithm::exact && ocl::ExactSeparable::needed(resolved)
            ? std::make_unique<ocl::ExactSeparable>(ctx, dims, model->world.voxels(), palette,
                                                    resolved)
            : ocl::make_generator(ctx, model->world, palette, options);
    phases.upload = ms_since(t_upload);
    std::vector<double> samples;
    StageTimes stage_times;
    double first_run_ms = 0;
    const auto t_kernels = Clock::now();
    for (std::uint32_t i = 0; i < o.warmup + o.repeat; ++i) {
        progress.set(i < o.warmup
                         ? "warm-up run " + std::to_string(i + 1) + "/" + std::to_string(o.warmup)
                         : "run " + std::to_string(i + 1 - o.warmup) + "/" +
                               std::to_string(o.repeat));
        const double ms = job->run();
        if (i == 0) {
            first_run_ms = ms_since(t_kernels);
        }
        if (i >= o.warmup) {
            samples.push_back(ms);
            stage_times.add(*job);
        }
    }
    phases.kernels = ms_since(t_kernels);
    // A plain .npy output streams the field from the device into the file (the download of
    // one piece beside the write of the one before); a .vdb output and --stats need it whole.
    const std::size_t field_bytes = dims.count() * element_size(format);
    const bool streamed = !vdb && !o.stats;
    std::optional<ocl::MappedBuffer> field;
    ocl::FieldTiming timing;
    timing.upload_ms = job->upload_ms();
    timing.kernel_ms = summarize(samples).median;
    if (!streamed) {
        progress.set("downloading the field");
        const auto t_download = Clock::now();
        field.emplace(ctx, job->field_buffer(), field_bytes);
        phases.download = ms_since(t_download);
        timing.download_ms = field->map_ms();
    }
    const double end_to_end_ms = build_ms + phases.upload + first_run_ms + phases.download;

    // Every output goes into one batch, renamed onto its target only once all are written:
    // a failure leaves none of them.
    if (reserving.valid()) {
        reserving.get();
    }
    progress.set("writing " + o.output);
    const auto t_write = Clock::now();
    if (vdb) {
        write_vdb(outputs, o.output, dims,
                  in_place ? voxels.span() : std::span(model->world.voxels()), field->bytes(),
                  format, *vdb);
    } else if (streamed) {
        write_npy_shape(outputs, o.output, npy_type(format), {dims.z, dims.y, dims.x},
                        [&](const OutputBatch::Sink& sink) {
                            timing.download_ms =
                                ocl::read_streamed(ctx, job->field_buffer(), field_bytes, sink);
                        });
    } else {
        write_npy(outputs, o.output, npy_type(format), dims, field->bytes());
    }
    // With --stats the index planes are read whole once, written and then checked; else
    // streamed from the device's planes a slab at a time (read while written: part of the
    // write phase), never whole on the host beside them.
    std::vector<std::int32_t> index_planes;
    if (options.indices) {
        if (o.stats) {
            index_planes = job->read_indices();
        }
        write_npy_shape(outputs, o.indices, NpyType::i32, {3, dims.z, dims.y, dims.x},
                        [&](const OutputBatch::Sink& sink) {
                            if (o.stats) {
                                sink({reinterpret_cast<const std::uint8_t*>(index_planes.data()),
                                      index_planes.size() * sizeof(std::int32_t)});
                            } else {
                                job->read_indices(sink);
                            }
                        });
    }
    phases.write = ms_since(t_write);
    phases.wall = ms_since(kProgramStart);

    progress.stop();
    const double voxel_count = static_cast<double>(dims.count());
    const double gvox = voxel_count / (timing.kernel_ms * 1e-3) / 1e9;
    std::cout << "device:  " << ctx.info().name << " (" << ctx.info().platform << ", "
              << ctx.info().type << ")\n"
              << "world:   " << o.input << "  " << dims.to_string() << " = " << dims.count()
              << " voxels, " << (in_place ? solid : model->world.solid_count()) << " solid\n"
              << "field:   " << o.generator.algorithm << " (" << job->variant() << "), "
              << to_string(options.metric)
              << (options.spacing.unit() ? "" : " spacing " + options.spacing.to_string())
              << (options.signed_field ? ", signed" : "") << ", " << to_string(format) << " -> "
              << o.output << (options.indices ? ", indices -> " + o.indices : "") << '\n'
              << "time:    kernels " << fixed(timing.kernel_ms, 3) << " ms"
              << (samples.size() > 1 ? " median of " + std::to_string(samples.size()) : "") << " ("
              << rate(gvox) << " Gvox/s); end to end " << fixed(end_to_end_ms, 1) << " ms = "
              << (in_place ? "kernel build " + fixed(build_ms, 1) + " + upload "
                           : std::string("upload (incl. kernel build) "))
              << fixed(phases.upload, 1) << " + first run " << fixed(first_run_ms, 1)
              << (streamed ? " ms (wall); the download (" + fixed(timing.download_ms, 1) +
                                 " ms of transfers) streamed into the write"
                           : " + download " + fixed(phases.download, 1) + " ms (wall)")
              << '\n';

    nlohmann::json j = {
        {"device", device_json(ctx.info())},
        {"commit", commit()},
        {"input", o.input},
        {"size", {dims.x, dims.y, dims.z}},
        {"algorithm", o.generator.algorithm},
        {"chunk", options.chunk == 0 ? nlohmann::json() : nlohmann::json(options.chunk)},
        {"variant", job->variant()},
        {"jfa_extra", options.jfa_extra},
        {"metric", to_string(options.metric)},
        {"spacing", {options.spacing.x, options.spacing.y, options.spacing.z}},
        {"signed", options.signed_field},
        {"format", to_string(format)},
        {"kernel_ms", timing.kernel_ms},
        {"kernel_ms_samples", samples},
        {"warmup", o.warmup},
        {"upload_ms", timing.upload_ms},
        {"download_ms", timing.download_ms},
        {"end_to_end_ms", end_to_end_ms},
        {"world_read_in_place", in_place},
        {"field_streamed", streamed},
        {"phases_ms",
         {{"read", phases.read},
          {"setup", phases.setup},
          {"upload", phases.upload},
          {"kernels", phases.kernels},
          {"download", phases.download},
          {"write", phases.write},
          {"wall", phases.wall}}},
        {"gvox_per_s", gvox},
        {"iterations", job->iterations()}};
    j["stages"] = stage_times.json();  // per kernel, in launch order
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
        std::cout << "phases:  read " << fixed(phases.read, 1) << " ms"
                  << (in_place ? " (into the kernels' memory, beside setup)" : "") << ", setup "
                  << fixed(phases.setup, 1) << " ms ("
                  << (in_place ? "device " + fixed(phases.setup - build_ms, 1) + ", kernel build " +
                                     fixed(build_ms, 1)
                               : std::string("device"))
                  << "), upload " << fixed(phases.upload, 1) << " ms"
                  << (in_place ? "" : " (incl. kernel build)") << ", kernels "
                  << fixed(phases.kernels, 1) << " ms, download " << fixed(phases.download, 1)
                  << " ms, write " << fixed(phases.write, 1) << " ms; wall "
                  << fixed(phases.wall, 1) << " ms (program start to output written)\n";
        std::optional<World> copy;
        if (!model) {
            copy.emplace(dims,
                         std::vector<std::uint8_t>(voxels.span().begin(), voxels.span().end()));
        }
        const World& world = model ? model->world : *copy;
        const std::vector<std::uint8_t> bytes(field->bytes().begin(), field->bytes().end());
        Progress checking("generate");
        checking.set("checking against the CPU reference");
        // With indices, the reference distance once, for the field and the indices both.
        std::optional<std::vector<double>> distance;
        if (options.indices) {
            distance = reference_distance(world, options.metric, options.spacing);
        }
        const Accuracy a =
            accuracy_of(world, palette, options, bytes, distance ? &*distance : nullptr);
        checking.stop();
        std::cout << "stats:   " << fixed(voxel_count / (timing.kernel_ms * 1e-3) / 1e6, 1)
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
        if (options.indices) {
            // SciPy's ties are the kernels' for unit-spacing L1 and L2 (KEYED); L-inf and
            // spacing are checked for a nearest solid only.
            const bool ties = options.spacing.unit() && options.metric != Metric::chebyshev;
            Progress indexing("generate");
            indexing.set("checking the indices against the CPU reference");
            const std::vector<std::int32_t>& planes = index_planes;
            std::optional<std::vector<std::int64_t>> scipy;
            if (ties) {
                scipy = reference_features(world, options.metric, options.spacing);
            }
            const IndexAccuracy ia = check_indices(world, options.metric, options.spacing, planes,
                                                   *distance, scipy ? &*scipy : nullptr);
            indexing.stop();
            std::cout << "stats:   indices: " << ia.not_nearest << " of " << ia.checked
                      << " name no nearest solid"
                      << (ties ? ", " + std::to_string(ia.not_scipy) +
                                     " a nearest solid other than SciPy's"
                               : std::string(" (ties not compared: ") +
                                     (options.spacing.unit() ? "chebyshev" : "spacing") + ")");
            if (ia.first_wrong >= 0) {
                const auto w = static_cast<std::size_t>(ia.first_wrong);
                const std::size_t n = dims.count();
                std::cout << "; first at voxel (" << w % dims.x << "," << w / dims.x % dims.y << ","
                          << w / dims.x / dims.y << "), which names (" << planes[2 * n + w] << ","
                          << planes[n + w] << "," << planes[w] << ")";
            }
            std::cout << '\n';
            j["indices_checked"] = ia.checked;
            j["indices_not_nearest"] = ia.not_nearest;
            j["indices_not_scipy"] = ties ? nlohmann::json(ia.not_scipy) : nlohmann::json();
        }
    }
    if (!o.json.empty()) {
        outputs.write(o.json, j.dump(2) + "\n");
    }
    outputs.commit();
    exit_after_outputs(0);
}

}  // namespace

Command add_generate(CLI::App& root) {
    auto o = std::make_shared<GenerateOptions>();
    auto* app = root.add_subcommand(
        "generate", "Generate the distance field of a world into a .npy or .vdb file");
    app->add_option("INPUT", o->input, kWorldInputHelp)->required();
    app->add_option("--grid", o->grid, ".vdb input: the grid to read (default: the first grid)");
    app->add_option("-o,--output", o->output,
                    "Output .npy of shape (Z,Y,X), or .vdb: OpenVDB grids 'material' and "
                    "'distance' (background --max-distance, else 16; a level set with --signed; "
                    "uniform --spacing)")
        ->required();
    add_generator_flags(*app, o->generator);
    add_signed_flag(*app, o->generator);
    app->add_option("--indices", o->indices,
                    "Also write the feature transform: int32 .npy of shape (3,Z,Y,X) holding the "
                    "(z,y,x) of a nearest solid voxel of every voxel (-1 without solids; "
                    "unsigned fields, --algorithm exact)");
    app->add_option("--device", o->device, kDeviceHelp);
    add_format_option(*app, o->format);
    app->add_flag("--sparse", o->sparse,
                  "Store the world as a tile grid of 64-trees and compute the exact bounded "
                  "field per tile (--max-distance, default 16); automatic above 2^31 voxels");
    app->add_flag("--stats", o->stats,
                  "Also report the wall time of each phase (read, setup, upload, kernels, "
                  "download, write, and the whole from program start to output written), "
                  "voxels/s and accuracy against the exact CPU reference of the same semantics "
                  "(global, or chunk-local with --chunk); with --indices, each voxel's index "
                  "too: a nearest solid, and SciPy's among equally near ones for unit-spacing "
                  "manhattan and euclidean");
    app->add_option("--json", o->json,
                    "Write timings, phases and each kernel's median (stages), and --stats "
                    "accuracy, to this JSON file");
    app->add_option("--repeat", o->repeat,
                    "Run the transform this many times and report the median kernel time")
        ->check(positive())
        ->capture_default_str();
    app->add_option("--warmup", o->warmup,
                    "Untimed runs first (the first run pays page faults and kernel set-up)")
        ->capture_default_str();
    return {app, [o] { return run_generate(*o); }};
}

}  // namespace voxfield::cli
