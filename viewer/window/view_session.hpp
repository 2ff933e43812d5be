#pragma once
// `view`'s interactive session around the frame pipeline: the state the user changes (camera,
// render options, controls, the panel's selections, lod's focus, the sand's step), one frame's
// changes applied as one batch through the pipeline's scene (which owns the world, its field,
// the undo history and the simulation), the algorithm / metric / scene switch, and what
// `--script` selects, saves and checks.
#include <cstdint>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include "view_input.hpp"
#include "view_options.hpp"
#include "view_script.hpp"
#include "voxfield/pipeline/frame_pipeline.hpp"

namespace voxfield::cli {

class BenchmarkEdits;

// Lit shading has a sky gradient, flat shading a plain sky.
void set_shading(vk::RenderOptions& r, vk::Shading shading);
// lod and monolithic compute a focus region exactly.
bool has_focus(ocl::Algorithm a);

// The panel's selections, as entries of its combos (algorithm_names() is in DESIGN §4 order,
// not the enum's: entries and algorithms are matched by name, never by the enum's value).
struct PanelSelection {
    int algorithm = 0;  // of ocl::algorithm_names()
    int metric = 0;     // of metric_names()
    int scene = 0;      // of scene_names()
    int chunk_log2 = 4;
    int focus_size = 1;
    bool focus_follows = false;  // lod's focus follows the camera
    std::string algorithm_name() const;
    std::string metric_name() const;
};

// --simulate: the automaton runs in place on the scene's device voxels (Scene::step_sand).
struct SandState {
    bool single = false;  // N: one step while paused
    std::uint64_t step = 0;
    double last_ms = 0;
    std::size_t last_changed = 0;
};

// What the user changes in a session, beside the world and its field (the pipeline's).
struct ViewState {
    // The start: the default camera framing `framing`, --shading, the field's algorithm and
    // metric selected, --scene, lod's --focus.
    // `session` outlives the state: its scene holds the undo history.
    ViewState(const ViewCliOptions& o, pipeline::FramePipeline& session, const Framing& framing);
    // The undo history: the current scene's (a new scene, a new history).
    UndoStack& history() { return session_->scene().history(); }
    const UndoStack& history() const { return session_->scene().history(); }
    ViewCamera camera;
    vk::RenderOptions render;
    ViewControls controls;
    PanelSelection selection;
    Strokes strokes;
    SandState sand;
    Int3 focus_centre{0, 0, 0};           // lod / monolithic: --focus or the default, until changed
    std::string switch_error;             // why the last algorithm / scene switch failed
    pipeline::UpdateTimings last_update;  // of the last frame that updated anything
    std::optional<Brush> preview;         // the brush aimed at

  private:
    pipeline::FramePipeline* session_;
};

// What the panel (or the script) asks to rebuild: the field with the selected algorithm,
// metric and chunk, and a new world of the selected scene.
struct SwitchRequest {
    bool field = false, scene = false;
};
// The script's `select` actions of this frame, applied as the panel's widgets would.
SwitchRequest apply_selects(const std::vector<ScriptAction>& actions, ViewState& s);
// Rebuilds the field (of a new scene of scene_seed when asked) from the selections: a new
// history on success; refused options or a device failure keep the field, the
// overlay says why. The selections then show the field's algorithm and metric.
void switch_field(ViewState& s, pipeline::FramePipeline& session, const SwitchRequest& request,
                  std::uint64_t scene_seed);

// One frame's changes.
struct FrameEdits {
    std::vector<Brush> batch;  // the stroke's brush first, then --edits', then the benchmark's
    bool stroke = false;       // the batch's first brush is the stroke's (undoable)
    bool bench = false;        // the batch's last brush is the benchmark's
    History history = History::none;  // Ctrl+Z / Ctrl+Y
};
// What the frame's changes cost.
struct FrameUpdate {
    pipeline::UpdateTimings timings;  // field_ms and convert_ms: every update of the frame
    double simulate_ms = -1;          // the sand's step (-1: none)
    std::size_t sand_changed = 0;
};
// The frame's input beyond the controls: the camera moves and switches mode or resets, N asks
// for a sand step, Ctrl+Z / Ctrl+Y ask for an undo or redo, and the brush aimed at is
// previewed and, under a held button, added to the stroke.
void apply_input(const InputActions& a, double dt, ViewState& s,
                 const pipeline::FramePipeline& session, FrameEdits& edits);
// Moves lod's focus, applies the undo or redo, the batch (recording the stroke and the
// benchmark's edit) and one step of the sand (--simulate, unless paused).
FrameUpdate apply_frame(ViewState& s, pipeline::FramePipeline& session, const ViewCliOptions& o,
                        const FrameEdits& edits, BenchmarkEdits* bench);

// Ctrl+S and the script's `save`: the world as STEM.npy and STEM.vox.
void save_world(const pipeline::FramePipeline& session, const std::string& stem);
// The local time as YYYYMMDD-HHMMSS, for the names Ctrl+S and the screenshot key give files.
std::string local_timestamp();
// The script's actions after the frame: `save`, `check` (STEM-world.npy, STEM-field.npy and
// STEM-state.json: what the overlay shows, the brush, undo depth, camera, sand); true when it
// quits there.
bool finish_script_frame(const std::vector<ScriptAction>& actions, std::uint64_t frame,
                         const ViewState& s, pipeline::FramePipeline& session);

}  // namespace voxfield::cli
