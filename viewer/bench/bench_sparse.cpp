// `voxfield bench --suite sparse` (bench_sparse.hpp).
#include "bench_sparse.hpp"
#include "bench_sparse_trace.hpp"

#include <malloc.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstring>
#include <fstream>
#include <optional>
#include <random>
#include <string>

#include "cli_util.hpp"
#include "edit_log.hpp"
#include "openvdb_peer.hpp"
#include "process_memory.hpp"
#include "voxfield/cl/generator.hpp"
#include "voxfield/cl/sparse_field.hpp"
#include "voxfield/core/clock.hpp"
#include "voxfield/core/error.hpp"
#include "voxfield/core/format.hpp"
#include "voxfield/core/palette.hpp"
#include "voxfield/core/scenes.hpp"
#include "voxfield/core/sparse.hpp"
#include "voxfield/core/stats.hpp"

namespace voxfield::cli {

using bench::peak_rss_bytes;

ocl::GeneratorOptions sparse_options(const SuiteOptions& o) {
    GeneratorFlags flags = o.field;
    flags.algorithm = "exact";
    flags.chunk = 0;
    return ocl::resolve_sparse_options(
        generator_options(flags, parse_format(o.format), Dims{1, 1, 1}), true);
}

namespace {

using nlohmann::json;

constexpr std::int64_t kEditRadius = 8;
// Tiles on which --peer compares OpenVDB's distances with the exact ones.
constexpr std::uint32_t kPeerSampleTiles = 64;

// The highest solid voxel of column (x, z), or 0.
std::int64_t surface(const SparseWorld& w, std::uint32_t x, std::uint32_t z) {
    for (std::uint32_t y = w.dims().y; y-- > 0;) {
        if (w.at(x, y, z) != 0) {
            return y;
        }
    }
    return 0;
}

// Radius-8 spheres at random surface points, placing material 5 and erasing alternately.
std::vector<Brush> surface_edits(const SparseWorld& w, std::size_t count, std::uint64_t seed) {
    std::mt19937_64 rng(seed + 1);
    const Dims d = w.dims();
    std::uniform_int_distribution<std::uint32_t> px(0, d.x - 1), pz(0, d.z - 1);
    std::vector<Brush> edits;
    for (std::size_t e = 0; e < count; ++e) {
        Brush b;
        b.op = e % 2 == 0 ? BrushOp::place : BrushOp::erase;
        b.shape = BrushShape::sphere;
        b.radius = kEditRadius;
        b.material = 5;
        const std::uint32_t x = px(rng), z = pz(rng);
        b.centre = {x, surface(w, x, z), z};
        edits.push_back(b);
    }
    return edits;
}

// The dense bounded field (`options`) of `window` of the world: its voxels read densely and
// generated on the device, x fastest.
std::vector<std::uint8_t> window_field(ocl::Context& ctx, const SparseWorld& world,
                                       const Palette& palette, const ocl::GeneratorOptions& options,
                                       const Box& window) {
    const Dims wd{static_cast<std::uint32_t>(window.max.x - window.min.x),
                  static_cast<std::uint32_t>(window.max.y - window.min.y),
                  static_cast<std::uint32_t>(window.max.z - window.min.z)};
    World dense(wd);
    world.read_box(window, dense.voxels());
    return ocl::generate(ctx, dense, palette, ocl::resolve_options(options, wd)).bytes;
}

// The index of voxel (x, y, z) among `box`'s voxels, x fastest.
std::size_t index_in(const Box& box, std::int64_t x, std::int64_t y, std::int64_t z) {
    const std::int64_t bx = box.max.x - box.min.x, by = box.max.y - box.min.y;
    return static_cast<std::size_t>(((z - box.min.z) * by + (y - box.min.y)) * bx +
                                    (x - box.min.x));
}

// Compares the sparse field over each edit's recomputed box with the dense bounded field of the
// same voxels: a window around the box (the box with twice the halo, moved inside the world,
// one shape for all edits) generated densely; the box lies at least a halo inside the window
// wherever the window does not end at the world's edge, so its values are the world's.
struct ExactCheck {
    std::uint64_t voxels = 0, differing = 0;
    double max_error = 0, sum_error = 0;
};

ExactCheck check_edits(ocl::Context& ctx, ocl::SparseField& field, const Palette& palette,
                       const ocl::GeneratorOptions& options, const std::vector<Brush>& edits,
                       BenchObserver& observer, const std::string& label) {
    ExactCheck check;
    const SparseWorld& world = field.world();
    const Dims d = world.dims();
    const std::int64_t extent[3] = {d.x, d.y, d.z};
    std::int64_t size[3];
    for (int a = 0; a < 3; ++a) {
        size[a] = std::min<std::int64_t>(extent[a], 2 * kEditRadius + 1 + 4 * field.halo(a));
    }
    const Format f = options.format;
    const std::size_t elem = element_size(f);
    for (std::size_t e = 0; e < edits.size(); ++e) {
        observer.progress(label + ": checking edit " + std::to_string(e + 1) + "/" +
                          std::to_string(edits.size()) + " against the dense field");
        const Box bounds = brush_bounds(edits[e], d);
        if (bounds.empty()) {
            continue;
        }
        const std::int64_t lo[3] = {bounds.min.x, bounds.min.y, bounds.min.z};
        std::int64_t origin[3];
        Box box;
        std::int64_t* box_lo[3] = {&box.min.x, &box.min.y, &box.min.z};
        std::int64_t* box_hi[3] = {&box.max.x, &box.max.y, &box.max.z};
        const std::int64_t hi[3] = {bounds.max.x, bounds.max.y, bounds.max.z};
        for (int a = 0; a < 3; ++a) {
            const std::int64_t h = field.halo(a);
            origin[a] = std::clamp<std::int64_t>(lo[a] - 2 * h, 0, extent[a] - size[a]);
            *box_lo[a] = std::max<std::int64_t>(lo[a] - h, 0);
            *box_hi[a] = std::min<std::int64_t>(hi[a] + h, extent[a]);
        }
        const Box window{{origin[0], origin[1], origin[2]},
                         {origin[0] + size[0], origin[1] + size[1], origin[2] + size[2]}};
        const std::vector<std::uint8_t> dense = window_field(ctx, world, palette, options, window);
        const std::vector<std::uint8_t> got = field.read_box(box);
        for (std::int64_t z = box.min.z; z < box.max.z; ++z) {
            for (std::int64_t y = box.min.y; y < box.max.y; ++y) {
                for (std::int64_t x = box.min.x; x < box.max.x; ++x) {
                    const std::size_t i = index_in(box, x, y, z), j = index_in(window, x, y, z);
                    ++check.voxels;
                    if (!std::equal(got.begin() + static_cast<long>(i * elem),
                                    got.begin() + static_cast<long>((i + 1) * elem),
                                    dense.begin() + static_cast<long>(j * elem))) {
                        ++check.differing;
                        const double err =
                            std::abs(decode_value(got, f, i) - decode_value(dense, f, j));
                        check.max_error = std::max(check.max_error, err);
                        check.sum_error += err;
                    }
                }
            }
        }
    }
    return check;
}

// The exact f32 field of the tiles that --peer compares OpenVDB's distances on, whatever the
// row's format: each tile's dense bounded field, generated on a window of the tile with the
// bound's halo (every solid within the bound of the tile's voxels), so exact for the tile.
std::vector<bench::ExactTile> peer_exact_tiles(ocl::Context& ctx, const SparseWorld& world,
                                               const Palette& palette,
                                               const ocl::GeneratorOptions& options,
                                               BenchObserver& observer, const std::string& label) {
    ocl::GeneratorOptions f32 = options;
    f32.format = Format::f32;
    const auto halo = static_cast<std::int64_t>(std::ceil(*options.max_distance));
    const Dims d = world.dims();
    const std::int64_t extent[3] = {d.x, d.y, d.z};
    std::vector<bench::ExactTile> out;
    const std::vector<std::uint32_t> tiles = bench::peer_sample_tiles(world, kPeerSampleTiles);
    for (const std::uint32_t t : tiles) {
        observer.progress(label + ": exact field of compared tile " +
                          std::to_string(out.size() + 1) + "/" + std::to_string(tiles.size()));
        const Box b = world.tile_box(t);
        const std::int64_t lo[3] = {b.min.x, b.min.y, b.min.z}, hi[3] = {b.max.x, b.max.y, b.max.z};
        std::int64_t wlo[3], whi[3];
        for (int a = 0; a < 3; ++a) {
            wlo[a] = std::max<std::int64_t>(lo[a] - halo, 0);
            whi[a] = std::min<std::int64_t>(hi[a] + halo, extent[a]);
        }
        const Box window{{wlo[0], wlo[1], wlo[2]}, {whi[0], whi[1], whi[2]}};
        const std::vector<std::uint8_t> dense = window_field(ctx, world, palette, f32, window);
        bench::ExactTile& e = out.emplace_back();
        e.tile = t;
        e.values.reserve(static_cast<std::size_t>(b.volume()));
        for (std::int64_t z = b.min.z; z < b.max.z; ++z) {
            for (std::int64_t y = b.min.y; y < b.max.y; ++y) {
                for (std::int64_t x = b.min.x; x < b.max.x; ++x) {
                    const std::size_t j = index_in(window, x, y, z);
                    float v = 0;
                    std::memcpy(&v, dense.data() + j * sizeof(float), sizeof(float));
                    e.values.push_back(v);
                }
            }
        }
    }
    return out;
}

json sparse_row(ocl::Context& ctx, const SuiteOptions& o, Dims dims, std::uint32_t repeat,
                std::uint32_t warmup, std::uint32_t edit_count, BenchObserver& observer) {
    const std::string label = "sparse " + dims.to_string();
    const ocl::GeneratorOptions options = sparse_options(o);
    const json load_start = load_average();
    double build_ms = 0;
    SparseWorld world = build_city(dims, o.seed, label, observer, build_ms);
    const double rss_after_build = peak_rss_bytes();
    const std::vector<Brush> edits = surface_edits(world, warmup + edit_count, o.seed);
    const std::uint32_t tiles = world.tile_count();
    const std::uint64_t solid_count = world.solid_count(), world_bytes = world.bytes();
    const Palette palette = Palette::magicavoxel_default();

    observer.stage(label + ": " + std::to_string(tiles) + " tiles, " + std::to_string(solid_count) +
                   " solid voxels; whole bounded field");
    const auto t_upload = Clock::now();
    // Uploads the world's 64-trees; released before the trace (below).
    std::optional<ocl::SparseField> field_owner(std::in_place, ctx, world, palette, options);
    ocl::SparseField& field = *field_owner;
    const double upload_ms = ms_since(t_upload);
    std::vector<double> field_wall, field_kernel;
    for (std::uint32_t i = 0; i < repeat; ++i) {
        observer.progress(label + ": whole bounded field, run " + std::to_string(i + 1) + "/" +
                          std::to_string(repeat));
        const auto t0 = Clock::now();
        field_kernel.push_back(field.run());
        field_wall.push_back(ms_since(t0));
    }
    const Summary fw = summarize(field_wall), fk = summarize(field_kernel);
    json field_stages = json::object();
    for (const auto& [name, ms] : field.last_stages()) {
        field_stages[name] = ms;
    }
    const ocl::SparseField::Work field_work = field.last_work();
    json field_host_stages = json::object();
    for (const auto& [name, ms] : field.last_host_stages()) {
        field_host_stages[name] = ms;
    }
    // With --compare-blocks, the same field by per-tile blocks through the dense generator (the
    // path the sweep replaced), once, in the same run.
    const std::string method = field.run_method();
    json blocks_wall = nullptr, blocks_kernel = nullptr;
    if (method != "blocks" && o.compare_blocks) {
        observer.progress(label + ": whole bounded field by blocks, for comparison");
        field.force_blocks(true);
        const auto t0 = Clock::now();
        blocks_kernel = field.run();
        blocks_wall = ms_since(t0);
        field.force_blocks(false);
        observer.stage(label + ": by blocks " + fixed(blocks_wall.get<double>(), 1) +
                       " ms (kernels " + fixed(blocks_kernel.get<double>(), 1) + " ms)");
    }
    observer.stage(label + ": whole field in " + fixed(fw.median, 1) + " ms (kernels " +
                   fixed(fk.median, 1) + " ms), " + std::to_string(field.dense_tiles()) +
                   " field tiles; radius-8 edits on the device");

    // The timed edits alternate: profiled ones (a profiling event per command: per-kernel
    // stages and the device's idle time) and lean ones (events only where the host waits,
    // SparseField::set_edit_stage_events(false)), whose wall time is the row's edit time.
    std::vector<double> edit_wall, edit_kernel, edit_encode, edit_gap, edit_enqueues, edit_waits;
    std::vector<double> lean_wall;
    StageSamples edit_stages;       // per kernel name
    StageSamples edit_host_stages;  // per host stage (Update::host_stages)
    StageSamples lean_host_stages;
    std::vector<double> edit_device_span, edit_device_idle;
    std::size_t lean_single_block = 0;  // lean one-block edits (with host stages)
    std::uint64_t recomputed = 0;
    for (std::size_t e = 0; e < edits.size(); ++e) {
        const bool warm = e < warmup;
        const bool lean = !warm && (e - warmup) % 2 == 1;
        observer.progress(label + ": " + (warm ? "warm-up edit " : "edit ") +
                          std::to_string(warm ? e + 1 : e + 1 - warmup) + "/" +
                          std::to_string(warm ? warmup : edit_count));
        field.set_edit_stage_events(!lean);
        const auto t0 = Clock::now();
        const auto u = field.apply_brush(edits[e]);
        const double wall = ms_since(t0);
        recomputed +=
            warm || u.recomputed.empty() ? 0 : static_cast<std::uint64_t>(u.recomputed.volume());
        if (lean) {
            lean_wall.push_back(wall);
            if (!u.host_stages.empty()) {
                append_stage_samples(lean_host_stages, ++lean_single_block, u.host_stages);
            }
        } else if (!warm) {
            edit_wall.push_back(wall);
            edit_kernel.push_back(u.kernel_ms);
            edit_encode.push_back(u.edit_kernel_ms);
            edit_gap.push_back(wall - u.kernel_ms);
            edit_enqueues.push_back(u.traffic.enqueues);
            edit_waits.push_back(u.traffic.host_waits);
            append_stage_samples(edit_stages, edit_wall.size(), u.stages);
            if (!u.host_stages.empty()) {
                append_stage_samples(edit_host_stages, edit_device_span.size() + 1, u.host_stages);
                edit_device_span.push_back(u.device_span_ms);
                edit_device_idle.push_back(u.device_idle_ms);
            }
        }
    }
    field.set_edit_stage_events(true);
    // The row's edit time: the lean edits (the profiled one where a single edit was timed).
    const std::vector<double>& timed = lean_wall.empty() ? edit_wall : lean_wall;
    json stage_medians = json::object();
    for (const auto& [name, samples] : edit_stages) {
        stage_medians[name] = summarize(samples).median;
    }
    json host_stage_medians = json::object(), lean_host_stage_medians = json::object();
    for (const auto& [name, samples] : edit_host_stages) {
        host_stage_medians[name] = summarize(samples).median;
    }
    for (const auto& [name, samples] : lean_host_stages) {
        lean_host_stage_medians[name] = summarize(samples).median;
    }
    const double peak = peak_rss_bytes();
    const auto t_sync = Clock::now();
    field.world();
    const double host_sync_ms = ms_since(t_sync);
    const ExactCheck check = check_edits(ctx, field, palette, options, edits, observer, label);
    const std::uint64_t field_tiles = field.dense_tiles(), field_bytes = field.field_bytes();
    // The world on the host is up to date (world() above): the device's world and field are
    // released first, so that the trace's copy of the world fits beside nothing else (at
    // 16384 x 1024 x 16384 the OpenCL world and field take 124 GB, the trace's world 73 GB).
    // After the peak memory was read: the trace's copy of the world is not in it.
    field_owner.reset();
    observer.stage(label + ": tracing the edited world at 1920x1080 (Vulkan, flat and lit)");
    const json trace = sparse_trace_keys(world, palette, repeat);
    observer.stage(label + ": " + describe_sparse_trace(trace));
    const json load_end = load_average();
    json peer = nullptr;
    if (o.peer) {
        observer.stage(label + ": OpenVDB's fast sweeping (fogToSdf) on the same world");
        // The device's world and field, and the trace, were released: their heap pages go back
        // to the system, so that the peer's grids fit beside the world.
        malloc_trim(0);
        const bench::OpenVdbPeer p = bench::run_openvdb_peer(
            world, *options.max_distance,
            peer_exact_tiles(ctx, world, palette, options, observer, label));
        const double peer_ms = p.topology_ms + p.sweep_ms;
        peer = {{"name", "OpenVDB tools::fogToSdf (fast sweeping, 1 iteration)"},
                {"openvdb_version", p.version},
                {"band",
                 "empty voxels within ceil(D) of a solid one, solid voxels with an empty "
                 "26-neighbour"},
                {"band_voxels", p.band_voxels},
                {"leaf_nodes", p.leaf_nodes},
                {"topology_ms", p.topology_ms},
                {"sweep_ms", p.sweep_ms},
                {"total_ms", peer_ms},
                {"voxfield_field_wall_ms", fw.median},
                {"voxfield_speedup_vs_sweep", p.sweep_ms / fw.median},
                {"voxfield_speedup_vs_total", peer_ms / fw.median},
                {"compared_voxels", p.compared},
                {"mean_abs_error_voxels", p.mean_abs_error},
                {"max_abs_error_voxels", p.max_abs_error},
                {"error",
                 "over the empty voxels of the sampled tiles within D - 1 of a solid one: "
                 "OpenVDB's distance + 0.5 against the exact distance (voxfield's dense f32 "
                 "bounded field of each tile with its halo)"},
                {"rss_before_bytes", p.rss_before_bytes},
                {"peak_rss_bytes", p.peak_rss_bytes},
                {"peak_rss_is_own", p.peak_is_own},
                {"added_bytes_per_leaf",
                 p.peak_is_own && p.leaf_nodes > 0
                     ? json((p.peak_rss_bytes - p.rss_before_bytes) / double(p.leaf_nodes))
                     : json()},
                {"added_bytes_per_band_voxel",
                 p.peak_is_own && p.band_voxels > 0
                     ? json((p.peak_rss_bytes - p.rss_before_bytes) / double(p.band_voxels))
                     : json()},
                {"load_average_end", load_average()}};
        observer.stage(label + ": OpenVDB band " + std::to_string(p.band_voxels) +
                       " voxels, topology " + fixed(p.topology_ms / 1e3, 2) + " s, sweep " +
                       fixed(p.sweep_ms / 1e3, 2) + " s (voxfield's whole field " +
                       fixed(fw.median / 1e3, 2) + " s); error mean " + fixed(p.mean_abs_error, 3) +
                       ", max " + fixed(p.max_abs_error, 3) + " voxels; peak " +
                       fixed(p.peak_rss_bytes / 1048576.0, 0) + " MiB");
    }

    const double stored_voxels = static_cast<double>(tiles) * kTileVoxels;
    const double solid = static_cast<double>(solid_count);
    const double peak_target = 3 * stored_voxels + 256.0 * 1048576.0;
    json row = {
        {"table", "sparse"},
        {"group", dims.to_string()},
        {"algorithm", "exact (sparse tiles)"},
        {"size", {dims.x, dims.y, dims.z}},
        {"voxels", static_cast<double>(dims.count())},
        {"chunk", nullptr},
        {"tile", kTileSize},
        {"metric", to_string(options.metric)},
        {"spacing", options.spacing.to_string()},
        {"signed", options.signed_field},
        {"format", to_string(options.format)},
        {"max_distance", *options.max_distance},
        {"scene", "city"},
        {"seed", o.seed},
        {"build_ms", build_ms},
        {"tiles_stored", tiles},
        {"solid_voxels", solid_count},
        {"stored_voxels", stored_voxels},
        {"world_bytes", world_bytes},
        {"world_bytes_per_solid_voxel", solid > 0 ? json(double(world_bytes) / solid) : json()},
        {"world_bytes_per_stored_voxel", double(world_bytes) / stored_voxels},
        {"field_tiles", field_tiles},
        {"field_bytes", field_bytes},
        {"field_bytes_per_stored_voxel", double(field_bytes) / stored_voxels},
        {"world_upload_ms", upload_ms},
        {"field_runs", field_wall.size()},
        {"field_wall_ms", fw.median},
        {"field_kernel_ms", fk.median},
        {"field_wall_ms_samples", field_wall},
        {"field_kernel_ms_samples", field_kernel},
        {"field_stage_ms", field_stages},
        {"field_host_stage_ms", field_host_stages},
        {"field_method", method},
        {"field_blocks_wall_ms", blocks_wall},
        {"field_blocks_kernel_ms", blocks_kernel},
        {"field_blocks", field_work.blocks},
        {"field_batches", field_work.batches},
        {"field_block_voxels", field_work.block_voxels},
        {"field_region_voxels", field_work.region_voxels},
        {"field_halo_factor", field_work.region_voxels > 0 ? double(field_work.block_voxels) /
                                                                 double(field_work.region_voxels)
                                                           : 0.0},
        {"gvox_per_s", double(dims.count()) / (fw.median * 1e-3) / 1e9},
        {"iterations", nullptr},
        {"edit_radius", kEditRadius},
        {"edit_shape", "sphere"},
        {"edit_path", "device (decoded, brushed and encoded by kernels; host world lags)"},
        {"edits", edit_wall.size() + lean_wall.size()},
        {"edit_warmup", warmup},
        {"timed",
         lean_wall.empty()
             ? "median_ms..max_ms: one radius-8 edit with an event per command (one timed edit: "
               "no lean one), wall clock until the field is up to date"
             : "median_ms..max_ms: one radius-8 edit on the queue without profiling (every "
               "other timed edit), wall clock until the field is up to date; profiled_edit_*: "
               "the other edits, with an event per command, whose kernel and stage times the "
               "edit_* keys give"},
        {"profiled_edits", edit_wall.size()},
        {"profiled_edit_ms_median", summarize(edit_wall).median},
        {"profiled_edit_samples_ms", edit_wall},
        {"lean_edit_host_stage_ms_median", lean_host_stage_medians},
        {"edit_kernel_ms_median", summarize(edit_kernel).median},
        {"edit_kernel_ms_samples", edit_kernel},
        {"edit_world_kernel_ms_median", summarize(edit_encode).median},
        {"edit_stage_ms_median", stage_medians},
        {"edit_outside_kernels_ms_median", summarize(edit_gap).median},
        {"edit_host_stage_ms_median", host_stage_medians},
        {"edit_single_block_edits", edit_device_span.size()},
        {"edit_device_span_ms_median",
         edit_device_span.empty() ? json(nullptr) : json(summarize(edit_device_span).median)},
        {"edit_device_idle_ms_median",
         edit_device_idle.empty() ? json(nullptr) : json(summarize(edit_device_idle).median)},
        {"edit_enqueues", summarize(edit_enqueues).median},
        {"edit_host_waits", summarize(edit_waits).median},
        {"edit_enqueues_max", summarize(edit_enqueues).max},
        {"edit_host_waits_max", summarize(edit_waits).max},
        {"samples_ms", timed},
        {"edit_voxels_recomputed_mean",
         edit_count == 0 ? 0.0 : double(recomputed) / double(edit_count)},
        {"host_sync_ms", host_sync_ms},
        {"exact", check.differing == 0 && check.voxels > 0},
        {"exact_checked_voxels", check.voxels},
        {"exact_differing_voxels", check.differing},
        {"exact_check",
         "after all edits, each edit's recomputed box against the dense bounded field of "
         "a window of the same voxels (same device, same options)"},
        {"max_error", check.max_error},
        {"mean_error", check.voxels > 0 ? check.sum_error / double(check.voxels) : 0.0},
        {"peak_rss_bytes", peak},
        {"rss_after_build_bytes", rss_after_build},
        {"peak_bytes_per_stored_voxel", peak / stored_voxels},
        {"peak_target_bytes", peak_target},
        {"peak_within_target", peak <= peak_target},
        {"load_average_start", load_start},
        {"load_average_end", load_end}};
    if (o.peer) {
        row["peer"] = peer;
    }
    put_summary(row, summarize(timed));
    row.update(trace);
    return row;
}

}  // namespace

SparseWorld build_city(Dims dims, std::uint64_t seed, const std::string& label,
                       BenchObserver& observer, double& build_ms) {
    observer.stage(label + ": building the city scene tile by tile");
    const auto t_build = Clock::now();
    const CityScene scene(dims, seed);
    SparseWorld world = SparseWorld::from_fill(
        dims, [&](const Box& box, std::span<std::uint8_t> out) { scene.fill(box, out); });
    build_ms = ms_since(t_build);
    return world;
}

json load_average() {
    std::ifstream in("/proc/loadavg");
    double a = 0, b = 0, c = 0;
    if (!(in >> a >> b >> c)) {
        return json();
    }
    return {a, b, c};
}

void append_stage_samples(StageSamples& columns, std::size_t samples,
                          const std::vector<std::pair<std::string, double>>& named) {
    for (const auto& [name, ms] : named) {
        auto it = std::find_if(columns.begin(), columns.end(),
                               [&](const auto& c) { return c.first == name; });
        if (it == columns.end()) {
            columns.emplace_back(name, std::vector<double>(samples - 1, 0.0));
            it = columns.end() - 1;
        }
        it->second.push_back(ms);
    }
    for (auto& [name, column] : columns) {
        column.resize(samples, 0.0);
    }
}

void check_sparse_suite_options(const SuiteOptions& o) {
    const ocl::GeneratorOptions options = sparse_options(o);
    if (o.peer &&
        (options.metric != Metric::euclidean || options.signed_field || !options.spacing.unit())) {
        throw InputError(
            "--peer compares OpenVDB's fast sweeping with the exact unsigned Euclidean field: "
            "give --metric euclidean (no --signed, no --spacing)");
    }
    for (const Dims& dims : o.sizes) {
        if (dims.x > kMaxSparseAxis || dims.y > kMaxSparseAxis || dims.z > kMaxSparseAxis) {
            throw InputError("--sizes " + dims.to_string() + ": a sparse world takes at most " +
                             std::to_string(kMaxSparseAxis) + " voxels per axis");
        }
    }
}

json run_sparse(ocl::Context& ctx, const SuiteOptions& o, std::uint32_t repeat,
                std::uint32_t warmup, BenchObserver& observer) {
    const std::vector<Dims> sizes =
        !o.sizes.empty() ? o.sizes
                         : std::vector<Dims>{o.quick ? Dims{256, 128, 256} : Dims{1024, 256, 1024}};
    const std::uint32_t edits = o.edits != 0 ? o.edits : (o.quick ? 6 : 30);
    check_sparse_suite_options(o);  // bad options refused before the first row
    json rows = json::array();
    for (const Dims& dims : sizes) {
        rows.push_back(sparse_row(ctx, o, dims, repeat, warmup, edits, observer));
        const json& r = rows.back();
        observer.stage(
            "sparse " + dims.to_string() + ": whole field " +
            fixed(r["field_wall_ms"].get<double>() / 1e3, 2) + " s wall (" +
            fixed(r["field_kernel_ms"].get<double>() / 1e3, 2) +
            " s kernels); radius-8 edit median " + fixed(r["median_ms"].get<double>(), 3) +
            " ms (min " + fixed(r["min_ms"].get<double>(), 3) + ", max " +
            fixed(r["max_ms"].get<double>(), 3) + "; profiled " +
            fixed(r["profiled_edit_ms_median"].get<double>(), 3) + " ms, kernels " +
            fixed(r["edit_kernel_ms_median"].get<double>(), 3) + " ms; " +
            fixed(r["edit_enqueues"].get<double>(), 0) + " enqueues, " +
            fixed(r["edit_host_waits"].get<double>(), 0) + " host waits); peak " +
            fixed(r["peak_rss_bytes"].get<double>() / 1048576.0, 0) +
            " MiB = " + fixed(r["peak_bytes_per_stored_voxel"].get<double>(), 3) +
            " B per stored voxel; world " +
            fixed(r["world_bytes_per_stored_voxel"].get<double>(), 3) +
            " B per stored voxel; exact " + (r["exact"].get<bool>() ? "yes" : "NO") + " (" +
            std::to_string(r["exact_checked_voxels"].get<std::uint64_t>()) + " voxels checked)");
        observer.row(r);
    }
    return rows;
}

}  // namespace voxfield::cli
