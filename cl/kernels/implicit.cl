/* Implicit surfaces discretised into a tile grid of contrees (the reference blog, farfa.dev
 * "implicit surface rendering for CAD": recursive interval pruning, then 5^3 shared corner
 * samples per leaf of 4^3 voxels). The tape (sdf_layout.hpp and implicit_tape.cl, prepended)
 * is interpreted here in intervals, and in floats and forward-mode dual numbers by
 * implicit_eval.cl (prepended twice: scalar, and EV_W lanes for the CPU layout), in the same
 * operation order as core/src/sdf_eval.cpp. Distance bounds after Inigo Quilez's "distance functions" article. */
/* ------------------------------------------------------------- intervals (lo, hi) */

inline float2 i_sub(float2 a, float2 b) {
    return (float2)(a.x - b.y, a.y - b.x);
}
inline float2 i_add(float2 a, float2 b) {
    return (float2)(a.x + b.x, a.y + b.y);
}
inline float2 i_subs(float2 a, float s) {
    return (float2)(a.x - s, a.y - s);
}
inline float2 i_smul(float s, float2 a) {
    const float x = s * a.x, y = s * a.y;
    return (float2)(fmin(x, y), fmax(x, y));
}
inline float2 i_divs(float2 a, float s) {
    const float x = a.x / s, y = a.y / s;
    return (float2)(fmin(x, y), fmax(x, y));
}
inline float2 i_abs(float2 a) {
    if (a.x >= 0) {
        return a;
    }
    if (a.y <= 0) {
        return (float2)(-a.y, -a.x);
    }
    return (float2)(0.0f, fmax(-a.x, a.y));
}
inline float2 i_sq(float2 a) {
    const float2 m = i_abs(a);
    return (float2)(m.x * m.x, m.y * m.y);
}
inline float2 i_min(float2 a, float2 b) {
    return (float2)(fmin(a.x, b.x), fmin(a.y, b.y));
}
inline float2 i_max(float2 a, float2 b) {
    return (float2)(fmax(a.x, b.x), fmax(a.y, b.y));
}
inline float2 i_mins(float2 a, float s) {
    return (float2)(fmin(a.x, s), fmin(a.y, s));
}
inline float2 i_maxs(float2 a, float s) {
    return (float2)(fmax(a.x, s), fmax(a.y, s));
}
inline float2 i_len2(float2 a, float2 b) {
    const float2 s = i_add(i_sq(a), i_sq(b));
    return (float2)(sqrt(fmax(s.x, 0.0f)), sqrt(fmax(s.y, 0.0f)));
}
inline float2 i_len3(float2 a, float2 b, float2 c) {
    const float2 s = i_add(i_add(i_sq(a), i_sq(b)), i_sq(c));
    return (float2)(sqrt(fmax(s.x, 0.0f)), sqrt(fmax(s.y, 0.0f)));
}

inline float2 i_box(float2 dx, float2 dy, float2 dz, float sx, float sy, float sz) {
    const float2 qx = i_subs(i_abs(dx), sx), qy = i_subs(i_abs(dy), sy), qz = i_subs(i_abs(dz), sz);
    const float2 outside = i_len3(i_maxs(qx, 0.0f), i_maxs(qy, 0.0f), i_maxs(qz, 0.0f));
    return i_add(outside, i_mins(i_max(qx, i_max(qy, qz)), 0.0f));
}

