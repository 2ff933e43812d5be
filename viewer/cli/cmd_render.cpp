// `voxfield render INPUT -o OUT.png`: the exact field of a metric on the OpenCL device,
// ray-marched by the Vulkan DDA (vk/shaders/raymarch.comp) into an offscreen image, written as
// PNG; a sparse world (--sparse, or generate's rule) is traced through its 64-trees by
// vk/shaders/sparse_trace.comp instead, with no field.
#include <algorithm>
#include <array>
#include <cctype>
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <cstring>
#include <iostream>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include "cli_util.hpp"
#include "generate_sparse.hpp"
#include "png.hpp"
#include "traced_part.hpp"
#include "voxfield/cl/generator.hpp"
#include "voxfield/core/error.hpp"
#include "voxfield/core/metric.hpp"
#include "voxfield/core/output.hpp"
#include "voxfield/core/sdf.hpp"
#include "voxfield/core/sparse.hpp"
#include "voxfield/core/vox.hpp"
#include "voxfield/pipeline/frame_pipeline.hpp"
#include "voxfield/vk/raymarcher.hpp"
#include "voxfield/vk/shared.hpp"
#include "voxfield/vk/sparse_tracer.hpp"

namespace voxfield::cli {
namespace {

struct RenderCliOptions {
    std::string input, output, camera, target, shading = "flat", sky, device, field = "compact",
                                               spacing, metric = "manhattan";
    std::uint32_t width = 800, height = 600;
    double fov = 60;
    bool stats = false, validate = false, sparse = false;
    // The field options given on the command line (refused for sparse worlds).
    std::vector<std::string> field_options;
};

// "X,Y,Z" (finite decimal numbers, world voxel units).
vk::Vec3 parse_point(const std::string& text, const std::string& option) {
    vk::Vec3 v{};
    std::size_t pos = 0, n = 0;
    while (pos <= text.size()) {
        const std::size_t end = std::min(text.find(',', pos), text.size());
        const std::string part = text.substr(pos, end - pos);
        std::size_t used = 0;
        double value = 0;
        try {
            value = std::stod(part, &used);
        } catch (const std::exception&) {
            used = 0;
        }
        if (part.empty() || used != part.size() || !std::isfinite(value) || n >= 3) {
            throw InputError("invalid " + option + " '" + text +
                             "': expected X,Y,Z (three numbers, voxel units), e.g. -40,60,-40");
        }
        v[n++] = value;
        pos = end + 1;
    }
    if (n != 3) {
        throw InputError("invalid " + option + " '" + text + "': expected 3 numbers X,Y,Z, got " +
                         std::to_string(n));
    }
    return v;
}

// "RRGGBB" (hex, an optional leading '#').
Rgba parse_colour(const std::string& text) {
    std::string hex = text;
    if (!hex.empty() && hex[0] == '#') {
        hex.erase(0, 1);
    }
    if (hex.size() != 6 ||
        !std::all_of(hex.begin(), hex.end(), [](unsigned char c) { return std::isxdigit(c); })) {
        throw InputError("invalid --sky '" + text + "': expected a hex colour RRGGBB, e.g. 87ceeb");
    }
    const unsigned long v = std::stoul(hex, nullptr, 16);
    return Rgba{static_cast<std::uint8_t>(v >> 16), static_cast<std::uint8_t>(v >> 8),
                static_cast<std::uint8_t>(v), 255};
}

std::string point(const vk::Vec3& v) {
    return "(" + fixed(v[0], 2) + ", " + fixed(v[1], 2) + ", " + fixed(v[2], 2) + ")";
}

// A sparse world (core/sparse.hpp) traced through its 64-trees (vk::SparseTracer): no OpenCL
// device and no distance field, so the field options do not apply.
// The "image:" line of the report: the size, shading, camera and output of a render.
std::string image_line(const vk::Image& image, const RenderCliOptions& o,
                       const vk::RenderOptions& r) {
    return "image:   " + std::to_string(image.width) + "x" + std::to_string(image.height) + ", " +
           o.shading + " shading, camera " + point(r.camera.position) + " -> " +
           point(r.camera.target) + ", fov " + fixed(r.camera.fov_deg, 1) + " -> " + o.output +
           '\n';
}

// --stats' timing line: `what` (the trace, the ray march) by the GPU timestamps of `image`.
void print_timing(const vk::Image& image, const std::string& what) {
    if (image.raymarch_ms >= 0) {
        const double rays = double(image.width) * double(image.height);
        std::cout << "stats:   " << what << ' ' << fixed(image.raymarch_ms, 3)
                  << " ms (GPU timestamps), " << fixed(rays / (image.raymarch_ms * 1e-3) / 1e6, 1)
                  << " Mrays/s\n";
    } else {
        std::cout << "stats:   the Vulkan device has no compute timestamps\n";
    }
}

int run_render_sparse(const RenderCliOptions& o, vk::RenderOptions r,
                      const std::optional<vk::Vec3>& camera, const std::optional<vk::Vec3>& target,
                      const std::shared_ptr<vk::ValidationLog>& validation) {
    if (!o.field_options.empty()) {
        throw InputError(o.field_options.front() +
                         " does not apply to a sparse world: it is traced through its 64-trees, "
                         "with no distance field or OpenCL device");
    }
    if (sdf::is_sdf_path(o.input)) {
        throw InputError(
            "--sparse: an .sdf.json part is rendered on its implicit surface, "
            "which needs the dense field (drop --sparse)");
    }
    const SparseModel model =
        load_sparse_world(o.input, InputOptions{.grid = {}, .palette_values = true});
    const SparseWorld& world = model.world;
    const vk::Camera fallback = vk::default_camera(world, r.width, r.height, r.camera.fov_deg);
    r.camera.position = camera ? *camera : fallback.position;
    r.camera.target = target ? *target : fallback.target;
    vk::validate(r);
    vk::Context vk_ctx(vk::ContextOptions{"", validation});
    vk::SparseTracer tracer(vk_ctx);
    tracer.upload(world, model.palette);
    const vk::Image image = tracer.render(r);
    write_png(o.output, image);
    const vk::SparseDeviceStats& device = tracer.stats();
    std::cout << "vulkan:  " << vk_ctx.info().name << " (" << vk_ctx.info().type << ", Vulkan "
              << vk_ctx.info().api << ")\n"
              << "world:   " << o.input << "  " << world.dims().to_string() << " = "
              << world.dims().count() << " voxels, " << world.solid_count() << " solid in "
              << world.tile_count() << " tiles of 64^3 (sparse)\n"
              << "sparse:  traced through the 64-trees: " << device.bytes
              << " bytes on the device, nodes in " << device.node_chunks << " and materials in "
              << device.material_chunks << " storage-buffer binding(s), directory of "
              << device.blocks << " blocks of 512^3 voxels and " << device.pages
              << " tile page(s)\n"
              << image_line(image, o, r);
    if (o.stats) {
        print_timing(image, "trace");
        vk::RenderOptions counting = r;
        counting.count = true;
        const vk::Image counted = tracer.render(counting);
        const double rays = double(counted.width) * double(counted.height);
        std::cout << "stats:   per ray " << fixed(double(counted.fetches) / rays, 2)
                  << " node visits, " << fixed(double(counted.steps) / rays, 2)
                  << " node exits (blocks, tiles, 16^3 and 4^3 nodes, voxels)\n";
    }
    return 0;
}

int run_render(const RenderCliOptions& o, const std::shared_ptr<vk::ValidationLog>& validation) {
    // Everything the user typed is checked before any file is read or device touched.
    require_png_name("-o", o.output);
    check_outputs({{"-o", o.output}}, {{"INPUT", o.input}});
    vk::RenderOptions r;
    r.width = o.width;
    r.height = o.height;
    r.camera.fov_deg = o.fov;
    r.shading = o.shading == "lit" ? vk::Shading::lit : vk::Shading::flat;
    r.sky_gradient = o.sky.empty();
    if (!o.sky.empty()) {
        r.sky = parse_colour(o.sky);
    }
    std::optional<vk::Vec3> camera, target;
    if (!o.camera.empty()) {
        camera = parse_point(o.camera, "--camera");
    }
    if (!o.target.empty()) {
        target = parse_point(o.target, "--target");
    }
    if (camera && target) {
        r.camera.position = *camera;
        r.camera.target = *target;
        vk::validate(r);
    } else {
        vk::Camera c = r.camera;
        c.position = {0, 0, 0};
        c.target = {0, 0, 1};
        vk::RenderOptions check = r;
        check.camera = c;
        vk::validate(check);  // sizes and field of view
    }

    if (o.sparse || (!sdf::is_sdf_path(o.input) && needs_sparse(o.input, ""))) {
        return run_render_sparse(o, r, camera, target, validation);
    }
    // A part (.sdf.json), or the parts of a mixed scene (.scene.json), is discretised on the
    // OpenCL device and traced on its smooth surface; any other input is read as voxels.
    std::optional<sdf::Part> part;
    std::optional<scene::Scene> mixed;
    std::optional<VoxModel> loaded;
    if (sdf::is_sdf_path(o.input)) {
        part = sdf::load_part(o.input);
    } else if (scene::is_scene_path(o.input)) {
        mixed = scene::load_scene(o.input);
        if (!mixed->part) {
            loaded = VoxModel{mixed->world(o.input), mixed->palette};
        }
    } else {
        loaded = load_world(o.input, InputOptions{.grid = {}, .palette_values = true});
    }
    ocl::Context cl_ctx(ocl::select_device(o.device));
    std::optional<TracedPart> traced;
    if (part) {
        traced = load_traced_part(cl_ctx, *part, o.input);
    } else if (mixed && mixed->part) {
        traced = load_traced_scene(cl_ctx, *mixed, o.input);
    }
    const VoxModel& model = traced ? traced->model : *loaded;
    const World& world = model.world;
    const vk::Camera fallback = vk::default_camera(world, r.width, r.height, r.camera.fov_deg);
    r.camera.position = camera ? *camera : fallback.position;
    r.camera.target = target ? *target : fallback.target;
    vk::validate(r);

    const vk::FieldFormat format = vk::parse_field_format(o.field);
    // The exact global field of the metric (unit spacing), distances rounded down.
    ocl::GeneratorOptions g;
    g.algorithm = ocl::Algorithm::exact;
    g.metric = parse_metric(o.metric);
    if (!o.spacing.empty()) {
        g.spacing = parse_spacing(o.spacing);
        if (format == vk::FieldFormat::packed32 && !g.spacing.unit()) {
            throw InputError("--spacing " + g.spacing.to_string() +
                             " needs --field compact (the packed32 field is copied as it is, "
                             "in the spacing's units, which the ray marcher cannot step by)");
        }
    }
    g.format = format == vk::FieldFormat::packed32 ? Format::packed32 : Format::u16;
    g = ocl::resolve_options(g, world.dims());
    vk::Context vk_ctx(vk::ContextOptions{"", validation});
    // The frame pipeline that view and bench use too. compact: OpenCL converts the u16 field
    // and the world's voxels into the compact format where Vulkan reads it (paths 1, 2) or
    // into a buffer that is copied (path 3), with the per-block minima for coarse skipping.
    // packed32: generated in that format and copied (path 3).
    pipeline::PipelineOptions po;
    po.render_format = format;
    pipeline::FramePipeline frames(cl_ctx, vk_ctx, model.palette, world.dims(), po);
    const double build_ms = frames.rebuild(World(world), g);
    if (traced) {
        frames.marcher().set_implicit(traced->surface());
    }
    const vk::Raymarcher& marcher = frames.marcher();
    const std::string why_not = frames.why_not();
    vk::Image image;
    frames.render(r, image);

    write_png(o.output, image);

    std::cout << "opencl:  " << cl_ctx.info().name << " (" << cl_ctx.info().platform << ", "
              << cl_ctx.info().type << "): exact " << to_string(g.metric) << " field, "
              << vk::to_string(format) << " ("
              << (format == vk::FieldFormat::compact ? "2 bytes per voxel, world + field"
                                                     : "4 + 1 material byte per voxel")
              << "), built in " << fixed(build_ms, 1) << " ms\n"
              << "vulkan:  " << vk_ctx.info().name << " (" << vk_ctx.info().type << ", Vulkan "
              << vk_ctx.info().api << ")\n"
              << "world:   " << o.input << "  " << world.dims().to_string() << " = " << world.size()
              << " voxels, "
              << (traced ? std::to_string(traced->solid) + " solid at the centre, " +
                               std::to_string(world.solid_count() - traced->solid) +
                               " more crossed by the surface\n"
                         : std::to_string(world.solid_count()) + " solid\n")
              << (traced
                      ? "implicit: " + std::to_string(traced->grid.crossed_count()) +
                            " crossed voxels traced on the trilinear interpolant of their "
                            "corners (tile depth " +
                            std::to_string(traced->grid.tile_depth) + ", " +
                            std::to_string(marcher.implicit_bytes()) + " bytes), discretised in " +
                            fixed(traced->discretise_ms, 1) + " ms\n"
                      : std::string())
              << "sharing: " << marcher.sharing_path()
              << (why_not.empty() ? std::string() : " [" + why_not + "]") << "; field in "
              << marcher.field_bindings() << " storage-buffer binding"
              << (marcher.field_bindings() == 1 ? "" : "s") << " of up to " << marcher.slab_depth()
              << " z-slices\n"
              << image_line(image, o, r);
    if (o.stats) {
        print_timing(image, "ray march");
        // One more frame through the counting pipeline (not timed).
        vk::RenderOptions counting = r;
        counting.count = true;
        vk::Image counted;
        frames.render(counting, counted);
        const double rays = double(counted.width) * double(counted.height);
        std::cout << "stats:   per ray " << fixed(double(counted.fetches) / rays, 2)
                  << " field fetches, " << fixed(double(counted.steps) / rays, 2) << " DDA steps ("
                  << to_string(g.metric) << " field)\n";
    }
    return 0;
}

}  // namespace

Command add_render(CLI::App& root) {
    auto o = std::make_shared<RenderCliOptions>();
    auto* app = root.add_subcommand(
        "render",
        "Ray-march a world (.vox, .npy, .vdb, .sdf.json or .scene.json) through its distance "
        "field (a sparse world: through its 64-trees) into a PNG image");
    app->add_option("INPUT", o->input, kWorldInputHelp)->required();
    app->add_option("-o,--output", o->output, "Output .png image (written atomically)")->required();
    app->add_option("--width", o->width, "Image width in pixels, 1..16384")->capture_default_str();
    app->add_option("--height", o->height, "Image height in pixels, 1..16384")
        ->capture_default_str();
    app->add_option("--camera", o->camera,
                    "Camera position X,Y,Z in voxel units (y up; default: in front of the "
                    "world's solid voxels (-z, MagicaVoxel's front), left of and above them, "
                    "just far enough for the image to hold them all)");
    app->add_option("--target", o->target,
                    "Point X,Y,Z the camera looks at (default: the centre of the box of the "
                    "world's solid voxels)");
    app->add_option("--fov", o->fov, "Vertical field of view in degrees, in (0, 180)")
        ->capture_default_str();
    app->add_option("--shading", o->shading,
                    "flat: the hit voxel's palette colour exactly, unlit, misses the --sky "
                    "colour; lit: face normal (an implicit part's surface: the interpolated "
                    "gradient), sun (shadows by a ray marched toward it) and "
                    "ambient light (occlusion from the field), sRGB-correct, misses the "
                    "sky gradient and sun disc unless --sky is given. render defaults to flat "
                    "(exact colours, comparable pixel for pixel); view opens lit")
        ->check(CLI::IsMember({"flat", "lit"}))
        ->capture_default_str();
    app->add_option("--sky", o->sky, "Colour of rays that miss, hex RRGGBB (flat default: 000000)");
    app->add_option("--device", o->device,
                    "OpenCL device generating the field: cpu, gpu or an index from `voxfield "
                    "devices` (default: $VOXFIELD_DEVICE, else the first GPU, else the first "
                    "CPU); the Vulkan device is chosen automatically ($VOXFIELD_VK_DEVICE: gpu, "
                    "cpu or an index)");
    app->add_option("--field", o->field,
                    "Field format the ray marcher reads: compact (16 bits per voxel, distance "
                    "and palette index: world + field in 2 bytes, shared with OpenCL where the "
                    "devices allow) or packed32 (4 bytes plus a material byte, always copied)")
        ->check(CLI::IsMember({"packed32", "compact"}))
        ->capture_default_str();
    app->add_option("--metric", o->metric,
                    "Metric of the exact field the ray marcher steps through: manhattan (L1), "
                    "chebyshev (L-inf) or euclidean (L2, rounded down); the image is the same, "
                    "the number of steps per ray is not")
        ->check(CLI::IsMember(metric_names()))
        ->capture_default_str();
    app->add_option("--spacing", o->spacing,
                    "Voxel size X,Y,Z of the field's metric (default 1,1,1): the field is computed "
                    "in those units and turned into voxel steps (divided by the largest, rounded "
                    "down) for the ray marcher; the image is the same, the steps per ray are not "
                    "(--field compact only)");
    app->add_flag("--sparse", o->sparse,
                  "Store the world as a tile grid of 64-trees and trace it through them (no "
                  "distance field, no OpenCL device: --field, --metric, --spacing and --device "
                  "are refused); automatic for a .npy, .vox scene or .vdb grid of more than 2^31 "
                  "voxels. Flat images equal the dense ray marcher's pixel for pixel; lit "
                  "shading takes its ambient occlusion from 20 voxels around the hit face");
    app->add_flag("--stats", o->stats,
                  "Report the ray-march dispatch time (GPU timestamps), Mrays/s, and the field "
                  "fetches and DDA steps per ray (from one more, counting frame; sparse: node "
                  "visits and exits per ray)");
    app->add_flag("--validate", o->validate,
                  "Run with the Vulkan validation layer (synchronisation validation included; "
                  "Debian: vulkan-validationlayers): each message is printed to stderr and any "
                  "makes the command exit 1")
        ->envname("VOXFIELD_VALIDATE");
    return {app, [o, app] {
                o->field_options.clear();
                for (const char* name : {"--field", "--metric", "--spacing", "--device"}) {
                    if (app->count(name) > 0) {
                        o->field_options.emplace_back(name);
                    }
                }
                std::shared_ptr<vk::ValidationLog> log;
                if (o->validate) {
                    log = std::make_shared<vk::ValidationLog>([](const std::string& m) {
                        std::cerr << "voxfield: Vulkan validation: " << m << '\n';
                    });
                }
                const int code = run_render(*o, log);  // every Vulkan object is gone afterwards
                if (log && log->count() > 0) {
                    std::cerr << "voxfield render: " << log->count()
                              << " Vulkan validation message(s) (--validate)\n";
                    return code == 0 ? 1 : code;
                }
                return code;
            }};
}

}  // namespace voxfield::cli
