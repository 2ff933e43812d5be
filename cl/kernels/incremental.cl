// Exact incremental update of a global Manhattan field after edits (ours; see
// cl/include/voxfield/cl/incremental.hpp for the method and why it is exact).
//
// `dist` holds exact distances (uint, VF_FAR where no solid exists; classic_common.cl's
// vf_encode saturates it), capped at the bound of a bounded field (its values are then
// min(exact, cap), and every update keeps them so). Boxes are int4 with w unused; b_lo/b_hi is the
// edit's changed box B (half-open).

#define VF_FAR 0xFFFFFFFFu

inline uint vf_sat_inc(uint v) {
    return v + (v != VF_FAR ? 1u : 0u);
}

// The distance from p to the sources of a box field f over the box [b_lo, b_hi) (x fastest;
// VF_FAR without a source): per axis outside the box, |p - s| splits at its face for every s
// inside, so it is L1(p, box) plus f at p clamped into the box.
inline uint vf_reach(global const uint* f, int3 p, int4 b_lo, int4 b_hi) {
    const int3 bs = b_hi.xyz - b_lo.xyz;
    const int3 c = clamp(p, b_lo.xyz, b_hi.xyz - (int3)(1));
    const int3 o = c - b_lo.xyz;
    const uint3 g = abs(p - c);
    return add_sat(f[(o.z * bs.y + o.y) * bs.x + o.x], g.x + g.y + g.z);
}

// Per axis the gap between the voxels [v_lo, v_hi) and the box [b_lo, b_hi) (0 where they
// overlap): its sum is the L1 distance between the two.
inline int3 vf_gap(int3 v_lo, int3 v_hi, int4 b_lo, int4 b_hi) {
    return max(max(b_lo.xyz - v_hi + (int3)(1), v_lo - b_hi.xyz + (int3)(1)), (int3)(0));
}

// Whether block b lies on a face of the cap box of blocks [lo, lo + size) that the margin (not
// the world's edge, nb blocks) cut: a region reaching it may reach further (overflow).
inline bool vf_on_cut_face(int3 b, int4 lo, int4 size, int4 nb) {
    const int3 cap_hi = lo.xyz + size.xyz;
    return any(b == lo.xyz && lo.xyz > (int3)(0)) ||
           any(b == cap_hi - (int3)(1) && cap_hi < nb.xyz);
}

// The least f over the part of the box's boundary that the voxels of [v_lo, v_hi) clamp to:
// per axis wholly below the box (0), across it (1) or wholly above (2); the 27 minima follow
// f's voxels.
inline uint vf_least(global const uint* f, int3 v_lo, int3 v_hi, int4 b_lo, int4 b_hi) {
    const int3 bs = b_hi.xyz - b_lo.xyz;
    const int3 side =
        select(select((int3)(1), (int3)(2), v_lo >= b_hi.xyz), (int3)(0), v_hi <= b_lo.xyz);
    return f[bs.x * bs.y * bs.z + (side.z * 3 + side.y) * 3 + side.x];
}

// This work-item's share of an edit's `count` voxel changes from changes + 2 * first
// (changes[2k] = linear index, changes[2k+1] = value), over the launch's range.
inline void vf_scatter_share(global uchar* vox, global const uint* changes, uint first,
                             uint count) {
    const size_t n = get_global_size(0) * get_global_size(1) * get_global_size(2);
    const size_t id =
        get_global_id(0) +
        get_global_size(0) * (get_global_id(1) + get_global_size(1) * get_global_id(2));
    for (size_t k = id; k < count; k += n) {
        vox[changes[2 * (first + k)]] = (uchar)changes[2 * (first + k) + 1];
    }
}

// Writes the edit's new voxel values: changes[2k] = linear index, changes[2k+1] = value.
kernel void inc_scatter(global uchar* vox, global const uint* changes, uint first, uint count) {
    vf_scatter_share(vox, changes, first, count);
}

// Per-block maxima of `dist` (VF_BLOCK^3 voxels per block) bound the voxels that an edit can
// change from outside. With C the voxels whose occupancy the edit changed, inside its box B,
// a voxel p changes only where dist(p) >= d_C(p) (placed solids lower it only if nearer than
// the old nearest; erased ones raise it only where they were the nearest), and d_C(p) =
// vf_reach of the box field of C. `regions + 8 * slot` holds the edit's box W of those
// voxels, R, stored so that zero is the neutral start and atomic_max accumulates it:
// {d.x - W.lo.x, d.y - W.lo.y, d.z - W.lo.z, W.hi.x, W.hi.y, W.hi.z, overflow}.
#define VF_BLOCK 8

inline int4 vf_blocks(int4 d) {
    return (d + (int4)(VF_BLOCK - 1)) / (int4)(VF_BLOCK);
}

// inc_block_max, inc_bounds and inc_place have two layouts over the blocks of a box
// [lo, lo + size) (x fastest), sharing the work of a block's rows (VF_BLOCK^2 rows, row r at
// y, z offsets r % VF_BLOCK, r / VF_BLOCK):
// - GPU: work-groups of VF_ROWS work-items. In inc_bounds and inc_place a work-group takes
//   `per_group` (at most VF_GROUP) blocks: one work-item tests each block (whether the edit
//   can reach it), the blocks that pass are gathered, and every work-item takes its row of
//   each of them, so a block's rows run side by side. inc_block_max instead splits the
//   work-items among its per_group (at most VF_ROWS) blocks, which each of a block's
//   work-items tests against W itself: per_group = VF_ROWS is a work-item per block.
// - CPU (the _seq kernels): a work-item per block over a 3-D range, its rows in sequence, no
//   barriers (PoCL runs a work-group's work-items one after another: local reductions and
//   work-groups of one both cost it 20-40% per unbounded update at 256^3).
#define VF_ROWS (VF_BLOCK * VF_BLOCK)
// VF_GROUP: a build option, the host's kGroupBlocks.

