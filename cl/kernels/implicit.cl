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

/* An enclosure of the value over the box x * y * z, running the instructions list[0..m) (or
 * 0..m when list is 0); with `live` (indexed by instruction, tapes up to
 * VF_SDF_SPECIALISE_MAX), also clears the instructions the box does not need. */
float2 eval_i(__global const Instr* tape, const ushort* list, uint m, float2 x, float2 y,
              float2 z, uchar* live) {
    float2 v[VF_SDF_STACK];
    float2 px[VF_SDF_STACK], py[VF_SDF_STACK], pz[VF_SDF_STACK];
    int nv = 0, np = 0;
    px[0] = x;
    py[0] = y;
    pz[0] = z;
    for (uint t = 0; t < m; ++t) {
        const uint i = list ? list[t] : t;
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
inline float2 eval_cells(__global const Instr* tape, const ushort* list, uint m, Grid g, uint i,
                         uint j, uint k, uint i1, uint j1, uint k1, uchar* live) {
    return eval_i(tape, list, m, (float2)(corner_at(g.x0, g.h, i), corner_at(g.x0, g.h, i1)),
                  (float2)(corner_at(g.y0, g.h, j), corner_at(g.y0, g.h, j1)),
                  (float2)(corner_at(g.z0, g.h, k), corner_at(g.z0, g.h, k1)), live);
}

/* The class of the cell of `edge` voxels at voxel (i, j, k), clipped to the grid: empty when
 * its interval is above 0, full when below, else ambiguous; a cell outside the grid is empty. */
uint classify_cell(__global const Instr* tape, const ushort* list, uint m, Grid g, uint i, uint j,
                   uint k, uint edge) {
    if (i >= g.nx || j >= g.ny || k >= g.nz) {
        return VF_SDF_CELL_EMPTY;
    }
    const uint i1 = min(i + edge, g.nx), j1 = min(j + edge, g.ny), k1 = min(k + edge, g.nz);
    const float2 r = eval_cells(tape, list, m, g, i, j, k, i1, j1, k1, 0);
    if (r.x > 0) {
        return VF_SDF_CELL_EMPTY;
    }
    return r.y < 0 ? VF_SDF_CELL_FULL : VF_SDF_CELL_AMBIGUOUS;
}

/* Levels on the device (no host between them): the nodes of level L are numbered from
 * level_base(L) = the nodes of the levels above it (counters[0..L)), in any order; a node's
 * children are reserved in one block by one atomic and packed in mask order. Kernels of a level
 * read its count from counters and store only what fits the capacities the host gave them. */
inline uint level_base(__global const uint* counters, uint level) {
    uint base = 0;
    for (uint l = 0; l < level; ++l) {
        base += counters[l];
    }
    return base;
}

/* The class of the cell of `edge` voxels at voxel (i, j, k) as classify_cell gives it, by the
 * instructions list[0..m) (the whole tape when list is 0 and m = n); for tapes up to
 * VF_SDF_SPECIALISE_MAX also the cell's specialised tape: those instructions less the operands its
 * box (clipped to the grid, which holds every corner it samples) shows are never selected there,
 * in order, into out, *kept of them (0 for a cell outside the grid). A child's box lies in its
 * parent's, so what the parent dropped the child never selects either. */
uint classify_special(__global const Instr* tape, uint n, const ushort* list, uint m, Grid g,
                      uint i, uint j, uint k, uint edge, ushort* out, uint* kept) {
    *kept = 0;
    if (n > VF_SDF_SPECIALISE_MAX) {
        return classify_cell(tape, 0, n, g, i, j, k, edge);
    }
    if (i >= g.nx || j >= g.ny || k >= g.nz) {
        return VF_SDF_CELL_EMPTY;
    }
    uchar live[VF_SDF_SPECIALISE_MAX];
    for (uint t = 0; t < m; ++t) {
        live[list ? list[t] : t] = 1;
    }
    const uint i1 = min(i + edge, g.nx), j1 = min(j + edge, g.ny), k1 = min(k + edge, g.nz);
    const float2 r = eval_cells(tape, list, m, g, i, j, k, i1, j1, k1, live);
    uint count = 0;
    for (uint t = 0; t < m; ++t) {
        const uint instr = list ? list[t] : t;
        if (live[instr]) {
            out[count++] = (ushort)instr;
        }
    }
    *kept = count;
    if (r.x > 0) {
        return VF_SDF_CELL_EMPTY;
    }
    return r.y < 0 ? VF_SDF_CELL_FULL : VF_SDF_CELL_AMBIGUOUS;
}

/* A node's specialised tape as the kernels keep it, slot s of `lists`: n + 1 ushorts, the count
 * then the instructions. */
inline void store_list(__global ushort* lists, uint n, uint s, const ushort* list, uint m) {
    __global ushort* dst = lists + (size_t)s * (n + 1);
    dst[0] = (ushort)m;
    for (uint t = 0; t < m; ++t) {
        dst[1 + t] = list[t];
    }
}

/* One work-item per tile of `edge` voxels, tiles (tx, ty, tz) x fastest: its entry in the tile
 * table, and for an ambiguous tile a root node of level 0 (origin with its node index in w, and
 * its specialised tape in `lists`) among the first `capacity`. */
__kernel void classify_tiles(__global const Instr* tape, uint n, Grid g, uint tx, uint ty,
                             uint tiles, uint edge, __global uint* table, __global uint4* origins,
                             __global ushort* lists, uint capacity, __global uint* counters) {
    const uint t = get_global_id(0);
    if (t >= tiles) {
        return;
    }
    const uint x = t % tx * edge, y = t / tx % ty * edge, z = t / tx / ty * edge;
    ushort list[VF_SDF_SPECIALISE_MAX];
    uint m;
    const uint cls = classify_special(tape, n, 0, n, g, x, y, z, edge, list, &m);
    if (cls == VF_SDF_CELL_EMPTY) {
        table[t] = VF_SDF_TILE_EMPTY;
    } else if (cls == VF_SDF_CELL_FULL) {
        table[t] = VF_SDF_TILE_FULL;
    } else {
        const uint index = atomic_inc(&counters[0]);
        table[t] = index;
        if (index < capacity) {
            origins[index] = (uint4)(x, y, z, index);
            if (n <= VF_SDF_SPECIALISE_MAX) {
                store_list(lists, n, index, list, m);
            }
        }
    }
}

inline uint rank_below(const uint* bits, uint i) {
    uint r = 0;
    for (uint w = 0; w < i / 32; ++w) {
        r += popcount(bits[w]);
    }
    return r + (i % 32 ? popcount(bits[i / 32] & ((1u << (i % 32)) - 1u)) : 0u);
}

/* A work-group of 64 per node of level `level` (its first `capacity` of counters[level]; origins:
 * voxel, node index in w; lists: its specialised tape), groups striding over the nodes: work-item
 * c tests child c with the node's tape, specialising it to the child; then the node's record
 * (nodes, up to node_capacity) and its ambiguous children as nodes of the next level with their
 * tapes (up to next_capacity). */
__kernel __attribute__((reqd_work_group_size(64, 1, 1))) void classify_children(
    __global const Instr* tape, uint n, Grid g, __global const uint4* origins,
    __global const ushort* lists, uint level, uint capacity, uint edge,
    __global uint4* next_origins, __global ushort* next_lists, uint next_capacity,
    __global uint* counters, __global uint* nodes, uint node_capacity) {
    __local ushort shared_list[VF_SDF_SPECIALISE_MAX];
    __local uint masks[4], first_child; /* occupied lo, hi; solid lo, hi */
    const uint c = get_local_id(0);
    const uint count = min(counters[level], capacity);
    const uint next_base = level_base(counters, level + 1);
    const bool special = n <= VF_SDF_SPECIALISE_MAX;
    const uint e = edge / 4;
    for (uint f = get_group_id(0); f < count; f += get_num_groups(0)) {
        const uint4 o = origins[f];
        uint m = n;
        if (special) {
            __global const ushort* src = lists + (size_t)f * (n + 1);
            m = src[0];
            for (uint t = c; t < m; t += 64) {
                shared_list[t] = src[1 + t];
            }
        }
        if (c < 4) {
            masks[c] = 0;
        }
        barrier(CLK_LOCAL_MEM_FENCE);
        ushort list[VF_SDF_SPECIALISE_MAX];
        for (uint t = 0; special && t < m; ++t) {
            list[t] = shared_list[t];
        }
        const uint cx = o.x + (c & 3) * e, cy = o.y + (c >> 2 & 3) * e, cz = o.z + (c >> 4) * e;
        ushort child_list[VF_SDF_SPECIALISE_MAX];
        uint kept;
        const uint cls = classify_special(tape, n, special ? list : 0, m, g, cx, cy, cz, e,
                                          child_list, &kept);
        if (cls != VF_SDF_CELL_EMPTY) {
            atomic_or(&masks[(cls == VF_SDF_CELL_FULL ? 2 : 0) + c / 32], 1u << (c % 32));
        }
        barrier(CLK_LOCAL_MEM_FENCE);
        const uint occ[2] = {masks[0], masks[1]};
        if (c == 0) {
            const uint kids = popcount(occ[0]) + popcount(occ[1]);
            const uint first = kids ? atomic_add(&counters[level + 1], kids) : 0u;
            first_child = first;
            if (o.w < node_capacity) {
                __global uint* rec = nodes + (size_t)o.w * VF_SDF_NODE_WORDS;
                rec[0] = next_base + first;
                rec[1] = VF_SDF_NOT_LEAF;
                rec[2] = occ[0];
                rec[3] = occ[1];
                rec[4] = masks[2];
                rec[5] = masks[3];
            }
        }
        barrier(CLK_LOCAL_MEM_FENCE);
        if (cls == VF_SDF_CELL_AMBIGUOUS) {
            const uint index = first_child + rank_below(occ, c);
            if (index < next_capacity) {
                next_origins[index] = (uint4)(cx, cy, cz, next_base + index);
                if (special) {
                    store_list(next_lists, n, index, child_list, kept);
                }
            }
        }
        barrier(CLK_LOCAL_MEM_FENCE); /* the local state is the next node's */
    }
}

inline uint corner_index(uint v, uint c) {
    /* voxel v = x + 4 y + 16 z of a leaf, corner c = cx + 2 cy + 4 cz -> x + 5 y + 25 z */
    return (v & 3) + (c & 1) + 5 * ((v >> 2 & 3) + (c >> 1 & 1)) + 25 * ((v >> 4) + (c >> 2));
}

/* Reserves a leaf's vertex and voxel records (counters VF_SDF_COUNT_VERTICES and
 * VF_SDF_COUNT_VOXELS) and writes its node record (when below node_capacity). When the
 * reservations fit the capacities, the kernels below then write its voxel records (crossed
 * voxels in mask order) and vertex records (its kept corners in index order). */
inline void leaf_reserve(__global uint* counters, __global uint* nodes, uint node_capacity,
                         uint node, uint kept_count, uint cross_count, uint2 occ, uint2 solid,
                         uint* voff, uint* xoff) {
    *voff = kept_count ? atomic_add(&counters[VF_SDF_COUNT_VERTICES], kept_count) : 0u;
    *xoff = cross_count ? atomic_add(&counters[VF_SDF_COUNT_VOXELS], cross_count) : 0u;
    if (node >= node_capacity) {
        return;
    }
    __global uint* rec = nodes + (size_t)node * VF_SDF_NODE_WORDS;
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

/* Of a leaf's corner rows (row r = y + 5 z: bits x = 0..4), the 4 voxels of voxel row (y, z)
 * (bits x = 0..3) any / all of whose 8 corners have their bit set. */
inline uint row_any(const uchar* rows, uint y, uint z) {
    const uint r = y + 5 * z;
    const uint a = rows[r] | rows[r + 1] | rows[r + 5] | rows[r + 6];
    return (a | a >> 1) & 15u;
}
inline uint row_all(const uchar* rows, uint y, uint z) {
    const uint r = y + 5 * z;
    const uint a = rows[r] & rows[r + 1] & rows[r + 5] & rows[r + 6];
    return a & a >> 1 & 15u;
}

/* CPU layout: one work-item per leaf, its 125 shared corners in one batch, then the centres
 * its corners leave open, EV_W points per instruction fetch (eval_f_v: the vector instance of
 * implicit_eval.cl). A voxel's class is read from bit masks: corner rows of 5 bits (outside,
 * far inside, far outside), voxel rows of 4. */
inline void sample_leaf_seq(__global const Instr* tape, uint n, Grid g, uint4 o,
                            __global const ushort* own_list, __global uint* nodes,
                            uint node_capacity, __global uint* voxels, uint voxel_capacity,
                            __global float4* vertices, uint vertex_capacity,
                            __global uint* counters, float decided) {
    ushort list[VF_SDF_SPECIALISE_MAX];
    const bool special = n <= VF_SDF_SPECIALISE_MAX;
    const uint m = special ? own_list[0] : n;
    for (uint t = 0; special && t < m; ++t) {
        list[t] = own_list[1 + t];
    }
    const ushort* run = special ? list : 0;
    /* Lanes past the last corner evaluate a repeat of it into the padding. */
    float f[128 + EV_W];
    for (uint c0 = 0; c0 < 125; c0 += EV_W) {
        const UTV c = min(c0 + EV_IOTA, (UTV)124u);
        MTV mat;
        const FTV fv = eval_f_v(tape, run, m, corner_at_v(g.x0, g.h, o.x + c % 5u),
                                corner_at_v(g.y0, g.h, o.y + c / 5u % 5u),
                                corner_at_v(g.z0, g.h, o.z + c / 25u), &mat);
        EV_STORE(fv, 0, f + c0);
    }
    /* f is a 1-Lipschitz distance bound: a corner with |f| > `decided` (half the voxel's
     * diagonal plus a rounding margin) gives the voxel's centre its sign. */
    uchar neg[25], far[25];
    for (uint r = 0; r < 25; ++r) {
        uint a = 0, b = 0;
        for (uint x = 0; x < 5; ++x) {
            const float fv = f[5 * r + x];
            a |= (fv < 0 ? 1u : 0u) << x;
            b |= (fabs(fv) > decided ? 1u : 0u) << x;
        }
        neg[r] = (uchar)a;
        far[r] = (uchar)b;
    }
    /* Voxel masks (bit v = x + 4 y + 16 z): in the grid, some corner inside, every corner
     * inside, some corner far. */
    const uint xs = g.nx - o.x >= 4 ? 15u : (1u << (g.nx - o.x)) - 1u;
    ulong grid = 0, any_in = 0, all_in = 0, any_far = 0;
    for (uint z = 0; z < 4; ++z) {
        for (uint y = 0; y < 4; ++y) {
            const uint s = 4 * y + 16 * z;
            if (o.y + y < g.ny && o.z + z < g.nz) {
                grid |= (ulong)xs << s;
            }
            any_in |= (ulong)row_any(neg, y, z) << s;
            all_in |= (ulong)row_all(neg, y, z) << s;
            any_far |= (ulong)row_any(far, y, z) << s;
        }
    }
    /* Crossed: the corners disagree, or (sampled below) the centre disagrees with them.
     * Solid: every corner inside and one far; else the centre decides. */
    ulong occ = any_in & ~all_in & grid;
    ulong solid = all_in & any_far & grid;
    ulong need = (occ | ~any_far) & grid;
    uchar mats[64];
    uint need_list[64 + EV_W];
    uint needed = 0;
    for (ulong b = need; b; b &= b - 1) {
        need_list[needed++] = (uint)(63 - clz(b & (~b + 1)));
    }
    for (uint q = needed; q < needed + EV_W; ++q) {
        need_list[q] = needed ? need_list[needed - 1] : 0u;
    }
    for (uint q0 = 0; q0 < needed; q0 += EV_W) {
        const UTV v = EV_LOAD(0, need_list + q0);
        MTV mat;
        const FTV fv = eval_f_v(tape, run, m, centre_at_v(g.x0, g.h, o.x + (v & 3u)),
                                centre_at_v(g.y0, g.h, o.y + (v >> 2 & 3u)),
                                centre_at_v(g.z0, g.h, o.z + (v >> 4)), &mat);
        float fc[EV_W];
        int mc[EV_W];
        EV_STORE(fv, 0, fc);
        EV_STORE(mat, 0, mc);
        for (uint l = 0; l < EV_W && q0 + l < needed; ++l) {
            const uint w = need_list[q0 + l];
            const ulong bit = (ulong)1 << w;
            mats[w] = (uchar)mc[l];
            if (fc[l] < 0) {
                solid |= bit;
            }
            if ((fc[l] < 0 ? ~any_in : all_in) & bit) {
                occ |= bit; /* all 8 corners outside with the centre in, or the reverse */
            }
        }
    }
    /* Kept corners: the 8 of every crossed voxel, as corner rows; their ranks by row. */
    uchar kept[25];
    for (uint r = 0; r < 25; ++r) {
        kept[r] = 0;
    }
    for (uint z = 0; z < 4; ++z) {
        for (uint y = 0; y < 4; ++y) {
            const uint x4 = (uint)(occ >> (4 * y + 16 * z)) & 15u;
            const uchar k = (uchar)(x4 | x4 << 1);
            const uint r = y + 5 * z;
            kept[r] |= k;
            kept[r + 1] |= k;
            kept[r + 5] |= k;
            kept[r + 6] |= k;
        }
    }
    uchar base[25];
    uint kept_count = 0;
    for (uint r = 0; r < 25; ++r) {
        base[r] = (uchar)kept_count;
        kept_count += popcount((uint)kept[r]);
    }
    const uint cross_count = popcount(occ);
    uint voff, xoff;
    leaf_reserve(counters, nodes, node_capacity, o.w, kept_count, cross_count,
                 (uint2)((uint)occ, (uint)(occ >> 32)), (uint2)((uint)solid, (uint)(solid >> 32)),
                 &voff, &xoff);
    if (voff + kept_count > vertex_capacity || xoff + cross_count > voxel_capacity) {
        return; /* the host reruns with the capacities the counters reached */
    }
    /* The kept corners in index order, EV_W gradients per instruction fetch (the last batch
     * repeats the last corner). */
    uint kept_list[128 + EV_W];
    uint r = 0;
    for (uint row = 0; row < 25; ++row) {
        for (uint b = kept[row]; b; b &= b - 1) {
            kept_list[r++] = 5 * row + (31 - clz(b & (~b + 1)));
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
            vertices[voff + r0 + l] =
                (float4)(gx[l] * g.h, gy[l] * g.h, gz[l] * g.h, f[kept_list[r0 + l]]);
        }
    }
    uint x = 0;
    for (ulong b = occ; b; b &= b - 1) {
        const uint v = (uint)(63 - clz(b & (~b + 1)));
        uint w[2] = {0u, 0u};
        for (uint c = 0; c < 8; ++c) {
            const uint row = (v >> 2 & 3) + (c >> 1 & 1) + 5 * ((v >> 4) + (c >> 2));
            const uint cx = (v & 3) + (c & 1);
            const uint rank = base[row] + popcount((uint)kept[row] & ((1u << cx) - 1u));
            w[c / 4] |= rank << (8 * (c % 4));
        }
        __global uint* rec = voxels + (xoff + x++) * VF_SDF_VOXEL_WORDS;
        rec[0] = w[0];
        rec[1] = w[1];
        rec[2] = mats[v];
    }
}

/* The leaves of level `level` (its first `capacity` of counters[level]; origin, node index in w;
 * lists: its specialised tape), work-items striding over them. */
__kernel void sample_leaves_seq(__global const Instr* tape, uint n, Grid g,
                                __global const uint4* leaves, __global const ushort* lists,
                                uint level, uint capacity,
                                __global uint* nodes, uint node_capacity, __global uint* voxels,
                                uint voxel_capacity, __global float4* vertices,
                                uint vertex_capacity, __global uint* counters, float decided) {
    const uint count = min(counters[level], capacity);
    for (uint id = get_global_id(0); id < count; id += get_global_size(0)) {
        /* (a tape too long to specialise has no lists) */
        const size_t slot = n <= VF_SDF_SPECIALISE_MAX ? (size_t)id * (n + 1) : 0;
        sample_leaf_seq(tape, n, g, leaves[id], lists + slot, nodes, node_capacity,
                        voxels, voxel_capacity, vertices, vertex_capacity, counters, decided);
    }
}

/* GPU layout: one work-group of 128 per leaf (groups striding over the leaves), the work
 * compacted onto the first work-items at each step: items c < 125 sample corner c; items v < 64
 * classify voxel v from its corners, and list it when its corners leave its centre open (a
 * corner with |f| > `decided` gives the centre its sign, as in the CPU layout) or disagree (its
 * material is the centre's); item q samples the centre of the q-th listed voxel; item r
 * evaluates the gradient of the r-th kept corner. */
__kernel __attribute__((reqd_work_group_size(128, 1, 1))) void sample_leaves_group(
    __global const Instr* tape, uint n, Grid g, __global const uint4* leaves,
    __global const ushort* lists, uint level, uint capacity, __global uint* nodes,
    uint node_capacity, __global uint* voxels, uint voxel_capacity,
    __global float4* vertices, uint vertex_capacity, __global uint* counters, float decided) {
    __local float f[125];
    /* bits: occupied (crossed) 0-1, solid 2-3, kept corners 4-7 */
    __local uint bits[8], offsets[2], needed;
    __local ushort special_list[VF_SDF_SPECIALISE_MAX];
    __local uchar corner_signs[64], need_list[64], kept_list[128];
    const uint lid = get_local_id(0);
    const uint count = min(counters[level], capacity);
    const bool special = n <= VF_SDF_SPECIALISE_MAX;
    for (uint id = get_group_id(0); id < count; id += get_num_groups(0)) {
        const uint4 o = leaves[id];
        uint m = n;
        if (special) {
            __global const ushort* src = lists + (size_t)id * (n + 1);
            m = src[0];
            for (uint t = lid; t < m; t += 128) {
                special_list[t] = src[1 + t];
            }
        }
        if (lid < 8) {
            bits[lid] = 0;
        }
        if (lid == 0) {
            needed = 0;
        }
        barrier(CLK_LOCAL_MEM_FENCE);
        ushort list[VF_SDF_SPECIALISE_MAX];
        for (uint t = 0; special && t < m; ++t) {
            list[t] = special_list[t];
        }
        const ushort* run = special ? list : 0;
        uint material = 0;
        if (lid < 125) {
            const uint i = o.x + lid % 5, j = o.y + lid / 5 % 5, k = o.z + lid / 25;
            f[lid] = eval_f(tape, run, m, corner_at(g.x0, g.h, i), corner_at(g.y0, g.h, j),
                            corner_at(g.z0, g.h, k), &material);
        }
        barrier(CLK_LOCAL_MEM_FENCE);
        if (lid < 64) {
            const uint i = o.x + (lid & 3), j = o.y + (lid >> 2 & 3), k = o.z + (lid >> 4);
            if (i < g.nx && j < g.ny && k < g.nz) {
                uint inside = 0, outside = 0, far = 0;
                for (uint c = 0; c < 8; ++c) {
                    const float fv = f[corner_index(lid, c)];
                    inside |= fv < 0 ? 1u : 0u;
                    outside |= fv < 0 ? 0u : 1u;
                    far |= fabs(fv) > decided ? 1u : 0u;
                }
                corner_signs[lid] = (uchar)(inside | outside << 1);
                if ((inside && outside) || !far) {
                    need_list[atomic_inc(&needed)] = (uchar)lid;
                } else if (inside) {
                    atomic_or(&bits[2 + lid / 32], 1u << (lid % 32)); /* every corner inside */
                }
            }
        }
        barrier(CLK_LOCAL_MEM_FENCE);
        bool crossed = false;
        uint v = 0;
        if (lid < needed) {
            v = need_list[lid];
            const float fc =
                eval_f(tape, run, m, centre_at(g.x0, g.h, o.x + (v & 3)),
                       centre_at(g.y0, g.h, o.y + (v >> 2 & 3)), centre_at(g.z0, g.h, o.z + (v >> 4)),
                       &material);
            const uint signs = corner_signs[v] | (fc < 0 ? 1u : 2u);
            crossed = signs == 3u;
            if (fc < 0) {
                atomic_or(&bits[2 + v / 32], 1u << (v % 32));
            }
            if (crossed) {
                atomic_or(&bits[v / 32], 1u << (v % 32));
                for (uint c = 0; c < 8; ++c) {
                    const uint ci = corner_index(v, c);
                    atomic_or(&bits[4 + ci / 32], 1u << (ci % 32));
                }
            }
        }
        barrier(CLK_LOCAL_MEM_FENCE);
        const uint occ_bits[2] = {bits[0], bits[1]};
        const uint kept_bits[4] = {bits[4], bits[5], bits[6], bits[7]};
        const uint kept_count = popcount(kept_bits[0]) + popcount(kept_bits[1]) +
                                popcount(kept_bits[2]) + popcount(kept_bits[3]);
        const uint cross_count = popcount(occ_bits[0]) + popcount(occ_bits[1]);
        if (lid == 0) {
            uint voff, xoff;
            leaf_reserve(counters, nodes, node_capacity, o.w, kept_count, cross_count,
                         (uint2)(occ_bits[0], occ_bits[1]), (uint2)(bits[2], bits[3]), &voff,
                         &xoff);
            offsets[0] = voff;
            offsets[1] = xoff;
        }
        if (lid < 125 && (kept_bits[lid / 32] >> (lid % 32) & 1u)) {
            kept_list[rank_below(kept_bits, lid)] = (uchar)lid;
        }
        barrier(CLK_LOCAL_MEM_FENCE);
        const uint voff = offsets[0], xoff = offsets[1];
        if (voff + kept_count <= vertex_capacity && xoff + cross_count <= voxel_capacity) {
            if (lid < kept_count) {
                const uint c = kept_list[lid];
                const uint i = o.x + c % 5, j = o.y + c / 5 % 5, k = o.z + c / 25;
                const Dual d = eval_d(tape, run, m, corner_at(g.x0, g.h, i),
                                      corner_at(g.y0, g.h, j), corner_at(g.z0, g.h, k));
                vertices[voff + lid] = (float4)(d.x * g.h, d.y * g.h, d.z * g.h, f[c]);
            }
            if (crossed) {
                const uint2 w = voxel_corner_words(kept_bits, v);
                __global uint* rec =
                    voxels + (size_t)(xoff + rank_below(occ_bits, v)) * VF_SDF_VOXEL_WORDS;
                rec[0] = w.x;
                rec[1] = w.y;
                rec[2] = material;
            }
        } /* else the host reruns with the capacities the counters reached */
        barrier(CLK_LOCAL_MEM_FENCE); /* the local state is the next leaf's */
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
