// Falling sand and water, one step of the 3-D block automaton whose rules and reference are
// core/include/voxfield/core/sand.hpp and core/src/sand.cpp, which this matches bit for bit.
// Source: Toffoli & Margolus, "Cellular Automata Machines" (1987), ch. 12 (Margolus blocks).
//
// In place, on the one device copy of the world `vox` (an incremental field's voxels): a
// block reads its own eight cells and, for its bottom water, the cells right below it, which
// belong to the block below in the same column of blocks. Each work-item takes whole columns
// of blocks (along y) from the top down, so the block below has not run yet when a block reads
// it: every read sees the world before the step, as the reference's. Each changed voxel is
// appended to `changes` as (linear index, before | after << 8) at a slot taken from
// summary[0] (slots past `capacity` are counted but not written: the list overflowed, and its
// reader falls back to what needs no list); summary[1..12] gather the boxes of the changed
// voxels and of those whose occupancy changed (VF_SUMMARY_* below), the work-items' own boxes
// merged by atomic_max. A block is held in a ulong, byte k = 4 * layer + column (layer 0
// bottom, 1 top; column dx + 2 * dz); cells outside the world hold `wall`, a value that is
// neither air, sand nor water, so nothing moves into or out of them.
// d: world size; o: the step's block offset; nb: blocks per axis; key: sand_step_key.

// summary: [0] changes made; [1..3] d - lo, [4..6] hi (half-open) of the changed voxels' box;
// [7..9], [10..12] the same for the voxels whose occupancy changed. Zero everywhere is an
// empty list with empty boxes, so the host clears it with a fill and atomic_max merges boxes.
#define VF_SUMMARY_CHANGED 1
#define VF_SUMMARY_OCCUPANCY 7

// A work-item's boxes (inclusive; empty while hi.x < lo.x).
typedef struct {
    int3 lo, hi, occ_lo, occ_hi;
} VfBoxes;

inline void vf_boxes_clear(VfBoxes* b) {
    b->lo = b->occ_lo = (int3)(INT_MAX);
    b->hi = b->occ_hi = (int3)(-1);
}

// Voxel p changed from `was` to `now`.
inline void vf_boxes_add(VfBoxes* b, int3 p, uint was, uint now) {
    b->lo = min(b->lo, p);
    b->hi = max(b->hi, p);
    if ((was == 0) != (now == 0)) {
        b->occ_lo = min(b->occ_lo, p);
        b->occ_hi = max(b->occ_hi, p);
    }
}

inline void vf_box_merge(global uint* s, int4 d, int3 lo, int3 hi) {
    if (hi.x < lo.x) {
        return;
    }
    atomic_max(s + 0, (uint)(d.x - lo.x));
    atomic_max(s + 1, (uint)(d.y - lo.y));
    atomic_max(s + 2, (uint)(d.z - lo.z));
    atomic_max(s + 3, (uint)(hi.x + 1));
    atomic_max(s + 4, (uint)(hi.y + 1));
    atomic_max(s + 5, (uint)(hi.z + 1));
}

inline void vf_boxes_merge(const VfBoxes* b, global uint* summary, int4 d) {
    vf_box_merge(summary + VF_SUMMARY_CHANGED, d, b->lo, b->hi);
    vf_box_merge(summary + VF_SUMMARY_OCCUPANCY, d, b->occ_lo, b->occ_hi);
}

inline ulong vf_sand_hash(ulong x) {
    ulong z = x + 0x9E3779B97F4A7C15ul;
    z = (z ^ (z >> 30)) * 0xBF58476D1CE4E5B9ul;
    z = (z ^ (z >> 27)) * 0x94D049BB133111EBul;
    return z ^ (z >> 31);
}

inline uint vf_get(ulong cells, int k) {
    return (uint)(cells >> (8 * k)) & 0xFFu;
}

inline ulong vf_put(ulong cells, int k, uint v) {
    return (cells & ~(0xFFul << (8 * k))) | ((ulong)v << (8 * k));
}

