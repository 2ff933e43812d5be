// `voxfield bench`: its options, the checks made before any work, and the run of the harness
// (bench/bench_grid.hpp: --algorithms x --sizes; bench/bench_suites.hpp: --suite) shown as a
// table on stdout and written as JSON/CSV records (DESIGN §4).
#include <filesystem>
#include <iostream>
#include <optional>

#include "bench_files.hpp"
#include "bench_grid.hpp"
#include "bench_print.hpp"
#include "bench_suites.hpp"
#include "cli_util.hpp"
#include "voxfield/cl/generator.hpp"
#include "voxfield/core/error.hpp"
#include "voxfield/core/output.hpp"
#include "voxfield/core/scenes.hpp"

namespace voxfield::cli {
namespace {

struct BenchOptions {
    std::vector<std::string> algorithms = {"exact"};
    std::vector<std::string> sizes = {"64", "128", "256"};
    std::string device, json, csv, scene = "spheres", format;
    GeneratorFlags field;  // --metric, --spacing, --signed
    std::uint32_t repeat = 10, warmup = 2, chunk = 0;
    std::uint64_t seed = 6683787;
    // --suite NAME runs a whole suite (bench_suites.hpp) instead of the grid above.
    std::string suite, plot;
    bool quick = false, compare_blocks = false, peer = false;
    double budget_s = 0;
    std::uint32_t edits = 0, world = 0;
};

// "N" is a cube; "XxYxZ" any box.
Dims parse_size(const std::string& text) {
    std::string s = text;
    for (char& c : s) {
        if (c == 'x' || c == 'X') {
            c = ',';
        }
    }
    return parse_dims(s);
}

// Before the long run starts: --plot's plotter and folder, then every output path (with
// --plot and no --json, the JSON goes to the plot folder as `json_name`, into `json_path`).
std::optional<Plotter> check_bench_outputs(const BenchOptions& o, const std::string& json_name,
                                           std::string& json_path) {
    std::optional<Plotter> plotter;
    if (!o.plot.empty()) {
        plotter = require_plotter();
        if (!std::filesystem::is_directory(o.plot)) {
            throw InputError("--plot " + o.plot + ": no such folder (create it first)");
        }
        if (json_path.empty()) {
            json_path = (std::filesystem::path(o.plot) / json_name).string();
        }
    }
    check_outputs({{"--json", json_path}, {"--csv", o.csv}}, {});
    return plotter;
}

int run_bench(const BenchOptions& o) {
    const Format format = field_format(o.field, o.format);
    std::vector<Dims> sizes;
    for (const auto& s : o.sizes) {
        sizes.push_back(parse_size(s));
    }
    std::string json_path = o.json;
    const std::optional<Plotter> plotter = check_bench_outputs(o, "bench.json", json_path);
    // What generate refuses, bench refuses too, before any work: options that no size can
    // take (a chunk that is not a power of two, a metric an algorithm lacks) exit 2; a size
    // that only some algorithms cannot do (brute force on a large grid) becomes a skipped row.
    for (const auto& algorithm : o.algorithms) {
        GeneratorFlags flags = o.field;
        flags.algorithm = algorithm;
        flags.chunk = algorithm == "exact" ? 0 : o.chunk;
        std::optional<std::string> refused;
        std::size_t accepted = 0;
        for (const Dims& dims : sizes) {
            try {
                generator_options(flags, format, dims);
                ++accepted;
            } catch (const InputError& e) {
                refused = refused.value_or(e.what());
            }
        }
        if (accepted == 0 && refused) {
            throw InputError("bench --algorithms " + algorithm + ": " + *refused);
        }
    }
    const ocl::DeviceInfo device = ocl::select_device(o.device);
    for (std::size_t i = 0; i < sizes.size(); ++i) {
        require_memory_for(sizes[i], format, device, "bench --sizes " + o.sizes[i]);
    }
    ocl::Context ctx(device);
    std::cerr << "bench: device " << ctx.info().name << " (" << ctx.info().platform << ")\n";
    GridOptions grid;
    grid.algorithms = o.algorithms;
    grid.sizes = sizes;
    grid.scene = o.scene;
    grid.seed = o.seed;
    grid.field = o.field;
    grid.format = format;
    grid.chunk = o.chunk;
    grid.repeat = o.repeat;
    grid.warmup = o.warmup;
    BenchPrinter printer("");
    const nlohmann::json doc = run_grid(ctx, grid, printer);
    printer.stop();
    OutputBatch outputs;  // both or neither
    if (!json_path.empty()) {
        outputs.write(json_path, doc.dump(2) + "\n");
    }
    if (!o.csv.empty()) {
        outputs.write(o.csv, grid_csv(doc["results"]));
    }
    outputs.commit();
    if (plotter) {
        run_plotter(*plotter, o.plot, {json_path});
    }
    return 0;
}

// --suite NAME: the harness (bench_suites.hpp) with its log, progress and table shown here
// (bench_print.hpp), the document written as JSON and CSV, then plotted.
int run_suite_command(SuiteOptions s, const BenchOptions& o) {
    std::string json_path = o.json;
    const std::optional<Plotter> plotter = check_bench_outputs(o, s.suite + ".json", json_path);
    if (s.suite == "implicit") {
        s.implicit_part = require_implicit_part().string();
    }
    ocl::Context ctx(ocl::select_device(o.device));
    std::cerr << "bench: device " << ctx.info().name << " (" << ctx.info().platform << ")\n";
    BenchPrinter printer(s.suite);
    const nlohmann::json doc = run_suite(ctx, s, printer);
    printer.stop();
    if (!json_path.empty()) {
        write_json_file(json_path, doc);
        std::cerr << "bench: wrote " << json_path << '\n';
    }
    if (!o.csv.empty()) {
        write_text_file(o.csv, suite_csv(doc["results"]));
        std::cerr << "bench: wrote " << o.csv << '\n';
    }
    if (plotter) {
        run_plotter(*plotter, o.plot, {json_path});
    }
    return 0;
}

}  // namespace

Command add_bench(CLI::App& root) {
    auto o = std::make_shared<BenchOptions>();
    auto* app = root.add_subcommand(
        "bench", "Time generators on generated worlds (kernel time from OpenCL profiling)");
    app->add_option("--algorithms", o->algorithms, "Generators to time")
        ->delimiter(',')
        ->check(CLI::IsMember(ocl::algorithm_names()))
        ->capture_default_str();
    app->add_option("--sizes", o->sizes, "World sizes: N (a cube) or XxYxZ, comma-separated")
        ->delimiter(',')
        ->capture_default_str();
    app->add_option("--chunk", o->chunk,
                    "Chunk size for the dissertation's algorithms (chunk-local semantics); "
                    "exact stays global")
        ->check(CLI::Range(1u, 1u << 20));
    app->add_option("--device", o->device, kDeviceHelp);
    app->add_option("--repeat", o->repeat, "Timed runs per size")
        ->check(positive())
        ->capture_default_str();
    app->add_option("--warmup", o->warmup, "Untimed runs before the timed ones")
        ->capture_default_str();
    app->add_option("--scene", o->scene,
                    "World generator: empty, spheres, terrain, menger, random, sand, city")
        ->check(CLI::IsMember(scene_names()))
        ->capture_default_str();
    app->add_option("--seed", o->seed, "Scene seed")->capture_default_str();
    add_format_option(*app, o->format);
    add_metric_flags(*app, o->field);
    add_signed_flag(*app, o->field);
    app->add_option("--json", o->json, "Write results as JSON (DESIGN §4 fields)");
    app->add_option("--csv", o->csv, "Write results as CSV");
    app->add_option("--plot", o->plot,
                    "Write PNG plots into this folder after the JSON (bench/plot.py; needs "
                    "python3-matplotlib, checked before the run; without --json the JSON goes "
                    "there too)");
    app->add_option(
           "--suite", o->suite,
           "Run a whole suite instead of --algorithms x --sizes: dissertation (the "
           "dissertation's generation-time tables, exact beside every row group), edits "
           "(its editing protocol, per-edit update times), render (ray-march frame "
           "times of every metric), sand (falling sand with the exact field updated "
           "every step; --repeat is its step count, default 200, --quick 10), implicit "
           "(discretising data/parts/bracket.sdf.json into tile grids of contrees at "
           "256^3, 1024^3 and 4096^3, --quick 256^3, then tracing it at 1920x1080, lit and "
           "flat), sparse (the city scene as a sparse world "
           "per --sizes XxYxZ, default 1024x256x1024, --quick 256x128x256: whole "
           "bounded field at --max-distance, default 16, --repeat times, default 1; "
           "--edits radius-8 edits on the device, default 30, --quick 6, alternately "
           "profiled (per-kernel times) and lean (events only where the host waits: the "
           "row's edit time); --format "
           "default u8; --metric, --spacing, --signed), sparse-sand (the city scene as "
           "a sparse world per --sizes, default 512x128x512, --quick 256x128x256, its "
           "snow falling as sand and its lakes flowing as water: --repeat steps, default "
           "100, --quick 10, after --warmup untimed ones, with the bounded field at "
           "--max-distance updated every step; --format, --metric, --spacing, --signed "
           "as sparse)")
        ->check(CLI::IsMember(suite_names()));
    app->add_flag("--quick", o->quick,
                  "Suites: smaller sizes and fewer runs (minutes on a 2-core CPU; what CI runs)");
    app->add_option("--time-budget", o->budget_s,
                    "Suites: wall-clock seconds per row; a row stops after the run that passes "
                    "it, larger sizes predicted to pass it are skipped (default 60, --quick 15)")
        ->check(positive());
    app->add_option("--edits", o->edits,
                    "Suites edits and sparse: number of edits (edits: default 200, --quick 20; "
                    "sparse: 30, --quick 6)")
        ->check(positive());
    app->add_flag("--compare-blocks", o->compare_blocks,
                  "Suite sparse: where the whole field takes the Manhattan sweep, also time it "
                  "once by per-tile blocks (the path the sweep replaced) in the same run");
    app->add_flag("--peer", o->peer,
                  "Suite sparse: after each row, OpenVDB's fast sweeping (tools::fogToSdf) on "
                  "the same world in the same run: its times, band, peak memory and error "
                  "against the exact field (needs --metric euclidean)");
    app->add_option("--world", o->world,
                    "Suites edits and sand: world edge N (edits: default 128, --quick 64; sand: "
                    "256, --quick 64)")
        ->check(positive());
    return {app, [o, app] {
                if (o->suite.empty()) {
                    for (const char* flag : {"--quick", "--time-budget", "--edits", "--world",
                                             "--compare-blocks", "--peer"}) {
                        if (app->count(flag) != 0) {
                            throw InputError(std::string(flag) + " applies to --suite only");
                        }
                    }
                    return run_bench(*o);
                }
                const bool sparse_sand = o->suite == "sparse-sand";
                const bool sparse = o->suite == "sparse" || sparse_sand;
                for (const char* flag : {"--algorithms", "--sizes", "--scene"}) {
                    if (app->count(flag) != 0 && !(sparse && std::string(flag) == "--sizes")) {
                        throw InputError(std::string(flag) +
                                         " does not apply to --suite (a suite fixes its "
                                         "algorithms, sizes and scene; --suite sparse and "
                                         "sparse-sand take --sizes)");
                    }
                }
                if (o->suite != "edits" && app->count("--chunk") != 0) {
                    throw InputError("--chunk applies to --suite edits only");
                }
                if (o->suite != "edits" && !sparse &&
                    (app->count("--edits") != 0 || app->count("--format") != 0)) {
                    throw InputError("--edits and --format apply to --suite edits and sparse only");
                }
                if (sparse_sand && app->count("--edits") != 0) {
                    throw InputError(
                        "--edits does not apply to --suite sparse-sand (--repeat is "
                        "its step count)");
                }

                if (o->suite != "sparse" && o->compare_blocks) {
                    throw InputError("--compare-blocks applies to --suite sparse only");
                }
                if (o->suite != "sparse" && o->peer) {
                    throw InputError("--peer applies to --suite sparse only");
                }
                if (o->suite != "edits" && o->suite != "sand" && app->count("--world") != 0) {
                    throw InputError("--world applies to --suite edits and sand only");
                }
                SuiteOptions s;
                s.suite = o->suite;
                s.quick = o->quick;
                s.repeat = app->count("--repeat") != 0 ? o->repeat : 0;
                if (app->count("--warmup") != 0) {
                    s.warmup = o->warmup;
                }
                s.budget_s = o->budget_s;
                s.seed = o->seed;
                s.chunk = o->chunk != 0 ? o->chunk : 16;
                s.edits = o->edits;
                s.world = o->world;
                s.format = o->format.empty() ? (sparse ? "u8" : "u16") : o->format;
                if (sparse) {
                    // Without --sizes, the suite's own default (not the grid's).
                    for (const auto& size :
                         app->count("--sizes") != 0 ? o->sizes : std::vector<std::string>{}) {
                        s.sizes.push_back(parse_size(size));
                    }
                    s.field = o->field;
                    s.compare_blocks = o->compare_blocks;
                    s.peer = o->peer;
                    check_sparse_suite_options(s);  // before the device is opened
                }
                return run_suite_command(s, *o);
            }};
}

}  // namespace voxfield::cli
