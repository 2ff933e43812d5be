/* The ray marcher's implicit-surface bindings (vk/shaders/raymarch.comp), shared by C++
 * (vk/src) and GLSL: only preprocessor constants. The four buffers are an ocl::ImplicitGrid's
 * arrays as they are (core/sdf_layout.hpp: tile table, 64-tree nodes, crossed-voxel records,
 * corner vertices (grad f, f)); the surface buffer is RenderOptions::surface's per-pixel hit. */
#ifndef VOXFIELD_VK_TRACE_LAYOUT_H
#define VOXFIELD_VK_TRACE_LAYOUT_H

#include "voxfield/layout.h"

#define VF_TRACE_BINDING_TILES (VF_RAYMARCH_BINDING_BLOCK_MIN + 1)
#define VF_TRACE_BINDING_NODES (VF_RAYMARCH_BINDING_BLOCK_MIN + 2)
#define VF_TRACE_BINDING_VOXELS (VF_RAYMARCH_BINDING_BLOCK_MIN + 3)
#define VF_TRACE_BINDING_VERTICES (VF_RAYMARCH_BINDING_BLOCK_MIN + 4)
/* Per pixel (row by row) two vec4: (hit point x, y, z in voxel units, kind), (normal x, y, z,
 * ray parameter t from the camera). */
#define VF_TRACE_BINDING_SURFACE (VF_RAYMARCH_BINDING_BLOCK_MIN + 5)
#define VF_TRACE_LAST_BINDING VF_TRACE_BINDING_SURFACE

/* Surface sample kinds. */
#define VF_TRACE_MISS 0u
#define VF_TRACE_CUBE 1u   /* a voxel's face (or the camera's cell): no corner data */
#define VF_TRACE_SMOOTH 2u /* the trilinear interpolant's first root in a crossed voxel */

#endif