inline float2 i_primitive(__global const Instr* in, float2 x, float2 y, float2 z) {
    __global const float* p = in->p;
    switch (in->op) {
        case VF_SDF_SPHERE:
            return i_subs(i_len3(i_subs(x, p[0]), i_subs(y, p[1]), i_subs(z, p[2])), p[3]);
        case VF_SDF_BOX:
            return i_box(i_subs(x, p[0]), i_subs(y, p[1]), i_subs(z, p[2]), p[3], p[4], p[5]);
        case VF_SDF_ROUND_BOX:
            return i_subs(i_box(i_subs(x, p[0]), i_subs(y, p[1]), i_subs(z, p[2]), p[3] - p[6],
                                p[4] - p[6], p[5] - p[6]),
                          p[6]);
        case VF_SDF_CYLINDER: {
            const float2 a = i_subs(i_len2(i_subs(x, p[0]), i_subs(z, p[2])), p[3]);
            const float2 b = i_subs(i_abs(i_subs(y, p[1])), p[4]);
            return i_add(i_mins(i_max(a, b), 0.0f), i_len2(i_maxs(a, 0.0f), i_maxs(b, 0.0f)));
        }
        case VF_SDF_TORUS: {
            const float2 a = i_subs(i_len2(i_subs(x, p[0]), i_subs(z, p[2])), p[3]);
            return i_subs(i_len2(a, i_subs(y, p[1])), p[4]);
        }
        case VF_SDF_CAPSULE: {
            const float bx = p[3] - p[0], by = p[4] - p[1], bz = p[5] - p[2];
            const float dd = bx * bx + by * by + bz * bz;
            const float2 ax = i_subs(x, p[0]), ay = i_subs(y, p[1]), az = i_subs(z, p[2]);
            const float2 dot = i_add(i_add(i_smul(bx, ax), i_smul(by, ay)), i_smul(bz, az));
            const float2 h =
                dd > 0 ? i_mins(i_maxs(i_divs(dot, dd), 0.0f), 1.0f) : i_smul(0.0f, dot);
            return i_subs(i_len3(i_sub(ax, i_smul(bx, h)), i_sub(ay, i_smul(by, h)),
                                 i_sub(az, i_smul(bz, h))),
                          p[6]);
        }
        default:
            return i_subs(i_add(i_add(i_smul(p[0], x), i_smul(p[1], y)), i_smul(p[2], z)), p[3]);
    }
}

/* The smooth minimum is non-decreasing in both operands: its endpoints bound it, widened by a
 * few ulps since its float evaluation need not be exactly monotone. */
inline float2 i_smooth_min(float2 a, float2 b, float k) {
    const float lo = f_smooth_min(a.x, b.x, k), hi = f_smooth_min(a.y, b.y, k);
    const float e = 8 * FLT_EPSILON;
    return (float2)(lo - e * (fabs(lo) + k), hi + e * (fabs(hi) + k));
}

/* Marks instructions first..last (inclusive) as not needed. */
inline void drop_range(uchar* live, uint first, uint last) {
    for (uint j = first; j <= last; ++j) {
        live[j] = 0;
    }
}

/* Where the box shows one operand of a binary operator at instruction i is never selected, marks
 * the other operand's code and the operator as not needed: the result is then exactly the
 * selected operand's, value, gradient and material (for the smooth operators: when the operands
 * are k apart, h = 0). A difference keeps A's material, so its A is never dropped. */
inline void decide(__global const Instr* in, uint i, float2 a, float2 b, uchar* live) {
    const uint op = in->op;
    const float k = in->p[0];
    const uint a_start = (uint)in->p[1], b_start = (uint)in->p[2];
    bool keep_a = false, keep_b = false;
    if (op == VF_SDF_MIN) {
        keep_a = a.y <= b.x;
        keep_b = b.y < a.x;
    } else if (op == VF_SDF_MAX) {
        keep_a = a.x >= b.y;
        keep_b = b.x > a.y;
    } else if (op == VF_SDF_DIFF) {
        keep_a = a.x >= -b.x;
    } else if (op == VF_SDF_SMOOTH_MIN) {
        keep_a = b.x - a.y >= k;
        keep_b = a.x - b.y >= k;
    } else {
        keep_a = b.x + a.x >= k; /* smooth_min(-A, B): B - (-A) >= k */
    }
    if (keep_a) {
        drop_range(live, b_start, i);
    } else if (keep_b) {
        drop_range(live, a_start, b_start - 1);
        live[i] = 0;
    }
}

/* An enclosure of the value over the box x * y * z; with `live` (tapes up to
 * VF_SDF_SPECIALISE_MAX), also marks the instructions the box does not need. */
