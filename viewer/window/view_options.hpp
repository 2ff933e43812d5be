#pragma once
// `voxfield view`'s command line: the options as typed, their registration with the help text
// (the window's keys as its footer), and the checks made before any device or window is
// touched.
#include <CLI/CLI.hpp>

#include <cstdint>
#include <optional>
#include <string>
#include <vector>

#include "cli_util.hpp"
#include "view_script.hpp"
#include "voxfield/core/edits.hpp"

namespace voxfield::cli {

struct ViewCliOptions {
    std::string input, dims, scene = "spheres", device, shading = "lit";
    std::uint32_t world = 0, width = 1280, height = 720, frames = 0;
    std::uint64_t scene_seed = 6683787;
    GeneratorFlags gen;
    std::string screenshot, edits, field_output, world_output, script;
    bool benchmark = false;
    std::uint64_t seed = 6683787;
    double interval_ms = 200, duration_s = 30;
    std::string json, csv;
    // format: empty for the default (u16; sparse worlds u8, as `bench --suite sparse`).
    std::string format, fallback_png, window_screenshot, present = "auto";
    bool validate = false;
    bool simulate = false;  // --simulate: falling sand and water every frame
    bool sparse = false;    // --sparse: the world as a tile grid of 64-trees (view_sparse)
};

// The dims of the generated world: --dims, else --world N cubed, else 128^3.
Dims view_dims(const ViewCliOptions& o);
// The field format asked for, or the default (u16 for dense worlds, u8 for sparse ones).
std::string view_format(const ViewCliOptions& o, bool sparse);

// The keys in the window, for F1 and --help: the keys and what they do.
inline constexpr const char* kViewKeys[][2] = {
    {"W A S D / arrows", "fly forward, left, back, right (10 voxels/s)"},
    {"Space / Left Shift", "fly up / down"},
    {"Left Ctrl (held)", "4x speed"},
    {"mouse", "look around (cursor captured)"},
    {"Left Alt (held)", "free the cursor for the overlay"},
    {"Tab", "orbit around the world's centre / free fly"},
    {"R", "reset the view"},
    {"left mouse", "place (paint mode: recolour)"},
    {"right mouse", "erase"},
    {"P", "paint mode on / off"},
    {"B", "sphere / cube brush"},
    {"scroll", "brush size (radius = size / 2)"},
    {"1 .. 9, 0", "colour 1 .. 9, 10"},
    {"Ctrl+Z / Ctrl+Y", "undo / redo the last stroke"},
    {"Ctrl+S", "save the world as .npy and .vox (sparse worlds: .vdb) in the current folder"},
    {"G", "--simulate: pause / run the sand and water (colour 2 is sand, 3 water)"},
    {"N", "--simulate, paused: one step"},
    {"F1", "this help"},
    {"F2", "full panel (algorithm, metric, scene, shading, palette) / compact overlay"},
    {"F12", "screenshot PNG (current folder; path printed)"},
    {"Esc", "quit"},
};

// Registers view's options into `app`, writing into `o`, and the keys as the help's footer.
void add_view_options(CLI::App& app, ViewCliOptions& o);

// What the checked options name: the scripted edits and the script.
struct ViewInputs {
    std::vector<Edit> edits;
    std::optional<ViewScript> script;
};
// Checks everything the user typed (InputError) and reads --edits and --script; with a
// script and no --frames, o.frames becomes the frame after the script's last action.
ViewInputs check_view_options(ViewCliOptions& o);

}  // namespace voxfield::cli
