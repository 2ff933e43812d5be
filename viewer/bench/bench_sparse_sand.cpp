// `voxfield bench --suite sparse-sand` (bench_sparse_sand.hpp).
#include "bench_sparse_sand.hpp"

#include <algorithm>
#include <random>
#include <string>
#include <utility>
#include <vector>

#include "bench_sparse.hpp"
#include "edit_log.hpp"
#include "process_memory.hpp"
#include "voxfield/cl/generator.hpp"
#include "voxfield/cl/sparse_sand.hpp"
#include "voxfield/core/brush.hpp"
#include "voxfield/core/clock.hpp"
#include "voxfield/core/format.hpp"
#include "voxfield/core/palette.hpp"
#include "voxfield/core/sand.hpp"
#include "voxfield/core/scenes.hpp"
#include "voxfield/core/sparse.hpp"
#include "voxfield/core/stats.hpp"

namespace voxfield::cli {

using bench::peak_rss_bytes;
namespace {

using nlohmann::json;

// The city's snow falls as sand, its lakes flow as water (CityScene's materials); both lie at
// rest in the city, so the row drops balls of them from above first.
constexpr SandRules kCityRules{2, 7};
constexpr std::int64_t kDropRadius = 6, kDropHeight = 24;
// One ball per this many 64 x 64 columns of tiles, at least kMinDrops.
constexpr std::uint64_t kColumnsPerDrop = 2, kMinDrops = 4;
// Worlds of at most this many voxels are checked against the dense path after the last step.
constexpr std::uint64_t kCheckVoxels = std::uint64_t{1} << 25;

// Balls of sand and water (alternately) kDropHeight above random surface points, seeded.
std::vector<Brush> drops(const SparseWorld& w, std::uint64_t seed) {
    const Dims d = w.dims(), g = w.tile_grid();
    const std::uint64_t count = std::max(kMinDrops, std::uint64_t{g.x} * g.z / kColumnsPerDrop);
    std::mt19937_64 rng(seed + 2);
    std::uniform_int_distribution<std::uint32_t> px(0, d.x - 1), pz(0, d.z - 1);
    std::vector<Brush> out;
    for (std::uint64_t i = 0; i < count; ++i) {
        const std::uint32_t x = px(rng), z = pz(rng);
        std::int64_t top = 0;
        for (std::uint32_t y = d.y; y-- > 0;) {
            if (w.at(x, y, z) != 0) {
                top = y;
                break;
            }
        }
        Brush b;
        b.op = BrushOp::place;
        b.shape = BrushShape::sphere;
        b.radius = kDropRadius;
        b.material = i % 2 == 0 ? kCityRules.sand : kCityRules.water;
        b.centre = {x, std::min<std::int64_t>(top + kDropHeight, d.y - 1 - kDropRadius), z};
        out.push_back(b);
    }
    return out;
}

json sparse_sand_row(ocl::Context& ctx, const SuiteOptions& o, Dims dims, std::uint32_t steps,
                     std::uint32_t warmup, double budget_s, BenchObserver& observer) {
    const std::string label = "sparse-sand " + dims.to_string();
    const ocl::GeneratorOptions options = sparse_options(o);
    const json load_start = load_average();
    double build_ms = 0;
    SparseWorld world = build_city(dims, o.seed, label, observer, build_ms);
    const std::uint32_t tiles = world.tile_count();
    const Palette palette = Palette::magicavoxel_default();
    const bool check = dims.count() <= kCheckVoxels;
    World dense = check ? world.to_dense() : World(Dims{1, 1, 1});

    observer.stage(label + ": " + std::to_string(tiles) + " tiles; whole bounded field");
    ocl::SparseField field(ctx, world, palette, options);
    const auto t_field = Clock::now();
    const double field_kernel_ms = field.run();
    const double field_wall_ms = ms_since(t_field);
    ocl::SparseSand sim(ctx, field, kCityRules);
    const std::vector<Brush> balls = drops(world, o.seed);
    observer.stage(label + ": dropping " + std::to_string(balls.size()) +
                   " balls of sand and water; stepping");
    for (const Brush& b : balls) {
        field.apply_brush(b);
        if (check) {
            apply_brush(dense, b);
        }
    }

    std::vector<double> wall, simulate, update, encode, field_update, tiles_run, tiles_changed;
    std::uint64_t changed = 0, recomputed = 0;
    StageSamples stages;  // update kernels by name
    const auto t_start = Clock::now();
    bool cut = false;
    std::uint64_t step = 0;
    for (; step < std::uint64_t{warmup} + steps; ++step) {
        const bool warm = step < warmup;
        observer.progress(label + ": " + (warm ? "warm-up step " : "step ") +
                          std::to_string(warm ? step + 1 : step + 1 - warmup) + "/" +
                          std::to_string(warm ? warmup : steps));
        const auto t0 = Clock::now();
        const ocl::SparseSand::Step s = sim.step(o.seed, step);
        const double ms = ms_since(t0);
        if (check) {
            sand_step(dense, kCityRules, o.seed, step);
        }
        if (warm) {
            continue;
        }
        wall.push_back(ms);
        simulate.push_back(s.simulate_ms);
        update.push_back(s.update_ms);
        encode.push_back(s.update.edit_kernel_ms);
        field_update.push_back(s.update_ms - s.update.edit_kernel_ms);
        tiles_run.push_back(s.tiles_run);
        tiles_changed.push_back(s.tiles_changed);
        changed += s.changed;
        recomputed += static_cast<std::uint64_t>(s.update.recomputed.volume());
        append_stage_samples(stages, wall.size(), s.update.stages);
        if (ms_since(t_start) > budget_s * 1e3) {
            cut = step + 1 < std::uint64_t{warmup} + steps;
            ++step;
            break;
        }
    }
    if (cut) {
        observer.stage(label + ": stopped after " + std::to_string(wall.size()) +
                       " steps (time budget)");
    }
    const double peak = peak_rss_bytes();
    json exact = nullptr;
    if (check) {
        observer.progress(label + ": comparing with the dense automaton and field");
        const bool same_world = field.world().to_dense().voxels() == dense.voxels();
        exact = same_world &&
                field.read_dense() ==
                    ocl::generate(ctx, dense, palette, ocl::resolve_options(options, dims)).bytes;
    }
    double device_ms = 0, wall_ms = 0;
    for (std::size_t i = 0; i < wall.size(); ++i) {
        device_ms += simulate[i] + update[i];
        wall_ms += wall[i];
    }
    const auto n = static_cast<double>(wall.size());
    json stage_medians = json::object();
    for (const auto& [name, samples] : stages) {
        stage_medians[name] = summarize(samples).median;
    }
    json row = {{"table", "sparse-sand"},
                {"group", dims.to_string()},
                {"algorithm", "sparse sand (windows) + exact bounded field"},
                {"size", {dims.x, dims.y, dims.z}},
                {"voxels", static_cast<double>(dims.count())},
                {"metric", to_string(options.metric)},
                {"spacing", options.spacing.to_string()},
                {"signed", options.signed_field},
                {"format", to_string(options.format)},
                {"max_distance", *options.max_distance},
                {"scene", "city"},
                {"seed", o.seed},
                {"sand_material", kCityRules.sand},
                {"water_material", kCityRules.water},
                {"drops", balls.size()},
                {"drop_radius", kDropRadius},
                {"drop_height", kDropHeight},
                {"build_ms", build_ms},
                {"tiles_stored", tiles},
                {"solid_voxels", world.solid_count()},
                {"field_wall_ms", field_wall_ms},
                {"field_kernel_ms", field_kernel_ms},
                {"steps", wall.size()},
                {"step_warmup", warmup},
                {"cut_by_time_budget", cut},
                {"timed", "median_ms..max_ms: one step, wall clock until the field is up to date"},
                {"steps_per_s_device", device_ms > 0 ? json(n * 1e3 / device_ms) : json()},
                {"steps_per_s_wall", wall_ms > 0 ? json(n * 1e3 / wall_ms) : json()},
                {"simulate_ms_median", summarize(simulate).median},
                {"update_ms_median", summarize(update).median},
                {"encode_ms_median", summarize(encode).median},
                {"field_update_ms_median", summarize(field_update).median},
                {"field_update_ms_max", summarize(field_update).max},
                {"update_stage_ms_median", stage_medians},
                {"tiles_run_median", summarize(tiles_run).median},
                {"tiles_changed_median", summarize(tiles_changed).median},
                {"voxels_changed", changed},
                {"voxels_recomputed", recomputed},
                {"samples_ms", wall},
                {"simulate_ms_samples", simulate},
                {"update_ms_samples", update},
                {"tiles_run_samples", tiles_run},
                {"exact", exact},
                {"exact_check",
                 check ? "after the last step: world equal to the CPU automaton's, field equal to "
                         "the dense bounded field (same device, same options)"
                       : "not checked: the world is too large for one dense array here"},
                {"peak_rss_bytes", peak},
                {"load_average_start", load_start},
                {"load_average_end", load_average()}};
    put_summary(row, summarize(wall));
    return row;
}

}  // namespace

json run_sparse_sand(ocl::Context& ctx, const SuiteOptions& o, std::uint32_t steps,
                     std::uint32_t warmup, double budget_s, BenchObserver& observer) {
    const std::vector<Dims> sizes =
        !o.sizes.empty() ? o.sizes
                         : std::vector<Dims>{o.quick ? Dims{256, 128, 256} : Dims{512, 128, 512}};
    check_sparse_suite_options(o);  // bad options refused before the first row
    json rows = json::array();
    for (const Dims& dims : sizes) {
        rows.push_back(sparse_sand_row(ctx, o, dims, steps, warmup, budget_s, observer));
        const json& r = rows.back();
        const json& exact = r["exact"];
        observer.stage("sparse-sand " + dims.to_string() + ": " +
                       std::to_string(r["steps"].get<std::size_t>()) + " steps, median " +
                       fixed(r["median_ms"].get<double>(), 2) + " ms (simulate " +
                       fixed(r["simulate_ms_median"].get<double>(), 2) + " ms, field update " +
                       fixed(r["field_update_ms_median"].get<double>(), 2) + " ms, tiles run " +
                       fixed(r["tiles_run_median"].get<double>(), 0) + "); exact " +
                       (exact.is_null()     ? "not checked"
                        : exact.get<bool>() ? "yes"
                                            : "NO"));
        observer.row(r);
    }
    return rows;
}

}  // namespace voxfield::cli
