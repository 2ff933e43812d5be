// Exact distance transforms of every metric (L1, L-inf, L2) with voxel spacing, signed fields
// and the feature transform, by the separable linear-time algorithm of Meijster, Roerdink &
// Hesselink, "A general algorithm for computing distance transforms in linear time" (2000):
// a 1-D nearest-target pass along x, then along y and z the lower envelope of the previous
// pass's per-line functions f_i(x) = F(x - i, g_i), found with a stack of sites and the
// metric's separator Sep(i, u) (the last x where site i is at least as near as site u).
//
// Build options:
//   METRIC   0 manhattan, 1 chebyshev, 2 euclidean
//   UNIT     1: unit spacing, partial distances are exact integers (GT = uint; L2 squared);
//            0: GT = float, each axis offset scaled by its spacing (sx, sy, sz arguments)
//   SIGNED   1: also the transform to the empty voxels, the world surrounded by empty space
//            (virtual empty sites at -1 and N on every line); the output is signed
//   INDICES  1: carry the linear index of the nearest solid and write (z, y, x) planes
//   OUT_KIND 0 unsigned integer (floor, saturate at OUT_MAX), 1 signed integer (toward zero,
//            saturate at +-OUT_MAX), 2 float, 3 double, 4 packed32; OUT_T its element type
// Final values are computed in double (cl_khr_fp64), so the L2 field of unit spacing is the
// correctly rounded sqrt of the exact squared distance, in f32 as in f64.
//
// Two layouts of the same passes: `per_item` lines per work-item, consecutive lines adjacent
// in x. The CPU layout gives each work-item a slice's or strip's worth of lines (its data
// stays in the core's cache), the GPU layout one line per work-item (neighbouring work-items
// touch neighbouring addresses); the stack of each work-item lives in `scratch`, laid out
// [k * kstride + item * istride] so that the GPU layout's stacks interleave.

#pragma OPENCL EXTENSION cl_khr_fp64 : enable

#if UNIT
typedef uint GT;
#define G_INF UINT_MAX
#else
typedef float GT;
#define G_INF INFINITY
#endif

#define SEP_NEVER (1 << 30)

inline int floor_div(int a, int b) {
    const int q = a / b;
    return (a % b != 0 && ((a < 0) != (b < 0))) ? q - 1 : q;
}

// The axis's offset d >= 0 (in voxels) as a partial distance: L2 squared, else plain.
inline GT offset_part(int d, float s) {
#if UNIT
    return METRIC == 2 ? (uint)(d * d) : (uint)d;
#else
    const float a = s * (float)d;
    return METRIC == 2 ? a * a : a;
#endif
}

// f_i(x): the partial distance at x from site i whose partial distance is gi.
inline GT fpart(int x, int i, GT gi, float s) {
    const GT o = offset_part(abs(x - i), s);
#if METRIC == 1
    return max(gi, o);
#else
    return gi + o;
#endif
}

// Sep(i, u) for i < u: the last x at which site i is at least as near as site u (u is
// strictly nearer beyond it); SEP_NEVER when u is never nearer, -SEP_NEVER when it always is.
inline int sep(int i, int u, GT gi, GT gu, float s) {
#if UNIT
    const int a = (int)gi, b = (int)gu;
#if METRIC == 0
    if (b >= a + (u - i)) {
        return SEP_NEVER;
    }
    if (a > b + (u - i)) {
        return -SEP_NEVER;
    }
    return floor_div(b - a + u + i, 2);
#elif METRIC == 1
    const int mid = floor_div(i + u, 2);
    return a <= b ? max(i + b, mid) : min(u - a, mid);
#else
    return floor_div(u * u - i * i + b - a, 2 * (u - i));
#endif
#else
    const float fi = (float)i, fu = (float)u;
#if METRIC == 0
    if (gu >= gi + s * (fu - fi)) {
        return SEP_NEVER;
    }
    if (gi > gu + s * (fu - fi)) {
        return -SEP_NEVER;
    }
    return (int)floor((gu - gi + s * (fu + fi)) / (2.0f * s));
#elif METRIC == 1
    const int mid = floor_div(i + u, 2);
    if (gi <= gu) {
        return max((int)floor(fi + gu / s), mid);
    }
    return min((int)floor(fu - gi / s), mid);
#else
    const float s2 = s * s;
    const float v = (s2 * (fu * fu - fi * fi) + gu - gi) / (2.0f * s2 * (fu - fi));
    return (int)clamp(floor(v), -4.0f, (float)SEP_NEVER);
#endif
#endif
}

