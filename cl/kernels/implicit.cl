/* Implicit surfaces discretised into a tile grid of contrees (the reference blog, farfa.dev
 * "implicit surface rendering for CAD": recursive interval pruning, then 5^3 shared corner
 * samples per leaf of 4^3 voxels). The tape (sdf_layout.hpp, prepended) is interpreted here
 * in floats, intervals and forward-mode dual numbers, in the same operation order as
 * core/src/sdf_eval.cpp. Distance bounds after Inigo Quilez's "distance functions" article. */
#pragma OPENCL FP_CONTRACT OFF

typedef struct {
    uint op;
    uint material;
    float p[VF_SDF_INSTR_PARAMS];
} Instr;

/* The grid: x0 + i h per axis, dims voxels. */
typedef struct {
    float x0, y0, z0, h;
    uint nx, ny, nz, pad;
} Grid;

inline float corner_at(float x0, float h, uint i) {
    return x0 + (float)i * h;
}
inline float centre_at(float x0, float h, uint i) {
    return x0 + ((float)i + 0.5f) * h;
}

/* ---------------------------------------------------------------- floats */

inline float f_len2(float a, float b) {
    return sqrt(fmax(a * a + b * b, 0.0f));
}
inline float f_len3(float a, float b, float c) {
    return sqrt(fmax(a * a + b * b + c * c, 0.0f));
}

inline float f_box(float dx, float dy, float dz, float sx, float sy, float sz) {
    const float qx = fabs(dx) - sx, qy = fabs(dy) - sy, qz = fabs(dz) - sz;
    const float outside = f_len3(fmax(qx, 0.0f), fmax(qy, 0.0f), fmax(qz, 0.0f));
    return outside + fmin(fmax(qx, fmax(qy, qz)), 0.0f);
}

inline float f_primitive(__global const Instr* in, float x, float y, float z) {
    __global const float* p = in->p;
    switch (in->op) {
        case VF_SDF_SPHERE:
            return f_len3(x - p[0], y - p[1], z - p[2]) - p[3];
        case VF_SDF_BOX:
            return f_box(x - p[0], y - p[1], z - p[2], p[3], p[4], p[5]);
        case VF_SDF_ROUND_BOX:
            return f_box(x - p[0], y - p[1], z - p[2], p[3] - p[6], p[4] - p[6], p[5] - p[6]) -
                   p[6];
        case VF_SDF_CYLINDER: {
            const float a = f_len2(x - p[0], z - p[2]) - p[3], b = fabs(y - p[1]) - p[4];
            return fmin(fmax(a, b), 0.0f) + f_len2(fmax(a, 0.0f), fmax(b, 0.0f));
        }
        case VF_SDF_TORUS: {
            const float a = f_len2(x - p[0], z - p[2]) - p[3];
            return f_len2(a, y - p[1]) - p[4];
        }
        case VF_SDF_CAPSULE: {
            const float bx = p[3] - p[0], by = p[4] - p[1], bz = p[5] - p[2];
            const float dd = bx * bx + by * by + bz * bz;
            const float ax = x - p[0], ay = y - p[1], az = z - p[2];
            const float dot = bx * ax + by * ay + bz * az;
            const float h = dd > 0 ? fmin(fmax(dot / dd, 0.0f), 1.0f) : 0.0f * dot;
            return f_len3(ax - bx * h, ay - by * h, az - bz * h) - p[6];
        }
        default: /* VF_SDF_PLANE */
            return p[0] * x + p[1] * y + p[2] * z - p[3];
    }
}

inline float f_smooth_min(float a, float b, float k) {
    const float h = fmax(k - fabs(a - b), 0.0f) / k;
    return fmin(a, b) - h * h * k * 0.25f;
}

/* The value at (x, y, z) and the material there (sdf.hpp's rules), running the instructions
 * list[0..n) (a leaf's specialised tape), or 0..n when list is 0. */
