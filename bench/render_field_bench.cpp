// Measures (does not test) what an edit costs a frame on sharing path 3 (issue 23's target: an
// edit frame <= 1.2x a frame without one at 256^3): frames of the same view with no edit, with
// a random edit (core's RandomEdits, as `view --benchmark`) whose changed boxes are copied, and
// with the whole field copied instead (what path 3 did before issue 23). A frame here is the
// edit's incremental update (OpenCL), RenderField::update and a ray march read back (Vulkan,
// waited for). Prints one JSON object. Usage: voxfield_render_field_bench [N [W H [FRAMES]]].
#include <algorithm>
#include <chrono>
#include <cstdio>
#include <cstdlib>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "voxfield/cl/generator.hpp"
#include "voxfield/cl/incremental.hpp"
#include "voxfield/core/clock.hpp"
#include "voxfield/core/scenes.hpp"
#include "voxfield/core/undo.hpp"
#include "voxfield/pipeline/render_field.hpp"

namespace {

using namespace voxfield;

double median(std::vector<double> v) {
    std::sort(v.begin(), v.end());
    return v.empty() ? 0 : v[v.size() / 2];
}

}  // namespace

int main(int argc, char** argv) {
    const std::uint32_t n = argc > 1 ? static_cast<std::uint32_t>(std::atoi(argv[1])) : 256;
    const std::uint32_t w = argc > 3 ? static_cast<std::uint32_t>(std::atoi(argv[2])) : 640;
    const std::uint32_t h = argc > 3 ? static_cast<std::uint32_t>(std::atoi(argv[3])) : 360;
    const int frames = argc > 4 ? std::atoi(argv[4]) : 30;
    const Dims dims{n, n, n};
    ocl::Context cl(ocl::select_device("cpu"));
    vk::Context vkc("");
    const Palette palette;
    ocl::GeneratorOptions g;
    g.format = Format::u16;
    ocl::IncrementalField field(cl, make_scene("spheres", dims, 5), palette,
                                ocl::resolve_options(g, dims));
    vk::Raymarcher marcher(vkc);
    pipeline::RenderField render(cl, vkc, marcher, dims, vk::SharingPath::copy);
    render.attach(marcher, field.field_buffer(), Format::u16, Metric::manhattan,
                  field.voxels_buffer(), palette);
    vk::RenderOptions r;
    r.width = w;
    r.height = h;
    r.shading = vk::Shading::lit;
    r.camera = vk::default_camera(field.world(), w, h, r.camera.fov_deg);
    vk::Image image;
    RandomEdits edits(dims, 16, 1);
    const Box world{{0, 0, 0}, {n, n, n}};
    std::vector<double> plain, edited, whole, update_ms, whole_update_ms;
    std::uint64_t bytes = 0, whole_bytes = 0;
    marcher.render(r, image);  // warm-up: pipelines, target
    for (int i = 0; i < frames; ++i) {
        auto t = Clock::now();
        marcher.render(r, image);
        plain.push_back(ms_since(t));
        for (const bool all : {false, true}) {
            t = Clock::now();
            const ocl::UpdateStats s = field.apply({edits.next()});
            std::vector<Box> regions = s.regions;
            for (const EditResult& e : s.edits) {
                if (e.changed()) {
                    regions.push_back(e.bounds);
                }
            }
            if (all) {
                regions = {world};
            }
            const std::uint64_t before = marcher.bytes_copied();
            const auto u = Clock::now();
            render.update(marcher, regions);
            (all ? whole_update_ms : update_ms).push_back(ms_since(u));
            marcher.render(r, image);
            (all ? whole : edited).push_back(ms_since(t));
            (all ? whole_bytes : bytes) += marcher.bytes_copied() - before;
        }
    }
    const double p = median(plain), e = median(edited), a = median(whole);
    const nlohmann::json out = {
        {"what",
         "path 3 frame cost of an edit (incremental update + RenderField::update + "
         "ray march read back), lit, RandomEdits(chunk 16)"},
        {"opencl_device", cl.info().name},
        {"vulkan_device", vkc.info().name},
        {"size", {n, n, n}},
        {"image", {w, h}},
        {"frames", frames},
        {"frame_without_edit_median_ms", p},
        {"edit_frame_median_ms", e},
        {"edit_frame_ratio", e / p},
        {"render_field_update_median_ms", median(update_ms)},
        {"bytes_copied_per_edit", frames > 0 ? double(bytes) / frames : 0.0},
        {"whole_field_copy_frame_median_ms", a},
        {"whole_field_copy_ratio", a / p},
        {"whole_field_update_median_ms", median(whole_update_ms)},
        {"whole_field_bytes_per_edit", frames > 0 ? double(whole_bytes) / frames : 0.0}};
    std::printf("%s\n", out.dump(2).c_str());
    return 0;
}
