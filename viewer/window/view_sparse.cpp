// `voxfield view` on sparse worlds (see view_sparse.hpp).
#include "view_sparse.hpp"

#include <algorithm>
#include <cstdlib>
#include <filesystem>
#include <iostream>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include "cli_util.hpp"
#include "frame_clock.hpp"
#include "generate_sparse.hpp"
#include "png.hpp"
#include "sparse_history.hpp"
#include "view_benchmark.hpp"
#include "view_input.hpp"
#include "view_overlay.hpp"
#include "view_session.hpp"
#include "voxfield/cl/runtime.hpp"
#include "voxfield/cl/sparse_field.hpp"
#include "voxfield/cl/sparse_sand.hpp"
#include "voxfield/core/clock.hpp"
#include "voxfield/core/error.hpp"
#include "voxfield/core/sand.hpp"
#include "voxfield/core/scene_file.hpp"
#include "voxfield/core/scenes.hpp"
#include "voxfield/core/sdf.hpp"
#include "voxfield/core/sparse.hpp"
#include "voxfield/core/vdb.hpp"
#include "voxfield/pipeline/shared_trees.hpp"
#include "voxfield/vk/sparse_tracer.hpp"

namespace voxfield::cli {
namespace {

// The world to view and its name: INPUT read sparse, or the generated scene (the city tile by
// tile; another scene dense, then converted, where it fits one array).
struct SparseView {
    SparseModel model;
    std::string name;
};

SparseView load_sparse_view(const ViewCliOptions& o) {
    if (!o.input.empty()) {
        if (sdf::is_sdf_path(o.input) || scene::is_scene_path(o.input)) {
            throw InputError(o.input +
                             ": parts and mixed scenes are viewed on their implicit surface, "
                             "which needs the dense field (drop --sparse)");
        }
        return {load_sparse_world(o.input, InputOptions{.grid = {}, .palette_values = true}),
                o.input};
    }
    const Dims dims = view_dims(o);
    if (dims.x > kMaxSparseAxis || dims.y > kMaxSparseAxis || dims.z > kMaxSparseAxis) {
        throw InputError("--dims " + dims.to_string() + ": a sparse world takes at most " +
                         std::to_string(kMaxSparseAxis) + " voxels per axis");
    }
    if (o.scene == "city") {
        const CityScene scene(dims, o.scene_seed);
        return {SparseModel{SparseWorld::from_fill(
                                dims, [&](const Box& box,
                                          std::span<std::uint8_t> out) { scene.fill(box, out); }),
                            Palette::dissertation()},
                "scene city"};
    }
    if (dims.count() > kMaxDenseVoxels) {
        throw InputError("--scene " + o.scene + " is generated as one dense array, at most " +
                         std::to_string(kMaxDenseVoxels) + " voxels (" + dims.to_string() +
                         " has " + std::to_string(dims.count()) +
                         "); `--scene city` is generated tile by tile at any size");
    }
    return {SparseModel{SparseWorld::from_dense(make_scene(o.scene, dims, o.scene_seed)),
                        Palette::dissertation()},
            "scene " + o.scene};
}

// The undo history's budget: 1024 tiles of 64^3 on the OpenCL device.
constexpr std::uint64_t kUndoBytes = std::uint64_t{1024} * kTileVoxels;

// The box of whole tiles `tiles` (tile coordinates).
Box tiles_box(const std::vector<Int3>& tiles) {
    Box b;
    for (const Int3& t : tiles) {
        const Box tb = tile_voxels(t);
        b = b.empty() ? tb : hull(b, tb);
    }
    return b;
}

// What sparse worlds do not take, refused before any device is opened.
void check_sparse_options(const ViewCliOptions& o) {
    if (o.present == "gpu") {
        throw InputError(
            "--present gpu: a sparse world's frames are read back and go through the "
            "host (--present auto or host)");
    }
    if (!o.field_output.empty()) {
        throw InputError(
            "--field-output does not apply to a sparse world: --world-output W.vdb writes the "
            "world and its field as OpenVDB grids");
    }
    // vdb_output_spec is nullopt for a path that does not end in .vdb.
    if (!o.world_output.empty() &&
        !vdb_output_spec(o.world_output, Spacing{}, std::nullopt, false)) {
        throw InputError("--world-output " + o.world_output +
                         ": a sparse world is written as .vdb (its material and distance grids; "
                         "--world-output " +
                         std::filesystem::path(o.world_output).replace_extension(".vdb").string() +
                         ")");
    }
    if (!o.script.empty()) {
        for (const ScriptAction& a : read_view_script(o.script)) {
            const bool selects_field =
                a.kind == ScriptAction::Kind::select && a.what != "shading" && a.what != "colour";
            if (selects_field || a.kind == ScriptAction::Kind::check) {
                throw InputError("--script line " + std::to_string(a.line) +
                                 ": a sparse world takes the script's keys, mouse, shading, "
                                 "colour, save and quit only");
            }
        }
    }
}

// Ctrl+S, the script's `save STEM` and --world-output: the world (read back from the device)
// and its field as .vdb grids, tile by tile (generate's write_vdb_tiles): a material Int32Grid,
// which `view` and `render` read back, and a distance FloatGrid.
void save_sparse_world(ocl::SparseField& field, const ocl::GeneratorOptions& options,
                       const std::string& path) {
    const std::optional<VdbFieldSpec> spec =
        vdb_output_spec(path, options.spacing, options.max_distance, options.signed_field);
    const SparseWorld& world = field.world();
    OutputBatch outputs;
    write_vdb_tiles(outputs, path, world, field, options.format, *spec);
    outputs.commit();
    std::cout << "saved " << path << '\n';
}

// The box of the solids (the whole world when there are none) for the start view.
Framing sparse_framing(const SparseWorld& world) {
    Box solids{};
    for (std::uint32_t t = 0; t < world.tile_count(); ++t) {
        solids = hull(solids, world.solid_bounds(t));
    }
    Framing f = world_framing(world.dims());
    if (!solids.empty()) {
        f.centre = {double(solids.min.x + solids.max.x) / 2,
                    double(solids.min.y + solids.max.y) / 2,
                    double(solids.min.z + solids.max.z) / 2};
        f.half = {double(solids.max.x - solids.min.x) / 2, double(solids.max.y - solids.min.y) / 2,
                  double(solids.max.z - solids.min.z) / 2};
        f.front = {0, 0, -1};
    }
    return f;
}

// The benchmark's brush on the surface: the protocol's sphere (RandomEdits), its centre moved
// to the highest solid voxel of its (x, z) column (the column's top when it has none), so that
// edits touch the scene rather than the air above it. The column is read from the device.
Brush on_surface(ocl::SparseDeviceWorld& world, const Dims& dims, Brush b) {
    std::vector<Int3> column(dims.y);
    for (std::uint32_t y = 0; y < dims.y; ++y) {
        column[y] = {b.centre.x, y, b.centre.z};
    }
    const std::vector<std::uint8_t> v = world.voxels(column);
    b.centre.y = 0;
    for (std::uint32_t y = dims.y; y-- > 0;) {
        if (v[y] != 0) {
            b.centre.y = y;
            break;
        }
    }
    return b;
}

// The sharing path the tracer's trees take: the first both devices have (SharedTrees), or path
// 3 when $VOXFIELD_TRACER_COPY is set (not empty, not 0; tests compare the two).
vk::SharingPath tracer_fastest_path() {
    const char* copy = std::getenv("VOXFIELD_TRACER_COPY");
    return copy != nullptr && *copy != '\0' && std::string(copy) != "0"
               ? vk::SharingPath::copy
               : vk::SharingPath::opaque_fd;
}

// What the tracer reads after the device world changed inside `changed`: in place, its records
// pointed at the trees' new places (paths 1 and 2); or, on path 3, the tiles read back into the
// host world (SparseField::world) and written into its edit arena.
vk::SparseTileUpdate feed_tracer(pipeline::SharedTrees& shared, ocl::SparseField& field,
                                 vk::SparseTracer& tracer, const Palette& palette, const Dims& dims,
                                 const Box& changed) {
    if (shared.shares()) {
        return shared.sync(tracer, field.device_world(), dims, palette, changed);
    }
    return tracer.update_tiles(field.world(), changed);
}

// The same after a change listed by tiles (a sand step, an undo): those tiles repointed on paths
// 1 and 2; on path 3 the box `bounds` of the change rewritten (nothing when it is empty).
void feed_tracer(pipeline::SharedTrees& shared, ocl::SparseField& field, vk::SparseTracer& tracer,
                 const Palette& palette, const Dims& dims, const std::vector<Int3>& tiles,
                 const Box& bounds) {
    if (shared.shares()) {
        shared.sync(tracer, field.device_world(), dims, palette, tiles);
    } else if (!bounds.empty()) {
        tracer.update_tiles(field.world(), bounds);
    }
}

// One edit through the device: the world and field edited there, the tracer told (feed_tracer);
// on path 3 the edited tiles are read back into the host world for the tracer first.
SparseEditRecord apply_edit(pipeline::SharedTrees& shared, ocl::SparseField& field,
                            vk::SparseTracer& tracer, const Palette& palette, const Dims& dims,
                            const Brush& brush) {
    SparseEditRecord e;
    e.brush = brush;
    const auto t0 = Clock::now();
    const ocl::SparseField::Update u = field.apply_brush(brush);
    e.field_kernel_ms = u.kernel_ms;
    e.edit_kernel_ms = u.edit_kernel_ms;
    e.field_tiles = u.tiles;
    const Box bounds = brush_bounds(brush, dims);
    if (!shared.shares()) {
        const auto t1 = Clock::now();
        field.world();  // reads back the tiles the edit changed
        e.readback_ms = ms_since(t1);
    }
    const auto t2 = Clock::now();
    const vk::SparseTileUpdate tu = feed_tracer(shared, field, tracer, palette, dims, bounds);
    e.tracer_ms = ms_since(t2);
    e.tiles_written = tu.tiles_written;
    e.tiles_removed = tu.tiles_removed;
    e.tracer_bytes = tu.bytes;
    e.tracer_whole = tu.whole;
    e.wall_ms = ms_since(t0);
    return e;
}

}  // namespace

bool view_goes_sparse(const ViewCliOptions& o) {
    if (o.sparse) {
        return true;
    }
    if (!o.input.empty()) {
        return needs_sparse(o.input, "");  // render's and generate's rule
    }
    return view_dims(o).count() > kSparseAutoVoxels;
}

int run_view_sparse(ViewCliOptions& o, const ViewInputs& in, Window& window,
                    const std::shared_ptr<vk::ValidationLog>& validation) {
    check_sparse_options(o);
    const ocl::GeneratorOptions options = ocl::resolve_sparse_options(
        generator_options(o.gen, parse_format(view_format(o, true)), Dims{1, 1, 1}), true);
    std::optional<ViewScript> script_state = in.script;  // played here (in is the checked copy)
    ViewScript* script = script_state ? &*script_state : nullptr;

    const auto t_load = Clock::now();
    SparseView view = load_sparse_view(o);
    SparseWorld& world = view.model.world;
    const SandRules rules;
    const std::string ext = std::filesystem::path(o.input).extension().string();
    if (o.simulate && ext != ".vox" && ext != ".VOX") {
        // As on dense worlds: a world without a palette of its own shows its falling
        // materials as what they are.
        view.model.palette[rules.sand] = Rgba{218, 186, 120, 255};
        view.model.palette[rules.water] = Rgba{48, 110, 210, 255};
    }
    const Palette& palette = view.model.palette;
    const double load_ms = ms_since(t_load);
    const Dims dims = world.dims();

    ocl::Context cl_ctx(ocl::select_device(o.device));
    std::string why_not_one_device;
    const std::unique_ptr<vk::Context> vk_ctx =
        marcher_context(window.handle(), validation, why_not_one_device);
    // The field's trees in memory the tracer reads in place; path 3 when that memory cannot be
    // had (an allocation over the Vulkan device's limit, say).
    auto shared_trees =
        std::make_unique<pipeline::SharedTrees>(cl_ctx, *vk_ctx, tracer_fastest_path());
    std::unique_ptr<ocl::SparseField> field_owner;
    std::string sharing_failed;
    try {
        field_owner = std::make_unique<ocl::SparseField>(cl_ctx, world, palette, options,
                                                         shared_trees->allocator());
    } catch (const pipeline::SharedTrees::AllocationError& e) {
        const std::string tried = vk::describe(shared_trees->path());
        sharing_failed = tried.substr(0, tried.find(':')) + " failed: " + e.what();
        shared_trees =
            std::make_unique<pipeline::SharedTrees>(cl_ctx, *vk_ctx, vk::SharingPath::copy);
        field_owner = std::make_unique<ocl::SparseField>(cl_ctx, world, palette, options);
    }
    pipeline::SharedTrees& shared = *shared_trees;
    ocl::SparseField& field = *field_owner;
    const auto t_field = Clock::now();
    const double field_kernel_ms = field.run();
    const double field_ms = ms_since(t_field);
    // The edits' block programs set up now, not at the first click (about 2 s on a GPU whose
    // program cache lacks them).
    const auto t_prepare = Clock::now();
    field.prepare_edits(8);
    const double prepare_ms = ms_since(t_prepare);
    // --simulate: the automaton on the device's tiles (ocl::SparseSand), the stepped tiles read
    // back and rewritten in the tracer as an edit's are.
    std::optional<ocl::SparseSand> sand;
    if (o.simulate) {
        sand.emplace(cl_ctx, field, rules);
    }
    std::uint64_t sand_step = 0;
    bool sand_single = false;
    vk::SparseTracer tracer(*vk_ctx);
    const auto t_upload = Clock::now();
    if (shared.shares()) {
        shared.sync(tracer, field.device_world(), dims, palette, Box{});
    } else {
        tracer.upload(field.world(), palette);
    }
    const double upload_ms = ms_since(t_upload);
    const std::string sharing =
        shared.shares() ? vk::describe(shared.path())
                        : "path 3: copy (the tracer holds its own copy of the trees; edits read "
                          "the tiles back into the host world and upload them)";

    std::cout << "opencl:  " << cl_ctx.info().name << " (" << cl_ctx.info().type << ")\n"
              << "vulkan:  " << vk_ctx->info().name << " (" << vk_ctx->info().type << ")\n"
              << "world:   " << view.name << " " << dims.to_string()
              << " (sparse): " << world.tile_count() << " tiles of 64^3, " << world.solid_count()
              << " solid, " << world.bytes() << " bytes of 64-trees, made in " << fixed(load_ms, 1)
              << " ms\n"
              << "field:   exact, bounded at " << options.max_distance.value_or(0) << ", "
              << to_string(options.format) << ", " << field.dense_tiles() << " tiles with values ("
              << field.field_bytes() << " bytes) in " << fixed(field_ms, 1) << " ms (kernels "
              << fixed(field_kernel_ms, 1) << " ms); edits set up in " << fixed(prepare_ms, 1)
              << " ms\n"
              << "tracer:  " << tracer.stats().bytes << " bytes of its own on the device, "
              << tracer.stats().shared_bytes << " read in place, ready in " << fixed(upload_ms, 1)
              << " ms; "
              << (shared.shares() ? "edits repoint the tiles they touch"
                                  : "edits rewrite the tiles they touch from the host world")
              << "\n"
              << "sharing: " << sharing
              << (!sharing_failed.empty()    ? " (" + sharing_failed + ")"
                  : shared.why_not().empty() ? std::string()
                                             : " (" + shared.why_not() + ")")
              << '\n';

    std::unique_ptr<Screen> screen;
    if (window.handle() != nullptr) {
        o.present = "host";  // the tracer's frames are read back (Screen says so)
        screen =
            std::make_unique<Screen>(window.handle(), *vk_ctx, o, validation, why_not_one_device);
    }
    ViewCamera camera(dims, sparse_framing(field.world()),
                      double(o.width) / double(std::max(o.height, 1u)));
    // Fly at a speed that crosses the world in minutes, not hours.
    camera.settings.speed =
        std::max(camera.settings.speed, double(std::max({dims.x, dims.y, dims.z})) / 100);
    ViewControls controls;
    vk::RenderOptions render;
    set_shading(render, o.shading == "flat" ? vk::Shading::flat : vk::Shading::lit);
    render.sky = Rgba{0, 0, 0, 255};
    std::optional<BenchmarkEdits> bench;
    if (o.benchmark) {
        bench.emplace(dims, 0, o.seed, o.interval_ms);
    }
    SparseOverlayInfo info;
    info.world = view.name;
    info.vulkan = vk_ctx->info().name;
    info.opencl = cl_ctx.info().name;
    info.sharing = sharing.substr(0, sharing.find(':'));
    info.format = to_string(options.format);
    info.dims = dims;
    info.max_distance = options.max_distance.value_or(0);
    info.simulate = o.simulate;

    std::vector<FrameRecord> records;
    std::vector<SparseEditRecord> edits;
    InputMapper mapper;
    std::optional<Brush> preview, last_stroke;
    SparseHistory history(cl_ctx, kUndoBytes);
    vk::Image image;
    FrameClock frame_clock(script != nullptr);
    std::uint64_t frame = 0;
    double world_read_s = -1;  // when the overlay's world figures were last taken
    bool running = true;
    while (running) {
        const auto [t0, dt, time_s] = frame_clock.tick();
        std::uint32_t fb_w = o.width, fb_h = o.height;
        std::vector<Brush> batch;
        std::vector<bool> from_bench, new_step;
        const std::vector<ScriptAction> actions =
            script ? script->begin_frame(frame) : std::vector<ScriptAction>{};
        for (const ScriptAction& a : actions) {
            if (a.kind == ScriptAction::Kind::select && a.what == "shading") {
                set_shading(render, a.value == "lit" ? vk::Shading::lit : vk::Shading::flat);
            } else if (a.kind == ScriptAction::Kind::select && a.what == "colour") {
                controls.brush.material = static_cast<std::uint8_t>(std::stoi(a.value));
            }
        }
        if (screen) {
            if (!window.poll()) {
                break;
            }
            const RawInput raw = window.input(script, frame == 0);
            fb_w = raw.fb_width;
            fb_h = raw.fb_height;
            const InputActions a = mapper.map(raw, controls);
            running = !a.quit;
            camera.update(a.camera, dt);
            if (a.toggle_camera_mode) {
                camera.toggle_mode();
            }
            if (a.reset_camera) {
                camera.reset();
            }
            sand_single = sand_single || a.sand_step;
            if (a.history != History::none) {
                const bool undo = a.history == History::undo;
                const auto tiles = undo ? history.undo(field) : history.redo(field);
                if (!tiles) {
                    std::cout << (undo ? "nothing to undo\n" : "nothing to redo\n");
                } else {
                    const Box box = tiles_box(*tiles);
                    feed_tracer(shared, field, tracer, palette, dims, *tiles, box);
                    if (sand) {
                        sand->touched(box);
                    }
                    ++info.edits;
                }
            }
            if (a.save) {
                save_sparse_world(field, options, "voxfield-world-" + local_timestamp() + ".vdb");
            }
            preview = aimed_brush(field.device_world(), camera, controls, a);
            // A held button strokes: every frame whose aimed brush differs adds it.
            if ((a.left || a.right) && preview && preview != last_stroke) {
                batch.push_back(*preview);
                from_bench.push_back(false);
                new_step.push_back(!last_stroke.has_value());  // a stroke is one undo step
                last_stroke = preview;
            } else if (!a.left && !a.right) {
                last_stroke.reset();
            }
            if (a.screenshot && !image.rgba.empty()) {
                const std::string path = "voxfield-sparse-frame-" + std::to_string(frame) + ".png";
                write_png(path, image);
                std::cout << "screenshot " << path << '\n';
            }
        }
        if (frame < in.edits.size()) {
            batch.push_back(in.edits[frame].brush);
            from_bench.push_back(false);
            new_step.push_back(true);
        }
        if (const auto brush = bench ? bench->due(time_s) : std::nullopt) {
            batch.push_back(on_surface(field.device_world(), dims, *brush));
            from_bench.push_back(true);
            new_step.push_back(true);
        }
        double update_ms = 0;
        for (std::size_t i = 0; i < batch.size(); ++i) {
            if (new_step[i]) {
                history.begin_step();
            }
            // Enqueued before the edit, which waits for it: the edit's wall time includes it.
            history.before_edit(field, brush_bounds(batch[i], dims));
            SparseEditRecord e = apply_edit(shared, field, tracer, palette, dims, batch[i]);
            if (sand) {
                sand->touched(brush_bounds(batch[i], dims));
            }
            e.time_s = time_s;
            e.bench = from_bench[i];
            update_ms += e.wall_ms;
            info.edit_ms = e.wall_ms;
            info.field_kernel_ms = e.field_kernel_ms;
            info.readback_ms = e.readback_ms;
            info.tracer_ms = e.tracer_ms;
            info.tiles_written = e.tiles_written;
            info.tiles_removed = e.tiles_removed;
            ++info.edits;
            edits.push_back(e);
        }
        double simulate_ms = -1;
        std::size_t sand_changed = 0;
        if (sand && (!controls.sand_paused || sand_single)) {
            sand_single = false;
            const auto t_step = Clock::now();
            const ocl::SparseSand::Step st = sand->step(o.seed, sand_step++);
            simulate_ms = st.simulate_ms;
            sand_changed = static_cast<std::size_t>(st.changed);
            feed_tracer(shared, field, tracer, palette, dims, st.tiles, st.bounds);
            update_ms += ms_since(t_step);
            info.sand_steps = sand_step;
            info.sand_ms = ms_since(t_step);
            info.sand_changed = st.changed;
            info.sand_tiles_run = st.tiles_run;
            info.sand_tiles_changed = st.tiles_changed;
        }
        double trace_ms = -1;
        if (fb_w > 0 && fb_h > 0) {
            render.width = std::min(fb_w, vk::kMaxImageSize);
            render.height = std::min(fb_h, vk::kMaxImageSize);
            render.camera.position = camera.position();
            render.camera.target = camera.target();
            render.camera.fov_deg = camera.settings.fov_deg;
            if (screen && time_s - world_read_s >= 0.5) {
                // The overlay's world figures from the device, at most twice a second: the
                // slots' counts read, not the world (its host copy is never brought up to date
                // here: at 16384^2 that copy's growth alone would stall for seconds).
                const ocl::SparseDeviceWorld::Figures fig = field.device_world().figures();
                world_read_s = time_s;
                info.tiles = static_cast<std::uint32_t>(fig.tiles);
                info.solid = fig.solid;
                info.world_bytes = fig.tree_bytes;
            }
            if (screen) {
                {
                    const pipeline::SharedTrees::TraceScope scope(shared);
                    tracer.render(render, image);
                }
                trace_ms = image.raymarch_ms;
                screen->overlay().new_frame();
                info.frame_ms = records.empty() ? 0 : records.back().frame_ms;
                info.trace_ms = trace_ms;
                info.field_tiles = field.dense_tiles();
                info.field_bytes = field.field_bytes();
                info.tracer = tracer.stats();
                draw_sparse_overlay(info, controls, camera, preview, render, palette, fb_w, fb_h);
                if (!o.window_screenshot.empty() && frame + 1 >= o.frames) {
                    screen->presenter().capture_next_frame();
                }
                screen->presenter().present(image.rgba.data(), image.width, image.height, fb_w,
                                            fb_h, ImGuiBackend::record);
            } else {
                const pipeline::SharedTrees::TraceScope scope(shared);
                trace_ms = tracer.trace(render);
            }
        }
        records.push_back({time_s, ms_since(t0), update_ms, 0, trace_ms, !batch.empty(),
                           simulate_ms, sand_changed});
        for (const ScriptAction& a : actions) {
            if (a.kind == ScriptAction::Kind::save) {
                save_sparse_world(field, options, a.value + ".vdb");
            }
            running = running && a.kind != ScriptAction::Kind::quit;
        }
        ++frame;
        if ((o.frames != 0 && frame >= o.frames) || (o.benchmark && time_s >= o.duration_s)) {
            running = false;
        }
    }

    if (!o.screenshot.empty()) {
        // The last view traced again and read back (headless frames stay on the device).
        if (render.width == 0) {
            throw std::runtime_error("no frame was rendered for --screenshot");
        }
        vk::Image shot;
        {
            const pipeline::SharedTrees::TraceScope scope(shared);
            shot = tracer.render(render);
        }
        write_png(o.screenshot, shot);
        std::cout << "screenshot " << o.screenshot << " (" << shot.width << "x" << shot.height
                  << ", frame " << frame << ")\n";
    }
    if (!o.window_screenshot.empty()) {
        const std::optional<vk::Image> shown =
            screen ? screen->presenter().captured_frame() : std::nullopt;
        if (!shown) {
            throw std::runtime_error("--window-screenshot: no window frame was captured");
        }
        write_png(o.window_screenshot, *shown);
        std::cout << "window screenshot " << o.window_screenshot << '\n';
    }
    if (!o.world_output.empty()) {
        save_sparse_world(field, options, o.world_output);
    }
    std::cout << "frames:  " << frame << ", edits " << edits.size()
              << (sand ? ", sand steps " + std::to_string(sand_step) : std::string()) << '\n';
    if (bench) {
        const SparseWorld& w = field.world();
        const vk::SparseDeviceStats& ts = tracer.stats();
        const nlohmann::json keys = {
            {"dims", {dims.x, dims.y, dims.z}},
            {"tiles", w.tile_count()},
            {"stored_voxels", std::uint64_t{w.tile_count()} * kTileVoxels},
            {"solid_voxels", w.solid_count()},
            {"world_bytes", w.bytes()},
            {"format", to_string(options.format)},
            {"max_distance", options.max_distance.value_or(0)},
            {"field_tiles", field.dense_tiles()},
            {"field_bytes", field.field_bytes()},
            {"field_ms", field_ms},
            {"edits_setup_ms", prepare_ms},
            {"field_kernel_ms", field_kernel_ms},
            {"load_ms", load_ms},
            {"tracer_upload_ms", upload_ms},
            {"tracer_bytes", ts.bytes},
            {"tracer_shared_bytes", ts.shared_bytes},
            {"tracer_sharing", sharing},
            {"tracer_node_chunks", ts.node_chunks},
            {"tracer_material_chunks", ts.material_chunks},
            {"arena_tiles", ts.arena_tiles},
            {"arena_nodes", ts.arena_nodes},
            {"arena_material_bytes", ts.arena_material_bytes},
            {"edit_protocol",
             "RandomEdits spheres (size 1..15, radius size/2, 1 in 12 erases), centre moved to "
             "the surface of its column"}};
        const BenchmarkSetup setup{
            view.name, cl_ctx.info(), vk_ctx->info().name,
            screen ? std::optional(screen->presenter().mode()) : std::nullopt};
        report_sparse_benchmark(o, setup, keys, render, records, edits);
    }
    return 0;
}

}  // namespace voxfield::cli
