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

// The lowest set bit of m (m != 0).
inline uint lowest_bit(ulong m) {
    return (uint)popcount((m & (~m + 1ul)) - 1ul);
}

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

// gather's values with one work-item per voxel (global ids x, y and block * bz + z): the GPU
// layout's, where neighbouring work-items write neighbouring bytes and share the tree's nodes.
__kernel void gather_voxels(__global const ulong* restrict masks,
                            __global const uint* restrict offsets,
                            __global const uchar* restrict materials,
                            __global const ulong* restrict slot_masks,
                            __global const uint* restrict slot_offsets,
                            __global const uchar* restrict slot_materials,
                            __global const long* restrict jobs, __global const ulong* restrict refs,
                            __global uchar* restrict vox, uint bx, uint by, uint bz, long wx,
                            long wy, long wz) {
    const uint x = (uint)get_global_id(0), y = (uint)get_global_id(1);
    const size_t gz = get_global_id(2);
    if (x >= bx || y >= by) {
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
        const size_t r = (size_t)(job[7] + (((pz >> 6) - job[5]) * nty + ((py >> 6) - job[4])) * ntx +
                                  ((px >> 6) - job[3]));
        ulong base = refs[2 * r];
        if (base != NO_TILE) {
            const bool slot = (base & SLOT_REF) != 0;
            base &= ~SLOT_REF;
            __global const ulong* m = slot ? slot_masks : masks;
            __global const uint* o = slot ? slot_offsets : offsets;
            __global const uchar* mat = slot ? slot_materials : materials;
            const uint lx = (uint)(px & 63), ly = (uint)(py & 63), lz = (uint)(pz & 63);
            const ulong n4 = leaf_node(m, o, base, m[base], lx, ly, lz);
            if (n4 != NO_TILE) {
                const ulong m4 = m[n4];
                const uint bv = (lz & 3) << 4 | (ly & 3) << 2 | (lx & 3);
                if ((m4 >> bv & 1ul) != 0) {
                    v = mat[refs[2 * r + 1] + o[n4] + rank_below(m4, bv)];
                }
            }
        }
    }
    vox[(gz * by + y) * bx + x] = v;
}

// One work-item per row (y | z << 4) of each dense 16^3 node block (global id 1: the block,
// whose first voxel is origins[3 b..3 b+2]): core/brush.hpp's brush on the row's voxels inside
// the world (op 0 place, 1 erase, 2 paint; shape 0 sphere, 1 cube).
__kernel void brush_nodes(__global uchar* restrict vox, __global const long* restrict origins,
                          uint op, uint shape, long cx, long cy, long cz, ulong radius,
                          uchar material, long wx, long wy, long wz) {
    const uint row = (uint)get_global_id(0);
    const size_t b = get_global_id(1);
    const long py = origins[3 * b + 1] + (row & 15), pz = origins[3 * b + 2] + (row >> 4);
    if (row >= NODE * NODE || py >= wy || pz >= wz) {
        return;
    }
    const ulong ay = (ulong)(py > cy ? py - cy : cy - py), az = (ulong)(pz > cz ? pz - cz : cz - pz);
    if (ay > radius || az > radius) {
        return;
    }
    __global uchar* out = vox + b * NODE_VOXELS + (size_t)row * NODE;
    const long x0 = origins[3 * b];
    for (uint x = 0; x < NODE && x0 + x < wx; ++x) {
        const long px = x0 + x;
        const ulong ax = (ulong)(px > cx ? px - cx : cx - px);
        if (ax > radius || (shape == 0 && ax * ax + ay * ay + az * az > radius * radius)) {
            continue;
        }
        const uchar v = out[x];
        out[x] = op == 0 ? material : op == 1 ? (uchar)0 : v != 0 ? material : v;
    }
}

// Encoding a tile whose 16^3 nodes are each either dense (re-encoded from voxels) or kept (copied
// from the tile's previous 64-tree). Per tile t: refs[2 t], refs[2 t + 1] its previous tree's node
// base (NO_TILE: none, SLOT_REF: in the slot buffers) and material base; per node (t * 64 + its
// child bit) src[...]: the index in `vox` of its first voxel (rows of `pitch_y`, slices of
// `pitch_z` voxels), or NO_TILE to keep it.

// The previous tree's buffers of tile t, and its root (0 when none).
#define PREVIOUS(t)                                                   \
    ulong base = refs[2 * (t)];                                       \
    const bool none = base == NO_TILE;                                \
    const bool in_slot = !none && (base & SLOT_REF) != 0;             \
    base &= ~SLOT_REF;                                                \
    __global const ulong* om = in_slot ? slot_masks : masks;          \
    __global const uint* oo = in_slot ? slot_offsets : offsets;       \
    const ulong root0 = none ? 0ul : om[base];

