/* The implicit-surface tape and tile grid as the device sees them, shared by C++ (core/, cl/)
 * and OpenCL C (cl/kernels/implicit.cl). Only preprocessor constants, so both languages read
 * it; static_asserts in core/src/sdf_tape.cpp and cl/src/implicit.cpp keep the structs in step.
 *
 * Tape: postfix instructions of VF_SDF_INSTR_WORDS 32-bit words each: word 0 the opcode, word
 * 1 the material (primitives; 1..255), words 2.. float parameters. A value stack holds the
 * operands; a point stack holds the point each primitive is evaluated at (the world point at
 * the bottom, one entry per enclosing transform). */
#ifndef VOXFIELD_SDF_LAYOUT_H
#define VOXFIELD_SDF_LAYOUT_H

#define VF_SDF_INSTR_WORDS 16
#define VF_SDF_INSTR_PARAMS 14

/* Primitives push one value: parameters as named in DESIGN §3, in that order. */
#define VF_SDF_SPHERE 0u    /* center[3], radius */
#define VF_SDF_BOX 1u       /* center[3], half_size[3] */
#define VF_SDF_ROUND_BOX 2u /* center[3], half_size[3], radius */
#define VF_SDF_CYLINDER 3u  /* center[3], radius, half_height (axis y) */
#define VF_SDF_TORUS 4u     /* center[3], major, minor (x-z plane) */
#define VF_SDF_CAPSULE 5u   /* a[3], b[3], radius */
#define VF_SDF_PLANE 6u     /* unit normal[3], offset */
/* Binary operators pop B then A and push the result (material: see sdf.hpp). p[0]: k (smooth
 * operators), p[1]: the index of A's first instruction, p[2]: of B's (B's code ends just before
 * the operator), so that a leaf may skip an operand its interval shows is never selected. */
#define VF_SDF_MIN 7u         /* union */
#define VF_SDF_MAX 8u         /* intersection */
#define VF_SDF_DIFF 9u        /* max(A, -B) */
#define VF_SDF_SMOOTH_MIN 10u /* k: min(a, b) - h^2 k / 4, h = max(k - |a - b|, 0) / k */
#define VF_SDF_SMOOTH_DIFF 11u /* k: -smooth_min(-A, B) */
/* Unary. */
#define VF_SDF_SHELL 12u /* thickness: |v| - thickness */
/* Point stack: PUSH evaluates the child at M (p - t) (M = R^-1 / s, row-major m[9], then t[3]);
 * POP multiplies the child's value by s (p[0]). */
#define VF_SDF_PUSH_POINT 13u
#define VF_SDF_POP_POINT 14u

/* Tapes up to this long are specialised per node (operands never selected there skipped); the
 * discretiser keeps a node's specialised tape as n + 1 16-bit words: a count, then that many
 * instruction indices. */
#define VF_SDF_SPECIALISE_MAX 256

/* Nesting limit of a part (nodes on the longest root-to-leaf path); the stacks hold one more. */
#define VF_SDF_MAX_DEPTH 32
#define VF_SDF_STACK (VF_SDF_MAX_DEPTH + 1)

/* Tile grid of contrees. A node has 64 children (4x4x4, index x + 4 y + 16 z); tile_table[t]
 * is the root node of tile t or one of these two markers. */
#define VF_SDF_TILE_EMPTY 0xFFFFFFFFu
#define VF_SDF_TILE_FULL 0xFFFFFFFEu
/* Node: 6 words: child (interior: first child node, densely packed in the order of the
 * occupied mask; leaf: first voxel record), vertex (leaf: first vertex record of the leaf;
 * interior: VF_SDF_NOT_LEAF), occupied lo/hi (interior: ambiguous child, subdivided; leaf:
 * voxel the surface crosses), solid lo/hi (interior: child surely inside; leaf: f < 0 at the
 * voxel's centre). */
#define VF_SDF_NODE_WORDS 6
#define VF_SDF_NOT_LEAF 0xFFFFFFFFu
/* Voxel record (a crossed voxel of a leaf): 3 words: its 8 corners' vertex indices relative to
 * the leaf's first vertex, one byte each (corner c = x + 2 y + 4 z; corners 0-3 in word 0, low
 * byte first, 4-7 in word 1), then its material. */
#define VF_SDF_VOXEL_WORDS 3
/* Vertex record: 4 floats: h grad f (x, y, z), f, with h the voxel size: f's first-order change
 * over one voxel along each axis, so that the tracer works in voxel units. */
#define VF_SDF_VERTEX_FLOATS 4

/* The discretiser's counters on the device (uints): nodes reserved per level (level 0: the
 * tiles' roots; the last level: the leaves; tile depths up to VF_SDF_MAX_LEVELS - 1), then the
 * vertex and voxel records the leaves reserved. A kernel stores only what fits its capacities
 * and counts everything: a count above a capacity is an overflow, seen by the host. */
#define VF_SDF_MAX_LEVELS 9
#define VF_SDF_COUNT_VERTICES 9
#define VF_SDF_COUNT_VOXELS 10
#define VF_SDF_COUNTERS 11

/* Cell classes of the interval test. */
#define VF_SDF_CELL_EMPTY 0u
#define VF_SDF_CELL_FULL 1u
#define VF_SDF_CELL_AMBIGUOUS 2u

#endif