float eval_f(__global const Instr* tape, const ushort* list, uint n, float x, float y, float z,
             uint* material) {
    float v[VF_SDF_STACK];
    uchar m[VF_SDF_STACK];
    float px[VF_SDF_STACK], py[VF_SDF_STACK], pz[VF_SDF_STACK];
    int nv = 0, np = 0;
    px[0] = x;
    py[0] = y;
    pz[0] = z;
    for (uint t = 0; t < n; ++t) {
        __global const Instr* in = tape + (list ? list[t] : t);
        const uint op = in->op;
        if (op <= VF_SDF_PLANE) {
            v[nv] = f_primitive(in, px[np], py[np], pz[np]);
            m[nv++] = (uchar)in->material;
        } else if (op <= VF_SDF_SMOOTH_DIFF) {
            const float b = v[--nv], a = v[nv - 1];
            const float k = in->p[0];
            if (op == VF_SDF_MIN) {
                m[nv - 1] = a <= b ? m[nv - 1] : m[nv];
                v[nv - 1] = fmin(a, b);
            } else if (op == VF_SDF_MAX) {
                m[nv - 1] = a >= b ? m[nv - 1] : m[nv];
                v[nv - 1] = fmax(a, b);
            } else if (op == VF_SDF_DIFF) {
                v[nv - 1] = fmax(a, -b);
            } else if (op == VF_SDF_SMOOTH_MIN) {
                m[nv - 1] = a <= b ? m[nv - 1] : m[nv];
                v[nv - 1] = f_smooth_min(a, b, k);
            } else {
                v[nv - 1] = -f_smooth_min(-a, b, k);
            }
        } else if (op == VF_SDF_SHELL) {
            v[nv - 1] = fabs(v[nv - 1]) - in->p[0];
        } else if (op == VF_SDF_PUSH_POINT) {
            __global const float* p = in->p;
            const float dx = px[np] - p[9], dy = py[np] - p[10], dz = pz[np] - p[11];
            ++np;
            px[np] = p[0] * dx + p[1] * dy + p[2] * dz;
            py[np] = p[3] * dx + p[4] * dy + p[5] * dz;
            pz[np] = p[6] * dx + p[7] * dy + p[8] * dz;
        } else { /* VF_SDF_POP_POINT */
            --np;
            v[nv - 1] = v[nv - 1] * in->p[0];
        }
    }
    *material = m[0];
    return v[0];
}

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

/* ------------------------------------------------- dual numbers: (grad x, y, z, value) */

inline float4 d_sub(float4 a, float4 b) {
    return a - b;
}
inline float4 d_subs(float4 a, float s) {
    return (float4)(a.xyz, a.w - s);
}
inline float4 d_mul(float4 a, float4 b) {
    return (float4)(a.w * b.xyz + b.w * a.xyz, a.w * b.w);
}
inline float4 d_abs(float4 a) {
    return a.w < 0 ? -a : a;
}
inline float4 d_sq(float4 a) {
    return d_mul(a, a);
}
inline float4 d_sqrt(float4 a) {
    const float r = sqrt(fmax(a.w, 0.0f));
    return (float4)(r > 0 ? (0.5f / r) * a.xyz : (float3)(0.0f), r);
}
inline float4 d_min(float4 a, float4 b) {
    return a.w <= b.w ? a : b;
}
inline float4 d_max(float4 a, float4 b) {
    return a.w >= b.w ? a : b;
}
inline float4 d_mins(float4 a, float s) {
    return a.w <= s ? a : (float4)(0.0f, 0.0f, 0.0f, s);
}
inline float4 d_maxs(float4 a, float s) {
    return a.w >= s ? a : (float4)(0.0f, 0.0f, 0.0f, s);
}
inline float4 d_len2(float4 a, float4 b) {
    return d_sqrt(d_sq(a) + d_sq(b));
}
inline float4 d_len3(float4 a, float4 b, float4 c) {
    return d_sqrt(d_sq(a) + d_sq(b) + d_sq(c));
}

inline float4 d_box(float4 dx, float4 dy, float4 dz, float sx, float sy, float sz) {
    const float4 qx = d_subs(d_abs(dx), sx), qy = d_subs(d_abs(dy), sy), qz = d_subs(d_abs(dz), sz);
    const float4 outside = d_len3(d_maxs(qx, 0.0f), d_maxs(qy, 0.0f), d_maxs(qz, 0.0f));
    return outside + d_mins(d_max(qx, d_max(qy, qz)), 0.0f);
}

inline float4 d_primitive(__global const Instr* in, float4 x, float4 y, float4 z) {
    __global const float* p = in->p;
    switch (in->op) {
        case VF_SDF_SPHERE:
            return d_subs(d_len3(d_subs(x, p[0]), d_subs(y, p[1]), d_subs(z, p[2])), p[3]);
        case VF_SDF_BOX:
            return d_box(d_subs(x, p[0]), d_subs(y, p[1]), d_subs(z, p[2]), p[3], p[4], p[5]);
        case VF_SDF_ROUND_BOX:
            return d_subs(d_box(d_subs(x, p[0]), d_subs(y, p[1]), d_subs(z, p[2]), p[3] - p[6],
                                p[4] - p[6], p[5] - p[6]),
                          p[6]);
        case VF_SDF_CYLINDER: {
            const float4 a = d_subs(d_len2(d_subs(x, p[0]), d_subs(z, p[2])), p[3]);
            const float4 b = d_subs(d_abs(d_subs(y, p[1])), p[4]);
            return d_mins(d_max(a, b), 0.0f) + d_len2(d_maxs(a, 0.0f), d_maxs(b, 0.0f));
        }
        case VF_SDF_TORUS: {
            const float4 a = d_subs(d_len2(d_subs(x, p[0]), d_subs(z, p[2])), p[3]);
            return d_subs(d_len2(a, d_subs(y, p[1])), p[4]);
        }
        case VF_SDF_CAPSULE: {
            const float bx = p[3] - p[0], by = p[4] - p[1], bz = p[5] - p[2];
            const float dd = bx * bx + by * by + bz * bz;
            const float4 ax = d_subs(x, p[0]), ay = d_subs(y, p[1]), az = d_subs(z, p[2]);
            const float4 dot = bx * ax + by * ay + bz * az;
            const float4 h = dd > 0 ? d_mins(d_maxs(dot / dd, 0.0f), 1.0f) : 0.0f * dot;
            return d_subs(d_len3(ax - bx * h, ay - by * h, az - bz * h), p[6]);
        }
        default:
            return d_subs(p[0] * x + p[1] * y + p[2] * z, p[3]);
    }
}

