// `voxfield view`: the interactive viewer (issue 6). A GLFW window with a Vulkan swapchain
// shows the world ray-marched through its distance field; edits go through the incremental
// updater every frame; Dear ImGui draws the overlay. Without a display it says so in one line
// and exits 2 (suggesting `voxfield render`), except in benchmark mode, which then runs
// headless (same loop, no window). The loop here wires the pieces: the options
// (view_options), the window and presenter (view_window), the input mapping (view_input), the
// session's state and edits (view_session), the overlay (view_overlay) and the benchmark's
// records (view_benchmark). Sparse worlds take their own loop (view_sparse).
#include <filesystem>
#include <iostream>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include "cli_util.hpp"
#include "frame_clock.hpp"
#include "png.hpp"
#include "traced_part.hpp"
#include "view_benchmark.hpp"
#include "view_input.hpp"
#include "view_options.hpp"
#include "view_overlay.hpp"
#include "view_session.hpp"
#include "view_sparse.hpp"
#include "view_window.hpp"
#include "voxfield/core/clock.hpp"
#include "voxfield/core/npy.hpp"
#include "voxfield/core/sand.hpp"
#include "voxfield/core/scenes.hpp"
#include "voxfield/core/sdf.hpp"
#include "voxfield/core/vox.hpp"