// Pass 1: one work-item per 16^3 node: its mask, its solid voxel count and where its leaves
// lie; a dense node also its 64 leaf masks (occupancy of each 4^3 child) into leaf_masks; a kept
// node its previous leaves' first index into kept (in the buffer the tile's refs name).
__kernel void encode_count(__global const uchar* restrict vox, __global const ulong* restrict src,
                           uint pitch_y, uint pitch_z, __global const ulong* restrict refs,
                           __global const ulong* masks, __global const uint* offsets,
                           __global const ulong* slot_masks, __global const uint* slot_offsets,
                           __global ulong* restrict leaf_masks, __global ulong* restrict mid_masks,
                           __global uint* restrict mid_counts, __global ulong* restrict kept,
                           uint tiles) {
    const size_t i = get_global_id(0);
    if (i >= (size_t)tiles * 64) {
        return;
    }
    const uint b16 = (uint)(i & 63);
    const ulong first = src[i];
    ulong mid = 0;
    uint count = 0;
    if (first == NO_TILE) {
        PREVIOUS(i >> 6)
        if ((root0 >> b16 & 1ul) != 0) {
            const ulong n16 = base + oo[base] + rank_below(root0, b16);
            mid = om[n16];
            const ulong leaf = base + oo[n16];
            kept[i] = leaf;
            const uint n = (uint)popcount(mid);
            for (uint k = 0; k < n; ++k) {
                count += (uint)popcount(om[leaf + k]);
            }
        }
        mid_masks[i] = mid;
        mid_counts[i] = count;
        return;
    }
    __global const uchar* node = vox + first;
    for (uint b4 = 0; b4 < 64; ++b4) {
        const uint x4 = (b4 & 3) * 4, y4 = (b4 >> 2 & 3) * 4, z4 = (b4 >> 4) * 4;
        ulong m = 0;
        for (uint z = 0; z < 4; ++z) {
            for (uint y = 0; y < 4; ++y) {
                const uchar4 r = vload4(0, node + (size_t)(z4 + z) * pitch_z + (y4 + y) * pitch_y + x4);
                const ulong bits = (ulong)(r.x != 0) | (ulong)(r.y != 0) << 1 |
                                   (ulong)(r.z != 0) << 2 | (ulong)(r.w != 0) << 3;
                m |= bits << (z << 4 | y << 2);
            }
        }
        leaf_masks[i * 64 + b4] = m;
        mid |= (ulong)(m != 0) << b4;
        count += (uint)popcount(m);
    }
    mid_masks[i] = mid;
    mid_counts[i] = count;
}