inline int3 vf_block_at(int i, int4 lo, int4 size) {
    return lo.xyz + (int3)(i % size.x, i / size.x % size.y, i / (size.x * size.y));
}

// The block at 3-D global id in the box [lo, lo + size) of blocks (the _seq kernels), or
// false outside it.
inline bool vf_seq_block(int4 lo, int4 size, int3* b) {
    const int3 g = (int3)((int)get_global_id(0), (int)get_global_id(1), (int)get_global_id(2));
    *b = lo.xyz + g;
    return all(g < size.xyz);
}

// Accumulates the voxel box [lo, hi] into the edit's W at r (regions' encoding).
inline void vf_region_add(global int* r, int4 d, int3 lo, int3 hi) {
    atomic_max(&r[0], d.x - lo.x);
    atomic_max(&r[1], d.y - lo.y);
    atomic_max(&r[2], d.z - lo.z);
    atomic_max(&r[3], hi.x + 1);
    atomic_max(&r[4], hi.y + 1);
    atomic_max(&r[5], hi.z + 1);
}

// Empties a work-group's list of the blocks that passed its test (before any work-item
// appends to it).
inline void vf_gather_start(local int* n_cand) {
    if (get_local_id(0) == 0) {
        *n_cand = 0;
    }
    barrier(CLK_LOCAL_MEM_FENCE);
}

// The maximum of `dist` over a block's row (y, z), x in [x0, x1).
inline uint vf_row_max(global const uint* dist, int4 d, int x0, int x1, int y, int z) {
    const int row = (z * d.y + y) * d.x;
    uint m = 0;
    for (int x = x0; x < x1; ++x) {
        m = max(m, dist[row + x]);
    }
    return m;
}

// Whether block b lies in the edit's W (slot < 0: every block does).
inline bool vf_in_w(int3 b, int4 d, global const int* regions, int slot) {
    if (slot < 0) {
        return true;
    }
    global const int* r = regions + 8 * slot;
    const int3 w_lo = d.xyz - (int3)(r[0], r[1], r[2]);
    const int3 w_hi = (int3)(r[3], r[4], r[5]);
    return !any(b * VF_BLOCK >= w_hi) && !any((b + 1) * VF_BLOCK <= w_lo);
}

// inc_block_max's CPU layout.
kernel void inc_block_max_seq(global const uint* dist, global uint* block_max, int4 d, int4 lo,
                              int4 size, global const int* regions, int slot) {
    int3 b;
    if (!vf_seq_block(lo, size, &b) || !vf_in_w(b, d, regions, slot)) {
        return;
    }
    const int3 v_lo = b * VF_BLOCK;
    const int3 v_hi = min(v_lo + (int3)(VF_BLOCK), d.xyz);
    uint m = 0;
    for (int z = v_lo.z; z < v_hi.z; ++z) {
        for (int y = v_lo.y; y < v_hi.y; ++y) {
            m = max(m, vf_row_max(dist, d, v_lo.x, v_hi.x, y, z));
        }
    }
    const int4 nb = vf_blocks(d);
    block_max[(b.z * nb.y + b.y) * nb.x + b.x] = m;
}

// The maximum over each block of the box [lo, lo + size) of blocks; with slot >= 0 only over
// the blocks of the edit's W (the others did not change). Each block takes L / per_group of
// the L work-items, which share its rows (per_group = L: a work-item per block).
kernel void inc_block_max(global const uint* dist, global uint* block_max, int4 d, int4 lo,
                          int4 size, global const int* regions, int slot, int per_group) {
    local uint bm[VF_ROWS];
    const int lid = (int)get_local_id(0);
    const int per_block = max(1, (int)get_local_size(0) / per_group);
    const int j = lid / per_block;
    const int i = (int)get_group_id(0) * per_group + j;
    const int3 b = vf_block_at(i, lo, size);
    const bool changed =
        j < per_group && i < size.x * size.y * size.z && vf_in_w(b, d, regions, slot);
    if (changed && lid % per_block == 0) {
        bm[j] = 0;
    }
    barrier(CLK_LOCAL_MEM_FENCE);
    if (changed) {
        const int3 v_lo = b * VF_BLOCK;
        const int3 v_hi = min(v_lo + (int3)(VF_BLOCK), d.xyz);
        uint m = 0;
        for (int rr = lid % per_block; rr < VF_ROWS; rr += per_block) {
            const int y = v_lo.y + rr % VF_BLOCK, z = v_lo.z + rr / VF_BLOCK;
            if (y >= v_hi.y || z >= v_hi.z) {
                continue;
            }
            m = max(m, vf_row_max(dist, d, v_lo.x, v_hi.x, y, z));
        }
        atomic_max(&bm[j], m);
    }
    barrier(CLK_LOCAL_MEM_FENCE);
    if (changed && lid % per_block == 0) {
        const int4 nb = vf_blocks(d);
        block_max[(b.z * nb.y + b.y) * nb.x + b.x] = bm[j];
    }
}

// A block-local box of voxels in local memory: acc[0..2] the least x, y, z, acc[3..5] the
// greatest (empty while acc[3] < 0), gathered from each work-item's own box.
inline void vf_box_clear(local int* acc) {
    for (int a = 0; a < 3; ++a) {
        acc[a] = INT_MAX;
        acc[3 + a] = -1;
    }
}