namespace voxfield::cli {
namespace {

// The world to view: INPUT, or a generated scene; named for the reports. A part (.sdf.json),
// or a mixed scene (.scene.json) with parts, is read here and discretised once the OpenCL
// device is open (traced_part.hpp).
struct ViewWorld {
    VoxModel model{World(Dims{1, 1, 1}), Palette::dissertation()};
    std::string name;
    std::optional<sdf::Part> part;
    std::optional<scene::Scene> mixed;
};

ViewWorld load_view_world(const ViewCliOptions& o) {
    ViewWorld w;
    if (!o.input.empty() && sdf::is_sdf_path(o.input)) {
        w.part = sdf::load_part(o.input);
        w.model.world = World(w.part->dims);
        w.name = o.input;
    } else if (!o.input.empty() && scene::is_scene_path(o.input)) {
        w.mixed = scene::load_scene(o.input);
        if (w.mixed->part) {
            w.model.world = World(w.mixed->dims);
        } else {
            w.model = VoxModel{w.mixed->world(o.input), w.mixed->palette};
            w.mixed.reset();
        }
        w.name = o.input;
    } else if (!o.input.empty()) {
        w.model = load_world(o.input, InputOptions{.grid = {}, .palette_values = true});
        w.name = o.input;
    } else {
        const Dims dims = view_dims(o);
        w.model.world = make_scene(o.scene, dims, o.scene_seed);
        w.name = "scene " + o.scene;
    }
    const std::string ext = std::filesystem::path(o.input).extension().string();
    if (o.simulate && ext != ".vox" && ext != ".VOX") {
        // A world without a palette of its own (a scene, a .npy) shows its falling materials
        // as what they are, not as the palette's white and pale yellow.
        const SandRules rules;
        w.model.palette[rules.sand] = Rgba{218, 186, 120, 255};
        w.model.palette[rules.water] = Rgba{48, 110, 210, 255};
    }
    return w;
}

void print_start(const ocl::Context& cl, const vk::Context& vkc,
                 const pipeline::FramePipeline& session, const std::string& world_name,
                 double build_ms) {
    const ocl::GeneratorOptions& g = session.options();
    std::cout << "opencl:  " << cl.info().name << " (" << cl.info().type << ")\n"
              << "vulkan:  " << vkc.info().name << " (" << vkc.info().type << ")\n"
              << "world:   " << world_name << " " << session.world().dims().to_string()
              << ", algorithm " << ocl::to_string(g.algorithm)
              << (g.chunk ? ", chunk " + std::to_string(g.chunk) : std::string(", global"))
              << ", field " << to_string(g.format) << " built in " << fixed(build_ms, 1) << " ms\n"
              << "sharing: " << session.marcher().sharing_path()
              << (session.why_not().empty() ? std::string() : " [" + session.why_not() + "]")
              << '\n';
}

// What the options ask to write at exit: the last frame (--screenshot), what the window
// showed (--window-screenshot), the world and the field.
void write_outputs(const ViewCliOptions& o, pipeline::FramePipeline& session, Frames& frames,
                   Screen* screen, const vk::RenderOptions& r, std::uint64_t frame) {
    // One batch, renamed onto the targets once all are written: a failure leaves none.
    OutputBatch outputs;
    std::vector<std::string> said;
    if (!o.screenshot.empty()) {
        if (!frames.rendered()) {
            throw std::runtime_error("no frame was rendered for --screenshot");
        }
        const vk::Image& image = frames.host_image(session, screen, r);
        outputs.write(o.screenshot, encode_png(image));
        said.push_back("screenshot " + o.screenshot + " (" + std::to_string(image.width) + "x" +
                       std::to_string(image.height) + ", frame " + std::to_string(frame) + ")");
    }
    if (!o.window_screenshot.empty()) {
        const std::optional<vk::Image> shown =
            screen ? screen->presenter().captured_frame() : std::nullopt;
        if (!shown) {
            throw std::runtime_error(
                "--window-screenshot: no window frame was captured" +
                std::string(screen ? " (the swapchain cannot be copied from: no TRANSFER_SRC "
                                     "usage)"
                                   : " (there is no window)"));
        }
        outputs.write(o.window_screenshot, encode_png(*shown));
        said.push_back("window screenshot " + o.window_screenshot + " (" +
                       std::to_string(shown->width) + "x" + std::to_string(shown->height) +
                       ", overlay included)");
    }
    if (!o.world_output.empty()) {
        const NpyArray a = npy_from_world(session.world());
        write_npy(outputs, o.world_output, a.type, a.dims, a.data);
    }
    if (!o.field_output.empty()) {
        const std::vector<std::uint8_t> field = session.read_field();
        write_npy(outputs, o.field_output, npy_type(session.options().format),
                  session.world().dims(), field);
    }
    outputs.commit();
    for (const std::string& line : said) {
        std::cout << line << '\n';
    }
}

// validation: non-null with --validate, for every Vulkan instance of the viewer.
int run_view(ViewCliOptions o, const std::shared_ptr<vk::ValidationLog>& validation) {
    ViewInputs in = check_view_options(o);
    ViewScript* script = in.script ? &*in.script : nullptr;
    // A window, or why there is none.
    Window window(o.width, o.height);
    if (window.handle() == nullptr && !go_headless(o, script != nullptr, window.why_none())) {
        return no_display(window.why_none());
    }
    if (view_goes_sparse(o)) {
        return run_view_sparse(o, in, window, validation);
    }
    ViewWorld world = load_view_world(o);
    const Dims dims = world.model.world.dims();
    const ocl::GeneratorOptions gopts =
        generator_options(o.gen, parse_format(view_format(o, false)), dims);
    ocl::Context cl_ctx(ocl::select_device(o.device));
    std::string why_not_one_device;
    const std::unique_ptr<vk::Context> vk_ctx =
        marcher_context(window.handle(), validation, why_not_one_device);
    Frames frames(*vk_ctx);
    std::optional<TracedPart> traced;
    if (world.part) {
        traced = load_traced_part(cl_ctx, *world.part, o.input);
        world.model = traced->model;
    } else if (world.mixed) {
        traced = load_traced_scene(cl_ctx, *world.mixed, o.input);
        world.model = traced->model;
    }
    pipeline::FramePipeline session(cl_ctx, *vk_ctx, world.model.palette, dims);
    const Framing framing = solid_framing(world.model.world);  // the default camera's view
    const double build_ms = session.rebuild(std::move(world.model.world), gopts);
    if (traced) {
        // Traced on its trilinear surface until an edit changes the world (view_session).
        session.marcher().set_implicit(traced->surface());
        traced.reset();
    }
    print_start(cl_ctx, *vk_ctx, session, world.name, build_ms);
    std::unique_ptr<Screen> screen;
    std::unique_ptr<Overlay> overlay;
    if (window.handle() != nullptr) {
        screen =
            std::make_unique<Screen>(window.handle(), *vk_ctx, o, validation, why_not_one_device);
        overlay =
            std::make_unique<Overlay>(screen->presenter(), vk_ctx->info().name, cl_ctx.info().name,
                                      present_path(screen->path()), o.simulate, world.name);
    }

    ViewState s(o, session, framing);
    std::optional<BenchmarkEdits> bench;  // --benchmark: the protocol's edits
    if (o.benchmark) {
        bench.emplace(dims, gopts.chunk, o.seed, o.interval_ms);
    }
    std::vector<FrameRecord> records;
    InputMapper mapper;
    FrameClock frame_clock(script != nullptr);
    std::uint64_t frame = 0;
    bool running = true;
    while (running) {
        const auto [t0, dt, time_s] = frame_clock.tick();
        std::uint32_t fb_w = o.width, fb_h = o.height;
        FrameEdits edits;
        // --script: this frame's actions (keys, buttons, cursor and scroll are held in
        // `script`; its selections switch with the overlay's, checks are written at the end).
        const std::vector<ScriptAction> actions =
            script ? script->begin_frame(frame) : std::vector<ScriptAction>{};
        const SwitchRequest selected = apply_selects(actions, s);
        if (screen) {
            if (!window.poll()) {
                break;
            }
            const RawInput raw = window.input(script, frame == 0);
            fb_w = raw.fb_width;
            fb_h = raw.fb_height;
            const InputActions a = mapper.map(raw, s.controls);
            if (a.quit) {
                running = false;
            }
            apply_input(a, dt, s, session, edits);
            if (a.save) {
                save_world(session, "voxfield-world-" + local_timestamp());
            }
            if (a.screenshot && frames.rendered()) {
                const std::string path = "voxfield-" + local_timestamp() + ".png";
                write_png(path, frames.host_image(session, screen.get(), s.render));
                std::cout << "screenshot " << std::filesystem::absolute(path).string() << '\n';
            }
        }
        // Scripted and benchmark edits.
        if (frame < in.edits.size()) {
            edits.batch.push_back(in.edits[frame].brush);
        }
        if (const auto brush = bench ? bench->due(time_s) : std::nullopt) {
            edits.batch.push_back(*brush);
            edits.bench = true;
        }
        const FrameUpdate update = apply_frame(s, session, o, edits, bench ? &*bench : nullptr);
        frames.render(session, screen.get(), s.render, s.camera, fb_w, fb_h);
        if (screen) {
            screen->overlay().new_frame();
            const OverlayFrame shown{records.empty() ? 0 : records.back().frame_ms,
                                     frames.raymarch_ms(), fb_w, fb_h};
            switch_field(s, session, overlay->draw(s, session, shown, selected), o.scene_seed);
            if (!o.window_screenshot.empty() && frame + 1 >= o.frames) {
                screen->presenter().capture_next_frame();
            }
            frames.present(session, *screen, s.render, fb_w, fb_h);
        }
        records.push_back({time_s, ms_since(t0), update.timings.total_ms(),
                           update.timings.convert_ms, frames.raymarch_ms(), edits.bench,
                           update.simulate_ms, update.sand_changed});
        if (finish_script_frame(actions, frame, s, session)) {
            running = false;
        }
        ++frame;
        if (o.frames != 0 && frame >= o.frames) {
            running = false;
        }
        if (o.benchmark && time_s >= o.duration_s) {
            running = false;
        }
    }
    s.strokes.close(s.history());

    write_outputs(o, session, frames, screen.get(), s.render, frame);
    std::cout << "frames:  " << frame << '\n';
    if (screen) {
        // What the overlay showed last (scripted runs check it).
        std::cout << "overlay: algorithm " << s.selection.algorithm_name() << ", "
                  << (s.controls.full_panel ? "full panel" : "compact") << '\n';
    }
    if (bench) {
        const BenchmarkSetup setup{
            world.name, cl_ctx.info(), vk_ctx->info().name,
            screen ? std::optional(screen->presenter().mode()) : std::nullopt};
        report_benchmark(o, setup, session, s.render, records, bench->log());
    }
    return 0;
}

}  // namespace

Command add_view(CLI::App& root) {
    auto o = std::make_shared<ViewCliOptions>();
    auto* app = root.add_subcommand(
        "view",
        "Interactive viewer: fly through the world, paint voxels, switch algorithms (needs a "
        "display; without one it exits 2 and suggests `render`, except with --benchmark, which "
        "then runs headless, or --fallback-png, which then renders the first frame into it)");
    add_view_options(*app, *o);
    return {app, [o] {
                std::shared_ptr<vk::ValidationLog> log;
                if (o->validate) {
                    log = std::make_shared<vk::ValidationLog>([](const std::string& m) {
                        std::cerr << "voxfield: Vulkan validation: " << m << '\n';
                    });
                }
                const int code = run_view(*o, log);  // every Vulkan object is gone afterwards
                if (log && log->count() > 0) {
                    std::cerr << "voxfield view: " << log->count()
                              << " Vulkan validation message(s) (--validate)\n";
                    return code == 0 ? 1 : code;
                }
                return code;
            }};
}

}  // namespace voxfield::cli
