/* GPU-visible data layouts, shared by C++ (host), OpenCL C (kernels) and, later, GLSL.
 * Only preprocessor constants, so every language reads it; host static_asserts in
 * core/src/format.cpp and the kernels' use of these names keep both sides in step. */
#ifndef VOXFIELD_LAYOUT_H
#define VOXFIELD_LAYOUT_H

/* packed32 field element: (min(distance, 255) << 8) | rgb332 colour (0 for air). */
#define VF_PACKED_DISTANCE_SHIFT 8
#define VF_PACKED_DISTANCE_MAX 255u
#define VF_PACKED_COLOUR_MASK 0xFFu

/* RGB332 colour byte: rrrgggbb. */
#define VF_RGB332_R_SHIFT 5
#define VF_RGB332_G_SHIFT 2

#endif