// The rules on one block; bit c of `below_air`: the cell below bottom column c was air before
// the step.
inline ulong vf_sand_rules(ulong cells, uint below_air, ulong h, uint sand, uint water) {
    const int r = (int)(h & 3ul);
    uint moved = 0;  // bit k: cell k moved this step
    // 1. Falling: top-layer sand and water, down or diagonally down.
    for (int n = 0; n < 4; ++n) {
        const int c = (n + r) & 3;
        const uint v = vf_get(cells, 4 + c);
        if (v != sand && v != water) {
            continue;
        }
        const uint below = vf_get(cells, c);
        if (below == 0 || (v == sand && below == water && ((moved >> c) & 1u) == 0)) {
            cells = vf_put(vf_put(cells, c, v), 4 + c, below);
            moved |= (1u << c) | (below != 0 ? 1u << (4 + c) : 0u);
            continue;
        }
        const int a = c ^ 1, e = c ^ 2;
        const bool free_a = vf_get(cells, a) == 0, free_e = vf_get(cells, e) == 0;
        if (!free_a && !free_e) {
            continue;
        }
        const int t = free_a && free_e ? (((h >> (8 + c)) & 1ul) != 0 ? e : a) : (free_a ? a : e);
        cells = vf_put(vf_put(cells, t, v), 4 + c, 0);
        moved |= 1u << t;
    }
    // 2. Sideways: water that has not moved, top layer first.
    for (int l = 1; l >= 0; --l) {
        for (int n = 0; n < 4; ++n) {
            const int c = (n + r) & 3, k = 4 * l + c;
            if (vf_get(cells, k) != water || ((moved >> k) & 1u) != 0 ||
                (l == 0 && ((below_air >> c) & 1u) != 0)) {
                continue;
            }
            const int a = 4 * l + (c ^ 1), e = 4 * l + (c ^ 2);
            const bool free_a = vf_get(cells, a) == 0, free_e = vf_get(cells, e) == 0;
            if (!free_a && !free_e) {
                continue;
            }
            const int t =
                free_a && free_e ? (((h >> (16 + k)) & 1ul) != 0 ? e : a) : (free_a ? a : e);
            cells = vf_put(vf_put(cells, t, water), k, 0);
            moved |= 1u << t;
        }
    }
    return cells;
}

inline bool vf_inside(int3 p, int4 d) {
    return p.x >= 0 && p.y >= 0 && p.z >= 0 && p.x < d.x && p.y < d.y && p.z < d.z;
}

inline ulong vf_index(int3 p, int4 d) {
    return ((ulong)p.z * (ulong)d.y + (ulong)p.y) * (ulong)d.x + (ulong)p.x;
}

inline int3 vf_cell(int3 origin, int k) {
    return origin + (int3)(k & 1, k >> 2, (k >> 1) & 1);
}

// Bit 7 of every byte of `cells` that equals the byte `v` (the zero-byte test of Mycroft's SWAR
// trick). Exact for "some byte equals v"; a byte above one that does may be flagged too, which
// only makes vf_may_move below answer true more often.
inline ulong vf_eq(ulong cells, uint v) {
    const ulong x = cells ^ ((ulong)v * 0x0101010101010101ul);
    return (x - 0x0101010101010101ul) & ~x & 0x8080808080808080ul;
}

#define VF_TOP 0x8080808000000000ul
#define VF_BOTTOM 0x0000000080808080ul

// False only for a block the rules cannot change: falling and sliding need sand or water in
// the top layer and air (or water under sand) below, spreading needs water beside air. Blocks
// of resting sand, of water without air, and pile surfaces (air above sand) are skipped.
inline bool vf_may_move(ulong cells, uint sand, uint water) {
    const ulong air = vf_eq(cells, 0), wet = vf_eq(cells, water);
    const ulong top_sand = vf_eq(cells, sand) & VF_TOP;
    return (air != 0 && (wet != 0 || top_sand != 0)) || (top_sand != 0 && (wet & VF_BOTTOM) != 0);
}

// Bit 7 of every byte of x that is not zero (exact).
inline ulong vf_nonzero_bytes(ulong x) {
    return (((x & 0x7F7F7F7F7F7F7F7Ful) + 0x7F7F7F7F7F7F7F7Ful) | x) & 0x8080808080808080ul;
}