// The partial distance of site u of a line; virtual padding sites (-1 and n) are empty.
inline GT site_g(__global const GT* g, size_t base, size_t stride, int u, int n) {
    return (u < 0 || u >= n) ? (GT)0 : g[base + (size_t)u * stride];
}

// Lower envelope of the sites of one line (Meijster's first phase): on return the stack
// holds q + 1 sites s[k] owning positions [t[k], t[k+1]). Sites with no target are skipped;
// `pad` adds the virtual empty sites at -1 and n. Returns q (-1: no site at all).
inline int envelope(__global const GT* g, size_t base, size_t stride, int n, int pad, float sp,
                    __global int* s, __global int* t, size_t ks) {
    int q = -1;
    const int lo = pad ? -1 : 0;
    const int hi = pad ? n : n - 1;
    for (int u = lo; u <= hi; ++u) {
        const GT gu = site_g(g, base, stride, u, n);
        if (gu == G_INF) {
            continue;
        }
        // Pop the sites that u is nearer than from where they start (their separator with
        // u lies before their first position); testing the separator itself keeps the
        // starts strictly increasing even where float rounding blurs a tie.
        int w = 0;
        while (q >= 0) {
            const int sq = s[q * ks];
            w = 1 + sep(sq, u, site_g(g, base, stride, sq, n), gu, sp);
            if (w > t[q * ks]) {
                break;
            }
            --q;
        }
        if (q < 0) {
            q = 0;
            s[0] = u;
            t[0] = 0;
        } else if (w < n) {
            ++q;
            s[q * ks] = u;
            t[q * ks] = w;
        }
    }
    return q;
}

// ---- pass 1: rows along x, the 1-D distance to the nearest target ----

// Row r's nearest target to each voxel; `want` is the voxel value class (1 solid, 0 empty),
// `pad` counts the virtual voxels at -1 and X as targets. Writes partials (and features).
inline void row_nearest(__global const uchar* vox, size_t base, int X, int want, int pad, float sx,
                        __global GT* g, __global uint* feat) {
    int last = pad ? -1 : INT_MIN / 2;
    for (int x = 0; x < X; ++x) {
        if ((vox[base + x] != 0) == want) {
            last = x;
        }
        g[base + x] = last == INT_MIN / 2 ? G_INF : offset_part(x - last, sx);
#if INDICES
        feat[base + x] = last < 0 ? UINT_MAX : (uint)(base + last);
#endif
    }
    int next = pad ? X : INT_MAX / 2;
    for (int x = X - 1; x >= 0; --x) {
        if ((vox[base + x] != 0) == want) {
            next = x;
        }
        if (next != INT_MAX / 2) {
            const GT o = offset_part(next - x, sx);
            if (o < g[base + x]) {
                g[base + x] = o;
#if INDICES
                feat[base + x] = next >= X ? UINT_MAX : (uint)(base + next);
#endif
            }
        }
    }
}

__kernel void x_pass(__global const uchar* restrict vox, __global GT* restrict g,
                     __global GT* restrict h, __global uint* restrict feat, uint X, uint rows,
                     uint per_item, float sx) {
    const size_t r0 = get_global_id(0) * per_item;
    for (size_t r = r0; r < min(r0 + per_item, (size_t)rows); ++r) {
        row_nearest(vox, r * X, (int)X, 1, 0, sx, g, feat);
#if SIGNED
        row_nearest(vox, r * X, (int)X, 0, 1, sx, h, feat);
#endif
    }
}

// ---- passes 2 and 3: columns along y, then z ----