float2 eval_i(__global const Instr* tape, uint n, float2 x, float2 y, float2 z, uchar* live) {
    float2 v[VF_SDF_STACK];
    float2 px[VF_SDF_STACK], py[VF_SDF_STACK], pz[VF_SDF_STACK];
    int nv = 0, np = 0;
    px[0] = x;
    py[0] = y;
    pz[0] = z;
    for (uint i = 0; i < n; ++i) {
        __global const Instr* in = tape + i;
        const uint op = in->op;
        if (op <= VF_SDF_PLANE) {
            v[nv++] = i_primitive(in, px[np], py[np], pz[np]);
        } else if (op <= VF_SDF_SMOOTH_DIFF) {
            const float2 b = v[--nv], a = v[nv - 1];
            const float k = in->p[0];
            if (live) {
                decide(in, i, a, b, live);
            }
            if (op == VF_SDF_MIN) {
                v[nv - 1] = i_min(a, b);
            } else if (op == VF_SDF_MAX) {
                v[nv - 1] = i_max(a, b);
            } else if (op == VF_SDF_DIFF) {
                v[nv - 1] = i_max(a, -b.yx);
            } else if (op == VF_SDF_SMOOTH_MIN) {
                v[nv - 1] = i_smooth_min(a, b, k);
            } else {
                v[nv - 1] = -i_smooth_min(-a.yx, b, k).yx;
            }
        } else if (op == VF_SDF_SHELL) {
            v[nv - 1] = i_subs(i_abs(v[nv - 1]), in->p[0]);
        } else if (op == VF_SDF_PUSH_POINT) {
            __global const float* p = in->p;
            const float2 dx = i_subs(px[np], p[9]), dy = i_subs(py[np], p[10]),
                         dz = i_subs(pz[np], p[11]);
            ++np;
            px[np] = i_add(i_add(i_smul(p[0], dx), i_smul(p[1], dy)), i_smul(p[2], dz));
            py[np] = i_add(i_add(i_smul(p[3], dx), i_smul(p[4], dy)), i_smul(p[5], dz));
            pz[np] = i_add(i_add(i_smul(p[6], dx), i_smul(p[7], dy)), i_smul(p[8], dz));
        } else {
            --np;
            v[nv - 1] = i_smul(in->p[0], v[nv - 1]);
        }
    }
    return v[0];
}

/* ------------------------------------------------------------------ the tile grid */

/* eval_i over the voxels [i, i1) x [j, j1) x [k, k1) of the grid. */
inline float2 eval_cells(__global const Instr* tape, uint n, Grid g, uint i, uint j, uint k,
                         uint i1, uint j1, uint k1, uchar* live) {
    return eval_i(tape, n, (float2)(corner_at(g.x0, g.h, i), corner_at(g.x0, g.h, i1)),
                  (float2)(corner_at(g.y0, g.h, j), corner_at(g.y0, g.h, j1)),
                  (float2)(corner_at(g.z0, g.h, k), corner_at(g.z0, g.h, k1)), live);
}

/* The class of the cell of `edge` voxels at voxel (i, j, k), clipped to the grid: empty when
 * its interval is above 0, full when below, else ambiguous; a cell outside the grid is empty. */
uint classify_cell(__global const Instr* tape, uint n, Grid g, uint i, uint j, uint k, uint edge) {
    if (i >= g.nx || j >= g.ny || k >= g.nz) {
        return VF_SDF_CELL_EMPTY;
    }
    const uint i1 = min(i + edge, g.nx), j1 = min(j + edge, g.ny), k1 = min(k + edge, g.nz);
    const float2 r = eval_cells(tape, n, g, i, j, k, i1, j1, k1, 0);
    if (r.x > 0) {
        return VF_SDF_CELL_EMPTY;
    }
    return r.y < 0 ? VF_SDF_CELL_FULL : VF_SDF_CELL_AMBIGUOUS;
}

/* One work-item per tile of `edge` voxels, tiles (tx, ty, tz) x fastest. */
__kernel void classify_tiles(__global const Instr* tape, uint n, Grid g, uint tx, uint ty,
                             uint tiles, uint edge, __global uchar* out) {
    const uint t = get_global_id(0);
    if (t >= tiles) {
        return;
    }
    out[t] = (uchar)classify_cell(tape, n, g, t % tx * edge, t / tx % ty * edge, t / tx / ty * edge,
                                  edge);
}

