// An implicit part loaded for tracing (traced_part.hpp).
#include "traced_part.hpp"

namespace voxfield::cli {

vk::ImplicitSurface surface_of(const ocl::ImplicitGrid& grid) {
    vk::ImplicitSurface s;
    s.dims = grid.dims;
    s.tiles = grid.tiles;
    s.tile_depth = grid.tile_depth;
    s.tile_table = grid.tile_table;
    s.nodes = grid.nodes;
    s.voxels = grid.voxels;
    s.vertices = grid.vertices;
    return s;
}

vk::ImplicitSurface TracedPart::surface() const {
    return surface_of(grid);
}

namespace {

// Discretises `part` into out.grid.
void discretise_into(ocl::Context& ctx, const sdf::Part& part, TracedPart& out) {
    ocl::ImplicitDiscretiser job(ctx, part);
    job.run(out.grid);
    out.discretise_ms = job.timing().total_ms;
}

// Adds the grid's crossed voxels to out's world where it is empty, with their materials.
void add_crossed(TracedPart& out) {
    World& world = out.model.world;
    for (const ocl::ImplicitGrid::Crossed& c : out.grid.crossed()) {
        std::uint8_t& v = world.voxels()[world.dims().index(c.x, c.y, c.z)];
        if (v == 0) {
            v = static_cast<std::uint8_t>(c.material);
        }
    }
}

}  // namespace

TracedPart load_traced_part(ocl::Context& ctx, const sdf::Part& part, const std::string& name) {
    TracedPart out{VoxModel{sdf::solid_world(part, name), Palette()}, {}, 0, 0};
    discretise_into(ctx, part, out);
    out.solid = out.model.world.solid_count();
    add_crossed(out);
    return out;
}

TracedPart load_traced_scene(ocl::Context& ctx, const scene::Scene& scene,
                             const std::string& name) {
    TracedPart out{VoxModel{scene.world(name), scene.palette}, {}, 0, 0};
    discretise_into(ctx, *scene.part, out);
    World models(scene.dims);
    scene.place_vox([&](std::uint32_t x, std::uint32_t y, std::uint32_t z, std::uint8_t) {
        models.set(x, y, z, 1);
    });
    out.grid.drop_crossed(
        [&](std::uint32_t x, std::uint32_t y, std::uint32_t z) { return models.at(x, y, z) != 0; });
    out.solid = out.model.world.solid_count();
    add_crossed(out);
    return out;
}

}  // namespace voxfield::cli
