// Sparse worlds' 64-trees on the device (cl/src/sparse_device_world.cpp; the tile grid of
// contrees of the implicit-surface rendering blog, core/sparse.hpp's layout): gathers tiles
// into dense blocks, applies brushes to dense 16^3 nodes and encodes tiles into 64-trees bit for
// bit as core's SparseWorld::encode_tile does, re-encoding only the 16^3 nodes an edit touched
// and copying the others from the tile's previous tree. No build options.
//
// A tile's 64-tree lies either in the main buffers (the host world as uploaded) or in a slot
// of the slot buffers (tiles encoded since: TILE_MAX_NODES nodes and TILE_VOXELS materials
// per slot); a reference to a slot has SLOT_REF set in its node base. The tree's constants and
// leaf lookup are sparse_tree.cl's, compiled before this source.

// A job is 8 longs: a block's first voxel x, y, z; the first tile x, y, z of the tiles it
// overlaps; their counts (x | y << 16 | z << 32); its first entry in `refs` (per tile, x
// fastest, its node base and material base, NO_TILE when not stored).

// One work-item per row (along x) of blocks bx x by x bz stacked along z (global id 1 =
// block * bz + z): the world's voxels there (0 outside the world and in tiles that are not
// stored). Along a row, the tile is looked up once per 64 voxels and the leaf once per 4.
__kernel void gather(__global const ulong* restrict masks, __global const uint* restrict offsets,
                     __global const uchar* restrict materials,
                     __global const ulong* restrict slot_masks,
                     __global const uint* restrict slot_offsets,
                     __global const uchar* restrict slot_materials,
                     __global const long* restrict jobs, __global const ulong* restrict refs,
                     __global uchar* restrict vox, uint bx, uint by, uint bz, long wx, long wy,
                     long wz) {
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
        ulong base = refs[2 * r];
        if (base == NO_TILE) {
            for (; x < end; ++x) {
                out[x] = 0;
            }
            continue;
        }
        const bool slot = (base & SLOT_REF) != 0;
        base &= ~SLOT_REF;
        __global const ulong* m = slot ? slot_masks : masks;
        __global const uint* o = slot ? slot_offsets : offsets;
        __global const uchar* mat = slot ? slot_materials : materials;
        const ulong mbase = refs[2 * r + 1];
        const ulong root = m[base];
        for (uint lx = lx0; x < end; lx += 4) {
            // The leaf of voxels lx..lx+3 (from lx0, which may not be a multiple of 4).
            const uint group_end = min(end, x + (4 - (lx & 3)));
            ulong m4 = 0, first = 0;
            const ulong n4 = leaf_node(m, o, base, root, lx, ly, lz);
            if (n4 != NO_TILE) {
                m4 = m[n4];
                first = mbase + o[n4];
            }
            for (uint v = lx & 3; x < group_end; ++x, ++v) {
                const uint bv = (lz & 3) << 4 | (ly & 3) << 2 | v;
                out[x] = (m4 >> bv & 1ul) != 0 ? mat[first + rank_below(m4, bv)] : 0;
            }
            lx &= ~3u;
        }
    }
}