/* One work-item per child (64 per node) of the nodes whose origins (voxels) are listed. */
__kernel void classify_children(__global const Instr* tape, uint n, Grid g,
                                __global const uint4* origins, uint count, uint child_edge,
                                __global uchar* out) {
    const uint id = get_global_id(0);
    if (id >= count * 64) {
        return;
    }
    const uint4 o = origins[id / 64];
    const uint c = id % 64;
    out[id] = (uchar)classify_cell(tape, n, g, o.x + (c & 3) * child_edge,
                                   o.y + (c >> 2 & 3) * child_edge, o.z + (c >> 4) * child_edge,
                                   child_edge);
}

/* The leaf at voxel o's specialised tape: the instructions its box (clipped to the grid, which
 * holds every corner it keeps) needs, in order, into list; returns how many. */
uint specialise(__global const Instr* tape, uint n, Grid g, uint4 o, ushort* list) {
    uchar live[VF_SDF_SPECIALISE_MAX];
    for (uint i = 0; i < n; ++i) {
        live[i] = 1;
    }
    const uint i1 = min(o.x + 4, g.nx), j1 = min(o.y + 4, g.ny), k1 = min(o.z + 4, g.nz);
    eval_cells(tape, n, g, o.x, o.y, o.z, i1, j1, k1, live);
    uint m = 0;
    for (uint i = 0; i < n; ++i) {
        if (live[i]) {
            list[m++] = (ushort)i;
        }
    }
    return m;
}

inline uint corner_index(uint v, uint c) {
    /* voxel v = x + 4 y + 16 z of a leaf, corner c = cx + 2 cy + 4 cz -> x + 5 y + 25 z */
    return (v & 3) + (c & 1) + 5 * ((v >> 2 & 3) + (c >> 1 & 1)) + 25 * ((v >> 4) + (c >> 2));
}

inline uint rank_below(const uint* bits, uint i) {
    uint r = 0;
    for (uint w = 0; w < i / 32; ++w) {
        r += popcount(bits[w]);
    }
    return r + (i % 32 ? popcount(bits[i / 32] & ((1u << (i % 32)) - 1u)) : 0u);
}

/* Reserves a leaf's vertex and voxel records (counters[0]: vertices reserved, counters[1]:
 * voxel records reserved) and writes its node record. When the reservations fit the
 * capacities, the kernels below then write its voxel records (crossed voxels in mask order)
 * and vertex records (its kept corners in index order). */
inline void leaf_reserve(__global uint* counters, __global uint* nodes, uint node, uint kept_count,
                         uint cross_count, uint2 occ, uint2 solid, uint* voff, uint* xoff) {
    *voff = kept_count ? atomic_add(&counters[0], kept_count) : 0u;
    *xoff = cross_count ? atomic_add(&counters[1], cross_count) : 0u;
    __global uint* rec = nodes + node * VF_SDF_NODE_WORDS;
    rec[0] = *xoff;
    rec[1] = *voff;
    rec[2] = occ.x;
    rec[3] = occ.y;
    rec[4] = solid.x;
    rec[5] = solid.y;
}

/* The first two words of voxel v's record: the ranks among the kept corners of its corners
 * 0..3 and 4..7, a byte each. */
inline uint2 voxel_corner_words(const uint* kept, uint v) {
    uint w0 = 0, w1 = 0;
    for (uint c = 0; c < 4; ++c) {
        w0 |= rank_below(kept, corner_index(v, c)) << (8 * c);
        w1 |= rank_below(kept, corner_index(v, c + 4)) << (8 * c);
    }
    return (uint2)(w0, w1);
}

/* corner_at and centre_at per lane. */
inline FTV corner_at_v(float x0, float h, UTV i) {
    return x0 + EV_CONVERT(i) * h;
}
inline FTV centre_at_v(float x0, float h, UTV i) {
    return x0 + (EV_CONVERT(i) + 0.5f) * h;
}

