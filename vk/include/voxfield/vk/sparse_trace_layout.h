/* The sparse tracer's bindings and directory (vk/shaders/sparse_trace.comp, vk/src/
 * sparse_tracer.cpp), shared by C++ and GLSL: only preprocessor constants.
 *
 * Directory: the tile grid is cut into blocks of VF_SPARSE_BLOCK_TILES^3 tiles (512^3 voxels).
 * The block table (x fastest over ceil(tile grid / VF_SPARSE_BLOCK_TILES)) holds, per block,
 * the index of its page in the tile table or VF_SPARSE_NONE when none of its tiles is stored;
 * a page is VF_SPARSE_BLOCK_TILES^3 tile indices (x fastest), VF_SPARSE_NONE for an absent
 * tile. A tile's record is VF_SPARSE_RECORD_UVEC4S uvec4: its root's index in its node chunk,
 * its first material's index in its material chunk, the device address (low word first) of its
 * root's mask; the address of its root's offset, the address of its material chunk. Nodes and
 * materials are core/sparse.hpp's buffers as they are, cut at tile boundaries into chunks
 * (buffers) of at most maxStorageBufferRange bytes, any number of them, read through device
 * addresses (VK_KHR_buffer_device_address): node masks two uints per node (low word first),
 * node offsets one uint per node, materials four bytes per uint (the lowest first). A world in
 * one node chunk and one material chunk is also read through the bindings of chunk 0 (the
 * tracer's specialization constant 2: faster on lavapipe, whose SIMD gathers of 64-bit
 * addresses cost more than those of a binding's 32-bit offsets). */
#ifndef VOXFIELD_VK_SPARSE_TRACE_LAYOUT_H
#define VOXFIELD_VK_SPARSE_TRACE_LAYOUT_H

#define VF_SPARSE_LOCAL_SIZE 8
#define VF_SPARSE_BLOCK_TILES 8
#define VF_SPARSE_NONE 0xFFFFFFFFu
#define VF_SPARSE_RECORD_UVEC4S 2

#define VF_SPARSE_BINDING_IMAGE 0
#define VF_SPARSE_BINDING_PALETTE 1
#define VF_SPARSE_BINDING_BLOCKS 2
#define VF_SPARSE_BINDING_PAGES 3
#define VF_SPARSE_BINDING_RECORDS 4
/* Per pixel (row by row) the ray's node visits and node exits (RenderOptions::count). */
#define VF_SPARSE_BINDING_COUNTERS 5
/* Node chunk 0's masks and offsets, material chunk 0 (a world without chunks: any buffer). */
#define VF_SPARSE_BINDING_MASKS0 6
#define VF_SPARSE_BINDING_OFFSETS0 7
#define VF_SPARSE_BINDING_MATERIALS0 8
#define VF_SPARSE_LAST_BINDING VF_SPARSE_BINDING_MATERIALS0

#endif
