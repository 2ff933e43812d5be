// `voxfield bench --suite NAME` (bench_suites.hpp).
#include "bench_suites.hpp"

#include <algorithm>
#include <chrono>
#include <map>
#include <optional>
#include <stdexcept>
#include <utility>

#include "bench_implicit.hpp"
#include "bench_sparse.hpp"
#include "bench_sparse_sand.hpp"
#include "cli_util.hpp"
#include "edit_log.hpp"
#include "sand_run.hpp"
#include "voxfield/cl/generator.hpp"
#include "voxfield/cl/incremental.hpp"
#include "voxfield/core/accuracy.hpp"
#include "voxfield/core/brush.hpp"
#include "voxfield/core/error.hpp"
#include "voxfield/core/metric.hpp"
#include "voxfield/core/output.hpp"
#include "voxfield/core/palette.hpp"
#include "voxfield/core/sand.hpp"
#include "voxfield/core/scenes.hpp"
#include "voxfield/core/stats.hpp"
#include "voxfield/core/undo.hpp"
#include "voxfield/pipeline/frame_pipeline.hpp"
#include "voxfield/pipeline/scene.hpp"
#include "voxfield/vk/raymarcher.hpp"

namespace voxfield::cli {
namespace {

using Clock = std::chrono::steady_clock;
using nlohmann::json;

// The dissertation's scene (a floor plus random spheres) for every suite world.
const std::string kScene = "spheres";

double seconds_since(Clock::time_point t0) {
    return std::chrono::duration<double>(Clock::now() - t0).count();
}

json opt_chunk(std::uint32_t chunk) {
    return chunk == 0 ? json() : json(chunk);
}

json focus_json(const std::optional<Focus>& f) {
    if (!f) {
        return json();
    }
    return {f->centre.x, f->centre.y, f->centre.z, f->size};
}

// Summary statistics as DESIGN §4 keys (the editing protocol's, edit_log.hpp) and the samples.
void put_samples(json& row, const std::vector<double>& ms) {
    put_summary(row, summarize(ms));
    row["samples_ms"] = ms;
}

void put_accuracy(json& row, const Accuracy& a) {
    row["max_error"] = a.max_error;
    row["mean_error"] = a.mean_error;
    row["over_fraction"] = a.over_fraction;
    row["under_fraction"] = a.under_fraction;
}

// ---------------------------------------------------------------------------------------
// dissertation suite

// One generator configuration measured on a group's world.
struct Variant {
    Variant(std::string a, std::uint32_t c = 0, std::optional<Focus> f = std::nullopt)
        : algorithm(std::move(a)), chunk(c), focus(f) {}
    std::string algorithm;
    std::uint32_t chunk = 0;
    std::optional<Focus> focus;
};

// A row group: one world, the dissertation's algorithm(s) at one table column, and `exact`
// on the same world in the same run.
struct Group {
    std::string table;  // "Table 4.4", "Figure 4.8"
    std::string label;  // e.g. "chunk 32^3"
    Dims dims;
    std::string format;
    std::vector<Variant> variants;  // exact is appended by the suite
};

struct RunPlan {
    std::uint32_t repeat = 0, warmup = 0;
    double budget_s = 0;
    std::uint64_t seed = 0;
};

// What each dissertation table is and what the suite measures for it (recorded in the JSON).
json dissertation_mapping() {
    return json::array(
        {{{"table", "Table 4.1"},
          {"mapped", false},
          {"why", "frame rate of the demo application (render + edits), not generation time"}},
         {{"table", "Table 4.2"},
          {"mapped", true},
          {"dissertation", "brute force (Algorithm 1), compute-shader time by world size N^3"},
          {"ours", "brute on an N^3 world, global semantics, packed32 (distance + colour)"}},
         {{"table", "Table 4.3"},
          {"mapped", true},
          {"dissertation",
           "brute force in 16^3 chunks (Algorithm 3), execution time per update (the edited "
           "chunks) by world size"},
          {"ours",
           "brute-chunked --chunk 16 regenerating the WHOLE N^3 world (a full-world figure, not "
           "the per-edit one: `--suite edits` gives per-edit update times)"}},
         {{"table", "Table 4.4"},
          {"mapped", true},
          {"dissertation",
           "FIM (Algorithms 4-5, host-driven convergence), time for one chunk of C^3, average "
           "iterations, inside the running demo (fields mostly converged already)"},
          {"ours",
           "fim-host (the table's protocol) and fim (device-driven) on a world of one C^3 chunk "
           "(--chunk C), from a freshly initialised field: iterations are FIM passes from "
           "scratch"}},
         {{"table", "Table 4.5"},
          {"mapped", true},
          {"dissertation", "JFA (Algorithm 6, one dispatch per pass), one chunk of C^3"},
          {"ours", "jfa-host and jfa on a world of one C^3 chunk (--chunk C)"}},
         {{"table", "Table 4.6"},
          {"mapped", true},
          {"dissertation", "JFA seed + FIM refinement (section 4.5), one chunk of C^3"},
          {"ours", "jfa-fim on a world of one C^3 chunk (--chunk C)"}},
         {{"table", "Table 4.7"},
          {"mapped", true},
          {"dissertation",
           "optimised monolithic shader, pure distance field, single-chunk time; 2x2x2 chunks, "
           "focus over half the chunks"},
          {"ours",
           "monolithic --chunk C, u32 field, on a 2C x C x C world (2 chunks) with the focus on "
           "chunk (0,0,0) only: half the chunks FIM, half JFA as in the table (our focus is a "
           "cube around one chunk, so 2x2x2 with a half focus cannot be expressed); the time "
           "is for the whole 2-chunk world in one launch"}},
         {{"table", "Figure 4.8"},
          {"mapped", true},
          {"dissertation",
           "level of detail (Algorithm 7): generation time by focus size (a figure; no table "
           "and no published numbers in the text)"},
          {"ours", "lod --chunk 16, focus on the centre chunk with sizes 0.. (whole world)"}},
         {{"table", "Table 5.1"},
          {"mapped", true},
          {"dissertation",
           "final monolithic shader with colour in the field, single-chunk time; 2x2x2 chunks, "
           "half in focus (plus demo FPS, not mapped)"},
          {"ours", "as Table 4.7 with the packed32 field (distance + colour)"}},
         {{"table", "Table 5.2"},
          {"mapped", false},
          {"why",
           "per-edit update time and ray-march time in a 512^3 world against a dynamic SVO: "
           "see `--suite edits` (monolithic/lod) and `--suite render`"}}});
}

std::vector<Group> dissertation_groups(bool quick) {
    std::vector<Group> groups;
    const auto cube = [](std::uint32_t n) { return Dims{n, n, n}; };
    const auto edge = [](std::uint32_t n) { return std::to_string(n) + "^3"; };
    for (std::uint32_t n : quick ? std::vector<std::uint32_t>{8, 16, 32}
                                 : std::vector<std::uint32_t>{8, 16, 32, 64, 128}) {
        groups.push_back({"Table 4.2", "world " + edge(n), cube(n), "packed32", {{"brute"}}});
    }
    for (std::uint32_t n : quick ? std::vector<std::uint32_t>{32, 64}
                                 : std::vector<std::uint32_t>{32, 64, 128, 256, 512}) {
        groups.push_back(
            {"Table 4.3", "world " + edge(n), cube(n), "packed32", {{"brute-chunked", 16}}});
    }
    const std::vector<std::uint32_t> chunk_sizes =
        quick ? std::vector<std::uint32_t>{8, 16, 32}
              : std::vector<std::uint32_t>{8, 16, 32, 64, 128};
    for (std::uint32_t c : chunk_sizes) {
        groups.push_back(
            {"Table 4.4", "chunk " + edge(c), cube(c), "packed32", {{"fim-host", c}, {"fim", c}}});
    }
    for (std::uint32_t c : chunk_sizes) {
        groups.push_back(
            {"Table 4.5", "chunk " + edge(c), cube(c), "packed32", {{"jfa-host", c}, {"jfa", c}}});
    }
    for (std::uint32_t c : chunk_sizes) {
        groups.push_back({"Table 4.6", "chunk " + edge(c), cube(c), "packed32", {{"jfa-fim", c}}});
    }
    const std::vector<std::uint32_t> mono_sizes =
        quick ? std::vector<std::uint32_t>{16, 32}
              : std::vector<std::uint32_t>{16, 32, 64, 128, 256};
    for (const auto& [table, format] :
         {std::pair<std::string, std::string>{"Table 4.7", "u32"}, {"Table 5.1", "packed32"}}) {
        for (std::uint32_t c : mono_sizes) {
            groups.push_back({table,
                              "chunk " + edge(c) + ", 2 chunks, focus 1",
                              Dims{2 * c, c, c},
                              format,
                              {{"monolithic", c, Focus{{0, 0, 0}, 0}}}});
        }
    }
    {
        const std::uint32_t n = quick ? 64 : 128;
        const std::int64_t centre = n / 16 / 2;
        Group g{"Figure 4.8",
                "world " + edge(n) + ", chunk 16^3, focus sizes",
                cube(n),
                "packed32",
                {}};
        for (std::int64_t s :
             quick ? std::vector<std::int64_t>{0, 1} : std::vector<std::int64_t>{0, 1, 2, centre}) {
            g.variants.push_back({"lod", 16, Focus{{centre, centre, centre}, s}});
        }
        groups.push_back(g);
    }
    return groups;
}

// Predicted time of one run from the same table's previous (smaller) row of this algorithm.
struct Previous {
    double ms = 0;
    std::size_t voxels = 0;
};

class DissertationSuite {
  public:
    DissertationSuite(ocl::Context& ctx, const RunPlan& plan, std::size_t total,
                      BenchObserver& observer)
        : ctx_(ctx), plan_(plan), total_(total), observer_(observer) {}