/* CPU layout: one work-item per leaf, its 125 shared corners and 64 centres in one batch,
 * EV_W points per instruction fetch (eval_f_v: the vector instance of implicit_eval.cl). */
__kernel void sample_leaves_seq(__global const Instr* tape, uint n, Grid g,
                                __global const uint4* leaves, uint count, __global uint* nodes,
                                __global uint* voxels, uint voxel_capacity,
                                __global float4* vertices, uint vertex_capacity,
                                __global uint* counters) {
    const uint id = get_global_id(0);
    if (id >= count) {
        return;
    }
    const uint4 o = leaves[id]; /* origin, node index in w */
    ushort list[VF_SDF_SPECIALISE_MAX];
    const bool special = n <= VF_SDF_SPECIALISE_MAX;
    const uint m = special ? specialise(tape, n, g, o, list) : n;
    const ushort* run = special ? list : 0;
    /* Lanes past the last corner or centre evaluate a repeat of it into the padding. */
    float f[128 + EV_W];
    float centre_f[64];
    int centre_mat[64];
    for (uint c0 = 0; c0 < 125; c0 += EV_W) {
        const UTV c = min(c0 + EV_IOTA, (UTV)124u);
        MTV mat;
        const FTV fv = eval_f_v(tape, run, m, corner_at_v(g.x0, g.h, o.x + c % 5u),
                                corner_at_v(g.y0, g.h, o.y + c / 5u % 5u),
                                corner_at_v(g.z0, g.h, o.z + c / 25u), &mat);
        EV_STORE(fv, 0, f + c0);
    }
    for (uint v0 = 0; v0 < 64; v0 += EV_W) {
        const UTV v = v0 + EV_IOTA;
        MTV mat;
        const FTV fv = eval_f_v(tape, run, m, centre_at_v(g.x0, g.h, o.x + (v & 3u)),
                                centre_at_v(g.y0, g.h, o.y + (v >> 2 & 3u)),
                                centre_at_v(g.z0, g.h, o.z + (v >> 4)), &mat);
        EV_STORE(fv, 0, centre_f + v0);
        EV_STORE(mat, 0, centre_mat + v0);
    }
    uint occ[2] = {0u, 0u}, solid[2] = {0u, 0u}, kept[4] = {0u, 0u, 0u, 0u};
    uchar mats[64];
    for (uint v = 0; v < 64; ++v) {
        const uint i = o.x + (v & 3), j = o.y + (v >> 2 & 3), k = o.z + (v >> 4);
        mats[v] = 0;
        if (i >= g.nx || j >= g.ny || k >= g.nz) {
            continue;
        }
        const float fc = centre_f[v];
        mats[v] = (uchar)centre_mat[v];
        uint inside = fc < 0 ? 1u : 0u, outside = fc < 0 ? 0u : 1u;
        for (uint c = 0; c < 8; ++c) {
            const float fv = f[corner_index(v, c)];
            inside |= fv < 0 ? 1u : 0u;
            outside |= fv < 0 ? 0u : 1u;
        }
        if (fc < 0) {
            solid[v / 32] |= 1u << (v % 32);
        }
        if (inside && outside) {
            occ[v / 32] |= 1u << (v % 32);
            for (uint c = 0; c < 8; ++c) {
                const uint ci = corner_index(v, c);
                kept[ci / 32] |= 1u << (ci % 32);
            }
        }
    }
    const uint kept_count =
        popcount(kept[0]) + popcount(kept[1]) + popcount(kept[2]) + popcount(kept[3]);
    const uint cross_count = popcount(occ[0]) + popcount(occ[1]);
    uint voff, xoff;
    leaf_reserve(counters, nodes, o.w, kept_count, cross_count, (uint2)(occ[0], occ[1]),
                 (uint2)(solid[0], solid[1]), &voff, &xoff);
    if (voff + kept_count > vertex_capacity || xoff + cross_count > voxel_capacity) {
        return; /* the host reruns with the capacities the counters reached */
    }
    /* The kept corners in index order, EV_W gradients per instruction fetch (the last batch
     * repeats the last corner). */
    uint kept_list[128 + EV_W];
    uint r = 0;
    for (uint c = 0; c < 125; ++c) {
        if (kept[c / 32] >> (c % 32) & 1u) {
            kept_list[r++] = c;
        }
    }
    for (uint q = r; q < r + EV_W; ++q) {
        kept_list[q] = r ? kept_list[r - 1] : 0u;
    }
    for (uint r0 = 0; r0 < r; r0 += EV_W) {
        const UTV c = EV_LOAD(0, kept_list + r0);
        const Dual_v d = eval_d_v(tape, run, m, corner_at_v(g.x0, g.h, o.x + c % 5u),
                                  corner_at_v(g.y0, g.h, o.y + c / 5u % 5u),
                                  corner_at_v(g.z0, g.h, o.z + c / 25u));
        float gx[EV_W], gy[EV_W], gz[EV_W];
        EV_STORE(d.x, 0, gx);
        EV_STORE(d.y, 0, gy);
        EV_STORE(d.z, 0, gz);
        for (uint l = 0; l < EV_W && r0 + l < r; ++l) {
            vertices[voff + r0 + l] = (float4)(gx[l], gy[l], gz[l], f[kept_list[r0 + l]]);
        }
    }
    uint x = 0;
    for (uint v = 0; v < 64; ++v) {
        if (occ[v / 32] >> (v % 32) & 1u) {
            const uint2 w = voxel_corner_words(kept, v);
            __global uint* rec = voxels + (xoff + x++) * VF_SDF_VOXEL_WORDS;
            rec[0] = w.x;
            rec[1] = w.y;
            rec[2] = mats[v];
        }
    }
}

