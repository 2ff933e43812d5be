#pragma once
// An implicit part (`.sdf.json`) as `render` and `view` show it: discretised on the OpenCL
// device into the tile grid of contrees (ocl::ImplicitDiscretiser), the world the ray marcher's
// field is built from (solid where f < 0 at a voxel's centre, as load_world reads a part, plus
// every voxel the surface crosses, so that the march stops there), and that grid for the ray
// marcher to trace the trilinear surface in the crossed voxels (vk::Raymarcher::set_implicit).
#include <cstdint>
#include <string>

#include "voxfield/cl/implicit.hpp"
#include "voxfield/cl/runtime.hpp"
#include "voxfield/core/scene_file.hpp"
#include "voxfield/core/sdf.hpp"
#include "voxfield/core/vox.hpp"
#include "voxfield/vk/raymarcher.hpp"

namespace voxfield::cli {

struct TracedPart {
    VoxModel model;  // the world to build the field of, and the default palette
    ocl::ImplicitGrid grid;
    double discretise_ms = 0;  // the discretisation's wall time
    std::uint64_t solid = 0;   // voxels solid at their centre (the rest of the world: crossed)

    // The grid as the ray marcher takes it (surface_of(grid)).
    vk::ImplicitSurface surface() const;
};

// An implicit grid as the ray marcher takes it (vk::Raymarcher::set_implicit).
vk::ImplicitSurface surface_of(const ocl::ImplicitGrid& grid);

// Discretises `part` (read from the file `name`) on `ctx`.
TracedPart load_traced_part(ocl::Context& ctx, const sdf::Part& part, const std::string& name);

// A mixed scene (scene_file.hpp) with parts: its parts discretised as one on `ctx`, the world
// its voxels (parts' solid voxels, .vox voxels over them) plus the parts' crossed voxels; a
// crossed voxel under a .vox voxel is dropped from the grid, so the model's cube is drawn there.
TracedPart load_traced_scene(ocl::Context& ctx, const scene::Scene& scene, const std::string& name);

}  // namespace voxfield::cli
