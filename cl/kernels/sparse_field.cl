// Sparse worlds' bounded fields (cl/src/sparse_field.cpp): scatters the transformed blocks'
// interiors (gathered by sparse_world.cl's gather from a tile grid of 64-trees, the
// implicit-surface rendering blog's contrees) into 64^3 field tiles, and takes each 16^3
// node's minimum for ray skipping.
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

// scatter with one work-item per voxel (global ids x, y and job * sz + z of the largest region,
// sx x sy x sz): the GPU layout's, where neighbouring work-items copy neighbouring values.
__kernel void scatter_voxels(__global const ELEM* restrict field, __global ELEM* restrict pool,
                             __global const long* restrict jobs,
                             __global const long* restrict regions,
                             __global const uint* restrict slots, uint bx, uint by, uint bz,
                             uint sx, uint sy, uint sz) {
    const uint x = (uint)get_global_id(0), y = (uint)get_global_id(1);
    const size_t gz = get_global_id(2);
    const size_t j = gz / sz;
    const uint z = (uint)(gz - j * sz);
    __global const long* job = jobs + 8 * j;
    __global const long* reg = regions + 6 * j;
    if (x >= sx || y >= sy || x >= reg[0] || y >= reg[1] || z >= reg[2]) {
        return;
    }
    const long px = job[0] + x, py = job[1] + y, pz = job[2] + z;
    const long nt = job[6];
    const long ntx = nt & 0xFFFF, nty = (nt >> 16) & 0xFFFF;
    const size_t slot = slots[job[7] + (((pz >> 6) - job[5]) * nty + ((py >> 6) - job[4])) * ntx +
                              ((px >> 6) - job[3])];
    pool[slot * TILE_VOXELS + (size_t)(((pz & 63) * TILE + (py & 63)) * TILE + (px & 63))] =
        field[((j * bz + (size_t)(pz - reg[5])) * by + (size_t)(py - reg[4])) * bx +
              (size_t)(px - reg[3])];
}

// One work-item per 16^3 node of the listed slots: the least KEY over its voxels inside the
// world (a tile cut by the world's edge holds no values beyond it), starting from the far
// value, which no value exceeds. `tiles`: per listed slot its tile's coordinates (3 uints).
// Written per slot into `minima` and in list order into `listed` (one read for the host).
// Only the nodes set in `nodes` (per listed slot, bit z << 4 | y << 2 | x) are computed; the
// others keep their minima (copied into `listed`).
__kernel void node_minima(__global const ELEM* restrict pool, __global const uint* restrict slots,
                          __global const uint* restrict tiles, uint count,
                          __global ELEM* restrict minima, ELEM far, uint wx, uint wy, uint wz,
                          __global ELEM* restrict listed, __global const ulong* restrict nodes) {
    const size_t i = get_global_id(0);
    if (i >= (size_t)count * 64) {
        return;
    }
    const size_t slot = slots[i / 64];
    __global const uint* t = tiles + 3 * (i / 64);
    const uint node = (uint)(i % 64);
    if ((nodes[i / 64] >> node & 1ul) == 0) {
        listed[i] = minima[slot * 64 + node];
        return;
    }
    const uint x0 = (node & 3) * 16, y0 = ((node >> 2) & 3) * 16, z0 = (node >> 4) * 16;
    // Voxels of the node inside the world: [0, n) along each axis.
    const long ox = (long)t[0] * TILE + x0, oy = (long)t[1] * TILE + y0, oz = (long)t[2] * TILE + z0;
    const uint nx = (uint)clamp((long)wx - ox, 0l, 16l), ny = (uint)clamp((long)wy - oy, 0l, 16l),
               nz = (uint)clamp((long)wz - oz, 0l, 16l);
    __global const ELEM* tile = pool + slot * TILE_VOXELS;
    ELEM best = KEY(far);
    for (uint z = 0; z < nz; ++z) {
        for (uint y = 0; y < ny; ++y) {
            __global const ELEM* row = tile + ((z0 + z) * TILE + y0 + y) * TILE + x0;
            for (uint x = 0; x < nx; ++x) {
                const ELEM k = KEY(row[x]);
                best = k < best ? k : best;
            }
        }
    }
    minima[slot * 64 + node] = best;
    listed[i] = best;
}