// gather's values with one work-item per leaf row, four voxels of a 4^3 leaf along x (global id 0
// = row * quads + quad, quads = bx / 4 + 2 (a multiple of 4 or not, a block's x range meets at
// most that many); global id 1 = block * bz + z): the GPU layout's for edit blocks, which walk the
// tree once per four voxels and index in 32 bits.
__kernel void gather_quads(__global const ulong* restrict masks,
                           __global const uint* restrict offsets,
                           __global const uchar* restrict materials,
                           __global const ulong* restrict slot_masks,
                           __global const uint* restrict slot_offsets,
                           __global const uchar* restrict slot_materials,
                           __global const long* restrict jobs, __global const ulong* restrict refs,
                           __global uchar* restrict vox, uint bx, uint by, uint bz, long wx,
                           long wy, long wz) {
    const uint quads = bx / 4 + 2;
    const uint i = (uint)get_global_id(0);
    const uint y = i / quads, q = i - y * quads;
    const uint gz = (uint)get_global_id(1);
    if (y >= by) {
        return;
    }
    const uint j = gz / bz;
    const uint z = gz - j * bz;
    __global const long* job = jobs + 8 * j;
    const long px0 = ((job[0] >> 2) + q) * 4;
    const long x0 = px0 - job[0];  // the quad's first voxel in the block's row, -3..bx + 3
    if (x0 >= (long)bx) {
        return;
    }
    __global uchar* out = vox + ((size_t)gz * by + y) * bx;
    const long py = job[1] + y, pz = job[2] + z;
    ulong m4 = 0, first = 0;
    __global const uchar* mat = materials;
    if (px0 >= 0 && py >= 0 && pz >= 0 && px0 < wx && py < wy && pz < wz) {
        const long nt = job[6];
        const uint ntx = (uint)(nt & 0xFFFF), nty = (uint)((nt >> 16) & 0xFFFF);
        const uint r = (uint)job[7] + ((uint)((pz >> 6) - job[5]) * nty +
                                       (uint)((py >> 6) - job[4])) * ntx +
                       (uint)((px0 >> 6) - job[3]);
        ulong base = refs[2 * r];
        if (base != NO_TILE) {
            const bool slot = (base & SLOT_REF) != 0;
            base &= ~SLOT_REF;
            __global const ulong* m = slot ? slot_masks : masks;
            __global const uint* o = slot ? slot_offsets : offsets;
            mat = slot ? slot_materials : materials;
            const ulong n4 = leaf_node(m, o, base, m[base], (uint)(px0 & 63), (uint)(py & 63),
                                       (uint)(pz & 63));
            if (n4 != NO_TILE) {
                m4 = m[n4];
                first = refs[2 * r + 1] + o[n4];
            }
        }
    }
    // The quad's row of its leaf: bits (lz & 3) << 4 | (ly & 3) << 2 | 0..3.
    const uint row = (uint)((pz & 3) << 4 | (py & 3) << 2);
    const uint rank = rank_below(m4, row);
    for (uint k = 0; k < 4; ++k) {
        const long x = x0 + k;
        if (x >= 0 && x < (long)bx) {
            const bool solid = px0 + k < wx && (m4 >> (row + k) & 1ul) != 0;
            out[x] = solid ? mat[first + rank + rank_below(m4 >> row, k)] : 0;
        }
    }
}

// Encoding tiles whose 16^3 nodes are each either dense (re-encoded from voxels) or kept (copied
// from the tile's previous 64-tree), into fresh slots. `tab`: a header of TAB_HEADER longs, then a
// record of REC longs per tile t:
//   [0] its previous tree's node base (NO_TILE: none, SLOT_REF: in the slot buffers),
//   [1] that tree's material base, [2] the slot it is written to (nodes from slot *
//   TILE_MAX_NODES, materials from slot * TILE_VOXELS; never the slot its previous tree lies in),
//   [3] the index in `vox` of the tile's voxel (0, 0, 0) (rows of `pitch_y`, slices of `pitch_z`
//   voxels), [4] its dense nodes (bit z << 4 | y << 2 | x), [5..7] its tile coordinates;
// then the dense nodes as a list (tile * 64 + the node's child bit, in any order).
// The header: [0] the brush's op (0 place, 1 erase, 2 paint; 3: no brush, the dense nodes' voxels
// are in `vox` already), [1] its shape (0 sphere, 1 cube), [2..4] its centre, [5] its radius,
// [6] its material, [7..9] the world's dims.
#define TAB_HEADER 16
#define REC 8