inline void vf_box_add(local int* acc, int3 lo, int3 hi) {
    if (hi.x >= 0) {
        atomic_min(&acc[0], lo.x);
        atomic_min(&acc[1], lo.y);
        atomic_min(&acc[2], lo.z);
        atomic_max(&acc[3], hi.x);
        atomic_max(&acc[4], hi.y);
        atomic_max(&acc[5], hi.z);
    }
}

// Accumulates a block's box into the edit's W (regions' encoding, see above).
inline void vf_box_to_region(local const int* acc, global int* r, int4 d) {
    vf_region_add(r, d, (int3)(acc[0], acc[1], acc[2]), (int3)(acc[3], acc[4], acc[5]));
}

// The least reach over block b's voxels of the box field f of B: its L1 gap to B plus the
// least f where its voxels clamp to.
inline uint vf_block_reach(int3 b, int4 d, global const uint* f, int4 b_lo, int4 b_hi) {
    const int3 v_lo = b * VF_BLOCK;
    const int3 v_hi = min(v_lo + (int3)(VF_BLOCK), d.xyz);
    const int3 gap = vf_gap(v_lo, v_hi, b_lo, b_hi);
    return add_sat((uint)(gap.x + gap.y + gap.z), vf_least(f, v_lo, v_hi, b_lo, b_hi));
}

// The box field's row at row (y, z) clamped into B [b_lo, b_hi), and the L1 offset of (y, z)
// from it: vf_reach along a row is then add_sat(fr[clamp(x) - b_lo.x], yz + |x - clamp(x)|).
inline global const uint* vf_field_row(global const uint* f, int4 b_lo, int4 b_hi, int y, int z,
                                       uint* yz) {
    const int cz = clamp(z, b_lo.z, b_hi.z - 1);
    const int cy = clamp(y, b_lo.y, b_hi.y - 1);
    *yz = (uint)(abs(z - cz) + abs(y - cy));
    return f + ((cz - b_lo.z) * (b_hi.y - b_lo.y) + (cy - b_lo.y)) * (b_hi.x - b_lo.x);
}

// inc_bounds' row (y, z) of a block, its n voxels from x0: grows [*r_lo, *r_hi] by the row's
// voxels in R (old distance >= vf_reach of the box field f).
inline void vf_bounds_row(global const uint* dist, global const uint* f, int4 d, int4 b_lo,
                          int4 b_hi, int x0, int n, int y, int z, int3* r_lo, int3* r_hi) {
    uint yz;
    global const uint* fr = vf_field_row(f, b_lo, b_hi, y, z, &yz);
    const int row = (z * d.y + y) * d.x + x0;
    uint in_r = 0;  // bit k: x = x0 + k lies in R
    for (int k = 0; k < n; ++k) {
        const int x = x0 + k;
        const int cx = clamp(x, b_lo.x, b_hi.x - 1);
        const uint reach = add_sat(fr[cx - b_lo.x], yz + (uint)abs(x - cx));
        in_r |= (dist[row + k] >= reach ? 1u : 0u) << k;
    }
    if (in_r != 0) {
        *r_lo = min(*r_lo, (int3)(x0 + 31 - (int)clz(in_r & (~in_r + 1u)), y, z));
        *r_hi = max(*r_hi, (int3)(x0 + 31 - (int)clz(in_r), y, z));
    }
}

// W: the bounding box of R within the cap box of blocks [lo, lo + size) (B grown by the
// margin): blocks whose maximum stays below the least d_C over them are skipped, the others
// test each voxel. R in a block on a face of the cap box that the margin (not the world) cut
// sets overflow: R may reach further. It also writes the edit's `count` voxel changes from
// changes + 2 * first into `vox` (as inc_scatter; it reads no voxel values itself).
kernel void inc_bounds(global const uint* dist, global const uint* block_max,
                       global const uint* fbox, uint f_off, int4 d, int4 b_lo, int4 b_hi, int4 lo,
                       int4 size, global int* regions, int slot, global uchar* vox,
                       global const uint* changes, uint first, uint count, int per_group) {
    local int acc[VF_GROUP][6];
    local int cand[VF_GROUP];
    local int n_cand;
    const int lid = (int)get_local_id(0);
    const int4 nb = vf_blocks(d);
    global const uint* f = fbox + f_off;
    vf_scatter_share(vox, changes, first, count);
    vf_gather_start(&n_cand);
    const int i = (int)get_group_id(0) * per_group + lid;
    if (lid < per_group && i < size.x * size.y * size.z) {
        const int3 b = vf_block_at(i, lo, size);
        if (block_max[(b.z * nb.y + b.y) * nb.x + b.x] >= vf_block_reach(b, d, f, b_lo, b_hi)) {
            const int j = atomic_inc(&n_cand);
            cand[j] = i;
            vf_box_clear(acc[j]);
        }
    }
    barrier(CLK_LOCAL_MEM_FENCE);
    for (int j = 0; j < n_cand; ++j) {
        const int3 v_lo = vf_block_at(cand[j], lo, size) * VF_BLOCK;
        const int3 v_hi = min(v_lo + (int3)(VF_BLOCK), d.xyz);
        int3 r_lo = (int3)(INT_MAX), r_hi = (int3)(-1);
        const int n = v_hi.x - v_lo.x;
        for (int rr = lid; rr < VF_ROWS; rr += (int)get_local_size(0)) {
            const int y = v_lo.y + rr % VF_BLOCK, z = v_lo.z + rr / VF_BLOCK;
            if (y >= v_hi.y || z >= v_hi.z) {
                continue;
            }
            vf_bounds_row(dist, f, d, b_lo, b_hi, v_lo.x, n, y, z, &r_lo, &r_hi);
        }
        vf_box_add(acc[j], r_lo, r_hi);
    }
    barrier(CLK_LOCAL_MEM_FENCE);
    if (lid < n_cand && acc[lid][3] >= 0) {
        global int* r = regions + 8 * slot;
        vf_box_to_region(acc[lid], r, d);
        if (vf_on_cut_face(vf_block_at(cand[lid], lo, size), lo, size, nb)) {
            atomic_max(&r[6], 1);
        }
    }
}

