// `voxfield view`'s command line (see view_options.hpp).
#include "view_options.hpp"

#include <algorithm>
#include <iomanip>
#include <limits>
#include <sstream>

#include "voxfield/core/error.hpp"
#include "voxfield/core/output.hpp"
#include "voxfield/core/scenes.hpp"
#include "voxfield/vk/raymarcher.hpp"

namespace voxfield::cli {

void add_view_options(CLI::App& app, ViewCliOptions& o) {
    app.add_option("INPUT", o.input, kWorldInputHelp);
    app.add_option("--world", o.world, "Generate a cube world of N^3 voxels (default 128)")
        ->check(CLI::Range(1u, 4096u));
    app.add_option("--dims", o.dims, "Generate a world of X,Y,Z voxels");
    app.add_option("--scene", o.scene, "Scene for a generated world")
        ->check(CLI::IsMember(scene_names()))
        ->capture_default_str();
    add_generator_flags(app, o.gen);
    app.add_option("--device", o.device,
                   "OpenCL device: cpu, gpu or an index from `voxfield devices` (Vulkan: "
                   "$VOXFIELD_VK_DEVICE)");
    app.add_option("--shading", o.shading,
                   "flat (the palette colours, as render draws by default) or lit (sun, "
                   "shadows and occlusion: view's default)")
        ->check(CLI::IsMember({"flat", "lit"}))
        ->capture_default_str();
    app.add_option("--width", o.width, "Window (or headless image) width")
        ->check(CLI::Range(1u, vk::kMaxImageSize))
        ->capture_default_str();
    app.add_option("--height", o.height, "Window (or headless image) height")
        ->check(CLI::Range(1u, vk::kMaxImageSize))
        ->capture_default_str();
    app.add_option("--frames", o.frames, "Quit after N frames (scripted runs)");
    app.add_option("--screenshot", o.screenshot,
                   "Write the last frame's ray-marched image (no overlay) as PNG at exit");
    app.add_option("--present", o.present,
                   "How frames reach the window: gpu (they stay on the GPU: ray-marched into the "
                   "swapchain image when the ray marcher's device presents, else imported by "
                   "the presenting device), host (read back and uploaded) or auto (gpu where "
                   "possible)")
        ->check(CLI::IsMember({"auto", "gpu", "host"}))
        ->capture_default_str();
    app.add_option("--window-screenshot", o.window_screenshot,
                   "Write what the window showed in the last frame (overlay included) as PNG at "
                   "exit; needs --frames");
    app.add_option("--script", o.script,
                   "Scripted input, one action per line `FRAME ACTION [ARGS]`: key NAME "
                   "(ctrl+z, F2, ...), down/up NAME, click/press/release left|right, mouse X Y, "
                   "scroll N, select algorithm|metric|scene|shading|colour VALUE, save STEM, "
                   "check STEM (STEM-world.npy, STEM-field.npy, STEM-state.json), quit; runs "
                   "until the last action's frame (or --frames); needs a display");
    app.add_option("--edits", o.edits,
                   "Scripted edits (the replay file format), one applied per frame from the "
                   "first frame");
    // The field the viewer renders from is an unsigned integer one (the render field is made
    // from these; the signed and float formats are generate's).
    app.add_option("--format", o.format,
                   "Field format: u8, u16, u32 (distance rounded down, saturated) or packed32 "
                   "((min(d,255)<<8)|rgb332); default u16, sparse worlds u8")
        ->check(CLI::IsMember({"u8", "u16", "u32", "packed32"}));
    app.add_flag("--sparse", o.sparse,
                 "View the world as a tile grid of 64-trees (traced through them, edited on the "
                 "OpenCL device with its bounded field: --max-distance, default 16); automatic "
                 "for inputs `render` takes sparse and generated worlds over 2^31 voxels. "
                 "`--scene city` is generated tile by tile, never as one dense array");
    app.add_option("--field-output", o.field_output,
                   "Write the final distance field (in --format, as `generate` writes it) at exit");
    app.add_option("--world-output", o.world_output,
                   "Write the final world at exit (.npy; sparse worlds: .vdb, with their field)");
    app.add_option("--fallback-png", o.fallback_png,
                   "Without a display: render the first frame headless into this PNG and exit 0 "
                   "(instead of exiting 2)");
    app.add_flag("--benchmark", o.benchmark,
                 "The dissertation's benchmark: a random sphere every --interval-ms (seeded, "
                 "reproducible), vsync off, per-frame times, summary printed and saved");
    app.add_option("--seed", o.seed, "Benchmark seed (and the sand's, with --simulate)")
        ->capture_default_str();
    app.add_flag("--simulate", o.simulate,
                 "Falling sand and water every frame (as `simulate`: colour 2 falls as sand, 3 "
                 "flows as water, every other solid stays), the field updated after each step "
                 "(on a --sparse world only the tiles near recent changes step, and the field "
                 "within D of them); G pauses, N steps; with --benchmark the sand's and the "
                 "update's times are recorded per frame");
    app.add_option("--interval-ms", o.interval_ms, "Benchmark: time between edits")
        ->capture_default_str();
    app.add_option("--duration-s", o.duration_s, "Benchmark: duration")->capture_default_str();
    app.add_option("--json", o.json, "Benchmark: summary and per-frame times as JSON");
    app.add_option("--csv", o.csv, "Benchmark: per-frame times as CSV");
    app.add_flag("--validate", o.validate,
                 "Run with the Vulkan validation layer (VK_LAYER_KHRONOS_validation, "
                 "synchronisation validation included; Debian: vulkan-validationlayers): each "
                 "message is printed to stderr and any makes the command exit 1")
        ->envname("VOXFIELD_VALIDATE");
    std::ostringstream keys;
    keys << "Keys in the window (F1 shows them there):\n";
    for (const auto& k : kViewKeys) {
        keys << "  " << std::left << std::setw(22) << k[0] << k[1] << '\n';
    }
    app.footer(keys.str());
}

Dims view_dims(const ViewCliOptions& o) {
    if (!o.dims.empty()) {
        return parse_dims(o.dims);
    }
    const std::uint32_t n = o.world != 0 ? o.world : 128;
    return Dims{n, n, n};
}

std::string view_format(const ViewCliOptions& o, bool sparse) {
    return !o.format.empty() ? o.format : sparse ? "u8" : "u16";
}

ViewInputs check_view_options(ViewCliOptions& o) {
    // Everything the user typed is checked before any device or window is touched.
    if (!o.input.empty() && (o.world != 0 || !o.dims.empty())) {
        throw InputError("give either INPUT or --world/--dims, not both");
    }
    if (o.world != 0 && !o.dims.empty()) {
        throw InputError("give either --world N or --dims X,Y,Z, not both");
    }
    for (const auto& [option, path] :
         {std::pair{"--screenshot", &o.screenshot}, std::pair{"--fallback-png", &o.fallback_png},
          std::pair{"--window-screenshot", &o.window_screenshot}}) {
        if (!path->empty()) {
            require_png_name(option, *path);
        }
    }
    check_outputs({{"--screenshot", o.screenshot},
                   {"--fallback-png", o.fallback_png},
                   {"--window-screenshot", o.window_screenshot},
                   {"--field-output", o.field_output},
                   {"--world-output", o.world_output},
                   {"--json", o.json},
                   {"--csv", o.csv}},
                  {{"INPUT", o.input}, {"--edits", o.edits}, {"--script", o.script}});
    if (!o.window_screenshot.empty() && o.frames == 0) {
        throw InputError("--window-screenshot needs --frames N (it captures the last frame)");
    }
    if (!(o.interval_ms > 0) || !(o.duration_s > 0)) {
        throw InputError("--interval-ms and --duration-s must be positive");
    }
    std::vector<Edit> scripted;
    if (!o.edits.empty()) {
        scripted = read_edits(o.edits);
    }
    std::optional<ViewScript> script;
    if (!o.script.empty()) {
        if (o.benchmark) {
            throw InputError("--script and --benchmark do not go together");
        }
        script.emplace(read_view_script(o.script));
        if (o.frames == 0) {
            if (script->end_frame() > std::numeric_limits<std::uint32_t>::max()) {
                throw InputError("--script: frame numbers above 4294967294");
            }
            o.frames = std::max(static_cast<std::uint32_t>(script->end_frame()), 1u);
        }
    }
    return {std::move(scripted), std::move(script)};
}

}  // namespace voxfield::cli