// 0xFF in every byte of `cells` that equals the byte `v`, 0 in the others (exact).
inline ulong vf_bytes_equal(ulong cells, uint v) {
    const ulong x = cells ^ ((ulong)v * 0x0101010101010101ul);
    return ((~vf_nonzero_bytes(x) & 0x8080808080808080ul) >> 7) * 0xFFul;
}

// Block b (block coordinates, origin its cell 0) after the step, holding `cells` before it.
// Over a bottom layer of air (a grain falling through the air, say) the rules come down to
// every sand and water cell of the top layer falling straight down: no diagonal, no sideways
// move, no random choice; that case is done here without them.
inline ulong vf_sand_after(global const uchar* src, int4 d, int4 nb, ulong key, uint sand,
                           uint water, int3 b, int3 origin, ulong cells) {
    if ((cells & 0xFFFFFFFFul) == 0) {
        const ulong falls = vf_bytes_equal(cells, sand) | vf_bytes_equal(cells, water);
        return (cells & ~falls) | ((cells & falls) >> 32);
    }
    uint below_air = 0;
    for (int c = 0; c < 4; ++c) {
        const int3 p = vf_cell(origin, c) - (int3)(0, 1, 0);
        if (vf_get(cells, c) == water && vf_inside(p, d) && src[vf_index(p, d)] == 0) {
            below_air |= 1u << c;
        }
    }
    const ulong block = ((ulong)b.z * (ulong)nb.y + (ulong)b.y) * (ulong)nb.x + (ulong)b.x;
    return vf_sand_rules(cells, below_air, vf_sand_hash(key ^ block), sand, water);
}

// GPU layout: one work-item per column of blocks (i, k), global size (nb.x, nb.z) rounded
// up, its blocks from the top down; a block that changes takes its slots with one atomic_add.
kernel void sand_step_blocks(global uchar* vox, int4 d, int4 o, int4 nb, ulong key, uint sand,
                             uint water, uint wall, global uint* summary, global uint2* changes,
                             uint capacity) {
    const int i = (int)get_global_id(0), k = (int)get_global_id(1);
    if (i >= nb.x || k >= nb.z) {
        return;
    }
    VfBoxes boxes;
    vf_boxes_clear(&boxes);
    for (int j = nb.y - 1; j >= 0; --j) {
        const int3 b = (int3)(i, j, k);
        const int3 origin = 2 * b - o.xyz;
        ulong cells = 0;
        for (int c = 0; c < 8; ++c) {
            const int3 p = vf_cell(origin, c);
            cells |= (ulong)(vf_inside(p, d) ? (uint)vox[vf_index(p, d)] : wall) << (8 * c);
        }
        if (!vf_may_move(cells, sand, water)) {
            continue;
        }
        const ulong after = vf_sand_after(vox, d, nb, key, sand, water, b, origin, cells);
        if (after == cells) {
            continue;
        }
        uint slot = atomic_add(summary, (uint)popcount(vf_nonzero_bytes(cells ^ after)));
        for (int c = 0; c < 8; ++c) {
            const uint was = vf_get(cells, c), now = vf_get(after, c);
            if (was != now) {
                const int3 p = vf_cell(origin, c);
                const ulong at = vf_index(p, d);
                vox[at] = (uchar)now;
                vf_boxes_add(&boxes, p, was, now);
                if (slot < capacity) {
                    changes[slot] = (uint2)((uint)at, was | (now << 8));
                }
                ++slot;
            }
        }
    }
    vf_boxes_merge(&boxes, summary, d);
}

// Changes a CPU-layout work-item holds before it takes their slots with one atomic_add.
#define VF_HELD 128

typedef struct {
    uint n;
    uint2 item[VF_HELD];
} VfHeld;

// Moves the held changes into the step's list.
inline void vf_flush(VfHeld* held, global uint* summary, global uint2* changes, uint capacity) {
    if (held->n == 0) {
        return;
    }
    const uint slot = atomic_add(summary, held->n);
    for (uint i = 0; i < held->n && slot + i < capacity; ++i) {
        changes[slot + i] = held->item[i];
    }
    held->n = 0;
}

