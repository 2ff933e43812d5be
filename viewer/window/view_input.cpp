// `view`'s input mapping (see view_input.hpp).
#include "view_input.hpp"

#include <GLFW/glfw3.h>

#include <algorithm>
#include <cmath>
#include <functional>
#include <limits>

#include "voxfield/core/pick.hpp"

namespace voxfield::cli {

const std::set<int>& mapped_keys() {
    static const std::set<int> keys = {
        // Flying.
        GLFW_KEY_W, GLFW_KEY_A, GLFW_KEY_S, GLFW_KEY_D, GLFW_KEY_UP, GLFW_KEY_DOWN, GLFW_KEY_LEFT,
        GLFW_KEY_RIGHT, GLFW_KEY_SPACE, GLFW_KEY_LEFT_SHIFT,
        // Modifiers.
        GLFW_KEY_LEFT_CONTROL, GLFW_KEY_RIGHT_CONTROL, GLFW_KEY_LEFT_ALT,
        // Switches and commands.
        GLFW_KEY_ESCAPE, GLFW_KEY_F1, GLFW_KEY_F2, GLFW_KEY_F12, GLFW_KEY_TAB, GLFW_KEY_R,
        GLFW_KEY_P, GLFW_KEY_G, GLFW_KEY_N, GLFW_KEY_B, GLFW_KEY_Z, GLFW_KEY_Y,
        // Colours.
        GLFW_KEY_0, GLFW_KEY_1, GLFW_KEY_2, GLFW_KEY_3, GLFW_KEY_4, GLFW_KEY_5, GLFW_KEY_6,
        GLFW_KEY_7, GLFW_KEY_8, GLFW_KEY_9};
    return keys;
}

void add_script_input(RawInput& in, const ViewScript& script) {
    for (const int k : mapped_keys()) {
        if (script.key_down(k)) {
            in.keys.insert(k);
        }
    }
    in.left = in.left || script.button_down(GLFW_MOUSE_BUTTON_LEFT);
    in.right = in.right || script.button_down(GLFW_MOUSE_BUTTON_RIGHT);
    in.script_scroll = script.scroll();
    if (script.has_cursor()) {
        in.cursor_x = script.cursor_x();
        in.cursor_y = script.cursor_y();
    }
}

bool InputMapper::cursor_free(const RawInput& in) {
    return in.keys.contains(GLFW_KEY_LEFT_ALT);
}

bool InputMapper::pressed(const RawInput& in, int key) {
    const bool now = in.keys.contains(key);
    bool& was = was_down_[key & 511];
    const bool edge = now && !was;
    was = now;
    return edge;
}

InputActions InputMapper::map(const RawInput& in, ViewControls& controls) {
    const auto down = [&in](int key) { return in.keys.contains(key); };
    const bool ui_mode = cursor_free(in);
    // The overlay takes the mouse only while the cursor is free (Left Alt); captured, the
    // crosshair aims even where the full panel lies under it.
    const bool overlay_has_mouse = ui_mode && in.overlay_mouse;
    // A jump of the cursor is not a mouse movement.
    if (in.cursor_warped) {
        cursor_x_ = in.cursor_x;
        cursor_y_ = in.cursor_y;
    }
    InputActions a;
    const bool ctrl = down(GLFW_KEY_LEFT_CONTROL) || down(GLFW_KEY_RIGHT_CONTROL);
    if (!in.overlay_keyboard) {
        a.camera.forward = down(GLFW_KEY_W) || down(GLFW_KEY_UP);
        a.camera.back = (down(GLFW_KEY_S) && !ctrl) || down(GLFW_KEY_DOWN);
        a.camera.left = down(GLFW_KEY_A) || down(GLFW_KEY_LEFT);
        a.camera.right = down(GLFW_KEY_D) || down(GLFW_KEY_RIGHT);
        a.camera.up = down(GLFW_KEY_SPACE);
        a.camera.down = down(GLFW_KEY_LEFT_SHIFT);
        a.camera.fast = down(GLFW_KEY_LEFT_CONTROL);
    }
    if (!ui_mode) {
        a.camera.look_dx = in.cursor_x - cursor_x_;
        a.camera.look_dy = in.cursor_y - cursor_y_;
    }
    cursor_x_ = in.cursor_x;
    cursor_y_ = in.cursor_y;

    a.quit = pressed(in, GLFW_KEY_ESCAPE);
    if (pressed(in, GLFW_KEY_F1)) {
        controls.show_help = !controls.show_help;
    }
    if (pressed(in, GLFW_KEY_F2)) {
        controls.full_panel = !controls.full_panel;
    }
    a.toggle_camera_mode = pressed(in, GLFW_KEY_TAB);
    a.reset_camera = pressed(in, GLFW_KEY_R) && !ctrl;
    if (pressed(in, GLFW_KEY_P)) {
        controls.paint_mode = !controls.paint_mode;
    }
    if (pressed(in, GLFW_KEY_G)) {
        controls.sand_paused = !controls.sand_paused;
    }
    a.sand_step = pressed(in, GLFW_KEY_N);
    BrushSettings& brush = controls.brush;
    if (pressed(in, GLFW_KEY_B)) {
        brush.shape = brush.shape == BrushShape::sphere ? BrushShape::cube : BrushShape::sphere;
    }
    for (int k = 0; k <= 9; ++k) {
        if (pressed(in, GLFW_KEY_0 + k)) {
            brush.material = static_cast<std::uint8_t>(k == 0 ? 10 : k);
        }
    }
    const double wheel = (overlay_has_mouse ? 0.0 : in.wheel) + in.script_scroll;
    if (wheel != 0) {
        brush.size = scroll_brush_size(brush.size, wheel, kMaxBrushSize);
    }
    const bool z = pressed(in, GLFW_KEY_Z), y = pressed(in, GLFW_KEY_Y);
    const bool s = pressed(in, GLFW_KEY_S), f12 = pressed(in, GLFW_KEY_F12);
    if (ctrl && z) {
        a.history = History::undo;
    } else if (ctrl && y) {
        a.history = History::redo;
    }
    a.save = ctrl && s;
    a.screenshot = f12;

    a.left = in.left;
    a.right = in.right;
    if (!overlay_has_mouse && in.fb_width > 0 && in.fb_height > 0) {
        Aim aim{in.fb_width / 2.0, in.fb_height / 2.0, in.fb_width, in.fb_height};
        if (ui_mode && in.window_width > 0 && in.window_height > 0) {
            aim.x = in.cursor_x * in.fb_width / in.window_width;
            aim.y = in.cursor_y * in.fb_height / in.window_height;
        }
        a.aim = aim;
    }
    return a;
}

namespace {

// aimed_brush with `pick`, the world's picking from the camera along a direction.
std::optional<Brush> aimed_brush_by(
    const ViewCamera& camera, const ViewControls& controls, const InputActions& actions,
    const std::function<std::optional<PickHit>(const Vec3d& direction)>& pick) {
    if (!actions.aim) {
        return std::nullopt;
    }
    const Aim& aim = *actions.aim;
    const Vec3d dir = pixel_direction(camera.forward(), camera.settings.fov_deg, aim.width,
                                      aim.height, aim.x, aim.y);
    const auto hit = pick(dir);
    if (!hit) {
        return std::nullopt;
    }
    const Tool tool =
        actions.right ? Tool::erase : (controls.paint_mode ? Tool::paint : Tool::place);
    return brush_for_pick(tool, controls.brush, *hit);
}

}  // namespace

std::optional<Brush> aimed_brush(const World& world, const ViewCamera& camera,
                                 const ViewControls& controls, const InputActions& actions) {
    return aimed_brush_by(camera, controls, actions, [&](const Vec3d& dir) {
        return pick_voxel(world, camera.position(), dir);
    });
}

std::optional<PickHit> pick_sparse_voxel(const SparseWorld& world, const Vec3d& origin,
                                         const Vec3d& direction, double max_distance) {
    return pick_solid_voxel(
        world.dims(),
        [&world](std::uint32_t x, std::uint32_t y, std::uint32_t z) {
            return world.at(x, y, z) != 0;
        },
        origin, direction, max_distance);
}

std::optional<Brush> aimed_brush(const SparseWorld& world, const ViewCamera& camera,
                                 const ViewControls& controls, const InputActions& actions) {
    return aimed_brush_by(camera, controls, actions, [&](const Vec3d& dir) {
        return pick_sparse_voxel(world, camera.position(), dir, kSparseAimDistance);
    });
}

std::optional<Brush> aimed_brush(ocl::SparseDeviceWorld& world, const ViewCamera& camera,
                                 const ViewControls& controls, const InputActions& actions) {
    return aimed_brush_by(camera, controls, actions, [&](const Vec3d& dir) {
        return world.pick(camera.position(), dir, kSparseAimDistance);
    });
}

std::optional<Brush> Strokes::update(bool held, const std::optional<Brush>& aimed,
                                     UndoStack& undo) {
    if (held && aimed) {
        if (aimed == last_) {
            return std::nullopt;
        }
        if (!open_) {
            undo.begin_stroke();
            open_ = true;
        }
        last_ = aimed;
        return aimed;
    }
    if (!held && open_) {
        undo.end_stroke();
        open_ = false;
        last_.reset();
    }
    return std::nullopt;
}

void Strokes::close(UndoStack& undo) {
    if (open_) {
        undo.end_stroke();
    }
}

}  // namespace voxfield::cli