// inc_place's row (y, z) of a block, its n voxels from x0: lowers them to min(old, d_B) and
// writes those that changed, with the span between (unchanged ones there keep their value),
// to `dist` and, encoded, to `out`; grows [*c_lo, *c_hi] by the changed voxels. Returns the
// row's new maximum.
inline uint vf_place_row(global const uchar* vox, global uint* dist, global const uchar* rgb,
                         global OUT_T* out, global const uint* f, int4 d, int4 b_lo, int4 b_hi,
                         int x0, int n, int y, int z, int3* c_lo, int3* c_hi) {
    uint yz;
    global const uint* fr = vf_field_row(f, b_lo, b_hi, y, z, &yz);
    const int row = (z * d.y + y) * d.x + x0;
    uint changed = 0;  // bit k: x = x0 + k
    uint nv[VF_BLOCK];
    uint m = 0;
    for (int k = 0; k < n; ++k) {
        const int x = x0 + k;
        const int cx = clamp(x, b_lo.x, b_hi.x - 1);
        const uint cand = add_sat(fr[cx - b_lo.x], yz + (uint)abs(x - cx));
        const uint old = dist[row + k];
        changed |= (cand < old ? 1u : 0u) << k;
        nv[k] = min(old, cand);
        m = max(m, nv[k]);
    }
    if (changed != 0) {
        const int lo_k = 31 - (int)clz(changed & (~changed + 1u));
        const int hi_k = 31 - (int)clz(changed);
        for (int k = lo_k; k <= hi_k; ++k) {
            dist[row + k] = nv[k];
#if PACKED
            out[row + k] = vf_encode(nv[k], vox[row + k], rgb);
#else
            out[row + k] = vf_encode(nv[k], 0, rgb);  // no voxel value is read (see inc_place)
#endif
        }
        *c_lo = min(*c_lo, (int3)(x0 + lo_k, y, z));
        *c_hi = max(*c_hi, (int3)(x0 + hi_k, y, z));
    }
    return m;
}

// inc_bounds' CPU layout.
kernel void inc_bounds_seq(global const uint* dist, global const uint* block_max,
                           global const uint* fbox, uint f_off, int4 d, int4 b_lo, int4 b_hi,
                           int4 lo, int4 size, global int* regions, int slot, global uchar* vox,
                           global const uint* changes, uint first, uint count) {
    vf_scatter_share(vox, changes, first, count);
    int3 b;
    if (!vf_seq_block(lo, size, &b)) {
        return;
    }
    const int4 nb = vf_blocks(d);
    global const uint* f = fbox + f_off;
    if (block_max[(b.z * nb.y + b.y) * nb.x + b.x] < vf_block_reach(b, d, f, b_lo, b_hi)) {
        return;
    }
    const int3 v_lo = b * VF_BLOCK;
    const int3 v_hi = min(v_lo + (int3)(VF_BLOCK), d.xyz);
    int3 r_lo = (int3)(INT_MAX), r_hi = (int3)(-1);
    for (int z = v_lo.z; z < v_hi.z; ++z) {
        for (int y = v_lo.y; y < v_hi.y; ++y) {
            vf_bounds_row(dist, f, d, b_lo, b_hi, v_lo.x, v_hi.x - v_lo.x, y, z, &r_lo, &r_hi);
        }
    }
    if (r_hi.x < 0) {
        return;
    }
    global int* r = regions + 8 * slot;
    vf_region_add(r, d, r_lo, r_hi);
    if (vf_on_cut_face(b, lo, size, nb)) {
        atomic_max(&r[6], 1);
    }
}