// A CPU-layout block row: its block coordinates (j, k), its four lines of voxels in `vox`
// (line r = 2 * layer + dz starts at voxel (0, y0 + layer, z0 + dz); inside: whether it lies
// in the world), and the linear index of voxel (0, y0, z0) modulo 2^32 (y0 or z0 may be -1).
typedef struct {
    int j, k, y0, z0;
    global uchar* line[4];
    bool inside[4];
    uint first;
} VfRow;

// The cells of the row's block at x, x + 1 inside the world.
inline ulong vf_row_cells(const VfRow* row, uint wall, int x) {
    ulong cells = 0;
    for (int r = 0; r < 4; ++r) {  // cells 4 * layer + 2 * dz, + 1 are line r's x, x + 1
        const uint pair =
            row->inside[r] ? (uint)row->line[r][x] | (uint)row->line[r][x + 1] << 8 : wall * 0x101u;
        cells |= (ulong)pair << (8 * (4 * (r >> 1) + 2 * (r & 1)));
    }
    return cells;
}

// The cells of the row's block at x, with bounds checks along x.
inline ulong vf_row_cells_checked(const VfRow* row, uint wall, int x, int dx) {
    ulong cells = 0;
    for (int c = 0; c < 8; ++c) {  // cell c = 4 * layer + dx + 2 * dz, of line 2 * layer + dz
        const int r = 2 * (c >> 2) + ((c >> 1) & 1), xc = x + (c & 1);
        const bool in = row->inside[r] && xc >= 0 && xc < dx;
        cells |= (ulong)(in ? (uint)row->line[r][xc] : wall) << (8 * c);
    }
    return cells;
}

// Runs the row's block i (cells x, x + 1) holding `cells`: its changes into `vox`, `held` and
// `boxes`.
inline void vf_row_block(global uchar* vox, int4 d, int4 nb, ulong key, uint sand, uint water,
                         global uint* summary, global uint2* changes, uint capacity,
                         VfHeld* held, VfBoxes* boxes, const VfRow* row, int i, int x,
                         ulong cells) {
    const ulong after = vf_sand_after(vox, d, nb, key, sand, water, (int3)(i, row->j, row->k),
                                      (int3)(x, row->y0, row->z0), cells);
    ulong changed = vf_nonzero_bytes(cells ^ after);
    if (changed == 0) {
        return;
    }
    if (held->n > VF_HELD - 8) {
        vf_flush(held, summary, changes, capacity);
    }
    const uint first = row->first + (uint)x, dx = (uint)d.x, dxy = (uint)d.x * (uint)d.y;
    while (changed != 0) {
        const ulong bit = changed & (~changed + 1);
        changed ^= bit;
        const int c = (63 - (int)clz(bit)) >> 3;  // cell 4 * layer + dx + 2 * dz
        const uint index = first + (uint)(c & 1) + (uint)(c >> 2) * dx + (uint)((c >> 1) & 1) * dxy;
        const uint was = vf_get(cells, c), now = vf_get(after, c);
        vox[index] = (uchar)now;
        held->item[held->n++] = (uint2)(index, was | (now << 8));
        vf_boxes_add(boxes, (int3)(x + (c & 1), row->y0 + (c >> 2), row->z0 + ((c >> 1) & 1)), was,
                     now);
    }
}

