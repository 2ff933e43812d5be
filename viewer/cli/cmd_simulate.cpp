// `voxfield simulate INPUT --steps N`: falling sand and water (DESIGN §4) in place on the
// device (pipeline::Scene), the distance field kept exact after every step by one update from
// the step's change list on the device, with optional verification against a full
// regeneration and per-step timings.
#include <algorithm>
#include <charconv>
#include <cstdint>
#include <filesystem>
#include <iostream>
#include <memory>
#include <optional>
#include <sstream>
#include <string>
#include <utility>
#include <vector>

#include "cli_util.hpp"
#include "progress.hpp"
#include "sand_run.hpp"
#include "voxfield/cl/generator.hpp"
#include "voxfield/cl/sand.hpp"
#include "voxfield/cl/sparse_sand.hpp"
#include "voxfield/core/error.hpp"
#include "voxfield/core/format.hpp"
#include "voxfield/core/npy.hpp"
#include "voxfield/core/output.hpp"
#include "voxfield/core/sand.hpp"
#include "voxfield/core/sparse.hpp"
#include "voxfield/core/stats.hpp"
#include "voxfield/core/vox.hpp"
#include "voxfield/pipeline/scene.hpp"

namespace voxfield::cli {
namespace {

// The full regeneration of the starting world: untimed warm-up, then the median of these.
constexpr std::uint32_t kRegenerateWarmup = 1;
constexpr std::uint32_t kRegenerateRepeat = 5;

struct SimulateOptions {
    GeneratorFlags generator;  // --metric, --spacing and --max-distance only
    std::string input, world_output, output, device, format, json;
    std::int64_t steps = -1;
    int sand = SandRules{}.sand, water = SandRules{}.water;
    std::string seed = "1";
    bool verify = false, sparse = false;
};

SandRules rules_of(const SimulateOptions& o) {
    for (const auto& [flag, value] :
         {std::pair{"--sand-material", o.sand}, std::pair{"--water-material", o.water}}) {
        if (value < 1 || value > 255) {
            throw InputError(std::string(flag) + " must be a material 1..255, got " +
                             std::to_string(value));
        }
    }
    if (o.sand == o.water) {
        throw InputError("--sand-material and --water-material are both " + std::to_string(o.sand) +
                         ": give sand and water different materials");
    }
    return {static_cast<std::uint8_t>(o.sand), static_cast<std::uint8_t>(o.water)};
}

std::uint64_t parse_seed(const std::string& text) {
    std::uint64_t seed = 0;
    const auto [end, ec] = std::from_chars(text.data(), text.data() + text.size(), seed);
    if (text.empty() || ec != std::errc() || end != text.data() + text.size()) {
        throw InputError("--seed must be an integer 0.." + std::to_string(UINT64_MAX) + ", got '" +
                         text + "'");
    }
    return seed;
}

// Every output writable, and no two outputs (or an output and the input) are one file.
void check_outputs(const SimulateOptions& o) {
    voxfield::check_outputs(
        {{"-o", o.output}, {"--world-output", o.world_output}, {"--json", o.json}},
        {{"INPUT", o.input}});
}

// Empty when the fields are equal; otherwise the first differing voxel, both values there
// and how many voxels differ.
std::string field_difference(const std::vector<std::uint8_t>& incremental,
                             const std::vector<std::uint8_t>& full, Format format, Dims dims) {
    if (incremental == full) {
        return {};
    }
    if (incremental.size() != full.size()) {
        return "the incremental field has " + std::to_string(incremental.size()) +
               " bytes, the full regeneration " + std::to_string(full.size());
    }
    const std::size_t es = element_size(format);
    std::optional<std::size_t> first;
    std::size_t count = 0;
    for (std::size_t i = 0; i < dims.count(); ++i) {
        if (!std::equal(incremental.begin() + static_cast<std::ptrdiff_t>(i * es),
                        incremental.begin() + static_cast<std::ptrdiff_t>((i + 1) * es),
                        full.begin() + static_cast<std::ptrdiff_t>(i * es))) {
            first = first.value_or(i);
            ++count;
        }
    }
    const std::size_t i = first.value_or(0);
    std::ostringstream s;
    s.precision(9);
    s << "first difference at voxel (" << i % dims.x << "," << i / dims.x % dims.y << ","
      << i / (std::size_t{dims.x} * dims.y) << "): incremental "
      << decode_value(incremental, format, i) << ", full regeneration "
      << decode_value(full, format, i) << "; " << count << " of " << dims.count()
      << " voxels differ";
    return s.str();
}

// Refuses an output of one dense array for a world too large for one.
void require_dense(Dims dims, const std::string& flag) {
    if (dims.count() > kMaxDenseVoxels) {
        throw InputError(flag + " needs the world as one dense array, and " + dims.to_string() +
                         " has more than " + std::to_string(kMaxDenseVoxels) + " voxels");
    }
}

// `simulate --sparse`: the world as a tile grid of 64-trees, stepped by ocl::SparseSand with
// its bounded field (--max-distance, default 16) updated within D of each step's changes;
// --verify compares world and field after every step with the dense automaton on the same
// device (ocl::SandSimulator on a dense copy) and the dense bounded field of its world.
int run_simulate_sparse(const SimulateOptions& o, const SandRules& rules, std::uint64_t seed,
                        Format format) {
    Progress progress("simulate");
    progress.set("reading the world");
    SparseModel model = load_sparse_world(o.input, InputOptions{"", format == Format::packed32});
    SparseWorld& world = model.world;
    const Dims dims = world.dims();
    const ocl::GeneratorOptions options =
        ocl::resolve_sparse_options(generator_options(o.generator, format, dims), true);
    if (!o.world_output.empty()) {
        require_dense(dims, "--world-output");
    }
    if (!o.output.empty()) {
        require_dense(dims, "-o");
    }
    if (o.verify) {
        require_dense(dims, "--verify (the dense automaton and field)");
    }
    progress.set("setting up the device");
    ocl::Context ctx(ocl::select_device(o.device));
    progress.set("computing the field");
    ocl::SparseField field(ctx, world, model.palette, options);
    const double full_ms = field.run();
    ocl::SparseSand sim(ctx, field, rules);

    // --verify: the dense automaton on a device copy of the world, and the dense bounded field.
    std::unique_ptr<World> dense;
    cl::Buffer dense_voxels;
    std::unique_ptr<ocl::SandSimulator> dense_sim;
    if (o.verify) {
        dense = std::make_unique<World>(world.to_dense());
        dense_voxels = cl::Buffer(ctx.context(), CL_MEM_READ_WRITE | CL_MEM_COPY_HOST_PTR,
                                  dense->voxels().size(), dense->voxels().data());
        dense_sim = std::make_unique<ocl::SandSimulator>(ctx, dense_voxels, dims, rules);
    }
    auto verify = [&](const std::string& when) {
        const std::vector<std::uint8_t>& want_world = dense->voxels();
        const std::vector<std::uint8_t> got_world = field.world().to_dense().voxels();
        std::string diff;
        if (got_world != want_world) {
            const auto at = static_cast<std::size_t>(
                std::mismatch(got_world.begin(), got_world.end(), want_world.begin()).first -
                got_world.begin());
            diff = "the sparse world differs from the dense automaton's at voxel (" +
                   std::to_string(at % dims.x) + "," + std::to_string(at / dims.x % dims.y) + "," +
                   std::to_string(at / (std::size_t{dims.x} * dims.y)) +
                   "): " + std::to_string(got_world[at]) + " vs " + std::to_string(want_world[at]);
        } else {
            const std::vector<std::uint8_t> full =
                ocl::generate(ctx, *dense, model.palette, options).bytes;
            diff = field_difference(field.read_dense(), full, format, dims);
            if (!diff.empty()) {
                diff = "the sparse field differs from the dense bounded field (" +
                       to_string(options.metric) + ", " + to_string(format) + "): " + diff;
            }
        }
        if (diff.empty()) {
            return true;
        }
        progress.stop();
        std::cerr << "voxfield: simulate --sparse --verify failed " << when << ": " << diff << '\n';
        return false;
    };
    if (o.verify && !verify("before the first step")) {
        return 1;
    }
    const auto steps = static_cast<std::uint64_t>(o.steps);
    bool verified = true;
    std::vector<std::pair<std::uint32_t, std::uint32_t>> tiles;
    const std::vector<SandStepRecord> records = run_sparse_sand_steps(
        sim, seed, steps,
        [&](const SandStepRecord& r) {
            if (o.verify) {
                dense_sim->step(seed, r.step);
                ctx.queue().enqueueReadBuffer(dense_voxels, CL_TRUE, 0, dense->voxels().size(),
                                              dense->voxels().data());
                if (!verify("after step " + std::to_string(r.step))) {
                    verified = false;
                    return false;
                }
            }
            progress.set("step " + std::to_string(r.step + 1) + "/" + std::to_string(steps) +
                         (o.verify ? " (verifying)" : ""));
            return true;
        },
        &tiles);
    if (!verified) {
        return 1;
    }
    progress.set("writing the outputs");
    OutputBatch outputs;
    if (!o.world_output.empty()) {
        const NpyArray w = npy_from_world(field.world().to_dense());
        write_npy(outputs, o.world_output, w.type, w.dims, w.data);
    }
    if (!o.output.empty()) {
        write_npy(outputs, o.output, npy_type(format), dims, field.read_dense());
    }
    const SandRunSummary sm = summarize_run(records);
    std::vector<double> run, changed;
    for (const auto& [r, c] : tiles) {
        run.push_back(r);
        changed.push_back(c);
    }
    const Summary tiles_run = summarize(run), tiles_changed = summarize(changed);
    const auto rate = [&](double ms) {
        return ms > 0 ? fixed(static_cast<double>(steps) * 1000.0 / ms, 1) : std::string("-");
    };
    progress.stop();
    std::cout << "device:   " << ctx.info().name << " (" << ctx.info().platform << ", "
              << ctx.info().type << "), sparse sand windows\n"
              << "world:    " << o.input << "  " << dims.to_string()
              << ", sparse: " << world.tile_count() << " tiles, sand material " << int{rules.sand}
              << ", water material " << int{rules.water} << ", seed " << seed << '\n'
              << "field:    exact bounded (sparse, D " << *options.max_distance << ") "
              << to_string(options.metric)
              << (options.spacing.unit() ? "" : ", spacing " + options.spacing.to_string()) << ", "
              << to_string(format) << '\n'
              << "steps:    " << steps << ", " << sm.voxels_changed << " voxels changed; tiles run "
              << "per step median " << fixed(tiles_run.median, 0) << ", changed median "
              << fixed(tiles_changed.median, 0) << '\n'
              << "rate:     " << rate(sm.device_ms) << " steps/s (device time), "
              << rate(sm.wall_ms) << " steps/s (wall clock, host included)\n"
              << "simulate: median " << fixed(sm.simulate.median, 4) << " ms, mean "
              << fixed(sm.simulate.mean, 4) << " ms, max " << fixed(sm.simulate.max, 4) << " ms\n"
              << "update:   median " << fixed(sm.update.median, 4) << " ms, mean "
              << fixed(sm.update.mean, 4) << " ms, max " << fixed(sm.update.max, 4)
              << " ms (encoding and field)\n"
              << "full:     " << fixed(full_ms, 4) << " ms (the starting world's whole field)\n";
    if (o.verify) {
        std::cout << "verify:   world and field matched the dense automaton and the dense "
                     "bounded field after every step\n";
    }
    if (!o.world_output.empty()) {
        std::cout << "wrote:    " << o.world_output << " (world)\n";
    }
    if (!o.output.empty()) {
        std::cout << "wrote:    " << o.output << " (field)\n";
    }
    if (!o.json.empty()) {
        nlohmann::json per_step = sm.per_step;
        for (std::size_t i = 0; i < per_step.size() && i < tiles.size(); ++i) {
            per_step[i]["tiles_run"] = tiles[i].first;
            per_step[i]["tiles_changed"] = tiles[i].second;
        }
        const auto per_s = [&](double ms) {
            return ms > 0 ? nlohmann::json(static_cast<double>(steps) * 1000.0 / ms)
                          : nlohmann::json();
        };
        const nlohmann::json j = {
            {"device", device_json(ctx.info())},
            {"commit", commit()},
            {"input", o.input},
            {"size", {dims.x, dims.y, dims.z}},
            {"sparse", true},
            {"tiles", world.tile_count()},
            {"metric", to_string(options.metric)},
            {"spacing", {options.spacing.x, options.spacing.y, options.spacing.z}},
            {"max_distance", *options.max_distance},
            {"format", to_string(format)},
            {"sand_material", rules.sand},
            {"water_material", rules.water},
            {"seed", seed},
            {"verified", o.verify},
            {"full_regeneration_ms", full_ms},
            {"steps", per_step},
            {"summary",
             {{"steps", steps},
              {"steps_per_s_device", per_s(sm.device_ms)},
              {"steps_per_s_wall", per_s(sm.wall_ms)},
              {"median_simulate_ms", sm.simulate.median},
              {"median_update_ms", sm.update.median},
              {"mean_simulate_ms", sm.simulate.mean},
              {"mean_update_ms", sm.update.mean},
              {"median_tiles_run", tiles_run.median},
              {"median_tiles_changed", tiles_changed.median},
              {"voxels_changed", sm.voxels_changed}}}};
        outputs.write(o.json, j.dump(2) + "\n");
    }
    outputs.commit();
    if (!o.json.empty()) {
        std::cout << "wrote:    " << o.json << " (timings)\n";
    }
    return 0;
}

int run_simulate(const SimulateOptions& o) {
    if (o.steps < 0) {
        throw InputError("--steps must be a step count >= 0, got " + std::to_string(o.steps));
    }
    const SandRules rules = rules_of(o);
    const std::uint64_t seed = parse_seed(o.seed);
    const Format format = field_format(o.generator, o.format);
    check_outputs(o);
    if (o.sparse) {
        return run_simulate_sparse(o, rules, seed, format);
    }
    const VoxModel model = load_world(o.input);
    const Dims dims = model.world.dims();
    const ocl::GeneratorOptions options = generator_options(o.generator, format, dims);
    // One updating line on a terminal once the run has taken a second; quiet otherwise.
    Progress progress("simulate");
    progress.set("setting up the device");
    ocl::Context ctx(ocl::select_device(o.device));

    progress.set("setting up the field");
    pipeline::Scene scene(ctx, model.world, model.palette, options);
    warm_up_updates(scene);
    progress.set("timing full regenerations");

    // Full regeneration of the starting world on this device: warm-up, then the median.
    std::vector<double> regen_samples;
    {
        const auto job = ocl::make_generator(ctx, model.world, model.palette, options);
        for (std::uint32_t i = 0; i < kRegenerateWarmup + kRegenerateRepeat; ++i) {
            const double ms = job->run();
            if (i >= kRegenerateWarmup) {
                regen_samples.push_back(ms);
            }
        }
    }
    const double full_ms = summarize(regen_samples).median;

    // --verify: a fresh generator on the current world, same options, byte for byte.
    auto verify = [&](const std::string& when) {
        const std::vector<std::uint8_t> full =
            ocl::generate(ctx, scene.world(), model.palette, options).bytes;
        const std::string diff = field_difference(scene.read_field(), full, format, dims);
        if (diff.empty()) {
            return true;
        }
        progress.stop();
        std::cerr << "voxfield: simulate --verify failed " << when
                  << ": the incremental field differs from a full regeneration ("
                  << to_string(options.metric) << ", " << to_string(format) << "): " << diff
                  << '\n';
        return false;
    };
    if (o.verify && !verify("before the first step (initial field)")) {
        return 1;
    }

    const auto steps = static_cast<std::uint64_t>(o.steps);
    bool verified = true;
    const std::vector<SandStepRecord> records =
        run_sand_steps(scene, rules, seed, steps, [&](const SandStepRecord& r) {
            if (o.verify && !verify("after step " + std::to_string(r.step))) {
                verified = false;
                return false;
            }
            progress.set("step " + std::to_string(r.step + 1) + "/" + std::to_string(steps) +
                         (o.verify ? " (verifying)" : ""));
            return true;
        });
    if (!verified) {
        return 1;
    }
    progress.set("writing the outputs");

    // Outputs only now, in one batch renamed onto their targets once all are written.
    OutputBatch outputs;
    if (!o.world_output.empty()) {
        const NpyArray w = npy_from_world(scene.world());
        write_npy(outputs, o.world_output, w.type, w.dims, w.data);
    }
    if (!o.output.empty()) {
        write_npy(outputs, o.output, npy_type(format), dims, scene.read_field());
    }

    const SandRunSummary sm = summarize_run(records);
    const Summary &sim_s = sm.simulate, &upd_s = sm.update, &step_s = sm.step;
    const double device_ms = sm.device_ms, wall_ms = sm.wall_ms;
    const std::size_t changed = sm.voxels_changed, fallbacks = sm.full_regenerations;
    const auto per_s = [&](double ms) {
        return ms > 0 ? nlohmann::json(static_cast<double>(steps) * 1000.0 / ms) : nlohmann::json();
    };
    const auto rate = [&](double ms) {
        return ms > 0 ? fixed(static_cast<double>(steps) * 1000.0 / ms, 1) : std::string("-");
    };
    const bool has_ratio = !records.empty() && full_ms > 0;
    progress.stop();
    std::cout << "device:   " << ctx.info().name << " (" << ctx.info().platform << ", "
              << ctx.info().type << "), sand kernel " << scene.sand_variant() << '\n'
              << "world:    " << o.input << "  " << dims.to_string() << ", sand material "
              << int{rules.sand} << ", water material " << int{rules.water} << ", seed " << seed
              << '\n'
              << "field:    exact " << to_string(options.metric)
              << (options.spacing.unit() ? "" : ", spacing " + options.spacing.to_string())
              << (options.max_distance ? ", bounded at " + fixed(*options.max_distance, 3) : "")
              << ", " << to_string(format) << '\n'
              << "steps:    " << steps << ", " << changed << " voxels changed"
              << (fallbacks != 0 ? ", " + std::to_string(fallbacks) +
                                       " updates fell back to a full regeneration"
                                 : "")
              << '\n'
              << "rate:     " << rate(device_ms) << " steps/s (device time), " << rate(wall_ms)
              << " steps/s (wall clock, host included)\n"
              << "simulate: median " << fixed(sim_s.median, 4) << " ms, mean "
              << fixed(sim_s.mean, 4) << " ms, max " << fixed(sim_s.max, 4) << " ms\n"
              << "update:   median " << fixed(upd_s.median, 4) << " ms, mean "
              << fixed(upd_s.mean, 4) << " ms, max " << fixed(upd_s.max, 4) << " ms\n"
              << "full:     " << fixed(full_ms, 4) << " ms (median of " << kRegenerateRepeat
              << " regenerations of the starting world)"
              << (has_ratio ? "; median step (simulate + update) " +
                                  fixed(step_s.median / full_ms, 2) + "x of it"
                            : "")
              << '\n';
    if (o.verify) {
        std::cout << "verify:   the field matched a full regeneration after every step\n";
    }
    if (!o.world_output.empty()) {
        std::cout << "wrote:    " << o.world_output << " (world)\n";
    }
    if (!o.output.empty()) {
        std::cout << "wrote:    " << o.output << " (field)\n";
    }

    if (!o.json.empty()) {
        const nlohmann::json j = {
            {"device", device_json(ctx.info())},
            {"commit", commit()},
            {"input", o.input},
            {"size", {dims.x, dims.y, dims.z}},
            {"metric", to_string(options.metric)},
            {"spacing", {options.spacing.x, options.spacing.y, options.spacing.z}},
            {"max_distance",
             options.max_distance ? nlohmann::json(*options.max_distance) : nlohmann::json()},
            {"format", to_string(format)},
            {"layout", scene.sand_variant()},
            {"sand_material", rules.sand},
            {"water_material", rules.water},
            {"seed", seed},
            {"verified", o.verify},
            {"full_regeneration_ms", full_ms},
            {"full_regeneration_ms_samples", regen_samples},
            {"steps", sm.per_step},
            {"summary",
             {{"steps", steps},
              {"steps_per_s_device", per_s(device_ms)},
              {"steps_per_s_wall", per_s(wall_ms)},
              {"median_simulate_ms", sim_s.median},
              {"median_update_ms", upd_s.median},
              {"mean_simulate_ms", sim_s.mean},
              {"mean_update_ms", upd_s.mean},
              {"ratio_median_step_to_full_regeneration",
               has_ratio ? nlohmann::json(step_s.median / full_ms) : nlohmann::json()},
              {"voxels_changed", changed},
              {"full_regenerations", fallbacks}}}};
        outputs.write(o.json, j.dump(2) + "\n");
    }
    outputs.commit();
    if (!o.json.empty()) {
        std::cout << "wrote:    " << o.json << " (timings)\n";
    }
    return 0;
}

}  // namespace

Command add_simulate(CLI::App& root) {
    auto o = std::make_shared<SimulateOptions>();
    auto* app = root.add_subcommand(
        "simulate",
        "Falling sand and water: run a block cellular automaton on the world, keeping its "
        "distance field exact after every step by one incremental update of the voxels the "
        "step changed; optionally verify every step and record timings");
    app->add_option("INPUT", o->input, kWorldInputHelp)->required();
    app->add_option("--steps", o->steps, "Number of steps to run (>= 0)")->required();
    app->add_option("--sand-material", o->sand,
                    "Material (1..255) that falls as sand: down into air or water (swapping "
                    "with it), else diagonally down into air")
        ->capture_default_str();
    app->add_option("--water-material", o->water,
                    "Material (1..255) that flows as water: down, else diagonally down, else "
                    "sideways into air; every other solid is static")
        ->capture_default_str();
    app->add_option("--seed", o->seed,
                    "Seed (0..2^64-1) of the random choices between diagonal and sideways "
                    "moves: the same seed gives the same run")
        ->capture_default_str();
    app->add_option("--world-output", o->world_output,
                    "Write the world after the last step to this uint8 .npy (Z,Y,X)");
    app->add_option("-o,--output", o->output,
                    "Write the distance field after the last step to this .npy (Z,Y,X)");
    add_metric_flags(*app, o->generator);
    add_format_option(*app, o->format);
    app->add_option("--device", o->device, kDeviceHelp);
    app->add_flag("--verify", o->verify,
                  "After every step, compare the field byte for byte with a full regeneration "
                  "of the current world (same options); exit 1 at the first difference, naming "
                  "the step and the voxel");
    app->add_flag("--sparse", o->sparse,
                  "Store the world as a tile grid of 64-trees and step it there: only the tiles "
                  "near recent changes run, and the bounded field (--max-distance, default 16) is "
                  "updated within D of each step's changes; --verify then compares with the "
                  "dense automaton and the dense bounded field");
    app->add_option("--json", o->json,
                    "Write per-step device times (simulate, update) and voxels changed, and the "
                    "full-regeneration time of the starting world on the same device, to this "
                    "JSON file");
    return {app, [o] { return run_simulate(*o); }};
}

}  // namespace voxfield::cli
