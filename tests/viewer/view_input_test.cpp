// `view`'s input mapping without a window: frames of held keys, buttons, cursor and wheel
// (typed here, or played from a `--script`) -> the controls, camera input, commands, the
// aimed brush and the strokes.
#include <gtest/gtest.h>

#include <GLFW/glfw3.h>

#include <sstream>
#include <string>
#include <vector>

#include "view_input.hpp"
#include "view_script.hpp"
#include "voxfield/core/brush.hpp"

namespace voxfield::cli {
namespace {

RawInput frame_with(std::set<int> keys) {
    RawInput in;
    in.keys = std::move(keys);
    in.fb_width = 200;
    in.fb_height = 100;
    in.window_width = 100;
    in.window_height = 50;
    return in;
}

RawInput cursor_at(double x, double y) {
    RawInput in = frame_with({});
    in.cursor_x = x;
    in.cursor_y = y;
    return in;
}

// Everything one frame of mapping gives, to compare frames by.
std::string outcome(std::set<int> keys) {
    InputMapper mapper;
    ViewControls c;
    const InputActions a = mapper.map(frame_with(std::move(keys)), c);
    const CameraInput& m = a.camera;
    std::ostringstream out;
    out << m.forward << m.back << m.left << m.right << m.up << m.down << m.fast << a.quit
        << a.toggle_camera_mode << a.reset_camera << a.sand_step << static_cast<int>(a.history)
        << a.save << a.screenshot << c.paint_mode << c.show_help << c.full_panel << c.sand_paused
        << static_cast<int>(c.brush.shape) << ' ' << int{c.brush.material} << ' '
        << (a.aim ? a.aim->x : -1);
    return out.str();
}

TEST(ViewInput, PollersAreAskedForEveryKeyTheMappingReads) {
    // A key that changes anything, alone or with Ctrl, must be one that pollers read.
    const std::string none = outcome({}), ctrl = outcome({GLFW_KEY_LEFT_CONTROL});
    int read = 0;
    for (int key = GLFW_KEY_SPACE; key <= GLFW_KEY_LAST; ++key) {
        if (outcome({key}) != none || outcome({key, GLFW_KEY_LEFT_CONTROL}) != ctrl) {
            EXPECT_TRUE(mapped_keys().contains(key)) << "key " << key;
            ++read;
        }
    }
    EXPECT_GE(read, 30);  // the keys of F1's list (Alt moves the aim to the cursor)
}

TEST(ViewInput, SwitchesToggleOnceWhileTheirKeyIsHeld) {
    InputMapper mapper;
    ViewControls c;
    for (int frame = 0; frame < 3; ++frame) {
        mapper.map(frame_with({GLFW_KEY_F1, GLFW_KEY_F2, GLFW_KEY_P, GLFW_KEY_G}), c);
        EXPECT_TRUE(c.show_help);
        EXPECT_TRUE(c.full_panel);
        EXPECT_TRUE(c.paint_mode);
        EXPECT_TRUE(c.sand_paused);
    }
    mapper.map(frame_with({}), c);  // released
    EXPECT_TRUE(c.full_panel);
    mapper.map(frame_with({GLFW_KEY_F2, GLFW_KEY_B}), c);  // down again
    EXPECT_FALSE(c.full_panel);
    EXPECT_TRUE(c.show_help);
    EXPECT_EQ(c.brush.shape, BrushShape::cube);
    mapper.map(frame_with({GLFW_KEY_B}), c);  // still held: no second toggle
    EXPECT_EQ(c.brush.shape, BrushShape::cube);
}

TEST(ViewInput, CommandsActOnTheFrameTheirKeyGoesDown) {
    InputMapper mapper;
    ViewControls c;
    InputActions a = mapper.map(frame_with({GLFW_KEY_ESCAPE, GLFW_KEY_TAB, GLFW_KEY_N}), c);
    EXPECT_TRUE(a.quit);
    EXPECT_TRUE(a.toggle_camera_mode);
    EXPECT_TRUE(a.sand_step);
    a = mapper.map(frame_with({GLFW_KEY_ESCAPE, GLFW_KEY_TAB, GLFW_KEY_N}), c);
    EXPECT_FALSE(a.quit);
    EXPECT_FALSE(a.toggle_camera_mode);
    EXPECT_FALSE(a.sand_step);
    a = mapper.map(frame_with({GLFW_KEY_F12, GLFW_KEY_R}), c);
    EXPECT_TRUE(a.screenshot);
    EXPECT_TRUE(a.reset_camera);
}

TEST(ViewInput, MovementKeysMoveWhileHeld) {
    InputMapper mapper;
    ViewControls c;
    for (int frame = 0; frame < 2; ++frame) {
        const InputActions a = mapper.map(
            frame_with({GLFW_KEY_W, GLFW_KEY_LEFT, GLFW_KEY_SPACE, GLFW_KEY_LEFT_CONTROL}), c);
        EXPECT_TRUE(a.camera.forward);
        EXPECT_TRUE(a.camera.left);
        EXPECT_TRUE(a.camera.up);
        EXPECT_TRUE(a.camera.fast);
        EXPECT_FALSE(a.camera.back);
        EXPECT_FALSE(a.camera.right);
        EXPECT_FALSE(a.camera.down);
    }
    const InputActions a =
        mapper.map(frame_with({GLFW_KEY_DOWN, GLFW_KEY_D, GLFW_KEY_LEFT_SHIFT}), c);
    EXPECT_TRUE(a.camera.back);
    EXPECT_TRUE(a.camera.right);
    EXPECT_TRUE(a.camera.down);
    EXPECT_FALSE(a.camera.forward);
    EXPECT_FALSE(a.camera.fast);
}

TEST(ViewInput, TheOverlaysKeyboardStopsMovementButNotCommands) {
    InputMapper mapper;
    ViewControls c;
    RawInput in = frame_with({GLFW_KEY_W, GLFW_KEY_ESCAPE, GLFW_KEY_F2});
    in.overlay_keyboard = true;
    const InputActions a = mapper.map(in, c);
    EXPECT_FALSE(a.camera.forward);
    EXPECT_TRUE(a.quit);
    EXPECT_TRUE(c.full_panel);
}

TEST(ViewInput, CtrlMakesCommandsOfSRAndZY) {
    InputMapper mapper;
    ViewControls c;
    InputActions a = mapper.map(frame_with({GLFW_KEY_LEFT_CONTROL, GLFW_KEY_S}), c);
    EXPECT_TRUE(a.save);
    EXPECT_FALSE(a.camera.back);  // Ctrl+S saves, it does not fly back
    a = mapper.map(frame_with({GLFW_KEY_S}), c);
    EXPECT_FALSE(a.save);  // S alone: already down, and not a save anyway
    EXPECT_TRUE(a.camera.back);

    a = mapper.map(frame_with({GLFW_KEY_RIGHT_CONTROL, GLFW_KEY_R}), c);
    EXPECT_FALSE(a.reset_camera);  // Right Ctrl is a Ctrl too
    EXPECT_FALSE(a.camera.fast);   // but only Left Ctrl speeds up

    a = mapper.map(frame_with({GLFW_KEY_LEFT_CONTROL, GLFW_KEY_Z}), c);
    EXPECT_EQ(a.history, History::undo);
    a = mapper.map(frame_with({GLFW_KEY_LEFT_CONTROL, GLFW_KEY_Z}), c);
    EXPECT_EQ(a.history, History::none);  // held: one undo
    a = mapper.map(frame_with({GLFW_KEY_LEFT_CONTROL, GLFW_KEY_Y}), c);
    EXPECT_EQ(a.history, History::redo);
    a = mapper.map(frame_with({GLFW_KEY_Z}), c);
    EXPECT_EQ(a.history, History::none);  // Z without Ctrl
    mapper.map(frame_with({}), c);
    a = mapper.map(frame_with({GLFW_KEY_LEFT_CONTROL, GLFW_KEY_Z, GLFW_KEY_Y}), c);
    EXPECT_EQ(a.history, History::undo);  // both at once: undo wins
}

TEST(ViewInput, DigitsPickColoursAndZeroIsTen) {
    InputMapper mapper;
    ViewControls c;
    EXPECT_EQ(c.brush.material, 4);
    mapper.map(frame_with({GLFW_KEY_7}), c);
    EXPECT_EQ(c.brush.material, 7);
    mapper.map(frame_with({GLFW_KEY_0}), c);
    EXPECT_EQ(c.brush.material, 10);
    mapper.map(frame_with({GLFW_KEY_1}), c);
    EXPECT_EQ(c.brush.material, 1);
}

TEST(ViewInput, TheWheelSizesTheBrushUnlessTheFreeCursorIsOnTheOverlay) {
    InputMapper mapper;
    ViewControls c;
    EXPECT_EQ(c.brush.size, 5);
    RawInput in = frame_with({});
    in.wheel = 3;
    mapper.map(in, c);
    EXPECT_EQ(c.brush.size, 8);
    in.overlay_mouse = true;  // captured cursor: the overlay does not take the wheel
    mapper.map(in, c);
    EXPECT_EQ(c.brush.size, 11);
    in.keys = {GLFW_KEY_LEFT_ALT};  // free cursor over the overlay: the wheel is the overlay's
    mapper.map(in, c);
    EXPECT_EQ(c.brush.size, 11);
    in.script_scroll = -4;  // the script's scroll still counts
    mapper.map(in, c);
    EXPECT_EQ(c.brush.size, 7);
    in = frame_with({});
    in.wheel = -100;
    mapper.map(in, c);
    EXPECT_EQ(c.brush.size, 1);  // clamped
}

TEST(ViewInput, TheMouseLooksWhileCapturedAndWarpsAreNoMovement) {
    InputMapper mapper;
    ViewControls c;
    RawInput in = cursor_at(300, 200);
    in.cursor_warped = true;  // first frame
    InputActions a = mapper.map(in, c);
    EXPECT_EQ(a.camera.look_dx, 0);
    EXPECT_EQ(a.camera.look_dy, 0);
    in.cursor_warped = false;
    in.cursor_x = 310;
    in.cursor_y = 195;
    a = mapper.map(in, c);
    EXPECT_EQ(a.camera.look_dx, 10);
    EXPECT_EQ(a.camera.look_dy, -5);
    in.keys = {GLFW_KEY_LEFT_ALT};  // free cursor: no look
    in.cursor_x = 350;
    a = mapper.map(in, c);
    EXPECT_EQ(a.camera.look_dx, 0);
    in.keys = {};  // captured again: the capture warped it
    in.cursor_warped = true;
    in.cursor_x = 50;
    a = mapper.map(in, c);
    EXPECT_EQ(a.camera.look_dx, 0);
    in.cursor_warped = false;
    in.cursor_x = 48;
    a = mapper.map(in, c);
    EXPECT_EQ(a.camera.look_dx, -2);
}

TEST(ViewInput, TheBrushAimsAtTheCrosshairOrTheFreeCursor) {
    InputMapper mapper;
    ViewControls c;
    RawInput in = cursor_at(25, 10);
    InputActions a = mapper.map(in, c);
    ASSERT_TRUE(a.aim);
    EXPECT_EQ(a.aim->x, 100);  // the framebuffer's centre
    EXPECT_EQ(a.aim->y, 50);
    EXPECT_EQ(a.aim->width, 200u);
    EXPECT_EQ(a.aim->height, 100u);
    in.keys = {GLFW_KEY_LEFT_ALT};
    a = mapper.map(in, c);
    ASSERT_TRUE(a.aim);
    EXPECT_EQ(a.aim->x, 50);  // window units -> framebuffer pixels (HiDPI: twice as many)
    EXPECT_EQ(a.aim->y, 20);
    in.overlay_mouse = true;
    EXPECT_FALSE(mapper.map(in, c).aim);  // over the overlay
    in = frame_with({});
    in.fb_height = 0;
    EXPECT_FALSE(mapper.map(in, c).aim);  // minimised
}

TEST(ViewInput, ScriptEventsMapAsTheKeyboardAndMouseWould) {
    ViewScript script(
        parse_view_script("0 key F2\n"
                          "1 key ctrl+z\n"
                          "2 down W\n"
                          "3 mouse 10 20\n"
                          "3 scroll 2\n"
                          "3 down LALT\n"
                          "4 up W\n"
                          "5 press right\n"
                          "7 release right\n"));
    InputMapper mapper;
    ViewControls c;
    std::vector<InputActions> frames;
    for (std::uint64_t f = 0; f < script.end_frame(); ++f) {
        script.begin_frame(f);
        RawInput in = frame_with({});
        add_script_input(in, script);
        frames.push_back(mapper.map(in, c));
        if (f == 0) {
            EXPECT_TRUE(c.full_panel);
        }
    }
    ASSERT_EQ(frames.size(), 8u);
    EXPECT_EQ(frames[1].history, History::undo);
    EXPECT_FALSE(frames[1].camera.back);
    EXPECT_TRUE(frames[2].camera.forward);
    EXPECT_TRUE(frames[3].camera.forward);
    EXPECT_FALSE(frames[4].camera.forward);
    EXPECT_EQ(c.brush.size, 7);  // 5 + 2 notches
    ASSERT_TRUE(frames[3].aim);
    EXPECT_EQ(frames[3].aim->x, 20);  // the script's cursor, Left Alt holding it free
    EXPECT_EQ(frames[3].aim->y, 40);
    EXPECT_FALSE(frames[4].right);
    EXPECT_TRUE(frames[5].right);
    EXPECT_TRUE(frames[6].right);
    EXPECT_FALSE(frames[7].right);
    EXPECT_FALSE(frames[7].left);
    EXPECT_TRUE(c.full_panel);  // F2 went down once
}

// A 16^3 world with a wall at z = 8 and a camera looking at it straight along +z.
struct WallScene {
    World world{Dims{16, 16, 16}};
    ViewCamera camera{Dims{16, 16, 16}};
    WallScene() {
        for (std::uint32_t y = 0; y < 16; ++y) {
            for (std::uint32_t x = 0; x < 16; ++x) {
                world.set(x, y, 8, 3);
            }
        }
        camera.look_at({8.5, 8.5, 2.5}, {8.5, 8.5, 12});
    }
};

TEST(ViewInput, TheAimedBrushPlacesErasesOrPaints) {
    WallScene scene;
    InputMapper mapper;
    ViewControls c;
    RawInput in = frame_with({});
    InputActions a = mapper.map(in, c);
    std::optional<Brush> b = aimed_brush(scene.world, scene.camera, c, a);
    ASSERT_TRUE(b);
    EXPECT_EQ(b->op, BrushOp::place);
    EXPECT_EQ(b->centre, (Int3{8, 8, 7}));  // in front of the face looked at
    EXPECT_EQ(b->radius, 2);                // size 5
    EXPECT_EQ(b->material, 4);
    EXPECT_EQ(b->shape, BrushShape::sphere);

    in.right = true;
    a = mapper.map(in, c);
    b = aimed_brush(scene.world, scene.camera, c, a);
    ASSERT_TRUE(b);
    EXPECT_EQ(b->op, BrushOp::erase);
    EXPECT_EQ(b->centre, (Int3{8, 8, 8}));

    in.right = false;
    in.keys = {GLFW_KEY_P};
    a = mapper.map(in, c);
    b = aimed_brush(scene.world, scene.camera, c, a);
    ASSERT_TRUE(b);
    EXPECT_EQ(b->op, BrushOp::paint);
    EXPECT_EQ(b->centre, (Int3{8, 8, 8}));

    in.keys = {GLFW_KEY_LEFT_ALT};
    in.overlay_mouse = true;  // the cursor is on the overlay: nothing aimed at
    EXPECT_FALSE(aimed_brush(scene.world, scene.camera, c, mapper.map(in, c)));
    scene.camera.look_at({8.5, 8.5, 2.5}, {8.5, 8.5, -12});  // looking away from the wall
    EXPECT_FALSE(aimed_brush(scene.world, scene.camera, c, mapper.map(frame_with({}), c)));
}

TEST(ViewInput, AStrokeIsOneUndoEntryAndAddsOnlyNewBrushes) {
    World world(Dims{16, 16, 16});
    UndoStack undo;
    Strokes strokes;
    const Brush a{BrushOp::place, BrushShape::cube, {4, 4, 4}, 1, 2};
    const Brush b{BrushOp::place, BrushShape::cube, {9, 4, 4}, 1, 2};
    const auto held = [&](const std::optional<Brush>& aimed) {
        const std::optional<Brush> added = strokes.update(true, aimed, undo);
        if (added) {
            undo.record(apply_brush(world, *added));
        }
        return added;
    };
    EXPECT_EQ(held(a), a);
    EXPECT_TRUE(undo.in_stroke());
    EXPECT_EQ(held(a), std::nullopt);             // the same brush again adds nothing
    EXPECT_EQ(held(std::nullopt), std::nullopt);  // aimed at the sky: the stroke goes on
    EXPECT_TRUE(undo.in_stroke());
    EXPECT_EQ(held(b), b);
    EXPECT_EQ(strokes.update(false, b, undo), std::nullopt);  // released
    EXPECT_FALSE(undo.in_stroke());
    EXPECT_EQ(undo.undo_count(), 1u);
    EXPECT_EQ(world.solid_count(), 2u * 27u);
    EXPECT_EQ(held(b), b);  // a new stroke at the same place
    strokes.close(undo);    // at exit
    EXPECT_FALSE(undo.in_stroke());
    EXPECT_EQ(undo.undo_count(), 1u);  // it changed nothing: not undoable
    const VoxelChanges back = undo.undo();
    EXPECT_EQ(back.size(), 2u * 27u);  // the first stroke, both brushes
}

}  // namespace
}  // namespace voxfield::cli