// An edit that only places solids: the new distance is min(old, d_B(p)), d_B the distance to
// the solids inside the edit's changed box B (an old solid there is already counted in the
// old distance, and every solid outside B is). Per axis outside B, |p - s| splits at B's face
// for every s in B, so d_B(p) = L1(p, B) + f(clamp(p, B)) with f = d_B inside B, which the
// host computed: fbox[f_off ...], B's voxels x fastest, then the least f over each part of B's
// boundary (27 entries, vf_least). Over the blocks of the cap box [lo, lo + size): a block
// can change only where its old maximum exceeds the least candidate
// d_B over it, at least its L1 distance to B plus the least f where its voxels clamp to. Each
// row computes its new values and change mask first, then writes the span of changed voxels
// (those between unchanged ones keep their value). Writes the lowered distances, the block's
// new maximum, and the box of the changed voxels into regions + 8 * slot (inc_bounds'
// encoding, overflow when a candidate block lies on a face of the cap box that the margin
// cut; [7] counts the voxels read). It also writes the edit's `count` changes from
// changes + 2 * first into `vox`, as inc_scatter does, unordered with the other work-groups'
// reads of `vox`: the host passes none where the output format reads voxel values (packed32),
// and scatters them before.
kernel void inc_place(global uchar* vox, global uint* dist, global const uchar* rgb,
                      global OUT_T* out, global uint* block_max, global const uint* fbox,
                      uint f_off, int4 d, int4 b_lo, int4 b_hi, int4 lo, int4 size,
                      global int* regions, int slot, global const uint* changes, uint first,
                      uint count, int per_group) {
    local int acc[VF_GROUP][6];
    local uint block_m[VF_GROUP];
    local int cand[VF_GROUP];
    local int n_cand;
    const int lid = (int)get_local_id(0);
    const int4 nb = vf_blocks(d);
    global const uint* f = fbox + f_off;
    global int* r = regions + 8 * slot;
    vf_scatter_share(vox, changes, first, count);
    vf_gather_start(&n_cand);
    const int i = (int)get_group_id(0) * per_group + lid;
    if (lid < per_group && i < size.x * size.y * size.z) {
        const int3 b = vf_block_at(i, lo, size);
        if (block_max[(b.z * nb.y + b.y) * nb.x + b.x] > vf_block_reach(b, d, f, b_lo, b_hi)) {
            const int j = atomic_inc(&n_cand);
            cand[j] = i;
            vf_box_clear(acc[j]);
            block_m[j] = 0;
            if (vf_on_cut_face(b, lo, size, nb)) {
                atomic_max(&r[6], 1);
            }
            const int3 v_lo = b * VF_BLOCK;
            const int3 v_hi = min(v_lo + (int3)(VF_BLOCK), d.xyz);
            atomic_add(&r[7], (v_hi.x - v_lo.x) * (v_hi.y - v_lo.y) * (v_hi.z - v_lo.z));
        }
    }
    barrier(CLK_LOCAL_MEM_FENCE);
    for (int j = 0; j < n_cand; ++j) {
        const int3 v_lo = vf_block_at(cand[j], lo, size) * VF_BLOCK;
        const int3 v_hi = min(v_lo + (int3)(VF_BLOCK), d.xyz);
        int3 c_lo = (int3)(INT_MAX), c_hi = (int3)(-1);
        uint m = 0;
        const int n = v_hi.x - v_lo.x;
        for (int rr = lid; rr < VF_ROWS; rr += (int)get_local_size(0)) {
            const int y = v_lo.y + rr % VF_BLOCK, z = v_lo.z + rr / VF_BLOCK;
            if (y >= v_hi.y || z >= v_hi.z) {
                continue;
            }
            m = max(m, vf_place_row(vox, dist, rgb, out, f, d, b_lo, b_hi, v_lo.x, n, y, z, &c_lo,
                                    &c_hi));
        }
        atomic_max(&block_m[j], m);
        vf_box_add(acc[j], c_lo, c_hi);
    }
    barrier(CLK_LOCAL_MEM_FENCE);
    if (lid < n_cand) {
        const int3 b = vf_block_at(cand[lid], lo, size);
        block_max[(b.z * nb.y + b.y) * nb.x + b.x] = block_m[lid];
        if (acc[lid][3] >= 0) {
            vf_box_to_region(acc[lid], r, d);
        }
    }
}

// inc_place's CPU layout.
kernel void inc_place_seq(global uchar* vox, global uint* dist, global const uchar* rgb,
                          global OUT_T* out, global uint* block_max, global const uint* fbox,
                          uint f_off, int4 d, int4 b_lo, int4 b_hi, int4 lo, int4 size,
                          global int* regions, int slot, global const uint* changes, uint first,
                          uint count) {
    vf_scatter_share(vox, changes, first, count);
    int3 b;
    if (!vf_seq_block(lo, size, &b)) {
        return;
    }
    const int4 nb = vf_blocks(d);
    global const uint* f = fbox + f_off;
    const int bi = (b.z * nb.y + b.y) * nb.x + b.x;
    if (block_max[bi] <= vf_block_reach(b, d, f, b_lo, b_hi)) {
        return;
    }
    global int* r = regions + 8 * slot;
    if (vf_on_cut_face(b, lo, size, nb)) {
        atomic_max(&r[6], 1);
    }
    const int3 v_lo = b * VF_BLOCK;
    const int3 v_hi = min(v_lo + (int3)(VF_BLOCK), d.xyz);
    atomic_add(&r[7], (v_hi.x - v_lo.x) * (v_hi.y - v_lo.y) * (v_hi.z - v_lo.z));
    int3 c_lo = (int3)(INT_MAX), c_hi = (int3)(-1);
    uint m = 0;
    for (int z = v_lo.z; z < v_hi.z; ++z) {
        for (int y = v_lo.y; y < v_hi.y; ++y) {
            m = max(m, vf_place_row(vox, dist, rgb, out, f, d, b_lo, b_hi, v_lo.x, v_hi.x - v_lo.x,
                                    y, z, &c_lo, &c_hi));
        }
    }
    block_max[bi] = m;
    if (c_hi.x >= 0) {
        vf_region_add(r, d, c_lo, c_hi);
    }
}

// W grown by the one-voxel ring whose old values are sources, clipped to the world.
inline void inc_ring(global const int* region, int4 d, int3* lo, int3* hi) {
    *lo = max(d.xyz - (int3)(region[0], region[1], region[2]) - (int3)(1), (int3)(0));
    *hi = min((int3)(region[3], region[4], region[5]) + (int3)(1), d.xyz);
}