// Holds the changes of the cells flagged (bit 7 of a byte) in `fell`: lanes 8h .. 8h + 7 of
// a 16-byte load `top` at x = base of the row's top line 2 + dz, whose values fell into the
// cells below.
inline void vf_row_falls(VfHeld* held, VfBoxes* boxes, const VfRow* row, uchar16 top, int dz,
                         int base, int h, ulong fell, uint dx, uint dxy) {
    const uint bottom = row->first + (uint)(base + 8 * h) + (uint)dz * dxy;
    const ulong values = h == 0 ? as_ulong2(top).s0 : as_ulong2(top).s1;
    fell &= 0x8080808080808080ul;
    while (fell != 0) {
        const ulong bit = fell & (~fell + 1);
        fell ^= bit;
        const int lane = (63 - (int)clz(bit)) >> 3;
        const uint v = vf_get(values, lane), at = bottom + (uint)lane;
        held->item[held->n++] = (uint2)(at + dx, v);
        held->item[held->n++] = (uint2)(at, v << 8);
        const int3 p = (int3)(base + 8 * h + lane, row->y0, row->z0 + dz);
        vf_boxes_add(boxes, p, 0, v);
        vf_boxes_add(boxes, p + (int3)(0, 1, 0), v, 0);
    }
}

// CPU layout: one work-item per column of block rows k, global size nb.z, running its rows
// (along x) from the top down (sand_row); a work-item's changes take their slots VF_HELD at a
// time. Runs of eight blocks are tested at once by 16-byte loads of the row's four lines (a line
// outside the world reads as `wall`): blocks that cannot move (vf_may_move's condition,
// exactly) are skipped, those over a bottom layer of air (vf_sand_after's first case) are run on
// the vectors, the rest block by block. The run at the row's end is loaded from as far left as
// it must to stay inside the world (its first lanes, blocks already run, are left out) and run
// block by block, and the blocks at either end that reach out of the world are read with bounds
// checks.
inline void vf_sand_row(global uchar* vox, int4 d, int4 o, int4 nb, ulong key, uint sand,
                        uint water, uint wall, global uint* summary, global uint2* changes,
                        uint capacity, VfHeld* held, VfBoxes* boxes, int j, int k) {
    VfRow row;
    row.j = j;
    row.k = k;
    row.y0 = 2 * row.j - o.y;
    row.z0 = 2 * row.k - o.z;
    row.first = ((uint)row.z0 * (uint)d.y + (uint)row.y0) * (uint)d.x;
    for (int r = 0; r < 4; ++r) {
        const int y = row.y0 + (r >> 1), z = row.z0 + (r & 1);
        row.inside[r] = y >= 0 && z >= 0 && y < d.y && z < d.z;
        row.line[r] = vox + (row.inside[r] ? vf_index((int3)(0, y, z), d) : 0);
    }
    const uint dx = (uint)d.x, dxy = (uint)d.x * (uint)d.y;
    global uchar* const out = row.line[0];  // where all four lines are inside
    // The last start of a 16-byte load inside the world with the parity of the block corners.
    int last = d.x - 16;
    last -= (last + o.x) & 1;
    const uchar16 s16 = (uchar16)((uchar)sand), w16 = (uchar16)((uchar)water);
    const uchar16 wall16 = (uchar16)((uchar)wall), zero16 = (uchar16)(0);
    // Lanes 2q, 2q + 1 <- byte q of a char8.
    const uchar16 pairs = (uchar16)(0, 0, 1, 1, 2, 2, 3, 3, 4, 4, 5, 5, 6, 6, 7, 7);
    for (int i = 0; i < nb.x;) {
        const int x0 = 2 * i - o.x;
        if (x0 < 0 || x0 + 1 >= d.x || last < 0) {
            const ulong cells = vf_row_cells_checked(&row, wall, x0, d.x);
            if (vf_may_move(cells, sand, water)) {
                vf_row_block(vox, d, nb, key, sand, water, summary, changes, capacity, held, boxes,
                             &row, i, x0, cells);
            }
            ++i;
            continue;
        }
        // Lanes 2q, 2q + 1 of the load at `base` are block i - skip + q's.
        const int base = min(x0, last), skip = (x0 - base) >> 1;
        // Lines 0, 1 are the bottom layer (dz = 0, 1), 2, 3 the top.
        const uchar16 b0 = row.inside[0] ? vload16(0, row.line[0] + base) : wall16;
        const uchar16 b1 = row.inside[1] ? vload16(0, row.line[1] + base) : wall16;
        const uchar16 t0 = row.inside[2] ? vload16(0, row.line[2] + base) : wall16;
        const uchar16 t1 = row.inside[3] ? vload16(0, row.line[3] + base) : wall16;
        const char16 air = (b0 == zero16) | (b1 == zero16) | (t0 == zero16) | (t1 == zero16);
        const char16 wet_bottom = (b0 == w16) | (b1 == w16);
        const char16 wet = wet_bottom | (t0 == w16) | (t1 == w16);
        const char16 top_sand = (t0 == s16) | (t1 == s16);
        const char8 a = air.even | air.odd, w = wet.even | wet.odd;
        const char8 wb = wet_bottom.even | wet_bottom.odd, ts = top_sand.even | top_sand.odd;
        // Bit 7 of byte q: block i - skip + q is run block by block.
        ulong one_by_one = as_ulong((a & (w | ts)) | (ts & wb));
        if (skip == 0 && one_by_one != 0) {
            const char16 bottom_air = (b0 == zero16) & (b1 == zero16);
            const char8 open = bottom_air.even & bottom_air.odd;
            const char16 falling = shuffle(open, pairs);
            const char16 f0 = falling & ((t0 == s16) | (t0 == w16));
            const char16 f1 = falling & ((t1 == s16) | (t1 == w16));
            // Only where all four lines lie in the world: one outside reads as wall, which is
            // not air and does not fall. The lanes that do not fall are written back as they
            // were loaded (these blocks are this work-item's alone).
            if (any(f0 | f1)) {
                if (held->n > VF_HELD - 64) {
                    vf_flush(held, summary, changes, capacity);
                }
                const uchar16 m0 = as_uchar16(f0), m1 = as_uchar16(f1);
                vstore16(b0 | (t0 & m0), 0, out + base);
                vstore16(b1 | (t1 & m1), 0, out + dxy + base);
                vstore16(t0 & ~m0, 0, out + dx + base);
                vstore16(t1 & ~m1, 0, out + dxy + dx + base);
                const ulong2 u0 = as_ulong2(f0), u1 = as_ulong2(f1);
                vf_row_falls(held, boxes, &row, t0, 0, base, 0, u0.s0, dx, dxy);
                vf_row_falls(held, boxes, &row, t0, 0, base, 1, u0.s1, dx, dxy);
                vf_row_falls(held, boxes, &row, t1, 1, base, 0, u1.s0, dx, dxy);
                vf_row_falls(held, boxes, &row, t1, 1, base, 1, u1.s1, dx, dxy);
            }
            one_by_one &= ~as_ulong(open);
        }
        one_by_one = (one_by_one >> (8 * skip)) & 0x8080808080808080ul;
        while (one_by_one != 0) {
            const ulong bit = one_by_one & (~one_by_one + 1);
            one_by_one ^= bit;
            const int q = (63 - (int)clz(bit)) >> 3, x = x0 + 2 * q;
            vf_row_block(vox, d, nb, key, sand, water, summary, changes, capacity, held, boxes,
                         &row, i + q, x, vf_row_cells(&row, wall, x));
        }
        i += 8 - skip;
    }
}