// Pass 2: one work-item per 16^3 node, as pass 1. Tile t's 64-tree goes to slot slots[t] (nodes
// from slot * TILE_MAX_NODES, materials from slot * TILE_VOXELS; never the slot its previous tree
// lies in): the root (written by child 0, mask 0 when the tile is empty), its 16^3 children in
// mask order, then their 4^3 children grouped by parent (pass 3 writes the materials of their
// voxels in mask order); each node's place and offset are prefix sums of pass 1's counts of the
// nodes before it, its first material's (materials_before) also into node_mats. A kept node's
// leaves are copied, their offsets moved by where its materials now start. counts[2 slot],
// counts[2 slot + 1]: the tile's nodes and materials (0, 0 when empty).
__kernel void encode_write(__global const ulong* restrict src, __global const ulong* restrict refs,
                           __global const ulong* masks, __global const uint* offsets,
                           __global const ulong* restrict leaf_masks,
                           __global const ulong* restrict mid_masks,
                           __global const uint* restrict mid_counts,
                           __global const ulong* restrict kept, __global const uint* restrict slots,
                           __global ulong* slot_masks, __global uint* slot_offsets,
                           __global uint* restrict counts, __global uint* restrict node_mats,
                           uint tiles) {
    const size_t i = get_global_id(0);
    if (i >= (size_t)tiles * 64) {
        return;
    }
    const uint b16 = (uint)(i & 63);
    const size_t t = i >> 6;
    __global const ulong* mids = mid_masks + t * 64;
    __global const uint* mats = mid_counts + t * 64;
    ulong root = 0;
    uint leaves_before = 0, materials_before = 0, leaves = 0, solid = 0;
    for (uint j = 0; j < 64; ++j) {
        const uint p = (uint)popcount(mids[j]);
        root |= (ulong)(p != 0) << j;
        if (j < b16) {
            leaves_before += p;
            materials_before += mats[j];
        }
        leaves += p;
        solid += mats[j];
    }
    const uint n16 = (uint)popcount(root);
    const size_t slot = slots[t];
    const size_t nb = slot * TILE_MAX_NODES;
    if (b16 == 0) {
        slot_masks[nb] = root;
        slot_offsets[nb] = 1;
        counts[2 * slot] = root != 0 ? 1 + n16 + leaves : 0;
        counts[2 * slot + 1] = solid;
    }
    const ulong mid = mids[b16];
    if (mid == 0) {
        return;
    }
    const uint r16 = rank_below(root, b16);
    slot_masks[nb + 1 + r16] = mid;
    slot_offsets[nb + 1 + r16] = 1 + n16 + leaves_before;
    node_mats[i] = materials_before;
    size_t node = nb + 1 + n16 + leaves_before;
    if (src[i] == NO_TILE) {
        PREVIOUS(t)
        const ulong leaf = kept[i];
        const uint n = (uint)popcount(mid);
        const uint from = oo[leaf];
        for (uint k = 0; k < n; ++k) {
            slot_masks[node + k] = om[leaf + k];
            slot_offsets[node + k] = oo[leaf + k] - from + materials_before;
        }
        return;
    }
    uint material = materials_before;
    for (ulong m2 = mid; m2 != 0; m2 &= m2 - 1, ++node) {
        const ulong leaf = leaf_masks[i * 64 + lowest_bit(m2)];
        slot_masks[node] = leaf;
        slot_offsets[node] = material;
        material += (uint)popcount(leaf);
    }
}

// Pass 3: the materials, a work-item per (k, node) (global ids 0 and 1): the k-th 4^3 leaf of
// the node in mask order, at most 64 bytes, after the node's materials_before (node_mats, from
// pass 2). A kept node's leaf copies its previous materials; a dense one's reads its voxels.
__kernel void encode_materials(__global const uchar* restrict vox, __global const ulong* restrict src,
                               uint pitch_y, uint pitch_z, __global const ulong* restrict refs,
                               __global const ulong* masks, __global const uint* offsets,
                               __global const uchar* materials,
                               __global const ulong* restrict leaf_masks,
                               __global const ulong* restrict mid_masks,
                               __global const ulong* restrict kept,
                               __global const uint* restrict slots, __global const ulong* slot_masks,
                               __global const uint* slot_offsets, __global uchar* slot_materials,
                               __global const uint* restrict node_mats, uint tiles) {
    const uint k = (uint)get_global_id(0);
    const size_t i = get_global_id(1);
    if (i >= (size_t)tiles * 64) {
        return;
    }
    const ulong mid = mid_masks[i];
    if (k >= (uint)popcount(mid)) {
        return;
    }
    const size_t t = i >> 6;
    __global uchar* out = slot_materials + (size_t)slots[t] * TILE_VOXELS + node_mats[i];
    const ulong first = src[i];
    if (first == NO_TILE) {
        PREVIOUS(t)
        __global const uchar* om8 = in_slot ? slot_materials : materials;
        const ulong leaf = kept[i];
        const uint from = oo[leaf];
        const uint at = oo[leaf + k];
        const uint c = (uint)popcount(om[leaf + k]);
        __global const uchar* in = om8 + refs[2 * t + 1] + at;
        out += at - from;
        for (uint j = 0; j < c; ++j) {
            out[j] = in[j];
        }
        return;
    }
    // The k-th set bit of mid, and the materials of the leaves before it.
    ulong m2 = mid;
    uint before = 0;
    for (uint j = 0; j < k; ++j) {
        before += (uint)popcount(leaf_masks[i * 64 + lowest_bit(m2)]);
        m2 &= m2 - 1;
    }
    const uint b4 = lowest_bit(m2);
    const uint x4 = (b4 & 3) * 4, y4 = (b4 >> 2 & 3) * 4, z4 = (b4 >> 4) * 4;
    __global const uchar* vnode = vox + first;
    out += before;
    for (ulong m3 = leaf_masks[i * 64 + b4]; m3 != 0; m3 &= m3 - 1) {
        const uint bv = lowest_bit(m3);
        *out++ = vnode[(size_t)(z4 + (bv >> 4)) * pitch_z + (y4 + (bv >> 2 & 3)) * pitch_y + x4 +
                       (bv & 3)];
    }
}