// Sources and the x sweeps: tmp = min over x' of g(x') + |x - x'| along each row of the
// ring box, g = 0 at solids, the old distance outside R, VF_FAR inside R (R as inc_bounds
// tests it, from the box field at fbox + f_off). Work-items cover the rows of the cap box (the
// largest W the margin allows) and skip rows outside W.
kernel void inc_sweep_x(global const uchar* vox, global const uint* dist, global uint* tmp,
                        global const int* regions, int slot, int4 d, int4 b_lo, int4 b_hi,
                        global const uint* fbox, uint f_off, int4 cap_lo, int4 cap_size) {
    global const int* region = regions + 8 * slot;
    int3 lo, hi;
    inc_ring(region, d, &lo, &hi);
    const int y = cap_lo.y + (int)get_global_id(0), z = cap_lo.z + (int)get_global_id(1);
    if ((int)get_global_id(0) >= cap_size.y || (int)get_global_id(1) >= cap_size.z || y < lo.y ||
        y >= hi.y || z < lo.z || z >= hi.z) {
        return;
    }
    const int row = (z * d.y + y) * d.x;
    uint run = VF_FAR;
    for (int x = lo.x; x < hi.x; ++x) {
        const int3 p = (int3)(x, y, z);
        const uint old = dist[row + x];
        const uint g = vox[row + x] != 0                             ? 0u
                       : old < vf_reach(fbox + f_off, p, b_lo, b_hi) ? old
                                                                     : VF_FAR;
        run = min(g, vf_sat_inc(run));
        tmp[row + x] = run;
    }
    run = VF_FAR;
    for (int x = hi.x - 1; x >= lo.x; --x) {
        run = min(tmp[row + x], vf_sat_inc(run));
        tmp[row + x] = run;
    }
}

// y sweeps over the columns of the ring box.
kernel void inc_sweep_y(global uint* tmp, global const int* regions, int slot, int4 d, int4 cap_lo,
                        int4 cap_size) {
    global const int* region = regions + 8 * slot;
    int3 lo, hi;
    inc_ring(region, d, &lo, &hi);
    const int x = cap_lo.x + (int)get_global_id(0), z = cap_lo.z + (int)get_global_id(1);
    if ((int)get_global_id(0) >= cap_size.x || (int)get_global_id(1) >= cap_size.z || x < lo.x ||
        x >= hi.x || z < lo.z || z >= hi.z) {
        return;
    }
    const int base = z * d.y * d.x + x;
    uint run = VF_FAR;
    for (int y = lo.y; y < hi.y; ++y) {
        run = min(tmp[base + y * d.x], vf_sat_inc(run));
        tmp[base + y * d.x] = run;
    }
    run = VF_FAR;
    for (int y = hi.y - 1; y >= lo.y; --y) {
        run = min(tmp[base + y * d.x], vf_sat_inc(run));
        tmp[base + y * d.x] = run;
    }
}

// z sweeps, then the new distances of W (not the ring, whose values were sources), capped at
// `cap` (a bounded field's bound, VF_FAR when unbounded: min-plus sweeps commute with the
// cap), replace the old ones where they differ, in `dist` and in the output format.
kernel void inc_sweep_z(global const uchar* vox, global uint* dist, global uint* tmp,
                        global const uchar* rgb, global OUT_T* out, global const int* regions,
                        int slot, int4 d, int4 cap_lo, int4 cap_size, uint cap) {
    global const int* region = regions + 8 * slot;
    int3 lo, hi;
    inc_ring(region, d, &lo, &hi);
    const int x = cap_lo.x + (int)get_global_id(0), y = cap_lo.y + (int)get_global_id(1);
    if ((int)get_global_id(0) >= cap_size.x || (int)get_global_id(1) >= cap_size.y || x < lo.x ||
        x >= hi.x || y < lo.y || y >= hi.y) {
        return;
    }
    const int plane = d.x * d.y;
    const int base = y * d.x + x;
    uint run = VF_FAR;
    for (int z = lo.z; z < hi.z; ++z) {
        run = min(tmp[base + z * plane], vf_sat_inc(run));
        tmp[base + z * plane] = run;
    }
    const int3 w_lo = d.xyz - (int3)(region[0], region[1], region[2]);
    const bool in_w_xy = x >= w_lo.x && x < region[3] && y >= w_lo.y && y < region[4];
    run = VF_FAR;
    for (int z = hi.z - 1; z >= lo.z; --z) {
        const int i = base + z * plane;
        run = min(tmp[i], vf_sat_inc(run));
        const uint v = min(run, cap);
        if (in_w_xy && z >= w_lo.z && z < region[5] && v != dist[i]) {
            dist[i] = v;
            out[i] = vf_encode(v, vox[i], rgb);
        }
    }
}

// Output of every voxel of a box from `dist` (after a recolour, or after a full
// regeneration when the box is the world), `dist` first capped at `cap` (a bounded field's
// bound; VF_FAR when unbounded).
kernel void inc_encode_box(global const uchar* vox, global uint* dist, global const uchar* rgb,
                           global OUT_T* out, int4 d, int4 lo, int4 size, uint cap) {
    const int3 p = lo.xyz + (int3)(get_global_id(0), get_global_id(1), get_global_id(2));
    if ((int)get_global_id(0) < size.x && (int)get_global_id(1) < size.y &&
        (int)get_global_id(2) < size.z) {
        const int i = (p.z * d.y + p.y) * d.x + p.x;
        const uint v = min(dist[i], cap);
        if (v != dist[i]) {
            dist[i] = v;
        }
        out[i] = vf_encode(v, vox[i], rgb);
    }
}