kernel void sand_step_rows(global uchar* vox, int4 d, int4 o, int4 nb, ulong key, uint sand,
                           uint water, uint wall, global uint* summary, global uint2* changes,
                           uint capacity) {
    const int k = (int)get_global_id(0);
    if (k >= nb.z) {
        return;
    }
    VfHeld held;
    held.n = 0;
    VfBoxes boxes;
    vf_boxes_clear(&boxes);
    for (int j = nb.y - 1; j >= 0; --j) {
        vf_sand_row(vox, d, o, nb, key, sand, water, wall, summary, changes, capacity, &held,
                    &boxes, j, k);
    }
    vf_flush(&held, summary, changes, capacity);
    vf_boxes_merge(&boxes, summary, d);
}

// Sparse worlds (cl/src/sparse_sand.cpp): the step on windows gathered from the 64-tree tiles,
// one per tile t whose voxels may change: tile t's 64^3 voxels with one voxel more on every side
// and two below (VF_WIN_* voxels, x fastest; window voxel (0, 0, 0) is world voxel 64 t - (1, 2,
// 1)). Global ids (column i, column k, window w): the columns of blocks that overlap the tile,
// blocks 32 t .. 32 t + 31 + o per axis (inside the world's block grid nb), each from the top
// down, as sand_step_blocks. The block partition, the hash (the block's index in the world's grid)
// and the walls (cells outside the world `d`) are the world's, so every block that overlaps tile
// t runs exactly as the dense step runs it; a block that overlaps two tiles runs in both windows,
// alike. summary[8 w ..]: [0] the voxels of tile t that changed, [1..3] VF_WIN - lo and [4..6] hi
// (half-open) of their box in window coordinates.
#define VF_WIN_X 66
#define VF_WIN_Y 67
#define VF_WIN_Z 66

