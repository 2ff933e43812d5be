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

// One work-item per row (along x) of blocks bx x by x bz stacked along z (global id 1 =
// block * bz + z): the world's voxels there (0 outside the world and in tiles that are not
// stored). Along a row, the tile is looked up once per 64 voxels and the leaf once per 4.
__kernel void gather(__global const ulong* restrict masks, __global const uint* restrict offsets,
                     __global const uchar* restrict materials, __global const long* restrict jobs,
                     __global const ulong* restrict refs, __global uchar* restrict vox, uint bx,
                     uint by, uint bz, long wx, long wy, long wz) {
    const uint y = (uint)get_global_id(0);
    const size_t gz = get_global_id(1);
    if (y >= by) {
        return;
    }
    const size_t j = gz / bz;
    const uint z = (uint)(gz - j * bz);
    __global const long* job = jobs + 8 * j;
    __global uchar* out = vox + (gz * by + y) * bx;
    const long py = job[1] + y, pz = job[2] + z;
    if (py < 0 || pz < 0 || py >= wy || pz >= wz) {
        for (uint x = 0; x < bx; ++x) {
            out[x] = 0;
        }
        return;
    }
    const long nt = job[6];
    const long ntx = nt & 0xFFFF, nty = (nt >> 16) & 0xFFFF;
    const long ry = (py >> 6) - job[4], rz = (pz >> 6) - job[5];
    const uint ly = (uint)(py & 63), lz = (uint)(pz & 63);
    uint x = 0;
    while (x < bx) {
        const long px = job[0] + x;
        if (px < 0 || px >= wx) {
            out[x++] = 0;
            continue;
        }
        // The voxels of this row in tile px >> 6.
        const uint lx0 = (uint)(px & 63);
        const uint end = min(bx, x + (TILE - lx0));
        const size_t r = (size_t)(job[7] + (rz * nty + ry) * ntx + ((px >> 6) - job[3]));
        const ulong base = refs[2 * r];
        if (base == NO_TILE) {
            for (; x < end; ++x) {
                out[x] = 0;
            }
            continue;
        }
        const ulong mbase = refs[2 * r + 1];
        const ulong root = masks[base];
        for (uint lx = lx0; x < end; lx += 4) {
            // The leaf of voxels lx..lx+3 (from lx0, which may not be a multiple of 4).
            const uint group_end = min(end, x + (4 - (lx & 3)));
            ulong m4 = 0, first = 0;
            const uint b16 = (lz >> 4) << 4 | (ly >> 4) << 2 | (lx >> 4);
            if ((root >> b16 & 1ul) != 0) {
                const ulong n16 = base + offsets[base] + rank_below(root, b16);
                const uint b4 = ((lz >> 2) & 3) << 4 | ((ly >> 2) & 3) << 2 | ((lx >> 2) & 3);
                const ulong m16 = masks[n16];
                if ((m16 >> b4 & 1ul) != 0) {
                    const ulong n4 = base + offsets[n16] + rank_below(m16, b4);
                    m4 = masks[n4];
                    first = mbase + offsets[n4];
                }
            }
            for (uint v = lx & 3; x < group_end; ++x, ++v) {
                const uint bv = (lz & 3) << 4 | (ly & 3) << 2 | v;
                out[x] = (m4 >> bv & 1ul) != 0 ? materials[first + rank_below(m4, bv)] : 0;
            }
            lx &= ~3u;
        }
    }
}

// One work-item per row (along x) of the largest job region (sy x sz rows, stacked along z
// per job): copies the transformed block's values into the field tiles that hold them. A
// job: its region's first voxel, tile span and first entry in `slots` (per tile, x
// fastest, its field slot); `regions` holds per job the region's size and the block's first
// voxel (6 longs).
__kernel void scatter(__global const ELEM* restrict field, __global ELEM* restrict pool,
                      __global const long* restrict jobs, __global const long* restrict regions,
                      __global const uint* restrict slots, uint bx, uint by, uint bz, uint sy,
                      uint sz) {
    const uint y = (uint)get_global_id(0);
    const size_t gz = get_global_id(1);
    const size_t j = gz / sz;
    const uint z = (uint)(gz - j * sz);
    __global const long* job = jobs + 8 * j;
    __global const long* reg = regions + 6 * j;
    if (y >= sy || y >= reg[1] || z >= reg[2]) {
        return;
    }
    const long py = job[1] + y, pz = job[2] + z;
    __global const ELEM* in =
        field + ((j * bz + (size_t)(pz - reg[5])) * by + (size_t)(py - reg[4])) * bx;
    const long nt = job[6];
    const long ntx = nt & 0xFFFF, nty = (nt >> 16) & 0xFFFF;
    const long ry = (py >> 6) - job[4], rz = (pz >> 6) - job[5];
    const size_t row = (size_t)(((pz & 63) * TILE + (py & 63)) * TILE);
    for (long px = job[0]; px < job[0] + reg[0];) {
        const long end = min(job[0] + reg[0], (px | 63) + 1);
        const size_t slot = slots[job[7] + (rz * nty + ry) * ntx + ((px >> 6) - job[3])];
        __global ELEM* dst = pool + slot * TILE_VOXELS + row;
        for (; px < end; ++px) {
            dst[px & 63] = in[px - reg[3]];
        }
    }
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