/* GPU layout: one work-group of 128 per leaf; work-item c < 125 samples corner c, v < 64 the
 * centre of voxel v, sharing them in local memory. */
__kernel __attribute__((reqd_work_group_size(128, 1, 1))) void sample_leaves_group(
    __global const Instr* tape, uint n, Grid g, __global const uint4* leaves, uint count,
    __global uint* nodes, __global uint* voxels, uint voxel_capacity, __global float4* vertices,
    uint vertex_capacity, __global uint* counters) {
    __local float f[125];
    __local uint occ[2], solid[2], kept[4], offsets[2], special_count;
    __local ushort special_list[VF_SDF_SPECIALISE_MAX];
    const uint id = get_group_id(0), lid = get_local_id(0);
    if (id >= count) {
        return;
    }
    const uint4 o = leaves[id];
    const bool special = n <= VF_SDF_SPECIALISE_MAX;
    if (special && lid == 0) {
        ushort l[VF_SDF_SPECIALISE_MAX];
        special_count = specialise(tape, n, g, o, l);
        for (uint t = 0; t < special_count; ++t) {
            special_list[t] = l[t];
        }
    }
    barrier(CLK_LOCAL_MEM_FENCE);
    ushort list[VF_SDF_SPECIALISE_MAX];
    const uint m = special ? special_count : n;
    for (uint t = 0; special && t < m; ++t) {
        list[t] = special_list[t];
    }
    const ushort* run = special ? list : 0;
    if (lid < 4) {
        kept[lid] = 0;
    }
    if (lid < 2) {
        occ[lid] = 0;
        solid[lid] = 0;
    }
    uint material = 0;
    if (lid < 125) {
        const uint i = o.x + lid % 5, j = o.y + lid / 5 % 5, k = o.z + lid / 25;
        f[lid] = eval_f(tape, run, m, corner_at(g.x0, g.h, i), corner_at(g.y0, g.h, j),
                        corner_at(g.z0, g.h, k), &material);
    }
    float fc = 1.0f;
    bool in_grid = false;
    if (lid < 64) {
        const uint i = o.x + (lid & 3), j = o.y + (lid >> 2 & 3), k = o.z + (lid >> 4);
        in_grid = i < g.nx && j < g.ny && k < g.nz;
        if (in_grid) {
            fc = eval_f(tape, run, m, centre_at(g.x0, g.h, i), centre_at(g.y0, g.h, j),
                        centre_at(g.z0, g.h, k), &material);
        }
    }
    barrier(CLK_LOCAL_MEM_FENCE);
    bool crossed = false;
    if (lid < 64 && in_grid) {
        uint inside = fc < 0 ? 1u : 0u, outside = fc < 0 ? 0u : 1u;
        for (uint c = 0; c < 8; ++c) {
            const float fv = f[corner_index(lid, c)];
            inside |= fv < 0 ? 1u : 0u;
            outside |= fv < 0 ? 0u : 1u;
        }
        crossed = inside && outside;
        if (fc < 0) {
            atomic_or(&solid[lid / 32], 1u << (lid % 32));
        }
        if (crossed) {
            atomic_or(&occ[lid / 32], 1u << (lid % 32));
            for (uint c = 0; c < 8; ++c) {
                const uint ci = corner_index(lid, c);
                atomic_or(&kept[ci / 32], 1u << (ci % 32));
            }
        }
    }
    barrier(CLK_LOCAL_MEM_FENCE);
    const uint kept_count =
        popcount(kept[0]) + popcount(kept[1]) + popcount(kept[2]) + popcount(kept[3]);
    const uint cross_count = popcount(occ[0]) + popcount(occ[1]);
    if (lid == 0) {
        uint voff, xoff;
        leaf_reserve(counters, nodes, o.w, kept_count, cross_count, (uint2)(occ[0], occ[1]),
                     (uint2)(solid[0], solid[1]), &voff, &xoff);
        offsets[0] = voff;
        offsets[1] = xoff;
    }
    barrier(CLK_LOCAL_MEM_FENCE);
    const uint voff = offsets[0], xoff = offsets[1];
    if (voff + kept_count > vertex_capacity || xoff + cross_count > voxel_capacity) {
        return;
    }
    uint kept_bits[4] = {kept[0], kept[1], kept[2], kept[3]};
    if (lid < 125 && (kept_bits[lid / 32] >> (lid % 32) & 1u)) {
        const uint i = o.x + lid % 5, j = o.y + lid / 5 % 5, k = o.z + lid / 25;
        const Dual d = eval_d(tape, run, m, corner_at(g.x0, g.h, i), corner_at(g.y0, g.h, j),
                              corner_at(g.z0, g.h, k));
        vertices[voff + rank_below(kept_bits, lid)] = (float4)(d.x, d.y, d.z, f[lid]);
    }
    if (crossed) {
        uint occ_bits[2] = {occ[0], occ[1]};
        const uint2 w = voxel_corner_words(kept_bits, lid);
        __global uint* rec = voxels + (xoff + rank_below(occ_bits, lid)) * VF_SDF_VOXEL_WORDS;
        rec[0] = w.x;
        rec[1] = w.y;
        rec[2] = material;
    }
}

