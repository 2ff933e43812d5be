/* GPU-visible data layouts, shared by C++ (host), OpenCL C (kernels) and GLSL (vk/shaders).
 * Only preprocessor constants, so every language reads it; host static_asserts in
 * core/src/format.cpp and the kernels' use of these names keep both sides in step. */
#ifndef VOXFIELD_LAYOUT_H
#define VOXFIELD_LAYOUT_H

/* packed32 field element: (min(distance, 255) << 8) | rgb332 colour (0 for air). */
#define VF_PACKED_DISTANCE_SHIFT 8
#define VF_PACKED_DISTANCE_MAX 255u
#define VF_PACKED_COLOUR_MASK 0xFFu

/* compact field element, 16 bits, two per 32-bit word (the lower half first):
 * (min(distance, 255) << 8) | material (palette index, 0 for air). World and field in 2 bytes
 * per voxel; the ray marcher looks up the exact palette colour by the material index. */
#define VF_COMPACT_DISTANCE_SHIFT 8
#define VF_COMPACT_DISTANCE_MAX 255u
#define VF_COMPACT_MATERIAL_MASK 0xFFu
/* In one allocation shared by OpenCL and Vulkan, each storage-buffer slab of the field starts
 * at a multiple of this many bytes (>= any minStorageBufferOffsetAlignment). */
#define VF_FIELD_SLAB_ALIGN 4096

/* RGB332 colour byte: rrrgggbb. */
#define VF_RGB332_R_SHIFT 5
#define VF_RGB332_G_SHIFT 2

/* Ray marcher (vk/shaders/raymarch.comp): work-group edge, the most storage-buffer bindings
 * the packed32 field (and the material bytes beside it) may be split across, since one
 * binding is limited to maxStorageBufferRange (lavapipe: 128 MiB), and its binding numbers. */
#define VF_RAYMARCH_LOCAL_SIZE 8
#define VF_RAYMARCH_MAX_SLABS 8
#define VF_RAYMARCH_BINDING_IMAGE 0
#define VF_RAYMARCH_BINDING_PALETTE 1
#define VF_RAYMARCH_BINDING_FIELD 2
#define VF_RAYMARCH_BINDING_MATERIAL 10
/* Ray marcher flags (push constant): lit shading, sky gradient instead of a flat colour. */
#define VF_RAYMARCH_FLAG_LIT 1u
#define VF_RAYMARCH_FLAG_SKY_GRADIENT 2u
/* Coarse skipping: the block-minimum binding holds, per block of VF_RAYMARCH_BLOCK^3 voxels
 * (x fastest over ceil(dims / VF_RAYMARCH_BLOCK)), the minimum of the unsaturated distance
 * over the block (in the field's metric); a lower bound for every voxel in it, used where the
 * field's 8-bit distance is saturated. Its binding follows the ray counters'
 * (VF_RAYMARCH_BINDING_MATERIAL + VF_RAYMARCH_MAX_SLABS). */
#define VF_RAYMARCH_FLAG_BLOCK_MIN 8u
#define VF_RAYMARCH_BLOCK 8
#define VF_RAYMARCH_BINDING_BLOCK_MIN (VF_RAYMARCH_BINDING_MATERIAL + VF_RAYMARCH_MAX_SLABS + 1)
/* Write pixels as B, G, R, A bytes (a BGRA swapchain) instead of R, G, B, A. */
#define VF_RAYMARCH_FLAG_BGRA 16u

#endif