inline float4 d_smooth_min(float4 a, float4 b, float k) {
    const float h = fmax(k - fabs(a.w - b.w), 0.0f) / k;
    const float4 lo = a.w <= b.w ? a : b;
    const float4 other = a.w <= b.w ? b : a;
    return (float4)((1.0f - 0.5f * h) * lo.xyz + (0.5f * h) * other.xyz,
                    fmin(a.w, b.w) - h * h * k * 0.25f);
}

/* The value and its gradient at (x, y, z) (list as for eval_f). */
float4 eval_d(__global const Instr* tape, const ushort* list, uint n, float x, float y, float z) {
    float4 v[VF_SDF_STACK];
    float4 px[VF_SDF_STACK], py[VF_SDF_STACK], pz[VF_SDF_STACK];
    int nv = 0, np = 0;
    px[0] = (float4)(1.0f, 0.0f, 0.0f, x);
    py[0] = (float4)(0.0f, 1.0f, 0.0f, y);
    pz[0] = (float4)(0.0f, 0.0f, 1.0f, z);
    for (uint t = 0; t < n; ++t) {
        __global const Instr* in = tape + (list ? list[t] : t);
        const uint op = in->op;
        if (op <= VF_SDF_PLANE) {
            v[nv++] = d_primitive(in, px[np], py[np], pz[np]);
        } else if (op <= VF_SDF_SMOOTH_DIFF) {
            const float4 b = v[--nv], a = v[nv - 1];
            const float k = in->p[0];
            if (op == VF_SDF_MIN) {
                v[nv - 1] = d_min(a, b);
            } else if (op == VF_SDF_MAX) {
                v[nv - 1] = d_max(a, b);
            } else if (op == VF_SDF_DIFF) {
                v[nv - 1] = d_max(a, -b);
            } else if (op == VF_SDF_SMOOTH_MIN) {
                v[nv - 1] = d_smooth_min(a, b, k);
            } else {
                v[nv - 1] = -d_smooth_min(-a, b, k);
            }
        } else if (op == VF_SDF_SHELL) {
            v[nv - 1] = d_subs(d_abs(v[nv - 1]), in->p[0]);
        } else if (op == VF_SDF_PUSH_POINT) {
            __global const float* p = in->p;
            const float4 dx = d_subs(px[np], p[9]), dy = d_subs(py[np], p[10]),
                         dz = d_subs(pz[np], p[11]);
            ++np;
            px[np] = p[0] * dx + p[1] * dy + p[2] * dz;
            py[np] = p[3] * dx + p[4] * dy + p[5] * dz;
            pz[np] = p[6] * dx + p[7] * dy + p[8] * dz;
        } else {
            --np;
            v[nv - 1] = v[nv - 1] * in->p[0];
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

/* CPU layout: one work-item per leaf, its 125 shared corners and 64 centres in one batch. */
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
    float f[125];
    uint material;
    for (uint c = 0; c < 125; ++c) {
        const uint i = o.x + c % 5, j = o.y + c / 5 % 5, k = o.z + c / 25;
        f[c] = eval_f(tape, run, m, corner_at(g.x0, g.h, i), corner_at(g.y0, g.h, j),
                      corner_at(g.z0, g.h, k), &material);
    }
    uint occ[2] = {0u, 0u}, solid[2] = {0u, 0u}, kept[4] = {0u, 0u, 0u, 0u};
    uchar mats[64];
    for (uint v = 0; v < 64; ++v) {
        const uint i = o.x + (v & 3), j = o.y + (v >> 2 & 3), k = o.z + (v >> 4);
        mats[v] = 0;
        if (i >= g.nx || j >= g.ny || k >= g.nz) {
            continue;
        }
        const float fc = eval_f(tape, run, m, centre_at(g.x0, g.h, i), centre_at(g.y0, g.h, j),
                                centre_at(g.z0, g.h, k), &material);
        mats[v] = (uchar)material;
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
    uint r = 0;
    for (uint c = 0; c < 125; ++c) {
        if (kept[c / 32] >> (c % 32) & 1u) {
            const uint i = o.x + c % 5, j = o.y + c / 5 % 5, k = o.z + c / 25;
            const float4 d = eval_d(tape, run, m, corner_at(g.x0, g.h, i), corner_at(g.y0, g.h, j),
                                    corner_at(g.z0, g.h, k));
            vertices[voff + r++] = (float4)(d.xyz, f[c]);
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
        const float4 d = eval_d(tape, run, m, corner_at(g.x0, g.h, i), corner_at(g.y0, g.h, j),
                                corner_at(g.z0, g.h, k));
        vertices[voff + rank_below(kept_bits, lid)] = (float4)(d.xyz, f[lid]);
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