    json measure(const Group& g, const World& world, const Variant& v) {
        ++index_;
        const Dims dims = world.dims();
        std::string label = "[" + std::to_string(index_) + "/" + std::to_string(total_) + "] " +
                            g.table + " " + v.algorithm + " " + dims.to_string();
        if (v.chunk != 0) {
            label += " chunk " + std::to_string(v.chunk);
        }
        if (v.focus) {
            label += " focus " + std::to_string(v.focus->size);
        }
        json row = {{"table", g.table},
                    {"group", g.label},
                    {"algorithm", v.algorithm},
                    {"size", {dims.x, dims.y, dims.z}},
                    {"chunk", opt_chunk(v.chunk)},
                    {"focus", focus_json(v.focus)},
                    {"metric", "manhattan"},
                    {"format", g.format},
                    {"scene", kScene},
                    {"seed", plan_.seed},
                    {"time_budget_s", plan_.budget_s}};
        const auto skip = [&](const std::string& why) {
            observer_.stage(label + ": skipped: " + why);
            row["skipped"] = why;
            return row;
        };
        const std::string key = g.table + "/" + v.algorithm;
        if (const auto it = previous_.find(key); it != previous_.end() && it->second.voxels > 0) {
            const double predicted_s = it->second.ms * 1e-3 * static_cast<double>(dims.count()) /
                                       static_cast<double>(it->second.voxels);
            if (predicted_s > plan_.budget_s) {
                return skip("predicted " + fixed(predicted_s, 1) +
                            " s per run (the previous size's median scaled by the voxel count) "
                            "exceeds the per-row time budget of " +
                            fixed(plan_.budget_s, 0) + " s (--time-budget)");
            }
        }
        ocl::GeneratorOptions options;
        std::unique_ptr<ocl::Generator> job;
        try {
            options.algorithm = ocl::parse_algorithm(v.algorithm);
            options.format = parse_format(g.format);
            options.chunk = v.chunk;
            options.focus = v.focus;
            options = ocl::resolve_options(options, dims);
            observer_.stage(label + ": setting up");
            job = ocl::make_generator(ctx_, world, Palette::magicavoxel_default(), options);
        } catch (const InputError& e) {
            // Sizes a generator refuses (brute force estimated over a minute) are reported.
            return skip(e.what());
        } catch (const ocl::ClError& e) {
            return skip(std::string("device failure: ") + e.what());
        }

        std::vector<double> ms;
        StageTimes stage_times;
        const auto t0 = Clock::now();
        double last_wall = 0;
        std::string truncated;
        try {
            for (std::uint32_t i = 0; i < plan_.warmup + plan_.repeat; ++i) {
                const bool warm = i < plan_.warmup;
                const double elapsed = seconds_since(t0);
                if (elapsed + last_wall > plan_.budget_s) {
                    if (warm) {
                        i = plan_.warmup - 1;  // straight to the first timed run
                        continue;
                    }
                    if (!ms.empty()) {
                        truncated = std::to_string(ms.size()) + " of " +
                                    std::to_string(plan_.repeat) +
                                    " timed runs: the per-row time budget of " +
                                    fixed(plan_.budget_s, 0) + " s (--time-budget) ran out";
                        break;
                    }
                }
                observer_.progress(label + ": " + (warm ? "warm-up " : "run ") +
                                   std::to_string(warm ? i + 1 : i + 1 - plan_.warmup) + "/" +
                                   std::to_string(warm ? plan_.warmup : plan_.repeat));
                const auto r0 = Clock::now();
                const double t = job->run();
                last_wall = seconds_since(r0);
                if (!warm) {
                    ms.push_back(t);
                    stage_times.add(*job);
                }
            }
        } catch (const ocl::ClError& e) {
            return skip(std::string("device failure: ") + e.what());
        }
        observer_.progress(label + ": checking against the CPU reference");
        double download_ms = 0;
        const auto field = job->read(&download_ms);
        const Accuracy a =
            compare_to_exact(field, options.format, ocl::exact_reference(world, options));
        put_samples(row, ms);
        const double median = row["median_ms"].get<double>();
        previous_[key] = {median, dims.count()};
        row["repeat"] = plan_.repeat;
        row["warmup"] = plan_.warmup;
        row["runs"] = ms.size();
        if (!truncated.empty()) {
            row["budget_truncated"] = truncated;
            observer_.stage(label + ": " + truncated);
        }
        row["gvox_per_s"] =
            median > 0 ? static_cast<double>(dims.count()) / (median * 1e-3) / 1e9 : 0.0;
        row["iterations"] = job->iterations();
        put_accuracy(row, a);
        row["variant"] = job->variant();
        row["upload_ms"] = job->upload_ms();
        row["download_ms"] = download_ms;
        row["stages"] = stage_times.json();
        return row;
    }