// CPU layout of the y and z sweeps: one work-item per z slice (y sweeps) or per y (z sweeps),
// the inner loops running along contiguous x so that they vectorise; the per-column kernels
// above keep each work-item on one column, which suits GPUs.
kernel void inc_sweep_y_slices(global uint* tmp, global const int* regions, int slot, int4 d,
                               int4 cap_lo, int4 cap_size) {
    global const int* region = regions + 8 * slot;
    int3 lo, hi;
    inc_ring(region, d, &lo, &hi);
    const int z = cap_lo.z + (int)get_global_id(0);
    if ((int)get_global_id(0) >= cap_size.z || z < lo.z || z >= hi.z) {
        return;
    }
    global uint* slice = tmp + z * d.y * d.x;
    for (int y = lo.y + 1; y < hi.y; ++y) {
        global uint* cur = slice + y * d.x;
        global const uint* prev = cur - d.x;
        for (int x = lo.x; x < hi.x; ++x) {
            cur[x] = min(cur[x], vf_sat_inc(prev[x]));
        }
    }
    for (int y = hi.y - 2; y >= lo.y; --y) {
        global uint* cur = slice + y * d.x;
        global const uint* next = cur + d.x;
        for (int x = lo.x; x < hi.x; ++x) {
            cur[x] = min(cur[x], vf_sat_inc(next[x]));
        }
    }
}

kernel void inc_sweep_z_rows(global const uchar* vox, global uint* dist, global uint* tmp,
                             global const uchar* rgb, global OUT_T* out, global const int* regions,
                             int slot, int4 d, int4 cap_lo, int4 cap_size, uint cap) {
    global const int* region = regions + 8 * slot;
    int3 lo, hi;
    inc_ring(region, d, &lo, &hi);
    const int y = cap_lo.y + (int)get_global_id(0);
    if ((int)get_global_id(0) >= cap_size.y || y < lo.y || y >= hi.y) {
        return;
    }
    const int plane = d.x * d.y;
    global uint* row0 = tmp + y * d.x;
    for (int z = lo.z + 1; z < hi.z; ++z) {
        global uint* cur = row0 + z * plane;
        global const uint* prev = cur - plane;
        for (int x = lo.x; x < hi.x; ++x) {
            cur[x] = min(cur[x], vf_sat_inc(prev[x]));
        }
    }
    const int3 w_lo = d.xyz - (int3)(region[0], region[1], region[2]);
    const bool in_w_y = y >= w_lo.y && y < region[4];
    for (int z = hi.z - 1; z >= lo.z; --z) {
        global uint* cur = row0 + z * plane;
        if (z + 1 < hi.z) {
            global const uint* next = cur + plane;
            for (int x = lo.x; x < hi.x; ++x) {
                cur[x] = min(cur[x], vf_sat_inc(next[x]));
            }
        }
        if (in_w_y && z >= w_lo.z && z < region[5]) {
            const int base = z * plane + y * d.x;
            for (int x = max(lo.x, w_lo.x); x < min(hi.x, region[3]); ++x) {
                const uint v = min(cur[x], cap);
                if (v != dist[base + x]) {
                    dist[base + x] = v;
                    out[base + x] = vf_encode(v, vox[base + x], rgb);
                }
            }
        }
    }
}

// CPU layout of inc_sweep_x: one work-item per z slice transforms its rows as xy_slices_seq
// does (exact_manhattan.cl): the sources of a row of W's ring box into `scratch`, then
// doubling steps s = 1, 2, 4, ... < w, d[x] = min(d[x], d[x-s] + s, d[x+s] + s), each a loop
// that vectorises, instead of two sequential scans. `scratch` holds two rows of d.x + 2 * pad
// elements (pad >= next_pow2(d.x) / 2) whose padding stays VF_FAR.
kernel void inc_sweep_x_slices(global const uchar* vox, global const uint* dist, global uint* tmp,
                               global const int* regions, int slot, int4 d, int4 b_lo, int4 b_hi,
                               global const uint* fbox, uint f_off, int4 cap_lo, int4 cap_size,
                               uint pad, local uint* scratch) {
    global const int* region = regions + 8 * slot;
    int3 lo, hi;
    inc_ring(region, d, &lo, &hi);
    const int z = cap_lo.z + (int)get_global_id(0);
    if ((int)get_global_id(0) >= cap_size.z || z < lo.z || z >= hi.z) {
        return;
    }
    const int w = hi.x - lo.x;
    const int span = d.x + 2 * (int)pad;
    for (int i = 0; i < 2 * span; ++i) {
        scratch[i] = VF_FAR;
    }
    for (int y = lo.y; y < hi.y; ++y) {
        const int row = (z * d.y + y) * d.x + lo.x;
        // vf_reach along the row: the box field's row at the clamped y and z.
        const int cy = clamp(y, b_lo.y, b_hi.y - 1), cz = clamp(z, b_lo.z, b_hi.z - 1);
        const uint yz = (uint)(abs(y - cy) + abs(z - cz));
        global const uint* fr =
            fbox + f_off + ((cz - b_lo.z) * (b_hi.y - b_lo.y) + (cy - b_lo.y)) * (b_hi.x - b_lo.x);
        local uint* a = scratch + pad;
        local uint* b = scratch + span + pad;
        for (int i = 0; i < w; ++i) {
            const int x = lo.x + i;
            const int cx = clamp(x, b_lo.x, b_hi.x - 1);
            const uint reach = add_sat(fr[cx - b_lo.x], yz + (uint)abs(x - cx));
            const uint old = dist[row + i];
            a[i] = vox[row + i] != 0 ? 0u : (old < reach ? old : VF_FAR);
        }
        for (int s = 1; s < w; s <<= 1) {
            local const uint* l = a - s;
            local const uint* h = a + s;
            for (int i = 0; i < w; ++i) {
                b[i] = min(a[i], add_sat(min(l[i], h[i]), (uint)s));
            }
            local uint* t = a;
            a = b;
            b = t;
        }
        for (int i = 0; i < w; ++i) {
            tmp[row + i] = a[i];
        }
    }
}