// The previous tree's buffers of the tile whose record is `rec`, and its root (0 when none).
#define PREVIOUS(rec)                                                 \
    ulong base = (rec)[0];                                            \
    const bool none = base == NO_TILE;                                \
    const bool in_slot = !none && (base & SLOT_REF) != 0;             \
    base &= ~SLOT_REF;                                                \
    __global const ulong* om = in_slot ? slot_masks : masks;          \
    __global const uint* oo = in_slot ? slot_offsets : offsets;       \
    __global const uchar* om8 = in_slot ? slot_materials : materials; \
    const ulong root0 = none ? 0ul : om[base];

// encode_count's work on layer z4 + `layer` of child b4 of dense node b16 of the tile whose record
// is `rec`: its 16 voxels (decoded and brushed, or read) into `vox` and their occupancy (bit
// y << 2 | x) into *bits.
void dense_layer(__global uchar* restrict vox, uint pitch_y, uint pitch_z,
                 __global const long* restrict tab, __global const long* restrict rec, uint b16,
                 uint b4, uint layer, __global const ulong* masks, __global const uint* offsets,
                 __global const uchar* materials, __global const ulong* slot_masks,
                 __global const uint* slot_offsets, __global const uchar* slot_materials,
                 __local ushort* bits) {
    // The 4^3 child's first voxel, tile-local, and this layer's place in vox.
    const uint x4 = (b16 & 3) * 16 + (b4 & 3) * 4, y4 = (b16 >> 2 & 3) * 16 + (b4 >> 2 & 3) * 4,
               z4 = (b16 >> 4) * 16 + (b4 >> 4) * 4;
    __global uchar* rows =
        vox + rec[3] + (size_t)(z4 + layer) * pitch_z + (size_t)y4 * pitch_y + x4;
    uint m = 0;
    const long op = tab[0];
    if (op == 3) {
        for (uint y = 0; y < 4; ++y) {
            const uchar4 r = vload4(0, rows + (size_t)y * pitch_y);
            m |= ((uint)(r.x != 0) | (uint)(r.y != 0) << 1 | (uint)(r.z != 0) << 2 |
                  (uint)(r.w != 0) << 3)
                 << (y << 2);
        }
    } else {
        PREVIOUS((__global const ulong*)rec)
        ulong m4 = 0, first = 0;
        const ulong n4 = none ? NO_TILE : leaf_node(om, oo, base, root0, x4, y4, z4);
        if (n4 != NO_TILE) {
            m4 = om[n4];
            first = (ulong)rec[1] + oo[n4];
        }
        // The layer's bits of the leaf, and its first material (the leaf's are contiguous, in
        // mask order).
        const uint lm = (uint)(m4 >> (layer << 4)) & 0xFFFFu;
        first += (ulong)popcount(m4 & ((1ul << (layer << 4)) - 1ul));
        const long shape = tab[1], cx = tab[2], cy = tab[3], cz = tab[4];
        const ulong radius = (ulong)tab[5];
        const uchar material = (uchar)tab[6];
        const long wx = tab[7], wy = tab[8], wz = tab[9];
        const long px0 = rec[5] * TILE + x4, py0 = rec[6] * TILE + y4,
                   pz = rec[7] * TILE + z4 + layer;
        // The layer's distance to the centre per axis (0 within its extent): a layer outside
        // the world or out of the brush's reach keeps its voxels.
        const ulong dx = (ulong)(cx < px0 ? px0 - cx : cx > px0 + 3 ? cx - px0 - 3 : 0);
        const ulong dy = (ulong)(cy < py0 ? py0 - cy : cy > py0 + 3 ? cy - py0 - 3 : 0);
        const ulong dz = (ulong)(pz > cz ? pz - cz : cz - pz);
        // The layer's voxels by position, loaded up front: 16 independent predicated loads.
        // Every loop over bv is unrolled, so `v` stays in registers.
        uchar v[16];
#pragma unroll
        for (uint bv = 0; bv < 16; ++bv) {
            v[bv] = (lm >> bv & 1u) != 0 ? om8[first + popcount(lm & ((1u << bv) - 1u))]
                                          : (uchar)0;
        }
        if (px0 >= wx || py0 >= wy || pz >= wz || dx > radius || dy > radius || dz > radius ||
            (shape == 0 && dx * dx + dy * dy + dz * dz > radius * radius)) {
            m = lm;
        } else {
#pragma unroll
            for (uint bv = 0; bv < 16; ++bv) {
                const long px = px0 + (bv & 3), py = py0 + (bv >> 2);
                const ulong ax = (ulong)(px > cx ? px - cx : cx - px);
                const ulong ay = (ulong)(py > cy ? py - cy : cy - py);
                if (px < wx && py < wy && ax <= radius && ay <= radius &&
                    (shape != 0 || ax * ax + ay * ay + dz * dz <= radius * radius)) {
                    v[bv] = op == 0 ? material : op == 1 ? (uchar)0 : v[bv] != 0 ? material : v[bv];
                }
                m |= (uint)(v[bv] != 0) << bv;
            }
        }
        // The layer's 4 rows of 4 voxels, one store each (the empty voxels' zeros too: this
        // layer's place in vox is this work-item's alone).
#pragma unroll
        for (uint y = 0; y < 4; ++y) {
            vstore4((uchar4)(v[4 * y], v[4 * y + 1], v[4 * y + 2], v[4 * y + 3]), 0,
                    rows + (size_t)y * pitch_y);
        }
    }
    *bits = (ushort)m;
}

