#pragma once
// `view`'s input mapping, free of any window: one frame of held keys, mouse buttons, cursor
// and wheel (polled from GLFW and the overlay, merged with `--script`'s) becomes what the frame
// does: the camera's moves and look, the switches (help, panel, paint mode, brush, sand),
// undo / redo, saving, a screenshot, and the brush a held button strokes. Keys act on the
// frame they go down (edges), movement keys while held.
#include <array>
#include <cstdint>
#include <limits>
#include <optional>
#include <set>

#include "view_script.hpp"
#include "voxfield/cl/sparse_device_world.hpp"
#include "voxfield/core/camera.hpp"
#include "voxfield/core/pick.hpp"
#include "voxfield/core/sparse.hpp"
#include "voxfield/core/undo.hpp"
#include "voxfield/core/world.hpp"

namespace voxfield::cli {

// One frame of input as polled.
struct RawInput {
    std::set<int> keys;                 // held keys (GLFW key codes)
    bool left = false, right = false;   // held mouse buttons
    double cursor_x = 0, cursor_y = 0;  // window units
    bool cursor_warped = false;         // the cursor jumped (first frame, captured or freed)
    double wheel = 0;                   // the mouse wheel's notches this frame
    double script_scroll = 0;           // `--script`'s scroll notches this frame
    bool overlay_keyboard = false;      // the overlay takes the keyboard
    bool overlay_mouse = false;         // the overlay would take the mouse (if the cursor is free)
    std::uint32_t fb_width = 0, fb_height = 0;  // framebuffer pixels
    int window_width = 0, window_height = 0;    // window units
};

// The keys the mapping reads, for pollers.
const std::set<int>& mapped_keys();
// Adds what `script` holds this frame: its keys and buttons, its scroll, its cursor (where it
// has set one).
void add_script_input(RawInput& in, const ViewScript& script);

// What the keys and the wheel switch, which the overlay shows (and partly sets).
struct ViewControls {
    BrushSettings brush{BrushShape::sphere, 5, 4};
    bool paint_mode = false;   // P
    bool show_help = false;    // F1
    bool full_panel = false;   // F2: the full panel instead of the compact overlay
    bool sand_paused = false;  // G
};

enum class History { none, undo, redo };

// Where the brush aims: a framebuffer pixel of a width x height framebuffer.
struct Aim {
    double x = 0, y = 0;
    std::uint32_t width = 0, height = 0;
};

// What one frame's input asks for beyond the controls.
struct InputActions {
    CameraInput camera;
    bool quit = false;                 // Esc
    bool toggle_camera_mode = false;   // Tab
    bool reset_camera = false;         // R
    bool sand_step = false;            // N
    History history = History::none;   // Ctrl+Z / Ctrl+Y
    bool save = false;                 // Ctrl+S
    bool screenshot = false;           // F12
    bool left = false, right = false;  // mouse buttons held
    // The crosshair, or the cursor while it is free; none while the overlay has the mouse or
    // the framebuffer is empty.
    std::optional<Aim> aim;
};

class InputMapper {
  public:
    // Whether the cursor is free for the overlay (Left Alt held) rather than captured for
    // looking around.
    static bool cursor_free(const RawInput& in);
    // Maps one frame; switches and brush changes go into `controls`.
    InputActions map(const RawInput& in, ViewControls& controls);

  private:
    bool pressed(const RawInput& in, int key);

    bool was_down_[512] = {};
    double cursor_x_ = 0, cursor_y_ = 0;
};

// The brush the aim puts on `world`, seen by `camera`: the right button erases, else paint
// mode paints, else the brush places in front of the face aimed at. None without an aim or a
// solid voxel under it.
std::optional<Brush> aimed_brush(const World& world, const ViewCamera& camera,
                                 const ViewControls& controls, const InputActions& actions);

// How far the brush aims on a sparse world (voxels along the ray).
inline constexpr double kSparseAimDistance = 4096;
// pick_voxel (core/pick.hpp) on a sparse world: the same hit, face and distance for the same
// voxels, by the same double-precision Amanatides & Woo walk (pick_solid_voxel) over
// SparseWorld::at.
std::optional<PickHit> pick_sparse_voxel(
    const SparseWorld& world, const Vec3d& origin, const Vec3d& direction,
    double max_distance = std::numeric_limits<double>::infinity());
// aimed_brush on a sparse world (the sparse viewer), aiming at most kSparseAimDistance voxels.
std::optional<Brush> aimed_brush(const SparseWorld& world, const ViewCamera& camera,
                                 const ViewControls& controls, const InputActions& actions);
// The same on the world as the OpenCL device has it (SparseDeviceWorld::pick: the ray's voxels
// read from the device in one transfer, the host world left lagging), the same hit as on the
// host world brought up to date.
std::optional<Brush> aimed_brush(ocl::SparseDeviceWorld& world, const ViewCamera& camera,
                                 const ViewControls& controls, const InputActions& actions);

// Mouse strokes: from a button going down until both are up, one undoable stroke; while a
// button is held, every frame whose aimed brush differs from the stroke's last adds it.
class Strokes {
  public:
    // The brush this frame adds to the stroke (none: no button, nothing aimed at, or the
    // same brush again).
    std::optional<Brush> update(bool held, const std::optional<Brush>& aimed, UndoStack& undo);
    // Ends a stroke still open (at exit).
    void close(UndoStack& undo);

  private:
    bool open_ = false;
    std::optional<Brush> last_;
};

}  // namespace voxfield::cli
