// `view`'s interactive session (see view_session.hpp).
#include "view_session.hpp"

#include <nlohmann/json.hpp>

#include <algorithm>
#include <ctime>
#include <iostream>

#include "cli_util.hpp"
#include "view_benchmark.hpp"
#include "voxfield/core/chunks.hpp"
#include "voxfield/core/error.hpp"
#include "voxfield/core/npy.hpp"
#include "voxfield/core/scenes.hpp"
#include "voxfield/core/vox.hpp"

namespace voxfield::cli {
namespace {

// While the sand runs, the host's copy of the world (what the brush aims at) is read back from
// the device every this many steps.
constexpr std::uint64_t kAimRefreshSteps = 16;

// The position of `name` in a combo's entries (entries.size() when it is not one).
int entry_of(const std::vector<std::string>& entries, const std::string& name) {
    return static_cast<int>(std::find(entries.begin(), entries.end(), name) - entries.begin());
}

int algorithm_entry(ocl::Algorithm a) {
    return entry_of(ocl::algorithm_names(), ocl::to_string(a));
}

int metric_entry(Metric m) {
    return entry_of(metric_names(), to_string(m));
}

// The failures an algorithm or scene switch survives (the session keeps its field): refused
// options and device errors. Anything else ends the viewer.
bool switch_failure(const std::exception& e) {
    return dynamic_cast<const InputError*>(&e) != nullptr ||
           dynamic_cast<const ocl::ClError*>(&e) != nullptr ||
           dynamic_cast<const ocl::BuildError*>(&e) != nullptr ||
           dynamic_cast<const vk::VkError*>(&e) != nullptr;
}

// What a scripted test checks after a frame: the world, the field and what the overlay
// shows.
void write_check(const std::string& stem, std::uint64_t frame, const ViewState& s,
                 pipeline::FramePipeline& session) {
    const NpyArray w = npy_from_world(session.world());
    write_npy(stem + "-world.npy", w.type, w.dims, w.data);
    write_npy(stem + "-field.npy", npy_type(session.options().format), session.world().dims(),
              session.read_field());
    const Vec3d eye = s.camera.position();
    const BrushSettings& brush = s.controls.brush;
    const bool orbit = s.camera.mode() == ViewCamera::Mode::orbit;
    const nlohmann::json state = {
        {"frame", frame},
        {"algorithm", s.selection.algorithm_name()},
        {"field_algorithm", ocl::to_string(session.options().algorithm)},
        {"metric", s.selection.metric_name()},
        {"field_metric", to_string(session.options().metric)},
        {"chunk", session.options().chunk},
        {"panel", s.controls.full_panel ? "full" : "compact"},
        {"help", s.controls.show_help},
        {"switch_error", s.switch_error},
        {"shading", s.render.shading == vk::Shading::lit ? "lit" : "flat"},
        {"paint_mode", s.controls.paint_mode},
        {"brush",
         {{"shape", to_string(brush.shape)}, {"size", brush.size}, {"material", brush.material}}},
        {"undo", s.history().undo_count()},
        {"redo", s.history().redo_count()},
        {"solid_voxels", session.world().solid_count()},
        {"camera", {{"position", {eye[0], eye[1], eye[2]}}, {"mode", orbit ? "orbit" : "fly"}}},
        {"simulate", {{"paused", s.controls.sand_paused}, {"step", s.sand.step}}},
        {"sharing", vk::describe(session.sharing())}};
    write_json_file(stem + "-state.json", state);
    std::cout << "checked " << stem << " (frame " << frame << ")\n";
}

}  // namespace

void set_shading(vk::RenderOptions& r, vk::Shading shading) {
    r.shading = shading;
    r.sky_gradient = shading == vk::Shading::lit;
}

bool has_focus(ocl::Algorithm a) {
    return a == ocl::Algorithm::lod || a == ocl::Algorithm::monolithic;
}

std::string PanelSelection::algorithm_name() const {
    return ocl::algorithm_names().at(static_cast<std::size_t>(algorithm));
}

std::string PanelSelection::metric_name() const {
    return metric_names().at(static_cast<std::size_t>(metric));
}

ViewState::ViewState(const ViewCliOptions& o, pipeline::FramePipeline& session,
                     const Framing& framing)
    : camera(session.world().dims(), framing, double(o.width) / double(std::max(o.height, 1u))),
      session_(&session) {
    set_shading(render, o.shading == "flat" ? vk::Shading::flat : vk::Shading::lit);
    render.sky = Rgba{0, 0, 0, 255};
    const ocl::GeneratorOptions& g = session.options();
    selection.algorithm = algorithm_entry(g.algorithm);
    selection.metric = metric_entry(g.metric);
    const std::vector<std::string> scenes = scene_names();
    selection.scene = std::find(scenes.begin(), scenes.end(), o.scene) == scenes.end()
                          ? 0
                          : entry_of(scenes, o.scene);
    if (g.focus) {
        selection.focus_size = static_cast<int>(std::min<std::int64_t>(g.focus->size, 8));
        focus_centre = g.focus->centre;
    }
}

SwitchRequest apply_selects(const std::vector<ScriptAction>& actions, ViewState& s) {
    SwitchRequest request;
    for (const ScriptAction& a : actions) {
        if (a.kind != ScriptAction::Kind::select) {
            continue;
        }
        if (a.what == "algorithm") {
            s.selection.algorithm = algorithm_entry(ocl::parse_algorithm(a.value));
            request.field = true;
        } else if (a.what == "metric") {
            s.selection.metric = metric_entry(parse_metric(a.value));
            request.field = true;
        } else if (a.what == "scene") {
            s.selection.scene = entry_of(scene_names(), a.value);
            request.scene = true;
        } else if (a.what == "shading") {
            set_shading(s.render, a.value == "lit" ? vk::Shading::lit : vk::Shading::flat);
        } else if (a.what == "colour") {
            s.controls.brush.material = static_cast<std::uint8_t>(std::stoi(a.value));
        }
    }
    return request;
}

void switch_field(ViewState& s, pipeline::FramePipeline& session, const SwitchRequest& request,
                  std::uint64_t scene_seed) {
    if (!request.field && !request.scene) {
        return;
    }
    const Dims dims = session.world().dims();
    try {
        // The dissertation's algorithms are updated per chunk (chunk-local); exact is global.
        ocl::GeneratorOptions next = session.options();
        next.algorithm = ocl::parse_algorithm(s.selection.algorithm_name());
        next.metric = parse_metric(s.selection.metric_name());
        next.chunk = next.algorithm == ocl::Algorithm::exact ? 0 : 1u << s.selection.chunk_log2;
        next.focus.reset();
        if (has_focus(next.algorithm)) {
            // FIM in the chunks within `focus size` of the centre chunk.
            require_chunk_fits(dims, next.chunk);
            const Dims n = ChunkGrid(dims, next.chunk).chunks();
            s.focus_centre = {n.x / 2, n.y / 2, n.z / 2};
            next.focus = Focus{s.focus_centre, s.selection.focus_size};
        }
        World world =
            request.scene
                ? make_scene(scene_names().at(static_cast<std::size_t>(s.selection.scene)), dims,
                             scene_seed)
                : World(session.world());
        const double ms = session.rebuild(std::move(world), next);
        if (request.scene) {
            session.marcher().clear_implicit();  // an implicit part's surface is not the scene's
        }
        s.switch_error.clear();
        std::cout << "regenerated: " << ocl::to_string(next.algorithm)
                  << (next.chunk ? ", chunk " + std::to_string(next.chunk)
                                 : std::string(", global"))
                  << " in " << fixed(ms, 1) << " ms\n";
    } catch (const std::exception& e) {
        // Refused options or a device failure (out of memory, a kernel that does not build):
        // the session keeps its field, the overlay says why.
        if (!switch_failure(e)) {
            throw;
        }
        s.switch_error = e.what();
        std::cout << "cannot switch: " << s.switch_error << '\n';
    }
    s.selection.algorithm = algorithm_entry(session.options().algorithm);
    s.selection.metric = metric_entry(session.options().metric);
}

void apply_input(const InputActions& a, double dt, ViewState& s,
                 const pipeline::FramePipeline& session, FrameEdits& edits) {
    s.camera.update(a.camera, dt);
    if (a.toggle_camera_mode) {
        s.camera.toggle_mode();
    }
    if (a.reset_camera) {
        s.camera.reset();
    }
    if (a.sand_step) {
        s.sand.single = true;
    }
    edits.history = a.history;
    // Aimed at the world as last read back: while the sand runs it lags the device by at most
    // kAimRefreshSteps steps (apply_frame), instead of a read-back every frame.
    s.preview = aimed_brush(session.last_read_world(), s.camera, s.controls, a);
    if (const auto brush = s.strokes.update(a.left || a.right, s.preview, s.history())) {
        edits.batch.push_back(*brush);
        edits.stroke = true;
    }
}

FrameUpdate apply_frame(ViewState& s, pipeline::FramePipeline& session, const ViewCliOptions& o,
                        const FrameEdits& edits, BenchmarkEdits* bench) {
    FrameUpdate update;
    const auto add = [&update](const pipeline::UpdateTimings& u) {
        update.timings.field_ms += u.field_ms;
        update.timings.convert_ms += u.convert_ms;
    };
    // Lod / monolithic: the focus is the centre chunk or, following the camera, the camera's
    // chunk; a changed focus recomputes the chunks that entered or left it.
    if (has_focus(session.options().algorithm)) {
        const std::uint32_t chunk = session.options().chunk;
        const Int3 centre = s.selection.focus_follows
                                ? chunk_at(s.camera.position(), session.dims(), chunk)
                                : s.focus_centre;
        const Focus f{centre, s.selection.focus_size};
        const auto& current = session.options().focus;
        if (!current || current->centre != f.centre || current->size != f.size) {
            add(session.set_focus(f));
        }
    }
    if (edits.history != History::none) {
        try {
            add(edits.history == History::undo ? session.undo() : session.redo());
        } catch (const InputError& e) {
            // Voxels of the stroke were changed by edits the history did not record (the
            // sand's); the scene cleared it.
            std::cout << "cannot undo/redo: " << e.what() << "; undo history cleared\n";
        }
    }
    if (!edits.batch.empty()) {
        std::vector<EditResult> results;
        // Only the stroke's brush (the first of the batch) is undoable.
        const pipeline::UpdateTimings u =
            session.apply(edits.batch, &results, edits.stroke ? 1 : 0);
        add(u);
        if (edits.bench && bench != nullptr && !results.empty()) {
            bench->record(edits.batch.back(), u, results.back());
        }
    }
    // One step of falling sand and water in place on the device, its changes through the
    // incremental update there.
    SandState& sand = s.sand;
    if (o.simulate && (!s.controls.sand_paused || sand.single)) {
        sand.single = false;
        const pipeline::UpdateTimings u = session.step_sand(SandRules{}, o.seed, sand.step++);
        update.simulate_ms = u.simulate_ms;
        update.sand_changed = static_cast<std::size_t>(u.voxels_changed);
        add(u);
        sand.last_ms = update.simulate_ms;
        sand.last_changed = update.sand_changed;
        if (sand.step % kAimRefreshSteps == 0) {
            static_cast<void>(session.world());  // reads back what the steps moved
        }
    }
    if (update.timings.total_ms() > 0) {
        s.last_update = update.timings;
    }
    // An implicit part's surface describes the world as loaded: any change shows voxels.
    if ((edits.history != History::none || !edits.batch.empty() || o.simulate) &&
        session.marcher().has_implicit()) {
        session.marcher().clear_implicit();
    }
    return update;
}

std::string local_timestamp() {
    const std::time_t t = std::time(nullptr);
    std::tm tm{};
    localtime_r(&t, &tm);
    char buf[32];
    std::strftime(buf, sizeof buf, "%Y%m%d-%H%M%S", &tm);
    return buf;
}

void save_world(const pipeline::FramePipeline& session, const std::string& stem) {
    const NpyArray a = npy_from_world(session.world());
    write_npy(stem + ".npy", a.type, a.dims, a.data);
    std::cout << "saved " << stem << ".npy\n";
    try {
        write_vox(stem + ".vox", session.world(), session.palette());
        std::cout << "saved " << stem << ".vox\n";
    } catch (const InputError& e) {
        std::cout << "not saved as .vox: " << e.what() << '\n';
    }
}

bool finish_script_frame(const std::vector<ScriptAction>& actions, std::uint64_t frame,
                         const ViewState& s, pipeline::FramePipeline& session) {
    bool quit = false;
    for (const ScriptAction& a : actions) {
        if (a.kind == ScriptAction::Kind::save) {
            save_world(session, a.value);
        } else if (a.kind == ScriptAction::Kind::check) {
            write_check(a.value, frame, s, session);
        } else if (a.kind == ScriptAction::Kind::quit) {
            quit = true;
        }
    }
    return quit;
}

}  // namespace voxfield::cli
