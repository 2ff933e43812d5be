// A sparse world's tile of 64^3 voxels as a 64-tree (core/sparse.hpp's layout, the
// implicit-surface rendering blog's contree): constants and the leaf lookup shared by
// sparse_world.cl and sparse_field.cl, compiled before either.

#define TILE 64
#define TILE_VOXELS 262144
#define TILE_MAX_NODES 4161
#define NODE 16
#define NODE_VOXELS 4096
#define NO_TILE 0xFFFFFFFFFFFFFFFFul
#define SLOT_REF 0x8000000000000000ul

// Set bits of m below bit b.
inline uint rank_below(ulong m, uint b) {
    return (uint)popcount(m & ((1ul << b) - 1ul));
}

// The 4^3 leaf node that holds voxel (lx, ly, lz) of the tile tree at node `base` (its root
// mask `root`; masks m, offsets o), or NO_TILE when that leaf is empty.
inline ulong leaf_node(__global const ulong* m, __global const uint* o, ulong base, ulong root,
                       uint lx, uint ly, uint lz) {
    const uint b16 = (lz >> 4) << 4 | (ly >> 4) << 2 | (lx >> 4);
    if ((root >> b16 & 1ul) == 0) {
        return NO_TILE;
    }
    const ulong n16 = base + o[base] + rank_below(root, b16);
    const uint b4 = ((lz >> 2) & 3) << 4 | ((ly >> 2) & 3) << 2 | ((lx >> 2) & 3);
    const ulong m16 = m[n16];
    if ((m16 >> b4 & 1ul) == 0) {
        return NO_TILE;
    }
    return base + o[n16] + rank_below(m16, b4);
}