// Pass 1, a work-group of 256 per tile, then per dense node (global id 1: the tiles' groups, then
// the dense nodes' in list order). A tile's group: each work-item j < 64 a node that is kept, its
// mask and count from the previous tree (its leaves' materials are contiguous, in mask order). A
// dense node's group: work-item layer * 64 + b4 takes layer z of its 4^3 child b4 (four work-items
// a leaf: a fourth of the serial work each); with a brush it decodes those 16 voxels from the
// tile's previous tree, applies core/brush.hpp's brush to those inside the world and writes them
// into `vox`; without one it reads them from `vox`. The leaf's occupancy goes to leaf_masks, the
// node's mask and solid voxel count to mid_masks and mid_counts.
__kernel void encode_count(__global uchar* restrict vox, uint pitch_y, uint pitch_z,
                           __global const long* restrict tab, __global const ulong* masks,
                           __global const uint* offsets, __global const uchar* materials,
                           __global const ulong* slot_masks, __global const uint* slot_offsets,
                           __global const uchar* slot_materials,
                           __global ulong* restrict leaf_masks, __global ulong* restrict mid_masks,
                           __global uint* restrict mid_counts, uint tiles, uint dense) {
    __local uint solid, lo, hi;
    __local ushort bits[256];
    const uint lid = (uint)get_local_id(0), b4 = lid & 63u, layer = lid >> 6;
    const size_t g = get_global_id(1);
    // Every work-item of every group passes every barrier (PoCL miscompiles a kernel where some
    // return before a barrier).
    const bool tile_group = g < tiles, dense_group = !tile_group && g < (size_t)tiles + dense;
    if (lid == 0) {
        solid = 0;
        lo = 0;
        hi = 0;
    }
    barrier(CLK_LOCAL_MEM_FENCE);
    if (tile_group && layer == 0) {
        __global const long* rec = tab + TAB_HEADER + REC * g;
        const uint j = b4;
        if ((((ulong)rec[4] >> j) & 1ul) == 0) {
            PREVIOUS((__global const ulong*)rec)
            ulong mid = 0;
            uint count = 0;
            if ((root0 >> j & 1ul) != 0) {
                const ulong n16 = base + oo[base] + rank_below(root0, j);
                mid = om[n16];
                const ulong leaf = base + oo[n16];
                const ulong last = leaf + (ulong)popcount(mid) - 1;
                count = oo[last] + (uint)popcount(om[last]) - oo[leaf];
            }
            mid_masks[g * 64 + j] = mid;
            mid_counts[g * 64 + j] = count;
        }
    }
    const size_t i = dense_group ? (size_t)tab[TAB_HEADER + REC * tiles + (g - tiles)] : 0;
    if (dense_group) {
        dense_layer(vox, pitch_y, pitch_z, tab, tab + TAB_HEADER + REC * (i >> 6), (uint)(i & 63),
                    b4, layer, masks, offsets, materials, slot_masks, slot_offsets,
                    slot_materials, &bits[lid]);
    }
    barrier(CLK_LOCAL_MEM_FENCE);
    // Each leaf's four layers into its mask, count and bit of the node's.
    if (dense_group && layer == 0) {
        const ulong m = (ulong)bits[b4] | (ulong)bits[64 + b4] << 16 |
                        (ulong)bits[128 + b4] << 32 | (ulong)bits[192 + b4] << 48;
        leaf_masks[i * 64 + b4] = m;
        if (m != 0) {
            atomic_add(&solid, (uint)popcount(m));
            atomic_or(b4 < 32 ? &lo : &hi, 1u << (b4 & 31));
        }
    }
    barrier(CLK_LOCAL_MEM_FENCE);
    if (dense_group && lid == 0) {
        mid_masks[i] = (ulong)lo | (ulong)hi << 32;
        mid_counts[i] = solid;
    }
}

