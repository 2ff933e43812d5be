// `voxfield replay EDITS.txt --input WORLD`: applies an edit file to a world one edit at a
// time, updating the distance field incrementally after each edit (DESIGN §4), with optional
// verification against a full regeneration and per-edit timings.
#include <chrono>
#include <cstdio>
#include <filesystem>
#include <iostream>
#include <optional>
#include <sstream>

#include "cli_util.hpp"
#include "progress.hpp"
#include "voxfield/cl/generator.hpp"
#include "voxfield/cl/incremental.hpp"
#include "voxfield/core/edits.hpp"
#include "voxfield/core/error.hpp"
#include "voxfield/core/npy.hpp"
#include "voxfield/core/output.hpp"
#include "voxfield/core/stats.hpp"
#include "voxfield/core/vox.hpp"
#include "voxfield/pipeline/scene.hpp"

namespace voxfield::cli {
namespace {

namespace fs = std::filesystem;

// Full regenerations timed once per run: untimed warm-up first, then the median of these.
constexpr std::uint32_t kRegenerateWarmup = 1;
constexpr std::uint32_t kRegenerateRepeat = 5;

struct ReplayOptions {
    GeneratorFlags generator;
    std::string edits, input, world_output, output, device, format, json;
    bool verify = false;
    std::uint32_t max_margin = 0;  // 0: no limit
};

// Element i of an encoded field as an unsigned integer (little-endian).
std::uint64_t element(const std::vector<std::uint8_t>& field, std::size_t size, std::size_t i) {
    std::uint64_t v = 0;
    for (std::size_t b = 0; b < size; ++b) {
        v |= std::uint64_t{field[i * size + b]} << (8 * b);
    }
    return v;
}

std::string describe_value(const std::vector<std::uint8_t>& field, Format format, std::size_t i) {
    const std::uint64_t v = element(field, element_size(format), i);
    if (format != Format::packed32) {
        return std::to_string(v);
    }
    return std::to_string(v) + " (distance " + std::to_string(v >> 8) + ", rgb332 " +
           std::to_string(v & 0xFF) + ")";
}

// Empty when equal; otherwise where the incremental field first differs from the full
// regeneration, with both values and how many voxels differ.
std::string field_difference(const std::vector<std::uint8_t>& incremental,
                             const std::vector<std::uint8_t>& full, Format format, Dims dims) {
    const std::size_t es = element_size(format);
    if (incremental.size() != full.size()) {
        return "the incremental field has " + std::to_string(incremental.size()) +
               " bytes, the full regeneration " + std::to_string(full.size());
    }
    if (incremental == full) {
        return {};
    }
    std::optional<std::size_t> first;
    std::size_t count = 0;
    for (std::size_t i = 0; i < dims.count(); ++i) {
        if (element(incremental, es, i) != element(full, es, i)) {
            if (!first) {
                first = i;
            }
            ++count;
        }
    }
    const std::size_t i = first.value_or(0);
    const std::size_t x = i % dims.x;
    const std::size_t y = i / dims.x % dims.y;
    const std::size_t z = i / (std::size_t{dims.x} * dims.y);
    return "first difference at voxel (" + std::to_string(x) + "," + std::to_string(y) + "," +
           std::to_string(z) + "): incremental " + describe_value(incremental, format, i) +
           ", full regeneration " + describe_value(full, format, i) + "; " + std::to_string(count) +
           " of " + std::to_string(dims.count()) + " voxels differ";
}

void check_outputs(const ReplayOptions& o) {
    // The inputs exist before anything is said about the outputs.
    require_input_file(o.edits);
    require_input_file(o.input);
    if (o.output.empty() && o.world_output.empty() && o.json.empty() && !o.verify) {
        throw InputError(
            "replay would produce nothing: give -o FIELD.npy, --world-output W.npy, --json FILE "
            "or --verify");
    }
    voxfield::check_outputs(
        {{"-o", o.output}, {"--world-output", o.world_output}, {"--json", o.json}},
        {{"EDITS", o.edits}, {"--input", o.input}});
}

int run_replay(const ReplayOptions& o) {
    check_outputs(o);
    const Format format = field_format(o.generator, o.format);
    // The whole edit file is parsed before any work: a bad line fails with FILE:LINE.
    const std::vector<Edit> edits = read_edits(o.edits);
    const VoxModel model = load_world(o.input);
    const Dims dims = model.world.dims();
    const ocl::GeneratorOptions options = generator_options(o.generator, format, dims);
    ocl::Context ctx(ocl::select_device(o.device));
    // Progress on a terminal for long replays; stopped before any message.
    Progress progress("replay");
    progress.set("setting up the field");

    // The world and its field, edited as every front end edits them (pipeline::Scene).
    pipeline::Scene field(ctx, model.world, model.palette, options,
                          o.max_margin == 0 ? ocl::IncrementalField::kNoMargin : o.max_margin);
    // The first launch of each update kernel pays its build (PoCL compiles per kernel and
    // work-group shape): one untimed edit toggles voxel (0,0,0), a second restores it (the
    // updates are exact, so the field is as before), and update times measure updates.
    {
        const std::uint8_t v0 = field.world().at(0, 0, 0);
        Brush toggle;
        toggle.shape = BrushShape::cube;
        toggle.radius = 0;
        toggle.op = v0 != 0 ? BrushOp::erase : BrushOp::place;
        field.apply({toggle});
        toggle.op = v0 != 0 ? BrushOp::place : BrushOp::erase;
        toggle.material = v0 != 0 ? v0 : std::uint8_t{1};
        field.apply({toggle});
    }

    // Full regeneration of the initial world on this device: warm-up, then the median.
    progress.set("timing full regenerations");
    std::vector<double> regen_samples;
    for (std::uint32_t i = 0; i < kRegenerateWarmup + kRegenerateRepeat; ++i) {
        const double ms = field.regenerate();
        if (i >= kRegenerateWarmup) {
            regen_samples.push_back(ms);
        }
    }
    const double full_ms = summarize(regen_samples).median;

    // --verify: a fresh generator on the current world, same options, byte for byte.
    auto verify = [&](const std::string& after) -> bool {
        const auto job = ocl::make_generator(ctx, field.world(), model.palette, options);
        job->run();
        const std::vector<std::uint8_t> full = job->read();
        const std::vector<std::uint8_t> incremental = field.read_field();
        const std::string diff = field_difference(incremental, full, format, dims);
        if (diff.empty()) {
            return true;
        }
        progress.stop();
        std::cerr << "voxfield: replay --verify failed " << after
                  << ": the incremental field differs from a full regeneration ("
                  << o.generator.algorithm
                  << (options.chunk != 0 ? ", chunk " + std::to_string(options.chunk) : "") << ", "
                  << to_string(format) << "): " << diff << '\n';
        return false;
    };
    if (o.verify && !verify("before the first edit (initial field)")) {
        return 1;
    }

    nlohmann::json edits_json = nlohmann::json::array();
    std::vector<double> update_ms;
    std::uint64_t recomputed_total = 0;
    std::size_t voxels_changed = 0, fallbacks = 0;
    for (std::size_t i = 0; i < edits.size(); ++i) {
        const Edit& e = edits[i];
        progress.set("edit " + std::to_string(i + 1) + "/" + std::to_string(edits.size()) +
                     (o.verify ? " (verifying)" : ""));
        const ocl::UpdateStats s = field.apply({e.brush}).stats;
        std::size_t changed = 0;
        for (const EditResult& r : s.edits) {
            changed += r.changes.size();
        }
        update_ms.push_back(s.update_ms);
        recomputed_total += s.voxels_recomputed;
        voxels_changed += changed;
        fallbacks += s.full_regeneration ? 1 : 0;
        nlohmann::json j = {{"line", e.line},
                            {"op", to_string(e.brush.op)},
                            {"shape", to_string(e.brush.shape)},
                            {"centre", {e.brush.centre.x, e.brush.centre.y, e.brush.centre.z}},
                            {"radius", e.brush.radius},
                            {"text", e.text},
                            {"update_ms", s.update_ms},
                            {"voxels_recomputed", s.voxels_recomputed},
                            {"voxels_changed", changed},
                            {"regions", s.regions.size()},
                            {"full_regeneration", s.full_regeneration}};
        if (e.brush.op != BrushOp::erase) {
            j["material"] = e.brush.material;
        }
        edits_json.push_back(std::move(j));
        if (o.verify &&
            !verify("after edit " + o.edits + ":" + std::to_string(e.line) + " '" + e.text + "'")) {
            return 1;
        }
    }
    progress.set("writing the outputs");

    // Outputs only now, in one batch renamed onto their targets once all are written.
    OutputBatch outputs;
    if (!o.world_output.empty()) {
        const NpyArray w = npy_from_world(field.world());
        write_npy(outputs, o.world_output, w.type, w.dims, w.data);
    }
    if (!o.output.empty()) {
        write_npy(outputs, o.output, npy_type(format), dims, field.read_field());
    }

    progress.stop();
    const Summary s = summarize(update_ms);
    const bool has_ratio = !update_ms.empty() && s.median > 0;
    const double ratio = has_ratio ? full_ms / s.median : 0;
    std::cout << "device:   " << ctx.info().name << " (" << ctx.info().platform << ", "
              << ctx.info().type << ")\n"
              << "world:    " << o.input << "  " << dims.to_string() << ", "
              << field.world().solid_count() << " solid after the edits\n"
              << "field:    " << o.generator.algorithm
              << (options.chunk != 0 ? " (chunk " + std::to_string(options.chunk) + ")" : "")
              << ", " << to_string(format) << '\n'
              << "edits:    " << edits.size() << " applied from " << o.edits << ", "
              << voxels_changed << " voxels changed"
              << (fallbacks != 0
                      ? ", " + std::to_string(fallbacks) + " fell back to full regeneration"
                      : "")
              << '\n'
              << "update:   median " << fixed(s.median, 4) << " ms, mean " << fixed(s.mean, 4)
              << " ms, max " << fixed(s.max, 4) << " ms\n"
              << "full:     " << fixed(full_ms, 4) << " ms (median of " << kRegenerateRepeat
              << " regenerations of the initial world)"
              << (has_ratio ? "; ratio full/median update " + fixed(ratio, 1) + "x" : "") << '\n'
              << "voxels recomputed: " << recomputed_total << " in total"
              << (edits.empty() ? ""
                                : ", " +
                                      fixed(static_cast<double>(recomputed_total) /
                                                static_cast<double>(edits.size()),
                                            1) +
                                      " per edit on average")
              << '\n';
    if (o.verify) {
        std::cout << "verify:   the field matched a full regeneration after every edit\n";
    }

    if (!o.json.empty()) {
        nlohmann::json j = {
            {"device", device_json(ctx.info())},
            {"commit", commit()},
            {"date", utc_now()},
            {"input", o.input},
            {"edits_file", o.edits},
            {"size", {dims.x, dims.y, dims.z}},
            {"algorithm", o.generator.algorithm},
            {"chunk", options.chunk == 0 ? nlohmann::json() : nlohmann::json(options.chunk)},
            {"format", to_string(format)},
            {"max_distance",
             options.max_distance ? nlohmann::json(*options.max_distance) : nlohmann::json()},
            {"max_margin", o.max_margin},
            {"verified", o.verify},
            {"full_regeneration_ms", full_ms},
            {"full_regeneration_ms_samples", regen_samples},
            {"edits", edits_json},
            {"summary",
             {{"edits", edits.size()},
              {"median_update_ms", s.median},
              {"mean_update_ms", s.mean},
              {"max_update_ms", s.max},
              {"ratio_full_to_median_update", has_ratio ? nlohmann::json(ratio) : nlohmann::json()},
              {"voxels_recomputed", recomputed_total},
              {"voxels_changed", voxels_changed},
              {"full_regenerations", fallbacks}}}};
        if (options.focus) {
            const Focus& f = *options.focus;
            j["focus"] = {f.centre.x, f.centre.y, f.centre.z, f.size};
        }
        outputs.write(o.json, j.dump(2) + "\n");
    }
    outputs.commit();
    if (!o.world_output.empty()) {
        std::cout << "wrote:    " << o.world_output << " (world)\n";
    }
    if (!o.output.empty()) {
        std::cout << "wrote:    " << o.output << " (field)\n";
    }
    if (!o.json.empty()) {
        std::cout << "wrote:    " << o.json << " (timings)\n";
    }
    return 0;
}

}  // namespace

Command add_replay(CLI::App& root) {
    auto o = std::make_shared<ReplayOptions>();
    auto* app = root.add_subcommand(
        "replay",
        "Apply an edit file to a world one edit at a time, updating the distance field "
        "incrementally after each edit; optionally verify every update and record timings");
    app->add_option("EDITS", o->edits,
                    "Edit file: one edit per line, 'place|erase|paint sphere|cube X Y Z R "
                    "[MATERIAL]', # comments; the whole file is checked before any work")
        ->required();
    app->add_option("--input", o->input, kWorldInputHelp)->required();
    app->add_option("--world-output", o->world_output,
                    "Write the edited world to this uint8 .npy (Z,Y,X) at the end");
    app->add_option("-o,--output", o->output,
                    "Write the final distance field to this .npy (Z,Y,X) at the end");
    add_generator_flags(*app, o->generator);
    app->add_option("--device", o->device, kDeviceHelp);
    add_format_option(*app, o->format);
    app->add_flag("--verify", o->verify,
                  "After every edit, compare the field byte for byte with a full regeneration of "
                  "the current world (same algorithm and options); exit 1 at the first "
                  "difference, naming the edit and the voxel");
    app->add_option("--json", o->json,
                    "Write per-edit update times and voxels recomputed, and the full-regeneration "
                    "time of the initial world on the same device, to this JSON file");
    app->add_option("--max-margin", o->max_margin,
                    "exact: an update whose region reaches further than this many voxels from "
                    "the edit falls back to a full regeneration (0: no limit)")
        ->capture_default_str();
    return {app, [o] { return run_replay(*o); }};
}

}  // namespace voxfield::cli
