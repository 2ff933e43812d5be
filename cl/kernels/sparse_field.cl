// Sparse worlds' bounded fields (cl/src/sparse_field.cpp): gathers tiles of a tile grid of
// 64-trees (the implicit-surface rendering blog's contrees, core/sparse.hpp) with their halos
// into dense blocks, scatters the transformed blocks' interiors into 64^3 field tiles, and
// takes each 16^3 node's minimum for ray skipping.
// Build options: ELEM (the field's element type), KEY_KIND (how KEY(v) reads a value's
// distance to the nearest solid, comparable in ELEM: 0 the value, 1 packed32's distance
// byte, 2 a signed value's positive part), ELEM_DOUBLE (1 for f64).

#if ELEM_DOUBLE
#pragma OPENCL EXTENSION cl_khr_fp64 : enable
#endif

#if KEY_KIND == 1
#define KEY(v) ((v) >> 8)
#elif KEY_KIND == 2
#define KEY(v) ((v) > (ELEM)0 ? (v) : (ELEM)0)
#else
#define KEY(v) (v)
#endif

#define TILE 64
#define TILE_VOXELS 262144
#define NO_TILE 0xFFFFFFFFFFFFFFFFul

// Set bits of m below bit b.
inline uint rank_below(ulong m, uint b) {
    return (uint)popcount(m & ((1ul << b) - 1ul));
}

// The material of tile-local voxel (x, y, z) of the tile whose nodes start at `base` and
// materials at `mbase` (0 for air): root -> 16^3 node -> 4^3 node -> voxel.
inline uchar lookup(__global const ulong* restrict masks, __global const uint* restrict offsets,
                    __global const uchar* restrict materials, ulong base, ulong mbase, uint x,
                    uint y, uint z) {
    const uint b16 = (z >> 4) << 4 | (y >> 4) << 2 | (x >> 4);
    const ulong root = masks[base];
    if ((root >> b16 & 1ul) == 0) {
        return 0;
    }
    const ulong n16 = base + offsets[base] + rank_below(root, b16);
    const uint b4 = ((z >> 2) & 3) << 4 | ((y >> 2) & 3) << 2 | ((x >> 2) & 3);
    const ulong m16 = masks[n16];
    if ((m16 >> b4 & 1ul) == 0) {
        return 0;
    }
    const ulong n4 = base + offsets[n16] + rank_below(m16, b4);
    const uint bv = (z & 3) << 4 | (y & 3) << 2 | (x & 3);
    const ulong m4 = masks[n4];
    if ((m4 >> bv & 1ul) == 0) {
        return 0;
    }
    return materials[mbase + offsets[n4] + rank_below(m4, bv)];
}

// A job is 8 longs: a block's (gather) or a region's (scatter) first voxel x, y, z; the
// first tile x, y, z of the tiles it overlaps; their counts (x | y << 16 | z << 32); its
// first entry in `refs` (gather: per tile, x fastest, its node base and material base,
// NO_TILE when not stored) or in `slots` (scatter: per tile, its field slot).

// One work-item per voxel of blocks bx x by x bz stacked along z (global z = block * bz + z):
// the world's voxel there (0 outside the world and in tiles that are not stored).
__kernel void gather(__global const ulong* restrict masks, __global const uint* restrict offsets,
                     __global const uchar* restrict materials, __global const long* restrict jobs,
                     __global const ulong* restrict refs, __global uchar* restrict vox, uint bx,
                     uint by, uint bz, long wx, long wy, long wz) {
    const uint x = (uint)get_global_id(0), y = (uint)get_global_id(1);
    const size_t gz = get_global_id(2);
    if (x >= bx) {
        return;
    }
    const size_t j = gz / bz;
    const uint z = (uint)(gz - j * bz);
    __global const long* job = jobs + 8 * j;
    const long px = job[0] + x, py = job[1] + y, pz = job[2] + z;
    uchar v = 0;
    if (px >= 0 && py >= 0 && pz >= 0 && px < wx && py < wy && pz < wz) {
        const long nt = job[6];
        const long ntx = nt & 0xFFFF, nty = (nt >> 16) & 0xFFFF;
        const long rx = (px >> 6) - job[3], ry = (py >> 6) - job[4], rz = (pz >> 6) - job[5];
        const size_t r = (size_t)(job[7] + (rz * nty + ry) * ntx + rx);
        const ulong base = refs[2 * r];
        if (base != NO_TILE) {
            v = lookup(masks, offsets, materials, base, refs[2 * r + 1], (uint)(px & 63),
                       (uint)(py & 63), (uint)(pz & 63));
        }
    }
    vox[(gz * by + y) * bx + x] = v;
}

// One work-item per voxel of the largest job region (sx x sy x sz, stacked along z per job):
// copies the transformed block's value into the field tile that holds the voxel. A job:
// region first voxel (ox, oy, oz), tile span and its slots from ref0; `regions` holds per
// job the region's size and the block's first voxel (6 longs).
__kernel void scatter(__global const ELEM* restrict field, __global ELEM* restrict pool,
                      __global const long* restrict jobs, __global const long* restrict regions,
                      __global const uint* restrict slots, uint bx, uint by, uint bz, uint sx,
                      uint sy, uint sz) {
    const uint x = (uint)get_global_id(0), y = (uint)get_global_id(1);
    const size_t gz = get_global_id(2);
    const size_t j = gz / sz;
    const uint z = (uint)(gz - j * sz);
    __global const long* job = jobs + 8 * j;
    __global const long* reg = regions + 6 * j;
    if (x >= sx || x >= reg[0] || y >= reg[1] || z >= reg[2]) {
        return;
    }
    const long px = job[0] + x, py = job[1] + y, pz = job[2] + z;
    const size_t in = ((j * bz + (size_t)(pz - reg[5])) * by + (size_t)(py - reg[4])) * bx +
                      (size_t)(px - reg[3]);
    const long nt = job[6];
    const long ntx = nt & 0xFFFF, nty = (nt >> 16) & 0xFFFF;
    const long rx = (px >> 6) - job[3], ry = (py >> 6) - job[4], rz = (pz >> 6) - job[5];
    const size_t slot = slots[job[7] + (rz * nty + ry) * ntx + rx];
    pool[slot * TILE_VOXELS + (size_t)(((pz & 63) * TILE + (py & 63)) * TILE + (px & 63))] =
        field[in];
}

// One work-item per 16^3 node of the listed slots: the least KEY over its voxels.
__kernel void node_minima(__global const ELEM* restrict pool, __global const uint* restrict slots,
                          uint count, __global ELEM* restrict minima) {
    const size_t i = get_global_id(0);
    if (i >= (size_t)count * 64) {
        return;
    }
    const size_t slot = slots[i / 64];
    const uint node = (uint)(i % 64);
    const uint x0 = (node & 3) * 16, y0 = ((node >> 2) & 3) * 16, z0 = (node >> 4) * 16;
    __global const ELEM* tile = pool + slot * TILE_VOXELS;
    ELEM best = KEY(tile[(z0 * TILE + y0) * TILE + x0]);
    for (uint z = 0; z < 16; ++z) {
        for (uint y = 0; y < 16; ++y) {
            __global const ELEM* row = tile + ((z0 + z) * TILE + y0 + y) * TILE + x0;
            for (uint x = 0; x < 16; ++x) {
                const ELEM k = KEY(row[x]);
                best = k < best ? k : best;
            }
        }
    }
    minima[slot * 64 + node] = best;
}