// Pass 2: a work-group of 64 (local id k) per `per_group` 16^3 nodes of one tile (1 or 64; global
// id 1: the group). Tile t's 64-tree goes to its slot: the root (written by node 0's group, mask
// 0 when the tile is empty), its 16^3 children in mask order, then their 4^3 children grouped by
// parent, and the materials of their voxels in mask order; each node's place and offset are
// prefix sums of pass 1's counts of the nodes before it. A kept node's leaves and materials are
// copied (work-item k: leaf k, and every 64th run of 16 bytes), the leaves' offsets moved by
// where its materials now start; a dense node's child b4 = k writes its leaf and reads its
// materials from `vox`. counts[2 slot], counts[2 slot + 1]: the tile's nodes and materials (0, 0
// when empty).
__kernel void encode_write(__global const uchar* restrict vox, uint pitch_y, uint pitch_z,
                           __global const long* restrict tab, __global const ulong* masks,
                           __global const uint* offsets, __global const uchar* materials,
                           __global const ulong* restrict leaf_masks,
                           __global const ulong* restrict mid_masks,
                           __global const uint* restrict mid_counts, __global ulong* slot_masks,
                           __global uint* slot_offsets, __global uchar* slot_materials,
                           __global uint* restrict counts, uint tiles, uint per_group) {
    // Per node of the tile its leaves and solid voxels, then (work-item j for node j) those of
    // the nodes before it.
    __local uint leaves16[64], solid16[64], leaves_below[64], solid_below[64];
    const uint k = (uint)get_local_id(0);
    const size_t first = get_global_id(1) * per_group;  // (groups: exactly tiles * 64 / per_group)
    const size_t t = first >> 6;
    __global const long* rec = tab + TAB_HEADER + REC * t;
    leaves16[k] = (uint)popcount(mid_masks[t * 64 + k]);
    solid16[k] = mid_counts[t * 64 + k];
    barrier(CLK_LOCAL_MEM_FENCE);
    ulong root = 0;
    uint lb = 0, mb = 0, leaves = 0, solid = 0;
    for (uint j = 0; j < 64; ++j) {
        const uint p = leaves16[j];
        root |= (ulong)(p != 0) << j;
        if (j < k) {
            lb += p;
            mb += solid16[j];
        }
        leaves += p;
        solid += solid16[j];
    }
    leaves_below[k] = lb;
    solid_below[k] = mb;
    barrier(CLK_LOCAL_MEM_FENCE);
    const uint n16 = (uint)popcount(root);
    const size_t slot = (size_t)rec[2];
    const size_t nb = slot * TILE_MAX_NODES;
    if ((first & 63) == 0 && k == 0) {
        slot_masks[nb] = root;
        slot_offsets[nb] = 1;
        counts[2 * slot] = root != 0 ? 1 + n16 + leaves : 0;
        counts[2 * slot + 1] = solid;
    }
    for (size_t i = first; i < first + per_group; ++i) {
        const uint b16 = (uint)(i & 63);
        const ulong mid = mid_masks[i];
        if (mid == 0) {
            continue;
        }
        const uint materials_before = solid_below[b16];
        if (k == 0) {
            const uint r16 = rank_below(root, b16);
            slot_masks[nb + 1 + r16] = mid;
            slot_offsets[nb + 1 + r16] = 1 + n16 + leaves_below[b16];
        }
        const size_t node = nb + 1 + n16 + leaves_below[b16];
        __global uchar* out = slot_materials + slot * TILE_VOXELS + materials_before;
        if ((((ulong)rec[4] >> b16) & 1ul) == 0) {
            PREVIOUS((__global const ulong*)rec)
            const ulong leaf = base + oo[base + oo[base] + rank_below(root0, b16)];
            const uint from = oo[leaf];
            if (k < (uint)popcount(mid)) {
                slot_masks[node + k] = om[leaf + k];
                slot_offsets[node + k] = oo[leaf + k] - from + materials_before;
            }
            __global const uchar* in = om8 + rec[1] + from;
            const uint c = solid16[b16];
            if (per_group != 1) {
                // A CPU: one work-item's byte loop (a memcpy to the compiler).
                if (k == 0) {
                    for (uint j = 0; j < c; ++j) {
                        out[j] = in[j];
                    }
                }
                continue;
            }
            // 16 bytes a work-item at a time (vload16 and vstore16 take any byte address), the
            // tail by byte.
            const uint whole = c / 16;
            for (uint j = k; j < whole; j += 64) {
                vstore16(vload16(j, in), j, out);
            }
            if (k < c - whole * 16) {
                out[whole * 16 + k] = in[whole * 16 + k];
            }
            continue;
        }
        __global const ulong* leaf_mask = leaf_masks + i * 64;
        const ulong m = leaf_mask[k];
        if (m == 0) {
            continue;
        }
        uint before = 0;
        for (uint j = 0; j < k; ++j) {
            before += (uint)popcount(leaf_mask[j]);
        }
        const size_t leaf = node + rank_below(mid, k);
        slot_masks[leaf] = m;
        slot_offsets[leaf] = materials_before + before;
        const uint x4 = (b16 & 3) * 16 + (k & 3) * 4, y4 = (b16 >> 2 & 3) * 16 + (k >> 2 & 3) * 4,
                   z4 = (b16 >> 4) * 16 + (k >> 4) * 4;
        __global const uchar* vnode =
            vox + rec[3] + (size_t)z4 * pitch_z + (size_t)y4 * pitch_y + x4;
        __global uchar* o = out + before;
        // The leaf's 16 rows loaded up front (independent loads), then its solid voxels stored
        // in mask order; the loops are unrolled, so the rows stay in registers.
        uchar4 row[16];
#pragma unroll
        for (uint r = 0; r < 16; ++r) {
            row[r] = vload4(0, vnode + (size_t)(r >> 2) * pitch_z + (size_t)(r & 3) * pitch_y);
        }
        uint j = 0;
#pragma unroll
        for (uint r = 0; r < 16; ++r) {
            const uint bits = (uint)(m >> (r * 4)) & 15u;
            if ((bits & 1u) != 0) {
                o[j++] = row[r].x;
            }
            if ((bits & 2u) != 0) {
                o[j++] = row[r].y;
            }
            if ((bits & 4u) != 0) {
                o[j++] = row[r].z;
            }
            if ((bits & 8u) != 0) {
                o[j++] = row[r].w;
            }
        }
    }
}