  private:
    ocl::Context& ctx_;
    RunPlan plan_;
    std::size_t total_ = 0, index_ = 0;
    BenchObserver& observer_;
    std::map<std::string, Previous> previous_;
};

json run_dissertation(ocl::Context& ctx, const RunPlan& plan, bool quick, BenchObserver& observer) {
    const std::vector<Group> groups = dissertation_groups(quick);
    std::size_t total = 0;
    for (const Group& g : groups) {
        total += g.variants.size() + 1;
    }
    observer.stage(std::string("suite dissertation") + (quick ? " (--quick)" : "") + ": " +
                   std::to_string(groups.size()) + " row groups, " + std::to_string(total) +
                   " rows, " + std::to_string(plan.repeat) + " timed runs after " +
                   std::to_string(plan.warmup) + " warm-up, at most ~" + fixed(plan.budget_s, 0) +
                   " s per row");
    DissertationSuite suite(ctx, plan, total, observer);
    json rows = json::array();
    const auto t0 = Clock::now();
    for (const Group& g : groups) {
        const World world = make_scene(kScene, g.dims, plan.seed);
        std::vector<Variant> variants = g.variants;
        variants.emplace_back("exact");
        for (const Variant& v : variants) {
            rows.push_back(suite.measure(g, world, v));
            observer.row(rows.back());
        }
    }
    observer.stage("suite dissertation done in " + fixed(seconds_since(t0), 1) + " s");
    return rows;
}

// ---------------------------------------------------------------------------------------
// edits suite

struct EditSpec {
    Brush brush;
    std::int64_t size = 0;  // the protocol's brush size 1..C-1; radius = size / 2
};

// The dissertation's benchmark mode, as `view --benchmark` runs it (core's RandomEdits: the
// same seed gives the same edits there and here). The same sequence for every algorithm.
std::vector<EditSpec> make_edit_sequence(Dims dims, std::uint32_t chunk, std::uint32_t count,
                                         std::uint64_t seed) {
    RandomEdits generator(dims, chunk, seed);
    std::vector<EditSpec> edits;
    for (std::uint32_t i = 0; i < count; ++i) {
        EditSpec e;
        e.brush = generator.next();
        e.size = generator.last_size();
        edits.push_back(e);
    }
    return edits;
}

json run_edits(ocl::Context& ctx, const SuiteOptions& o, const RunPlan& plan, Dims dims,
               std::uint32_t count, BenchObserver& observer) {
    // exact unbounded and bounded at several D (an edit's update then stays within D of it),
    // then the dissertation's algorithms.
    struct EditRow {
        std::string algorithm;
        std::optional<double> bound;
    };
    std::vector<EditRow> algorithms = {
        {"exact", {}}, {"exact", 4.0}, {"exact", 16.0}, {"exact", 64.0}};
    for (const char* name :
         {"brute-chunked", "fim-host", "fim", "jfa-host", "jfa", "jfa-fim", "lod", "monolithic"}) {
        algorithms.push_back({name, {}});
    }
    const std::vector<EditSpec> edits = make_edit_sequence(dims, o.chunk, count, o.seed);
    const World initial = make_scene(kScene, dims, o.seed);
    const Palette palette = Palette::magicavoxel_default();
    const Format format = parse_format(o.format);
    observer.stage(std::string("suite edits") + (o.quick ? " (--quick)" : "") + ": world " +
                   dims.to_string() + ", " + std::to_string(count) + " edits (seed " +
                   std::to_string(o.seed) + "), chunk " + std::to_string(o.chunk) + ", " +
                   std::to_string(algorithms.size()) + " algorithms, at most ~" +
                   fixed(plan.budget_s, 0) + " s each");
    json rows = json::array();
    const auto suite_t0 = Clock::now();
    for (std::size_t ai = 0; ai < algorithms.size(); ++ai) {
        const std::string& name = algorithms[ai].algorithm;
        const std::optional<double> bound = algorithms[ai].bound;
        const std::string label = "[" + std::to_string(ai + 1) + "/" +
                                  std::to_string(algorithms.size()) + "] edits " + name +
                                  (bound ? " max-distance " + fixed(*bound, 0) : "");
        const std::uint32_t chunk = name == "exact" ? 0 : o.chunk;
        json row = {{"table", "edits"},
                    {"group", "world " + dims.to_string() + ", " + std::to_string(count) +
                                  " edits, seed " + std::to_string(o.seed)},
                    {"algorithm", name},
                    {"size", {dims.x, dims.y, dims.z}},
                    {"chunk", opt_chunk(chunk)},
                    {"metric", "manhattan"},
                    {"max_distance", bound ? json(*bound) : json()},
                    {"format", o.format},
                    {"scene", kScene},
                    {"seed", o.seed},
                    {"time_budget_s", plan.budget_s}};
        const auto skip = [&](const std::string& why) {
            row["skipped"] = why;
            observer.stage(label + ": skipped: " + why);
            rows.push_back(row);
            observer.row(row);
        };
        ocl::GeneratorOptions options;
        std::unique_ptr<ocl::IncrementalField> field;
        try {
            options.algorithm = ocl::parse_algorithm(name);
            options.format = format;
            options.chunk = chunk;
            options.max_distance = bound;
            options = ocl::resolve_options(options, dims);
            if (options.focus) {
                row["focus"] = focus_json(options.focus);
            }
            observer.stage(label + ": setting up");
            field = std::make_unique<ocl::IncrementalField>(ctx, initial, palette, options);
            // Pay the update kernels' builds outside the timings (as `replay` does).
            warm_up_updates(*field);
        } catch (const InputError& e) {
            skip(e.what());
            continue;
        } catch (const ocl::ClError& e) {
            skip(std::string("device failure: ") + e.what());
            continue;
        }
        const auto t0 = Clock::now();
        // Full regeneration of the same world on the same device, in the same run.
        std::vector<double> regen;
        for (std::uint32_t i = 0; i < plan.warmup + plan.repeat; ++i) {
            observer.progress(label + ": full regeneration " + std::to_string(i + 1) + "/" +
                              std::to_string(plan.warmup + plan.repeat));
            const double t = field->regenerate();
            if (i >= plan.warmup) {
                regen.push_back(t);
            }
            if (seconds_since(t0) > plan.budget_s / 2 && !regen.empty()) {
                break;
            }
        }
        EditLog log;
        std::string truncated;
        for (std::size_t i = 0; i < edits.size(); ++i) {
            if (seconds_since(t0) > plan.budget_s && log.size() > 0) {
                truncated = std::to_string(i) + " of " + std::to_string(edits.size()) +
                            " edits: the per-row time budget of " + fixed(plan.budget_s, 0) +
                            " s (--time-budget) ran out";
                break;
            }
            if (i % 10 == 0 || i + 1 == edits.size()) {
                observer.progress(label + ": edit " + std::to_string(i + 1) + "/" +
                                  std::to_string(edits.size()));
            }
            const EditSpec& e = edits[i];
            const ocl::UpdateStats s = field->apply({e.brush});
            EditSample sample{
                e.brush, e.size, s.update_ms, s.voxels_recomputed, 0, s.full_regeneration};
            for (const EditResult& r : s.edits) {
                sample.voxels_changed += r.changes.size();
            }
            log.add(sample);
        }
        observer.progress(label + ": checking the final field against the CPU reference");
        std::vector<std::uint32_t> reference = ocl::exact_reference(field->world(), options);
        if (bound) {
            // A bounded field is the exact one capped at D (D is an integer here).
            const auto cap = static_cast<std::uint32_t>(*bound);
            for (std::uint32_t& v : reference) {
                v = std::min(v, cap);
            }
        }
        const Accuracy a = compare_to_exact(field->read(), options.format, reference);
        put_summary(row, log.update_summary());
        const Summary rs = summarize(regen);
        const double median = row["median_ms"].get<double>();
        row["gvox_per_s"] = json();  // not a whole-world rate
        row["iterations"] = json();
        put_accuracy(row, a);
        row["accuracy_of"] =
            "the field after the last edit, against the exact field of the "
            "row's semantics";
        row["edits_requested"] = edits.size();
        row["edits_done"] = log.size();
        row["repeat"] = plan.repeat;
        row["warmup"] = plan.warmup;
        if (!truncated.empty()) {
            row["budget_truncated"] = truncated;
            observer.stage(label + ": " + truncated);
        }
        row["full_regeneration_ms"] = rs.median;
        row["full_regeneration_ms_samples"] = regen;
        row["ratio_full_to_median_update"] = median > 0 ? json(rs.median / median) : json();
        row["voxels_recomputed_total"] = log.voxels_recomputed_total();
        row["voxels_recomputed_mean"] = log.size() == 0
                                            ? 0.0
                                            : static_cast<double>(log.voxels_recomputed_total()) /
                                                  static_cast<double>(log.size());
        row["full_regenerations"] = log.full_regenerations();
        row["edits"] = log.edits_json();
        rows.push_back(row);
        observer.row(row);
    }
    observer.stage("suite edits done in " + fixed(seconds_since(suite_t0), 1) + " s");
    return rows;
}

// ---------------------------------------------------------------------------------------
// render suite

// Ray-march time per frame across world sizes and resolutions (the floor + spheres scene,
// the default three-quarter camera, lit shading with the sky gradient, shadow rays and ambient
// occlusion), for the exact field of every metric on the same world: each through the frame
// pipeline (compact format with its per-block minima, as render and view show it); each frame's
// dispatch timed by GPU timestamps. One more frame per metric counts every primary ray's field
// fetches and DDA steps (a counting pipeline in flat shading, not timed) and checks that its image
// equals manhattan's: the metric changes how far rays walk per fetch, never which voxel they hit. A
// row is one world and resolution: manhattan's times at the top level (as before metrics existed),
// every metric's under "metrics".
json run_render(ocl::Context& ctx, const RunPlan& plan, bool quick, BenchObserver& observer) {
    const std::vector<std::uint32_t> sizes =
        quick ? std::vector<std::uint32_t>{32, 64} : std::vector<std::uint32_t>{128, 256, 512};
    const std::vector<std::pair<std::uint32_t, std::uint32_t>> resolutions =
        quick ? std::vector<std::pair<std::uint32_t, std::uint32_t>>{{320, 240}}
              : std::vector<std::pair<std::uint32_t, std::uint32_t>>{
                    {640, 480}, {1280, 720}, {1920, 1080}};
    const std::vector<Metric> metrics = {Metric::manhattan, Metric::chebyshev, Metric::euclidean};
    vk::Context vk_ctx;
    observer.stage("suite render: Vulkan device " + vk_ctx.info().name);
    json rows = json::array();
    const std::size_t total = sizes.size() * metrics.size() * resolutions.size();
    std::size_t k = 0;
    for (const std::uint32_t n : sizes) {
        const Dims dims{n, n, n};
        const World world = make_scene(kScene, dims, plan.seed);
        // The frame pipeline that render and view use: the exact field on the OpenCL device,
        // converted into the compact render field with its per-block minima.
        pipeline::FramePipeline frames(ctx, vk_ctx, Palette::magicavoxel_default(), dims);
        vk::Raymarcher& marcher = frames.marcher();
        std::vector<json> per_metric(resolutions.size(), json::array());
        std::vector<std::vector<std::uint8_t>> reference(resolutions.size());
        for (const Metric metric : metrics) {
            ocl::GeneratorOptions g;
            g.format = Format::u16;
            g.metric = metric;
            frames.rebuild(World(world), g);
            for (std::size_t res = 0; res < resolutions.size(); ++res) {
                const auto [w, h] = resolutions[res];
                ++k;
                const std::string label = dims.to_string() + " " + to_string(metric) + " at " +
                                          std::to_string(w) + "x" + std::to_string(h);
                vk::RenderOptions r;
                r.width = w;
                r.height = h;
                r.camera = vk::default_camera(dims);
                r.shading = vk::Shading::lit;
                r.sky_gradient = true;
                std::vector<double> ms;
                const auto start = std::chrono::steady_clock::now();
                for (std::uint32_t i = 0; i < plan.warmup + plan.repeat; ++i) {
                    observer.progress("render [" + std::to_string(k) + "/" + std::to_string(total) +
                                      "] " + label + ": " +
                                      (i < plan.warmup ? "warm-up " : "run ") +
                                      std::to_string(i + 1));
                    const vk::Image image = marcher.render(r);
                    if (image.raymarch_ms < 0) {
                        throw std::runtime_error(
                            vk_ctx.info().name +
                            " has no compute timestamps to time the ray march");
                    }
                    if (i >= plan.warmup) {
                        ms.push_back(image.raymarch_ms);
                    }
                    if (std::chrono::duration<double>(std::chrono::steady_clock::now() - start)
                            .count() > plan.budget_s) {
                        break;
                    }
                }
                // Counted in flat shading: the counters follow the primary rays, which lit
                // shading does not change, and flat images compare the hit voxels alone (lit
                // shading's ambient occlusion reads the metric's distances).
                r.count = true;
                r.shading = vk::Shading::flat;
                r.sky_gradient = false;
                const vk::Image counted = marcher.render(r);
                if (metric == Metric::manhattan) {
                    reference[res] = counted.rgba;
                }
                const Summary sm = summarize(ms);
                const double rays = double(w) * double(h);
                per_metric[res].push_back(
                    {{"metric", to_string(metric)},
                     {"runs", ms.size()},
                     {"median_ms", sm.median},
                     {"mean_ms", sm.mean},
                     {"std_ms", sm.std},
                     {"ci95_ms", {sm.ci95_lo, sm.ci95_hi}},
                     {"min_ms", sm.min},
                     {"max_ms", sm.max},
                     {"mrays_per_s", rays / (sm.median * 1e-3) / 1e6},
                     {"fetches_per_ray", double(counted.fetches) / rays},
                     {"steps_per_ray", double(counted.steps) / rays},
                     {"same_image_as_manhattan", counted.rgba == reference[res]}});
                json measurement = per_metric[res].back();
                measurement["size"] = {n, n, n};
                measurement["width"] = w;
                measurement["height"] = h;
                observer.measured(measurement);
            }
        }
        for (std::size_t res = 0; res < resolutions.size(); ++res) {
            const json& l1 = per_metric[res][0];
            rows.push_back({{"table", "render"},
                            {"algorithm", "raymarch"},
                            {"metric", "manhattan"},
                            {"size", {n, n, n}},
                            {"width", resolutions[res].first},
                            {"height", resolutions[res].second},
                            {"format", "compact"},
                            {"shading", "lit"},
                            {"vulkan_device", vk_ctx.info().name},
                            {"sharing", marcher.sharing_path()},
                            {"runs", l1["runs"]},
                            {"median_ms", l1["median_ms"]},
                            {"mean_ms", l1["mean_ms"]},
                            {"std_ms", l1["std_ms"]},
                            {"ci95_ms", l1["ci95_ms"]},
                            {"min_ms", l1["min_ms"]},
                            {"max_ms", l1["max_ms"]},
                            {"mrays_per_s", l1["mrays_per_s"]},
                            {"metrics", per_metric[res]}});
            observer.row(rows.back());
        }
    }
    return rows;
}

// ---------------------------------------------------------------------------------------------
// sand suite

// The falling-sand demo (`simulate`) on scene_sand's world (a sand cone, a water basin, grains
// falling from the upper half): `steps` steps with the exact L1 field updated after each, once
// unbounded and once bounded at D = 16; per step the simulation's and the update's device
// times and the voxels changed, beside a full regeneration of the starting world.
json run_sand(ocl::Context& ctx, const SuiteOptions& o, std::uint32_t n, std::uint32_t steps,
              BenchObserver& observer) {
    const Dims dims{n, n, n};
    const World world = scene_sand(dims, o.seed);
    json rows = json::array();
    for (const std::optional<double> bound : {std::optional<double>(), std::optional<double>(16)}) {
        ocl::GeneratorOptions g;
        g.format = Format::u16;
        g.max_distance = bound;
        g = ocl::resolve_options(g, dims);
        const std::string label =
            dims.to_string() + (bound ? " bounded at 16" : " unbounded") + ", L1";
        observer.stage("sand " + label + ": set-up");
        pipeline::Scene scene(ctx, world, Palette(), g);
        warm_up_updates(scene);
        std::vector<double> full;
        {
            const auto job = ocl::make_generator(ctx, world, Palette(), g);
            for (int i = 0; i < 6; ++i) {
                const double ms = job->run();
                if (i > 0) {
                    full.push_back(ms);
                }
            }
        }
        const double full_ms = summarize(full).median;
        const auto records =
            run_sand_steps(scene, SandRules{}, o.seed, steps, [&](const SandStepRecord& r) {
                observer.progress("sand " + label + ": step " + std::to_string(r.step + 1) + "/" +
                                  std::to_string(steps));
                return true;
            });
        const SandRunSummary sm = summarize_run(records);
        const Summary &ss = sm.simulate, &us = sm.update, &st = sm.step;
        const double device_ms = sm.device_ms, wall_ms = sm.wall_ms;
        const std::size_t changed = sm.voxels_changed, fallbacks = sm.full_regenerations;
        const auto count = static_cast<double>(records.size());
        const double rate = device_ms > 0 ? count * 1000.0 / device_ms : 0;
        const double wall_rate = wall_ms > 0 ? count * 1000.0 / wall_ms : 0;
        rows.push_back({{"size", {n, n, n}},
                        {"metric", "manhattan"},
                        {"format", "u16"},
                        {"max_distance", bound ? json(*bound) : json()},
                        {"steps", records.size()},
                        {"steps_per_s_device", rate},
                        {"steps_per_s_wall", wall_rate},
                        {"simulate_ms_median", ss.median},
                        {"update_ms_median", us.median},
                        {"update_ms_mean", us.mean},
                        {"update_ms_max", us.max},
                        {"step_ms_median", st.median},
                        {"full_regeneration_ms", full_ms},
                        {"step_over_full", full_ms > 0 ? st.median / full_ms : 0.0},
                        {"voxels_changed", changed},
                        {"full_regenerations", fallbacks},
                        {"per_step", sm.per_step}});
        observer.row(rows.back());
    }
    return rows;
}

}  // namespace

const std::vector<std::string>& suite_names() {
    static const std::vector<std::string> names = {"dissertation", "edits",  "render",     "sand",
                                                   "implicit",     "sparse", "sparse-sand"};
    return names;
}

json run_suite(ocl::Context& ctx, const SuiteOptions& o, BenchObserver& observer) {
    RunPlan plan;
    plan.seed = o.seed;
    plan.repeat = o.repeat != 0 ? o.repeat : (o.quick ? 3 : (o.suite == "edits" ? 5 : 10));
    plan.warmup = o.warmup ? *o.warmup : (o.quick ? 1u : 2u);
    plan.budget_s = o.budget_s > 0 ? o.budget_s : (o.quick ? 15.0 : 60.0);
    json doc = {{"device", device_json(ctx.info())},
                {"commit", commit()},
                {"date", utc_now()},
                {"suite", o.suite},
                {"quick", o.quick},
                {"scene", kScene},
                {"seed", o.seed},
                {"repeat", plan.repeat},
                {"warmup", plan.warmup},
                {"time_budget_s", plan.budget_s}};
    json rows;
    if (o.suite == "dissertation") {
        doc["mapping"] = dissertation_mapping();
        rows = run_dissertation(ctx, plan, o.quick, observer);
    } else if (o.suite == "edits") {
        const std::uint32_t n = o.world != 0 ? o.world : (o.quick ? 64 : 128);
        const std::uint32_t count = o.edits != 0 ? o.edits : (o.quick ? 20 : 200);
        const Dims dims{n, n, n};
        require_chunk_fits(dims, o.chunk);
        doc["edits"] = count;
        doc["chunk"] = o.chunk;
        doc["protocol"] =
            "the dissertation's benchmark mode (core's RandomEdits, as view --benchmark): spheres "
            "at uniformly random centres, size uniform in 1..C-1 (brush radius = size / 2, as the "
            "demo's brush), voxel type uniform in 0..11 where 0 (one in 12) erases and 1..11 "
            "place the dissertation's colours; splitmix64 seeded with `seed`, the same sequence "
            "for every algorithm and for view --benchmark; one edit per update";
        rows = run_edits(ctx, o, plan, dims, count, observer);
    } else if (o.suite == "sand") {
        const std::uint32_t n = o.world != 0 ? o.world : (o.quick ? 64 : 256);
        const std::uint32_t steps = o.repeat != 0 ? o.repeat : (o.quick ? 10 : 200);
        doc["scene"] = "sand";
        doc["steps"] = steps;
        doc["world"] = n;
        rows = run_sand(ctx, o, n, steps, observer);
    } else if (o.suite == "implicit") {
        doc["scene"] = "data/parts/bracket.sdf.json";
        rows = run_implicit(ctx, o.implicit_part, plan.repeat, plan.warmup, plan.budget_s, o.quick,
                            observer);
    } else if (o.suite == "sparse") {
        // The whole field runs once unless --repeat asks for more (minutes on a CPU).
        doc["scene"] = "city";
        doc["repeat"] = o.repeat != 0 ? o.repeat : 1;
        rows = run_sparse(ctx, o, doc["repeat"].get<std::uint32_t>(), plan.warmup, observer);
    } else if (o.suite == "sparse-sand") {
        const std::uint32_t steps = o.repeat != 0 ? o.repeat : (o.quick ? 10 : 100);
        doc["scene"] = "city";
        doc["steps"] = steps;
        doc["repeat"] = steps;
        rows = run_sparse_sand(ctx, o, steps, plan.warmup, plan.budget_s, observer);
    } else {
        rows = run_render(ctx, plan, o.quick, observer);
    }
    doc["results"] = rows;
    return doc;
}

}  // namespace voxfield::cli
