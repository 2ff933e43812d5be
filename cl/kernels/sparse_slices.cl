// A sparse field's edit block read straight from the world's 64-trees into the x and y passes of
// exact_manhattan.cl (GPU layout, unsigned L1): a work-group per z-slice of the block walks the
// trees as gather_quads (sparse_world.cl) does, but writes the slice into local memory as the
// sweeps' values (0 where solid, T_MAX where empty; no materials), then sweeps and stores it as
// xy_slice_local or xy_slice_segments does. One launch instead of the gather and the x and y
// pass. Compiled after sparse_tree.cl and exact_manhattan.cl, with the latter's options.
//
// The block: X x Y x bz voxels from the job's origin (jobs: gather_quads' 8 longs a block; refs:
// its tiles' node and material bases); slice g of the launch is z = g % bz of block g / bz.

// The solid bits of a quad's row of its 4^3 leaf (bits 0..3: x = px0..px0 + 3) at (px0, py,
// pz) of the world (wx, wy, wz), through the job's tile references; 0 outside the world or in
// an empty leaf.
inline uint quad_bits(__global const ulong* restrict masks, __global const uint* restrict offsets,
                      __global const ulong* restrict slot_masks,
                      __global const uint* restrict slot_offsets, __global const long* job,
                      __global const ulong* restrict refs, long px0, long py, long pz, long wx,
                      long wy, long wz) {
    if (px0 < 0 || py < 0 || pz < 0 || px0 >= wx || py >= wy || pz >= wz) {
        return 0;
    }
    const long nt = job[6];
    const uint ntx = (uint)(nt & 0xFFFF), nty = (uint)((nt >> 16) & 0xFFFF);
    const uint r = (uint)job[7] +
                   ((uint)((pz >> 6) - job[5]) * nty + (uint)((py >> 6) - job[4])) * ntx +
                   (uint)((px0 >> 6) - job[3]);
    ulong base = refs[2 * r];
    if (base == NO_TILE) {
        return 0;
    }
    const bool slot = (base & SLOT_REF) != 0;
    base &= ~SLOT_REF;
    __global const ulong* m = slot ? slot_masks : masks;
    __global const uint* o = slot ? slot_offsets : offsets;
    const ulong n4 =
        leaf_node(m, o, base, m[base], (uint)(px0 & 63), (uint)(py & 63), (uint)(pz & 63));
    if (n4 == NO_TILE) {
        return 0;
    }
    const uint row = (uint)((pz & 3) << 4 | (py & 3) << 2);
    uint bits = (uint)(m[n4] >> row) & 0xFu;
    // Voxels past the world's last x (a tile cut by its edge) are empty.
    const long past = px0 + 4 - wx;
    return past > 0 ? bits & (0xFu >> past) : bits;
}

// The work-group's slice from the trees into local memory (rows SX apart): quads of four voxels
// aligned in world x (X / 4 + 2 a row: a row's first and last may lie partly outside the
// block), four quads in flight per work-item before their stores.
inline void load_tree_slice(__global const ulong* restrict masks,
                            __global const uint* restrict offsets,
                            __global const ulong* restrict slot_masks,
                            __global const uint* restrict slot_offsets,
                            __global const long* restrict jobs, __global const ulong* restrict refs,
                            uint X, uint Y, uint bz, uint SX, long wx, long wy, long wz,
                            __local T* sl) {
    const uint lid = (uint)get_local_id(0), n = (uint)get_local_size(0);
    const uint g = (uint)get_group_id(0), b = g / bz, z = g - b * bz;
    __global const long* job = jobs + 8 * b;
    const long ox = job[0], qx = ox >> 2, pz = job[2] + z;
    const uint quads = X / 4 + 2, total = quads * Y;
    for (uint i = lid; i < total; i += 4 * n) {
        uint bits[4];
#pragma unroll
        for (uint u = 0; u < 4; ++u) {
            const uint k = i + u * n;
            const uint y = k / quads, q = k - y * quads;
            // A row's last quads may start past the block (and its tiles' references).
            bits[u] = k < total && (qx + q) * 4 - ox < (long)X
                          ? quad_bits(masks, offsets, slot_masks, slot_offsets, job, refs,
                                      (qx + q) * 4, job[1] + y, pz, wx, wy, wz)
                          : 0u;
        }
#pragma unroll
        for (uint u = 0; u < 4; ++u) {
            const uint k = i + u * n;
            const uint y = k / quads, q = k - y * quads;
            const long x0 = (qx + q) * 4 - ox;  // -3..X + 3
            for (uint v = 0; v < 4; ++v) {
                const long x = x0 + v;
                if (k < total && x >= 0 && x < (long)X) {
                    sl[y * SX + (uint)x] = (bits[u] >> v & 1u) != 0 ? (T)0 : (T)T_MAX;
                }
            }
        }
    }
}

__kernel void xy_tree_local(__global const ulong* restrict masks,
                            __global const uint* restrict offsets,
                            __global const ulong* restrict slot_masks,
                            __global const uint* restrict slot_offsets,
                            __global const long* restrict jobs, __global const ulong* restrict refs,
                            __global T* restrict work, uint X, uint Y, uint bz, uint SX, long wx,
                            long wy, long wz, __local T* sl) {
    load_tree_slice(masks, offsets, slot_masks, slot_offsets, jobs, refs, X, Y, bz, SX, wx, wy, wz,
                    sl);
    barrier(CLK_LOCAL_MEM_FENCE);
    sweep_and_store_lines(work, X, Y, SX, sl);
}

__kernel void xy_tree_segments(__global const ulong* restrict masks,
                               __global const uint* restrict offsets,
                               __global const ulong* restrict slot_masks,
                               __global const uint* restrict slot_offsets,
                               __global const long* restrict jobs,
                               __global const ulong* restrict refs, __global T* restrict work,
                               uint X, uint Y, uint bz, uint SX, long wx, long wy, long wz,
                               __local T* sl, __local T* ends) {
    load_tree_slice(masks, offsets, slot_masks, slot_offsets, jobs, refs, X, Y, bz, SX, wx, wy, wz,
                    sl);
    barrier(CLK_LOCAL_MEM_FENCE);
    sweep_and_store_segments(work, X, Y, SX, sl, ends);
}
