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

TracedPart load_traced_part(ocl::Context& ctx, const sdf::Part& part, const std::string& name) {
    TracedPart out{VoxModel{sdf::solid_world(part, name), Palette()}, {}, 0, 0};
    ocl::ImplicitDiscretiser job(ctx, part);
    job.run(out.grid);
    out.discretise_ms = job.timing().total_ms;
    World& world = out.model.world;
    out.solid = world.solid_count();
    for (const ocl::ImplicitGrid::Crossed& c : out.grid.crossed()) {
        std::uint8_t& v = world.voxels()[world.dims().index(c.x, c.y, c.z)];
        if (v == 0) {
            v = static_cast<std::uint8_t>(c.material);
        }
    }
    return out;
}

}  // namespace voxfield::cli
