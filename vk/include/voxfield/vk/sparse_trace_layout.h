/* The sparse tracer's bindings and directory (vk/shaders/sparse_trace.comp, vk/src/
 * sparse_tracer.cpp), shared by C++ and GLSL: only preprocessor constants.
 *
 * Directory: the tile grid is cut into blocks of VF_SPARSE_BLOCK_TILES^3 tiles (512^3 voxels).
 * The block table (x fastest over ceil(tile grid / VF_SPARSE_BLOCK_TILES)) holds, per block,
 * the index of its page in the tile table or VF_SPARSE_NONE when none of its tiles is stored;
 * a page is VF_SPARSE_BLOCK_TILES^3 tile indices (x fastest), VF_SPARSE_NONE for an absent
 * tile. A tile's record (uvec4): its root's index in its node chunk, its first material's
 * index in its material chunk, the node chunk, the material chunk. Nodes and materials are
 * core/sparse.hpp's buffers as they are, cut at tile boundaries into chunks of at most one
 * storage-buffer binding each. */
#ifndef VOXFIELD_VK_SPARSE_TRACE_LAYOUT_H
#define VOXFIELD_VK_SPARSE_TRACE_LAYOUT_H

#define VF_SPARSE_LOCAL_SIZE 8
#define VF_SPARSE_BLOCK_TILES 8
#define VF_SPARSE_NONE 0xFFFFFFFFu
#define VF_SPARSE_MAX_NODE_CHUNKS 4
#define VF_SPARSE_MAX_MATERIAL_CHUNKS 8

#define VF_SPARSE_BINDING_IMAGE 0
#define VF_SPARSE_BINDING_PALETTE 1
#define VF_SPARSE_BINDING_BLOCKS 2
#define VF_SPARSE_BINDING_PAGES 3
#define VF_SPARSE_BINDING_RECORDS 4
/* Per pixel (row by row) the ray's node visits and node exits (RenderOptions::count). */
#define VF_SPARSE_BINDING_COUNTERS 5
/* node_masks (two uints per node, low word first), VF_SPARSE_MAX_NODE_CHUNKS bindings */
#define VF_SPARSE_BINDING_MASKS 6
/* node_offsets (one uint per node) */
#define VF_SPARSE_BINDING_OFFSETS (VF_SPARSE_BINDING_MASKS + VF_SPARSE_MAX_NODE_CHUNKS)
/* materials (four bytes per uint, the lowest first) */
#define VF_SPARSE_BINDING_MATERIALS (VF_SPARSE_BINDING_OFFSETS + VF_SPARSE_MAX_NODE_CHUNKS)
#define VF_SPARSE_LAST_BINDING (VF_SPARSE_BINDING_MATERIALS + VF_SPARSE_MAX_MATERIAL_CHUNKS - 1)

#endif