// Meijster's second phase for one line: every position takes the partial distance from the
// site owning it. Returns through `out` (partials) and `win` (the winning site per position,
// written only when `win` is not null-like, i.e. with INDICES).
inline void line_pass(__global const GT* gin, __global GT* gout, size_t base, size_t stride,
                      int n, int pad, float sp, __global int* s, __global int* t, size_t ks,
                      __global const uint* fin, __global uint* fout) {
    int q = envelope(gin, base, stride, n, pad, sp, s, t, ks);
    for (int x = n - 1; x >= 0; --x) {
        const size_t i = base + (size_t)x * stride;
        if (q < 0) {
            gout[i] = G_INF;
#if INDICES
            fout[i] = UINT_MAX;
#endif
            continue;
        }
        const int sq = s[q * ks];
        gout[i] = fpart(x, sq, site_g(gin, base, stride, sq, n), sp);
#if INDICES
        fout[i] = fin[base + (size_t)sq * stride];
#endif
        if (x == t[q * ks]) {
            --q;
        }
    }
}

// Lines of length n and element stride `stride`, line l starting at (l / X) * mstride +
// l % X; the stacks of work-item w at scratch + w * istride (k-th entry k * kstride later).
__kernel void col_pass(__global const GT* restrict g, __global GT* restrict gout,
                       __global const GT* restrict h, __global GT* restrict hout,
                       __global const uint* restrict fin, __global uint* restrict fout,
                       __global int* restrict scratch, uint X, uint n, ulong stride,
                       ulong mstride, uint lines, uint per_item, ulong kstride, ulong istride,
                       float sp) {
    const size_t w = get_global_id(0);
    __global int* s = scratch + w * istride;
    __global int* t = s + (size_t)(n + 2) * kstride;
    const size_t l0 = w * per_item;
    for (size_t l = l0; l < min(l0 + per_item, (size_t)lines); ++l) {
        const size_t base = (l / X) * mstride + l % X;
        line_pass(g, gout, base, stride, (int)n, 0, sp, s, t, kstride, fin, fout);
#if SIGNED
        line_pass(h, hout, base, stride, (int)n, 1, sp, s, t, kstride, fin, fout);
#endif
    }
}

// ---- output ----

// The real distance of a partial.
inline double distance_of(GT p) {
    if (p == G_INF) {
        return INFINITY;
    }
    return METRIC == 2 ? sqrt((double)p) : (double)p;
}

inline void store(__global OUT_T* out, __constant uchar* rgb, uchar v, size_t i, double d) {
#if OUT_KIND == 0
    out[i] = (OUT_T)(d >= (double)OUT_MAX ? OUT_MAX : (uint)floor(d));
#elif OUT_KIND == 1
    const double c = clamp(trunc(d), -(double)OUT_MAX, (double)OUT_MAX);
    out[i] = (OUT_T)(int)c;
#elif OUT_KIND == 2
    out[i] = (float)d;
#elif OUT_KIND == 3
    out[i] = d;
#else
    const uint q = d >= 255.0 ? 255u : (uint)floor(d);
    out[i] = (q << VF_PACKED_DISTANCE_SHIFT) | rgb[v];
#endif
}

// Writes the output format from the final partials (and the index planes: z, y, x of the
// nearest solid, -1 without one, as SciPy's return_indices lays them out).
__kernel void finish(__global const GT* restrict g, __global const GT* restrict h,
                     __global const uchar* restrict vox, __constant uchar* rgb,
                     __global OUT_T* restrict out, __global const uint* restrict feat,
                     __global int* restrict idx, uint X, uint Y, ulong count) {
    const size_t i = get_global_id(0);
    if (i >= count) {
        return;
    }
    const uchar v = vox[i];
#if SIGNED
    const double d = v != 0 ? -distance_of(h[i]) : distance_of(g[i]);
#else
    const double d = distance_of(g[i]);
#endif
    store(out, rgb, v, i, d);
#if INDICES
    const uint f = feat[i];
    const size_t plane = (size_t)X * Y;
    idx[i] = f == UINT_MAX ? -1 : (int)(f / plane);
    idx[count + i] = f == UINT_MAX ? -1 : (int)((f / X) % Y);
    idx[2 * count + i] = f == UINT_MAX ? -1 : (int)(f % X);
#endif
}