// Changes made on the device (IncrementalField::apply_device_changes): a list of (linear index,
// before | after << 8), one entry per changed voxel, in any order.

// The linear index i as voxel coordinates.
inline int3 vf_voxel_of(uint i, int4 d) {
    return (int3)((int)(i % (uint)d.x), (int)(i / (uint)d.x % (uint)d.y),
                  (int)(i / ((uint)d.x * (uint)d.y)));
}

// The box field's sources over B [b_lo, b_hi) (f filled with VF_FAR before): 0 at the listed
// voxels whose occupancy changed, all inside B.
kernel void inc_field_mark(global uint* f, global const uint2* list, uint count, int4 d,
                           int4 b_lo, int4 b_hi) {
    const uint k = (uint)get_global_id(0);
    if (k >= count) {
        return;
    }
    const uint2 c = list[k];
    if (((c.y & 0xFFu) == 0) == (((c.y >> 8) & 0xFFu) == 0)) {
        return;
    }
    const int3 p = vf_voxel_of(c.x, d) - b_lo.xyz;
    const int3 n = (b_hi - b_lo).xyz;
    f[((size_t)p.z * (size_t)n.y + (size_t)p.y) * (size_t)n.x + (size_t)p.x] = 0;
}

// Forward and backward min-plus sweeps of the box field f (n voxels per axis, x fastest) along
// `axis`, a work-item per line.
kernel void inc_field_sweep(global uint* f, int4 n, int axis) {
    const size_t line = get_global_id(0);
    const size_t nx = (size_t)n.x, ny = (size_t)n.y, nz = (size_t)n.z;
    size_t start, count, stride;
    if (axis == 0) {
        if (line >= ny * nz) {
            return;
        }
        start = line * nx, count = nx, stride = 1;
    } else if (axis == 1) {
        if (line >= nx * nz) {
            return;
        }
        start = line / nx * nx * ny + line % nx, count = ny, stride = nx;
    } else {
        if (line >= nx * ny) {
            return;
        }
        start = line, count = nz, stride = nx * ny;
    }
    uint run = VF_FAR;
    for (size_t i = 0; i < count; ++i) {
        global uint* v = f + start + i * stride;
        run = min(*v, vf_sat_inc(run));
        *v = run;
    }
    run = VF_FAR;
    for (size_t i = count; i-- > 0;) {
        global uint* v = f + start + i * stride;
        run = min(*v, vf_sat_inc(run));
        *v = run;
    }
}

// The least f over each of the 27 parts of B's boundary (vf_least's order: part (side.z * 3 +
// side.y) * 3 + side.x, per axis 0 the low face, 1 any coordinate, 2 the high face), into
// f[n.x * n.y * n.z + part], which holds VF_FAR before. `lanes` work-items per part (a multiple
// of the work-group size, 64): part = id / lanes, each lane strides over the part's voxels (the
// part across B on every axis is all of B, too large for one work-item), the group reduces
// its lanes in local memory and one atomic per group merges the result.
kernel void inc_field_least(global uint* f, int4 n, uint lanes) {
    local uint group_least[64];
    const size_t id = get_global_id(0);
    const uint part = (uint)(id / lanes), lane = (uint)(id % lanes), l = (uint)get_local_id(0);
    uint least = VF_FAR;
    if (part < 27u) {
        int lo[3], extent[3];
        const int size[3] = {n.x, n.y, n.z};
        for (int a = 0, side = (int)part; a < 3; ++a, side /= 3) {
            lo[a] = side % 3 == 2 ? size[a] - 1 : 0;
            extent[a] = side % 3 == 1 ? size[a] : 1;
        }
        const size_t count = (size_t)extent[0] * (size_t)extent[1] * (size_t)extent[2];
        for (size_t k = lane; k < count; k += lanes) {
            const size_t x = lo[0] + k % (size_t)extent[0];
            const size_t rest = k / (size_t)extent[0];
            const size_t y = lo[1] + rest % (size_t)extent[1];
            const size_t z = lo[2] + rest / (size_t)extent[1];
            least = min(least, f[(z * (size_t)n.y + y) * (size_t)n.x + x]);
        }
    }
    group_least[l] = least;
    barrier(CLK_LOCAL_MEM_FENCE);
    for (uint width = 32; width > 0; width >>= 1) {
        if (l < width) {
            group_least[l] = min(group_least[l], group_least[l + width]);
        }
        barrier(CLK_LOCAL_MEM_FENCE);
    }
    if (l == 0 && part < 27u && group_least[0] != VF_FAR) {
        atomic_min(f + (size_t)n.x * (size_t)n.y * (size_t)n.z + part, group_least[0]);
    }
}

// Chunk-local fields: the chunks (`chunk` voxels per axis, nc per axis of the grid) holding a
// listed voxel, each once: flags[c] (0 before) marks chunk c, whose index is appended to ids at
// the slot taken from *n.
kernel void inc_mark_chunks(global const uint2* list, uint count, int4 d, uint chunk, int4 nc,
                            global uint* flags, global uint* ids, global uint* n) {
    const uint k = (uint)get_global_id(0);
    if (k >= count) {
        return;
    }
    const int3 p = vf_voxel_of(list[k].x, d) / (int)chunk;
    const uint c = ((uint)p.z * (uint)nc.y + (uint)p.y) * (uint)nc.x + (uint)p.x;
    if (atomic_xchg(flags + c, 1u) == 0u) {
        ids[atomic_inc(n)] = c;
    }
}
