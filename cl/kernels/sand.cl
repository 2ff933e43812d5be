// Falling sand and water, one step of the 3-D block automaton whose rules and reference are
// core/include/voxfield/core/sand.hpp and core/src/sand.cpp, which this matches bit for bit.
// Source: Toffoli & Margolus, "Cellular Automata Machines" (1987), ch. 12 (Margolus blocks).
//
// Two copies of the world that agree before every step: a step reads `src` and writes only the
// voxels it changes into `dst`, appending each to `changes` as (linear index, before | after
// << 8) at a slot taken from `count` (slots past `capacity` are counted but not written: the
// host grows the list and runs the step again, which writes the same values); sand_sync then
// writes the changes into `src` as well. A block is held in a ulong, byte k = 4 * layer +
// column (layer 0 bottom, 1 top; column dx + 2 * dz); cells outside the world hold `wall`, a
// value that is neither air, sand nor water, so nothing moves into or out of them.
// d: world size; o: the step's block offset; nb: blocks per axis; key: sand_step_key.

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

// Runs block b (block coordinates, origin its cell 0) of the step, holding `cells`.
void vf_sand_run(global const uchar* src, global uchar* dst, int4 d, int4 nb, ulong key, uint sand,
                 uint water, global uint* count, global uint2* changes, uint capacity, int3 b,
                 int3 origin, ulong cells) {
    uint below_air = 0;
    for (int c = 0; c < 4; ++c) {
        const int3 p = vf_cell(origin, c) - (int3)(0, 1, 0);
        if (vf_get(cells, c) == water && vf_inside(p, d) && src[vf_index(p, d)] == 0) {
            below_air |= 1u << c;
        }
    }
    const ulong block = ((ulong)b.z * (ulong)nb.y + (ulong)b.y) * (ulong)nb.x + (ulong)b.x;
    const ulong after = vf_sand_rules(cells, below_air, vf_sand_hash(key ^ block), sand, water);
    if (after == cells) {
        return;
    }
    uint n = 0;
    for (int k = 0; k < 8; ++k) {
        n += vf_get(after, k) != vf_get(cells, k) ? 1u : 0u;
    }
    uint slot = atomic_add(count, n);
    for (int k = 0; k < 8; ++k) {
        const uint was = vf_get(cells, k), now = vf_get(after, k);
        if (was != now) {
            const ulong i = vf_index(vf_cell(origin, k), d);
            dst[i] = (uchar)now;
            if (slot < capacity) {
                changes[slot] = (uint2)((uint)i, was | (now << 8));
            }
            ++slot;
        }
    }
}

// Runs block b of the step, reading its cells with bounds checks.
void vf_sand_block(global const uchar* src, global uchar* dst, int4 d, int4 o, int4 nb, ulong key,
                   uint sand, uint water, uint wall, global uint* count, global uint2* changes,
                   uint capacity, int3 b) {
    const int3 origin = 2 * b - o.xyz;
    ulong cells = 0;
    for (int k = 0; k < 8; ++k) {
        const int3 p = vf_cell(origin, k);
        cells |= (ulong)(vf_inside(p, d) ? (uint)src[vf_index(p, d)] : wall) << (8 * k);
    }
    if (vf_may_move(cells, sand, water)) {
        vf_sand_run(src, dst, d, nb, key, sand, water, count, changes, capacity, b, origin, cells);
    }
}

// GPU layout: one work-item per block, global size (nb.x, nb.y, nb.z) rounded up.
kernel void sand_step_blocks(global const uchar* src, global uchar* dst, int4 d, int4 o, int4 nb,
                             ulong key, uint sand, uint water, uint wall, global uint* count,
                             global uint2* changes, uint capacity) {
    const int3 b = (int3)((int)get_global_id(0), (int)get_global_id(1), (int)get_global_id(2));
    if (b.x < nb.x && b.y < nb.y && b.z < nb.z) {
        vf_sand_block(src, dst, d, o, nb, key, sand, water, wall, count, changes, capacity, b);
    }
}

// CPU layout: one work-item per row of blocks along x, global size (nb.y, nb.z). Where the
// row's four lines of voxels lie inside the world, blocks are read straight from them and runs
// of eight blocks that cannot move (vf_may_move) are skipped by 16-byte loads.
kernel void sand_step_rows(global const uchar* src, global uchar* dst, int4 d, int4 o, int4 nb,
                           ulong key, uint sand, uint water, uint wall, global uint* count,
                           global uint2* changes, uint capacity) {
    const int j = (int)get_global_id(0), k = (int)get_global_id(1);
    if (j >= nb.y || k >= nb.z) {
        return;
    }
    const int y0 = 2 * j - o.y, z0 = 2 * k - o.z;
    if (y0 < 0 || z0 < 0 || y0 + 1 >= d.y || z0 + 1 >= d.z) {
        for (int i = 0; i < nb.x; ++i) {
            vf_sand_block(src, dst, d, o, nb, key, sand, water, wall, count, changes, capacity,
                          (int3)(i, j, k));
        }
        return;
    }
    // Line r = 2 * layer + dz of the row.
    global const uchar* line[4];
    for (int r = 0; r < 4; ++r) {
        line[r] = src + vf_index((int3)(0, y0 + (r >> 1), z0 + (r & 1)), d);
    }
    const uchar16 s16 = (uchar16)((uchar)sand), w16 = (uchar16)((uchar)water);
    for (int i = 0; i < nb.x;) {
        const int x0 = 2 * i - o.x;
        if (x0 < 0 || x0 + 1 >= d.x) {
            vf_sand_block(src, dst, d, o, nb, key, sand, water, wall, count, changes, capacity,
                          (int3)(i, j, k));
            ++i;
            continue;
        }
        if (x0 + 16 <= d.x) {
            // Lines 0, 1 are the bottom layer, 2, 3 the top; lanes 2i, 2i + 1 are block i's.
            char16 air = (char16)(0), wet = (char16)(0), wet_bottom = (char16)(0);
            char16 top_sand = (char16)(0);
            for (int r = 0; r < 4; ++r) {
                const uchar16 v = vload16(0, line[r] + x0);
                air |= v == (uchar16)(0);
                wet |= v == w16;
                if (r < 2) {
                    wet_bottom |= v == w16;
                } else {
                    top_sand |= v == s16;
                }
            }
            const char8 a = air.even | air.odd, w = wet.even | wet.odd;
            const char8 wb = wet_bottom.even | wet_bottom.odd, ts = top_sand.even | top_sand.odd;
            if (!any((a & (w | ts)) | (ts & wb))) {
                i += 8;
                continue;
            }
        }
        ulong cells = 0;
        for (int q = 0; q < 8; ++q) {  // cell q = 4 * layer + dx + 2 * dz
            cells |= (ulong)line[2 * (q >> 2) + ((q >> 1) & 1)][x0 + (q & 1)] << (8 * q);
        }
        if (vf_may_move(cells, sand, water)) {
            vf_sand_run(src, dst, d, nb, key, sand, water, count, changes, capacity,
                        (int3)(i, j, k), (int3)(x0, y0, z0), cells);
        }
        ++i;
    }
}

// Writes a step's changes into the other copy of the world.
kernel void sand_sync(global uchar* world, global const uint2* changes, uint count) {
    const uint i = get_global_id(0);
    if (i < count) {
        world[changes[i].x] = (uchar)(changes[i].y >> 8);
    }
}
