#pragma once
// `view --script FILE`: scripted input for the viewer, frame by frame, so that tests (and
// users reproducing a session) drive the real window, keys, mouse and overlay under Xvfb.
//
// One action per line, `FRAME ACTION [ARGS]` (frames count from 0; '#' starts a comment):
//   key NAME          NAME is down this frame only (a press and release), e.g. `key F2`,
//                     `key ctrl+z` (Left Ctrl held with it)
//   down NAME / up NAME  hold a key from this frame / release it
//   click left|right  the mouse button is down this frame only (a one-brush stroke)
//   press left|right / release left|right  hold a button (a stroke) / release it
//   mouse X Y         the cursor at window coordinates (X, Y) from this frame on
//   scroll N          N wheel notches (brush size)
//   select algorithm NAME | metric NAME | scene NAME | shading flat|lit | colour N
//                     what the full panel's widgets do (a scene is generated at once)
//   save STEM         the world as STEM.npy and STEM.vox (what Ctrl+S writes)
//   check STEM        STEM-world.npy, STEM-field.npy (the field in --format) and
//                     STEM-state.json (what the overlay shows, the brush, undo depth, ...)
//   quit              ends the viewer after this frame
// Key names: A..Z, 0..9, F1..F12, ESC, TAB, SPACE, ENTER, UP, DOWN, LEFT, RIGHT, LSHIFT,
// LCTRL, LALT, RCTRL; `ctrl+` before any of them. Scripted frames advance the camera by a
// fixed 1/60 s, so a script gives the same views on any machine.
#include <cstdint>
#include <filesystem>
#include <map>
#include <set>
#include <string>
#include <vector>

namespace voxfield::cli {

struct ScriptAction {
    enum class Kind {
        key,
        down,
        up,
        click,
        press,
        release,
        mouse,
        scroll,
        select,
        save,
        check,
        quit
    };
    Kind kind = Kind::key;
    std::uint64_t frame = 0;
    int code = 0;             // key / down / up: the GLFW key; click / press / release: the button
    bool ctrl = false;        // key: with Left Ctrl
    double x = 0, y = 0;      // mouse: the position; scroll: x notches
    std::string what, value;  // select: what ("algorithm", ...) and the value; save / check:
                              // the stem in value
    std::size_t line = 0;
};

// Parses the script (InputError naming the line for anything it cannot read, including
// select values that do not exist: algorithms, metrics, scenes, shadings, colours 1..255).
std::vector<ScriptAction> parse_view_script(const std::string& text);
// Reads and parses a script file (InputError when it cannot be read).
std::vector<ScriptAction> read_view_script(const std::filesystem::path& path);

// Plays a parsed script: what is held, and the actions of each frame.
class ViewScript {
  public:
    explicit ViewScript(std::vector<ScriptAction> actions);
    // Applies the frame's key, button, cursor and scroll actions to the held state and
    // returns every action of that frame (in file order) for the viewer to act on.
    std::vector<ScriptAction> begin_frame(std::uint64_t frame);
    bool key_down(int key) const { return keys_.contains(key); }
    bool button_down(int button) const { return buttons_.contains(button); }
    bool has_cursor() const { return has_cursor_; }
    double cursor_x() const { return cursor_x_; }
    double cursor_y() const { return cursor_y_; }
    double scroll() const { return scroll_; }  // this frame's notches
    // The frame after the last action (the viewer quits there unless --frames says more).
    std::uint64_t end_frame() const;

  private:
    std::multimap<std::uint64_t, ScriptAction> by_frame_;
    std::set<int> keys_, buttons_, held_keys_, held_buttons_;
    bool has_cursor_ = false;
    double cursor_x_ = 0, cursor_y_ = 0, scroll_ = 0;
};

}  // namespace voxfield::cli