/* Brute force, for checking: f at every corner ((nx + 1) (ny + 1) (nz + 1), x fastest) and at
 * every centre (nx ny nz). */
__kernel void sample_corners(__global const Instr* tape, uint n, Grid g, __global float* out) {
    const size_t id = get_global_id(0);
    const size_t nx = g.nx + 1, ny = g.ny + 1;
    if (id >= nx * ny * (g.nz + 1)) {
        return;
    }
    const uint i = (uint)(id % nx), j = (uint)(id / nx % ny), k = (uint)(id / nx / ny);
    uint material;
    out[id] = eval_f(tape, 0, n, corner_at(g.x0, g.h, i), corner_at(g.y0, g.h, j),
                     corner_at(g.z0, g.h, k), &material);
}

__kernel void sample_centres(__global const Instr* tape, uint n, Grid g, __global float* out) {
    const size_t id = get_global_id(0);
    if (id >= (size_t)g.nx * g.ny * g.nz) {
        return;
    }
    const uint i = (uint)(id % g.nx), j = (uint)(id / g.nx % g.ny), k = (uint)(id / g.nx / g.ny);
    uint material;
    out[id] = eval_f(tape, 0, n, centre_at(g.x0, g.h, i), centre_at(g.y0, g.h, j),
                     centre_at(g.z0, g.h, k), &material);
}