inline size_t vf_win_index(int3 q) {
    return ((size_t)q.z * VF_WIN_Y + (size_t)q.y) * VF_WIN_X + (size_t)q.x;
}

kernel void sand_step_windows(global uchar* windows, global const int* tiles, int4 d, int4 o,
                              int4 nb, ulong key, uint sand, uint water, uint wall,
                              global uint* summary) {
    const int li = (int)get_global_id(0), lk = (int)get_global_id(1);
    const size_t w = get_global_id(2);
    const int3 t = vload3(w, tiles);
    const int i = 32 * t.x + li, k = 32 * t.z + lk;
    if (li > 31 + o.x || lk > 31 + o.z || i >= nb.x || k >= nb.z) {
        return;
    }
    global uchar* win = windows + w * (size_t)(VF_WIN_X * VF_WIN_Y * VF_WIN_Z);
    const int3 corner = 64 * t - (int3)(1, 2, 1);  // world voxel of window voxel (0, 0, 0)
    const int3 lo = 64 * t, hi = min(lo + 64, d.xyz);
    uint count = 0;
    VfBoxes boxes;
    vf_boxes_clear(&boxes);
    for (int j = min(32 * t.y + 31 + o.y, nb.y - 1); j >= 32 * t.y; --j) {
        const int3 b = (int3)(i, j, k);
        const int3 origin = 2 * b - o.xyz;
        ulong cells = 0;
        for (int c = 0; c < 8; ++c) {
            const int3 p = vf_cell(origin, c);
            cells |= (ulong)(vf_inside(p, d) ? (uint)win[vf_win_index(p - corner)] : wall)
                     << (8 * c);
        }
        if (!vf_may_move(cells, sand, water)) {
            continue;
        }
        ulong after;
        if ((cells & 0xFFFFFFFFul) == 0) {
            const ulong falls = vf_bytes_equal(cells, sand) | vf_bytes_equal(cells, water);
            after = (cells & ~falls) | ((cells & falls) >> 32);
        } else {
            uint below_air = 0;
            for (int c = 0; c < 4; ++c) {
                const int3 p = vf_cell(origin, c) - (int3)(0, 1, 0);
                if (vf_get(cells, c) == water && vf_inside(p, d) &&
                    win[vf_win_index(p - corner)] == 0) {
                    below_air |= 1u << c;
                }
            }
            const ulong block =
                ((ulong)b.z * (ulong)nb.y + (ulong)b.y) * (ulong)nb.x + (ulong)b.x;
            after = vf_sand_rules(cells, below_air, vf_sand_hash(key ^ block), sand, water);
        }
        for (ulong changed = vf_nonzero_bytes(cells ^ after); changed != 0;) {
            const ulong bit = changed & (~changed + 1);
            changed ^= bit;
            const int c = (63 - (int)clz(bit)) >> 3;
            const int3 p = vf_cell(origin, c);
            win[vf_win_index(p - corner)] = (uchar)vf_get(after, c);
            if (all(p >= lo) && all(p < hi)) {
                ++count;
                vf_boxes_add(&boxes, p - corner, 0, 0);
            }
        }
    }
    if (count != 0) {
        global uint* s = summary + 8 * w;
        atomic_add(s, count);
        vf_box_merge(s + 1, (int4)(VF_WIN_X, VF_WIN_Y, VF_WIN_Z, 0), boxes.lo, boxes.hi);
    }
}
