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
//   WIDE     1 (UNIT, L2): GT = ulong and 64-bit separators, for worlds whose squared
//            distances reach 2^30 (an axis past about 32768 voxels)
//   FP64     1 (not UNIT): GT = double and the spacing in double, for f64 fields
//   SIGNED   1: also the transform to the empty voxels, the world surrounded by empty space
//            (virtual empty sites at -1 and N on every line); the output is signed
//   INDICES  1: carry the key of the nearest solid (see KEYED) and write (z, y, x) planes
//   CPU_LAYOUT 1: the CPU layout (x_pass's scratch holds row_doubling's rows)
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

#if UNIT && WIDE
typedef ulong GT;
#define G_INF ULONG_MAX
#elif UNIT
typedef uint GT;
#define G_INF UINT_MAX
#elif FP64
typedef double GT;
#define G_INF ((double)INFINITY)
#else
typedef float GT;
#define G_INF INFINITY
#endif
// The spacing's type (the scans' arithmetic where not UNIT).
#if FP64
typedef double ST;
#else
typedef float ST;
#endif

#define SEP_NEVER (1 << 30)

// With INDICES a site's feature is the key (x * Y + y) * Z + z of its nearest solid (UINT_MAX:
// none), and of two equally near sites the one whose feature has the lower key is the nearer:
// each pass keeps the lowest key among its nearest targets, so every voxel names its nearest
// solid of lowest (x, y, z), the one SciPy's distance_transform_edt names (its passes run
// along z, y, then x in world terms, each taking the lowest position of equally near sites).
// KEYED(fa, fb): 1 where site b (after site a on the line) wins their ties. Not for L-inf:
// its flat functions tie so often that comparing features cost a third of its y and z passes,
// and SciPy's chessboard transform (cdt's chamfer sweeps) breaks ties its own way; there the
// lower position along each pass wins.
#if INDICES && METRIC != 1
#define KEYED(fa, fb) ((int)((fb) < (fa)))
#else
#define KEYED(fa, fb) 0
#endif

inline int floor_div(int a, int b) {
    const int q = a / b;
    return (a % b != 0 && ((a < 0) != (b < 0))) ? q - 1 : q;
}

// The axis's offset d >= 0 (in voxels) as a partial distance: L2 squared, else plain.
inline GT offset_part(int d, ST s) {
#if UNIT
    return METRIC == 2 ? (GT)d * (GT)d : (GT)d;
#else
    const ST a = s * (ST)d;
    return METRIC == 2 ? a * a : a;
#endif
}

// f_i(x): the partial distance at x from site i whose partial distance is gi.
inline GT fpart(int x, int i, GT gi, ST s) {
    const GT o = offset_part(abs(x - i), s);
#if METRIC == 1
    return max(gi, o);
#else
    return gi + o;
#endif
}

#if !UNIT
// The last integer at or before v, or (e) strictly before it.
inline ST floor_tie(ST v, int e) {
    const ST f = floor(v);
    return e && f == v ? f - (ST)1 : f;
}
#endif

#if UNIT && METRIC == 2
// Unit L2's tie point of sites i < u is num / (2 (u - i)): num = u^2 - i^2 + gu - gi (in int
// arithmetic below WIDE, as sep_tie's).
inline long l2_num(int i, int u, GT gi, GT gu) {
#if WIDE
    return (long)u * u - (long)i * i + (long)gu - (long)gi;
#else
    return (long)(u * u - i * i + (int)gu - (int)gi);
#endif
}
#elif METRIC == 2
// L2's tie point of sites i < u with spacing s: the x at which they are equally near,
// (s^2 (u^2 - i^2) + gu - gi) / (2 s^2 (u - i)) as (u + i) / 2 (exact) plus the partials' term:
// the squares of positions thousands apart would lose the separator's digits in float.
inline ST l2_tie_point(int i, int u, GT gi, GT gu, ST s) {
    return (ST)(u + i) * (ST)0.5 + (gu - gi) / ((ST)2 * (s * s) * (ST)(u - i));
}
#endif

#if !UNIT
// A separator q of sites i < u from a float tie point, checked against the partials as fpart
// evaluates them: moved up where site i is still at least as near at q + 1 (strictly with e),
// down where it is not at q. A tie point's floor can be off by one where the float arithmetic
// before it lost bits the partials keep (sep_tie's rule).
inline int sep_checked(int q, int i, int u, GT gi, GT gu, ST s, int e) {
    const GT a = fpart(q + 1, i, gi, s), b = fpart(q + 1, u, gu, s);
    const GT c = fpart(q, i, gi, s), d = fpart(q, u, gu, s);
    if (e ? a < b : a <= b) {
        return q + 1;
    }
    return (e ? c >= d : c > d) ? q - 1 : q;
}
#endif

#if METRIC == 2 && !UNIT
// L2's Sep(i, u) with spacing (sep_tie's rule): the floor of the tie point, sep_checked: a tie
// point thousands of positions along the line has only a few bits below the point in float,
// so that its floor alone could give a position to the farther site by far more than the
// partials' rounding.
inline int l2_sep(int i, int u, GT gi, GT gu, ST s, int e) {
    const int q = (int)clamp(floor_tie(l2_tie_point(i, u, gi, gu, s), e), (ST)-4, (ST)SEP_NEVER);
    return q > -4 && q < SEP_NEVER ? sep_checked(q, i, u, gi, gu, s, e) : q;
}
#endif

#if METRIC == 0 && !UNIT
// L1's Sep(i, u) with spacing (sep_tie's rule): SEP_NEVER or -SEP_NEVER where one site's
// partial beyond the other (as fpart evaluates it) is never above the other's, else the floor
// of the tie point (gu - gi + s (u + i)) / (2 s), sep_checked: with spacings far apart the
// partials' difference is a few thousandths beside s (u + i) in the tens of thousands, and
// the float sum loses it.
inline int l1_sep(int i, int u, GT gi, GT gu, ST s, int e) {
    const GT ui = fpart(u, i, gi, s), iu = fpart(i, u, gu, s);
    if (e ? gu > ui : gu >= ui) {
        return SEP_NEVER;
    }
    if (e ? gi >= iu : gi > iu) {
        return -SEP_NEVER;
    }
    const int q = (int)floor_tie((gu - gi + s * ((ST)u + (ST)i)) / ((ST)2 * s), e);
    return sep_checked(q, i, u, gi, gu, s, e);
}
#endif

// Sep(i, u) for i < u: the last x at which site i is at least as near as site u (u is
// strictly nearer beyond it), or with e (u wins their ties, KEYED) the last x at which i is
// strictly nearer; SEP_NEVER when u is never nearer, -SEP_NEVER when it always is.
inline int sep_tie(int i, int u, GT gi, GT gu, ST s, int e) {
#if UNIT && WIDE
    // 64-bit floor((u^2 - i^2 + gu - gi - e) / (2 (u - i))), clamped to the int range.
    const long num = l2_num(i, u, gi, gu) - e, den = 2 * (long)(u - i);
    long q = num / den;
    if (q * den > num) {
        --q;
    }
    return (int)clamp(q, (long)-SEP_NEVER, (long)SEP_NEVER);
#elif UNIT
    const int a = (int)gi, b = (int)gu;
#if METRIC == 0
    if (b >= a + (u - i) + e) {
        return SEP_NEVER;
    }
    if (a + e > b + (u - i)) {
        return -SEP_NEVER;
    }
    return floor_div(b - a + u + i - e, 2);
#elif METRIC == 1
    const int mid = floor_div(i + u - e, 2);
    return a + e <= b ? max(i + b - e, mid) : min(u - a - e, mid);
#else
    // floor(num / den) from a float quotient (off by at most one while |num| < 2^23), then
    // corrected exactly: integer division by a variable is slow on GPUs.
    const int num = u * u - i * i + b - a - e, den = 2 * (u - i);
    int q = (int)floor(native_divide((float)num, (float)den));
    while (q * den > num) {
        --q;
    }
    while ((q + 1) * den <= num) {
        ++q;
    }
    return q;
#endif
#elif METRIC == 2
    return l2_sep(i, u, gi, gu, s, e);
#elif METRIC == 0
    return l1_sep(i, u, gi, gu, s, e);
#else
    const ST fi = (ST)i, fu = (ST)u;
    const int mid = floor_div(i + u - e, 2);
    if (e ? gi < gu : gi <= gu) {
        return max((int)min(floor_tie(fi + gu / s, e), (ST)SEP_NEVER), mid);
    }
    return min((int)max(floor_tie(fu - gi / s, e), (ST)-SEP_NEVER), mid);
#endif
}

// Sep(i, u) where i wins their ties.
inline int sep(int i, int u, GT gi, GT gu, ST s) {
    return sep_tie(i, u, gi, gu, s, 0);
}

// Whether sep_tie(i, u, ..., e) < tq (any integer tq): for unit-spacing L2 by one
// multiplication instead of a division (floor(num / den) < tq exactly when num < tq * den, den >
// 0), since the envelope tests a separator about twice per site and divides only for the sites
// it keeps. Unlike sep_tie's, the WIDE quotient here is not clamped to +-SEP_NEVER: a test can
// differ from one on clamped values only where both separators lie outside the line, and a
// site kept or dropped there owns none of its positions.
inline bool sep_below(int i, int u, GT gi, GT gu, ST s, int tq, int e) {
#if UNIT && METRIC == 2
    return l2_num(i, u, gi, gu) - e < (long)tq * (2 * (long)(u - i));
#else
    return sep_tie(i, u, gi, gu, s, e) < tq;
#endif
}

// The partial distance of site u of a line; virtual padding sites (-1 and n) are empty.
inline GT site_g(__global const GT* g, size_t base, size_t stride, int u, int n) {
    return (u < 0 || u >= n) ? (GT)0 : g[base + (size_t)u * stride];
}

// The feature of site u of a line for KEYED (without INDICES none is read).
inline uint site_f(__global const uint* f, size_t base, size_t stride, int u, int n) {
#if INDICES
    return (u < 0 || u >= n) ? UINT_MAX : f[base + (size_t)u * stride];
#else
    return 0;
#endif
}

// (sep_tie(i, u, ..., 0), sep_tie(i, u, ..., 1)). For unit L2 below WIDE and for L2 with
// spacing both from one quotient: with e the last x moves back one exactly where the tie point
// is an integer (the division is exact). Other cases (WIDE included) take two calls.
inline int2 sep_pair(int i, int u, GT gi, GT gu, ST s) {
#if METRIC == 2 && UNIT && !WIDE
    const int q = sep_tie(i, u, gi, gu, s, 0);
    return (int2)(q, (long)q * (2 * (long)(u - i)) == l2_num(i, u, gi, gu) ? q - 1 : q);
#elif METRIC == 2 && !UNIT
    return (int2)(l2_sep(i, u, gi, gu, s, 0), l2_sep(i, u, gi, gu, s, 1));
#else
    return (int2)(sep_tie(i, u, gi, gu, s, 0), sep_tie(i, u, gi, gu, s, 1));
#endif
}

#if INDICES
// Sep(i, u) of the line's sites with KEYED ties, their features read only where it matters:
// where the two tie rules give different separators (an integer tie point).
inline int sep_keyed(__global const uint* f, size_t base, size_t stride, int n, int i, int u,
                     GT gi, GT gu, ST s) {
    const int2 t = sep_pair(i, u, gi, gu, s);
    const int s0 = t.x, s1 = t.y;
    return s1 != s0 && KEYED(site_f(f, base, stride, i, n), site_f(f, base, stride, u, n)) ? s1
                                                                                        : s0;
}
#endif

// Lower envelope of the sites [i0, i1) of one line for the positions [o0, o1) (Meijster's
// first phase): on return the stack holds q + 1 sites s[k] owning positions [t[k], t[k+1]).
// Sites with no target are skipped; `pad` adds the virtual empty sites at -1 and n where the
// site range reaches the line's ends; with INDICES ties go by the sites' features `f`
// (KEYED). Returns q (-1: no site at all).
#if UNIT && METRIC == 2 && !WIDE
// Unit-spacing L2 (squares below 2^30) without division: the stack keeps each site's real
// boundary with the site below it as a fraction t[k] / d[k] (site k is nearer beyond it,
// the one below at or before it; d[k] > 0; none for the bottom site), so testing a new site
// against the top compares two fractions by cross-multiplication in 64 bits. A kept site
// may own no integer position; line_pass steps over it. Where the later site wins their ties
// (KEYED) the numerator is one less: the boundary then falls before an integer tie point.
#define FRACTIONS 1
inline int envelope(__global const GT* g, __global const uint* f, size_t base, size_t stride,
                    int n, int pad, ST sp, __global int* s, __global int* t, __global int* d,
                    size_t ks, int o0, int o1, int i0, int i1) {
    int q = -1, sq = 0, nq = 0, dq = 1;
    int gq = 0;
    uint fq = 0;
    const int lo = pad && i0 == 0 ? -1 : i0;
    const int hi = pad && i1 == n ? n : i1 - 1;
    for (int u = lo; u <= hi; ++u) {
        const GT gv = site_g(g, base, stride, u, n);
        if (gv == G_INF) {
            continue;
        }
        const int gu = (int)gv;
        const uint fu = site_f(f, base, stride, u, n);
        // The boundary of u with the top: num / den, and the top's own: nq / dq. Pop while
        // u's boundary comes at or before the top's (the bottom site: before o0).
        int num = 0, den = 1;
        while (q >= 0) {
            num = u * u - sq * sq + gu - gq - KEYED(fq, fu);
            den = 2 * (u - sq);
            if (q == 0 ? (long)num >= (long)o0 * den : (long)num * dq > (long)nq * den) {
                break;
            }
            if (--q >= 0) {
                sq = s[q * ks];
                nq = t[q * ks];
                dq = d[q * ks];
                gq = (int)site_g(g, base, stride, sq, n);
                fq = site_f(f, base, stride, sq, n);
            }
        }
        if (q < 0) {
            q = 0;
            sq = u;
            gq = gu;
            fq = fu;
            s[0] = u;
        } else if ((long)num < (long)(o1 - 1) * den) {
            // u owns positions before o1 (1 + floor(num / den) < o1).
            ++q;
            sq = u;
            nq = num;
            dq = den;
            gq = gu;
            fq = fu;
            s[q * ks] = u;
            t[q * ks] = num;
            d[q * ks] = den;
        }
    }
    return q;
}
#else
#define FRACTIONS 0
inline int envelope(__global const GT* g, __global const uint* f, size_t base, size_t stride,
                    int n, int pad, ST sp, __global int* s, __global int* t, __global int* d,
                    size_t ks, int o0, int o1, int i0, int i1) {
    // The top of the stack (site, start, partial; its feature where read eagerly, WIDE) stays
    // in registers.
    int q = -1, sq = 0, tq = 0;
    GT gq = 0;
    uint fq = 0;
    const int lo = pad && i0 == 0 ? -1 : i0;
    const int hi = pad && i1 == n ? n : i1 - 1;
    for (int u = lo; u <= hi; ++u) {
        const GT gu = site_g(g, base, stride, u, n);
        if (gu == G_INF) {
            continue;
        }
        // Pop the sites that u is nearer than from where they start (their separator with
        // u lies before their first position); testing the separator itself keeps the
        // starts strictly increasing even where float rounding blurs a tie.
#if INDICES && !(UNIT && METRIC == 2)
        // With features: w = 1 + Sep(top, u), computed once for the test and the push.
        int w = 0;
        while (q >= 0 && (w = 1 + sep_keyed(f, base, stride, n, sq, u, gq, gu, sp)) <= tq) {
            if (--q >= 0) {
                sq = s[q * ks];
                tq = t[q * ks];
                gq = site_g(g, base, stride, sq, n);
            }
        }
        if (q < 0) {
            q = 0;
            sq = u;
            tq = o0;
            gq = gu;
            s[0] = u;
            t[0] = o0;
        } else if (w < o1) {
            ++q;
            sq = u;
            tq = w;
            gq = gu;
            s[q * ks] = u;
            t[q * ks] = w;
        }
#else
        const uint fu = site_f(f, base, stride, u, n);
        while (q >= 0 && sep_below(sq, u, gq, gu, sp, tq, KEYED(fq, fu))) {
            if (--q >= 0) {
                sq = s[q * ks];
                tq = t[q * ks];
                gq = site_g(g, base, stride, sq, n);
                fq = site_f(f, base, stride, sq, n);
            }
        }
        if (q < 0) {
            q = 0;
            sq = u;
            tq = o0;
            gq = gu;
            fq = fu;
            s[0] = u;
            t[0] = o0;
        } else {
            const int w = 1 + sep_tie(sq, u, gq, gu, sp, KEYED(fq, fu));
            if (w < o1) {
                ++q;
                sq = u;
                tq = w;
                gq = gu;
                fq = fu;
                s[q * ks] = u;
                t[q * ks] = w;
            }
        }
#endif
    }
    return q;
}
#endif

// Whether site q of the stack that envelope() left owns no position from p on (p is at or
// before its boundary with site q - 1); the bottom site owns everything before the next.
inline bool before_site(__global const int* t, __global const int* d, size_t ks, int q, int p) {
#if FRACTIONS
    return q > 0 && (long)p * d[q * ks] <= (long)t[q * ks];
#else
    return q > 0 && p < t[q * ks];
#endif
}

// ---- change tracking (incremental updates) ----

// box[0..5]: min x, max x, min y, max y, min z, max z of the voxels whose value a pass
// changed (empty while min > max); box[6] counts the voxels the passes recomputed.
inline void mark(__global int* box, int x, int y, int z) {
    atomic_min(&box[0], x);
    atomic_max(&box[1], x);
    atomic_min(&box[2], y);
    atomic_max(&box[3], y);
    atomic_min(&box[4], z);
    atomic_max(&box[5], z);
}

// ---- pass 1: rows along x, the 1-D distance to the nearest target ----

// Row `base`'s nearest target to each voxel of [o0, o1) among the voxels [i0, i1);
// `want` is the voxel value class (1 solid, 0 empty), `pad` counts the virtual voxels at -1
// and X as targets where the range reaches them. Partials are capped at `cap`. `left` holds
// the distances to the nearest target on the left between the two sweeps. With `box`, only
// changed values are written and marked (y, z: the row's coordinates). The feature of the
// target at x is x * kx + kr (KEYED; kx = Y * Z, kr = y * Z + z).
inline void row_nearest(__global const uchar* vox, size_t base, int X, int want, int pad, ST sx,
                        __global GT* g, __global uint* feat, __global int* left,
                        __global int* box, int y, int z, int o0, int o1, int i0, int i1,
                        GT cap, uint kx, uint kr) {
    int last = pad && i0 == 0 ? -1 : INT_MIN / 2;
    for (int x = i0; x < o1; ++x) {
        if ((vox[base + x] != 0) == want) {
            last = x;
        }
        left[x - i0] = last;
    }
    int next = pad && i1 == X ? X : INT_MAX / 2;
    for (int x = i1 - 1; x >= o0; --x) {
        if ((vox[base + x] != 0) == want) {
            next = x;
        }
        if (x >= o1) {
            continue;
        }
        const int l = left[x - i0];
        const bool has_l = l != INT_MIN / 2, has_n = next != INT_MAX / 2;
        const bool use_n = has_n && (!has_l || next - x < x - l);
        const int site = use_n ? next : l;
        const GT v = (has_l || has_n) ? min(offset_part(abs(site - x), sx), cap) : G_INF;
        if (box == 0 || g[base + x] != v) {
            g[base + x] = v;
            if (box != 0) {
                mark(box, x, y, z);
            }
        }
#if INDICES
        feat[base + x] =
            (site < 0 || site >= X || !(has_l || has_n)) ? UINT_MAX : (uint)site * kx + kr;
#endif
    }
}

// A whole row of a full transform without change tracking: the same nearest targets and
// features as row_nearest (ties to the left) from two branch-free sweeps, the forward one
// leaving each voxel's distance to its nearest target on the left in g itself (exact in
// every GT), so its cost is the same on every world.
#define ROW_NONE 0x3FFFFFFF
inline void row_full(__global const uchar* vox, size_t base, int X, int want, int pad, ST sx,
                     __global GT* g, __global uint* feat, GT cap, uint kx, uint kr) {
    int last = pad ? -1 : -ROW_NONE;
    for (int x = 0; x < X; ++x) {
        last = (vox[base + x] != 0) == want ? x : last;
        g[base + x] = (GT)min(x - last, ROW_NONE);
    }
    int next = pad ? X : X + ROW_NONE;
    for (int x = X - 1; x >= 0; --x) {
        next = (vox[base + x] != 0) == want ? x : next;
        const int dl = (int)g[base + x];
        const int dr = min(next - x, ROW_NONE);
        const int d = min(dl, dr);
        g[base + x] = d >= ROW_NONE ? G_INF : min(offset_part(d, sx), cap);
#if INDICES
        const int site = dr < dl ? next : x - dl;
        feat[base + x] =
            d >= ROW_NONE || site < 0 || site >= X ? UINT_MAX : (uint)site * kx + kr;
#endif
    }
}

#if CPU_LAYOUT
// A whole row of a full transform without change tracking: each voxel's 1-D
// distance to its nearest target by doubling, vectorised along the row (as xy_slices_seq
// of exact_manhattan.cl does): after the steps 1, 2, 4, ..., P, d[x] = min(d[x],
// d[x - s] + s, d[x + s] + s) has taken every offset below 2 s as a sum of distinct powers
// of two, the exact 1-D distance, in about 3 vector operations per voxel and step instead
// of a dependent select per voxel. `buf` holds two rows of X + 2 P ints (P = the largest
// step), padded on both sides with ROW_NONE, or with `pad` with targets (the virtual ones at
// -1 and X; those further out are never nearer). With INDICES (pad 0) each voxel's feature
// then comes from its distance d: the target at x - d where there is one (row_full's ties to
// the left), else the one at x + d.
inline void row_doubling(__global const uchar* vox, size_t base, int X, int want, int pad,
                         ST sx, __global GT* g, __global int* buf, GT cap,
                         __global uint* feat, uint kx, uint kr) {
    // P: the host's row_pad(X) (a row of one voxel takes one step too, to its padding).
    const int P = X > 1 ? 1 << (31 - clz(X - 1)) : 1;
    const int span = X + 2 * P;
    __global int* a = buf + P;
    __global int* b = buf + span + P;
    const int outside = pad ? 0 : ROW_NONE;
    for (int i = 0; i < P; ++i) {
        a[i - P] = outside;
        a[X + i] = outside;
        b[i - P] = outside;
        b[X + i] = outside;
    }
    for (int x = 0; x < X; ++x) {
        a[x] = (vox[base + x] != 0) == want ? 0 : ROW_NONE;
    }
    for (int s = 1; s <= P; s <<= 1) {
        for (int x = 0; x < X; ++x) {
            b[x] = min(a[x], min(a[x - s], a[x + s]) + s);
        }
        __global int* t = a;
        a = b;
        b = t;
    }
    for (int x = 0; x < X; ++x) {
        const int d = a[x];
        g[base + x] = d >= ROW_NONE ? G_INF : min(offset_part(d, sx), cap);
#if INDICES
        const bool left = d <= x && (vox[base + x - d] != 0) == want;
        feat[base + x] = d >= ROW_NONE ? UINT_MAX : (uint)(left ? x - d : x + d) * kx + kr;
#endif
    }
}
#endif

// Rows y in [lo.y, lo.y + size.y), z in [lo.z, lo.z + size.z), `per_item` per work-item,
// their voxels x in [lo.x, lo.x + size.x) from the voxels [i0, i1); `left` is each
// work-item's scratch of X ints (at scratch + item * istride; full transforms without
// features use 2 (X + 2 P) of them, row_doubling's two padded rows). `solid` 1: g's targets
// are the nonzero voxels; 0: the zero ones (SciPy's convention, no inverted copy of the
// input needed). Z: the world's depth, for the features' keys.
__kernel void x_pass(__global const uchar* restrict vox, __global GT* restrict g,
                     __global GT* restrict h, __global uint* restrict feat, uint X, uint Y,
                     int4 lo, int4 size, uint per_item, ST sx, __global int* restrict scratch,
                     ulong istride, __global int* box, int i0, int i1, GT cap, int solid,
                     uint Z) {
    const size_t rows = (size_t)size.y * size.z;
    __global int* left = scratch + get_global_id(0) * istride;
    const size_t r0 = get_global_id(0) * per_item;
    for (size_t r = r0; r < min(r0 + per_item, rows); ++r) {
        const int y = lo.y + (int)(r % size.y), z = lo.z + (int)(r / size.y);
        const size_t base = ((size_t)z * Y + y) * X;
        const uint kx = Y * Z, kr = (uint)y * Z + (uint)z;
        if (box == 0 && i0 == 0 && i1 == (int)X && lo.x == 0 && size.x == (int)X) {
#if !CPU_LAYOUT
            row_full(vox, base, (int)X, solid, 0, sx, g, feat, cap, kx, kr);
#if SIGNED
            row_full(vox, base, (int)X, 0, 1, sx, h, feat, cap, kx, kr);
#endif
#else
            row_doubling(vox, base, (int)X, solid, 0, sx, g, left, cap, feat, kx, kr);
#if SIGNED
            row_doubling(vox, base, (int)X, 0, 1, sx, h, left, cap, feat, kx, kr);
#endif
#endif
            continue;
        }
        row_nearest(vox, base, (int)X, solid, 0, sx, g, feat, left, box, y, z, lo.x,
                    lo.x + size.x, i0, i1, cap, kx, kr);
#if SIGNED
        row_nearest(vox, base, (int)X, 0, 1, sx, h, feat, left, box, y, z, lo.x, lo.x + size.x,
                    i0, i1, cap, kx, kr);
#endif
    }
}

// ---- passes 2 and 3: columns along y, then z ----

// Meijster's second phase for one line: every position takes the partial distance from the
// site owning it (and, with INDICES, the site's feature). With `box`, only changed values
// are written and marked; `pos` maps a line position to (x, y, z) through `axis`.
inline void line_pass(__global const GT* gin, __global GT* gout, size_t base, size_t stride,
                      int n, int pad, ST sp, __global int* s, __global int* t, __global int* d,
                      size_t ks, __global const uint* fin, __global uint* fout,
                      __global int* box, int x, int other, int axis, int o0, int o1, int i0,
                      int i1, GT cap) {
    int q = envelope(gin, fin, base, stride, n, pad, sp, s, t, d, ks, o0, o1, i0, i1);
    // The owning site (its partial and feature) in registers.
    int sq = 0;
    GT gq = 0;
    uint fq = UINT_MAX;
    bool load = true;
    for (int p = o1 - 1; p >= o0; --p) {
        const size_t i = base + (size_t)p * stride;
        GT v = G_INF;
        uint f = UINT_MAX;
        if (q >= 0) {
            while (before_site(t, d, ks, q, p)) {
                --q;
                load = true;
            }
            if (load) {
                sq = s[q * ks];
                gq = site_g(gin, base, stride, sq, n);
#if INDICES
                fq = fin[base + (size_t)sq * stride];
#endif
                load = false;
            }
            v = min(fpart(p, sq, gq, sp), cap);
            f = fq;
        }
        if (box == 0 || gout[i] != v) {
            gout[i] = v;
            if (box != 0) {
                if (axis == 1) {
                    mark(box, x, p, other);
                } else {
                    mark(box, x, other, p);
                }
            }
        }
#if INDICES
        fout[i] = f;
#else
        (void)f;
#endif
    }
}

#if METRIC == 0 && UNIT
// Unit-spacing L1 of the cw lines of a tile (element (p, c) at p * tw + c), a full transform
// (positions and sites [0, n)): the min-plus forward and backward sweeps (the lower envelope
// of V-shapes of slope 1 is their minimum), with the nearest site's feature. The lines run
// side by side (the inner loop over c vectorises), no division and no data-dependent stack,
// so the cost is the same on every world. `pad` adds the virtual empty sites at -1 and n.
// Of equally near sites the lower feature wins (KEYED).
inline void tile_sweep_l1(__global const GT* tin, __global GT* tout, int tw, int cw, int n,
                          int pad, __global const uint* fin, __global uint* fout, GT cap) {
    GT run[16];
    uint fr[16];
    // Virtual sites at -1 and n: partial 0, one step away from the line's ends.
    for (int c = 0; c < cw; ++c) {
        run[c] = pad ? 0u : G_INF;
        fr[c] = UINT_MAX;
    }
    for (int p = 0; p < n; ++p) {
        for (int c = 0; c < cw; ++c) {
            const size_t i = (size_t)p * tw + c;
            const GT cand = add_sat(run[c], 1u);
            const GT gp = tin[i];
#if INDICES
            const uint fp = fin[i];
            fr[c] = gp < cand || (gp == cand && fp < fr[c]) ? fp : fr[c];
            fout[i] = fr[c];
#endif
            run[c] = min(gp, cand);
            tout[i] = run[c];
        }
    }
    for (int c = 0; c < cw; ++c) {
        run[c] = pad ? 0u : G_INF;
    }
    for (int p = n - 1; p >= 0; --p) {
        for (int c = 0; c < cw; ++c) {
            const size_t i = (size_t)p * tw + c;
            const GT cand = add_sat(run[c], 1u);
            const GT gp = tout[i];
#if INDICES
            const uint fp = fout[i];
            fr[c] = gp < cand || (gp == cand && fp < fr[c]) ? fp : fr[c];
            fout[i] = fr[c];
#endif
            run[c] = min(gp, cand);
            tout[i] = min(run[c], cap);
        }
    }
}
#endif

#if METRIC == 2 && UNIT && !WIDE
// Unit-spacing L2 of cw <= 16 lines of a tile (element (p, c) at p * tw + c, tw a multiple
// of 16, the lines c = 0..15 ours), a full transform, by windowed minima with the lines side
// by side: position p takes the least g_u + (p - u)^2 over the sites u near enough to
// matter, all 16 lines in one vector add and minimum per site (no stack, no data-dependent
// branch per site). The bound: the site of p - 1 is one step further from p, so d(p) <=
// (sqrt(d(p - 1)) + 1)^2 <= U = (s + 2)^2 with s = floor(sqrt(m)), m the largest d(p - 1) of
// the lines that have a site, and a site u can only be nearer where g_u + (p - u)^2 <= U:
// within r = s + 2 of p, and in a block of 16 sites only where the block's least partial
// (over its sites and lines) plus its nearest squared offset stays within U. The first
// position takes every site. The blocks' least partials go to `bmin`, and `live` (n / 16 + 2
// entries each) leads the loop past blocks without a site. Returns false (tin as it came)
// where r passes WINDOW_MAX, for the envelope to take the tile. `pad` adds the virtual empty
// sites at -1 and n. Empty sites (G_INF) become L2_FAR in tin, which sums with any square
// below 2^30 without wrapping (the partials stay below 2^30 here, WIDE otherwise). The sites
// of a window go through two accumulators (even and odd sites), halving the dependent chain
// of minima. With INDICES the candidates are 64-bit (partial << 32 | feature), the sites'
// in `kt` (16 per site), so the same minima take of equally near sites the one with the
// lowest feature (KEYED), and each lane's feature goes to fout (fin, fout: tin's layout).
#define L2_FAR 0x80000000u
#define WINDOW_MAX 256
inline bool tile_window_l2(__global GT* tin, __global GT* tout, __global uint* bmin,
                           __global int* live, int tw, int cw, int n, int pad, GT cap,
                           __global const uint* fin, __global uint* fout, __global ulong* kt) {
    const int nb = (n + 15) / 16;
    for (int b = 0; b < nb; ++b) {
        uint16 lo = (uint16)L2_FAR;
        for (int u = b * 16; u < min(n, b * 16 + 16); ++u) {
            const uint16 v = min(vload16(0, tin + u * tw), (uint16)L2_FAR);
            const uint16 lane = (uint16)(0, 1, 2, 3, 4, 5, 6, 7, 8, 9, 10, 11, 12, 13, 14, 15);
            const uint16 w = select((uint16)L2_FAR, v, lane < (uint16)cw);
            vstore16(w, 0, tin + u * tw);
#if INDICES
            vstore16(upsample(w, vload16(0, fin + u * tw)), 0, kt + u * 16);
#endif
            lo = min(lo, w);
        }
        const uint8 l8 = min(lo.lo, lo.hi);
        const uint4 l4 = min(l8.lo, l8.hi);
        const uint2 l2 = min(l4.lo, l4.hi);
        bmin[b] = min(l2.x, l2.y);
    }
    // live[b]: the first block from b on that holds a site (nb: none).
    live[nb] = nb;
    for (int b = nb; b-- > 0;) {
        live[b] = bmin[b] < L2_FAR ? b : live[b + 1];
    }
    if (live[0] == nb && !pad) {
        for (int p = 0; p < n; ++p) {
            vstore16((uint16)G_INF, 0, tout + p * tw);
#if INDICES
            for (int c = 0; c < cw; ++c) {
                fout[p * tw + c] = UINT_MAX;
            }
#endif
        }
        return true;
    }
    int r = n;
    uint bound = UINT_MAX;
    for (int p = 0; p < n; ++p) {
        const uint edge = pad ? (uint)min((p + 1) * (p + 1), (n - p) * (n - p)) : L2_FAR;
#if INDICES
        ulong16 kb = (ulong16)(((ulong)edge << 32) | UINT_MAX);
        ulong16 kb1 = (ulong16)(((ulong)L2_FAR << 32) | UINT_MAX);
#else
        uint16 best = (uint16)edge, best1 = (uint16)L2_FAR;
#endif
        const int lo = max(0, p - r), hi = min(n - 1, p + r);
        for (int b = live[lo / 16]; b <= hi / 16; b = live[b + 1]) {
            const int b0 = b * 16, b1 = b0 + 15;
            const int off = p < b0 ? b0 - p : p > b1 ? p - b1 : 0;
            if (bmin[b] + (uint)(off * off) > bound) {
                continue;
            }
            const int ue = min(hi, b1);
            int u = max(lo, b0);
            for (; u < ue; u += 2) {
                const uint k0 = (uint)((p - u) * (p - u));
                const uint k1 = (uint)((p - u - 1) * (p - u - 1));
#if INDICES
                kb = min(kb, vload16(0, kt + u * 16) + (ulong16)((ulong)k0 << 32));
                kb1 = min(kb1, vload16(0, kt + (u + 1) * 16) + (ulong16)((ulong)k1 << 32));
#else
                const uint16 c0 = vload16(0, tin + u * tw) + k0;
                const uint16 c1 = vload16(0, tin + (u + 1) * tw) + k1;
                best = min(best, c0);
                best1 = min(best1, c1);
#endif
            }
            if (u == ue) {
#if INDICES
                kb = min(kb, vload16(0, kt + u * 16) +
                                 (ulong16)((ulong)((p - u) * (p - u)) << 32));
#else
                const uint16 c0 = vload16(0, tin + u * tw) + (uint)((p - u) * (p - u));
                best = min(best, c0);
#endif
            }
        }
#if INDICES
        kb = min(kb, kb1);
        const uint16 best = convert_uint16(kb >> (ulong16)32);
        const uint16 far = as_uint16(best >= (uint16)L2_FAR);
        vstore16(select(convert_uint16(kb & (ulong16)UINT_MAX), (uint16)UINT_MAX, far), 0,
                 fout + p * tw);
#else
        best = min(best, best1);
        const uint16 far = as_uint16(best >= (uint16)L2_FAR);
#endif
        vstore16(select(min(best, (uint16)cap), (uint16)G_INF, far), 0, tout + p * tw);
        const uint16 real = best & ~far;
        const uint8 h8 = max(real.lo, real.hi);
        const uint4 h4 = max(h8.lo, h8.hi);
        const uint2 h2 = max(h4.lo, h4.hi);
        const uint m = max(h2.x, h2.y);
        // s = floor(sqrt(m)) exactly, from the float root (off by at most one).
        int sr = (int)sqrt((float)m);
        sr -= (uint)(sr * sr) > m;
        sr += (uint)((sr + 1) * (sr + 1)) <= m;
        r = sr + 2;
        bound = (uint)(r * r);
        if (r > WINDOW_MAX) {
            for (int u = 0; u < n; ++u) {
                const uint16 v = vload16(0, tin + u * tw);
                const uint16 empty = as_uint16(v >= (uint16)L2_FAR);
                vstore16(select(v, (uint16)G_INF, empty), 0, tin + u * tw);
            }
            return false;
        }
    }
    return true;
}

#if !INDICES
// tile_window_l2 without features (ties need not be broken): positions go in groups of four
// that share each site's load, the walk over the blocks and one bound. From m, the largest
// d(p0 - 1) of the lines that have a site (s = floor(sqrt(m))), d(p0 + q) <= (sqrt(m) + q +
// 1)^2 < r_q^2 with r_q = s + 2 + q, so a site can only be nearest to a position of the group
// within [p0 - s - 2, p0 + 3 + s + 5], and in a block only where the block's least partial
// plus its squared offset from the group stays within r_3^2. The window is a few sites wider
// than a single position's, but the horizontal maximum, the root and the block walk are paid
// once per four positions, and each site's load feeds four independent minima. Same
// arguments, preparation of `tin` and fallback (false where r_3 passes WINDOW_MAX) as
// tile_window_l2.
inline bool tile_window_l2_dist(__global GT* tin, __global GT* tout, __global uint* bmin,
                                __global int* live, int tw, int cw, int n, int pad, GT cap) {
    const int nb = (n + 15) / 16;
    for (int b = 0; b < nb; ++b) {
        uint16 lo = (uint16)L2_FAR;
        for (int u = b * 16; u < min(n, b * 16 + 16); ++u) {
            const uint16 v = min(vload16(0, tin + u * tw), (uint16)L2_FAR);
            const uint16 lane = (uint16)(0, 1, 2, 3, 4, 5, 6, 7, 8, 9, 10, 11, 12, 13, 14, 15);
            const uint16 w = select((uint16)L2_FAR, v, lane < (uint16)cw);
            vstore16(w, 0, tin + u * tw);
            lo = min(lo, w);
        }
        const uint8 l8 = min(lo.lo, lo.hi);
        const uint4 l4 = min(l8.lo, l8.hi);
        const uint2 l2 = min(l4.lo, l4.hi);
        bmin[b] = min(l2.x, l2.y);
    }
    live[nb] = nb;
    for (int b = nb; b-- > 0;) {
        live[b] = bmin[b] < L2_FAR ? b : live[b + 1];
    }
    if (live[0] == nb && !pad) {
        for (int p = 0; p < n; ++p) {
            vstore16((uint16)G_INF, 0, tout + p * tw);
        }
        return true;
    }
    // The first group takes every site.
    int lo = 0, hi = n - 1;
    uint bound = UINT_MAX;
    for (int p0 = 0; p0 < n; p0 += 4) {
        const int last = min(p0 + 3, n - 1);
        uint16 best0 = (uint16)L2_FAR, best1 = (uint16)L2_FAR, best2 = (uint16)L2_FAR,
               best3 = (uint16)L2_FAR;
        if (pad) {
            // The virtual empty sites at -1 and n.
            best0 = (uint16)(uint)min((p0 + 1) * (p0 + 1), (n - p0) * (n - p0));
            best1 = (uint16)(uint)min((p0 + 2) * (p0 + 2), (n - p0 - 1) * (n - p0 - 1));
            best2 = (uint16)(uint)min((p0 + 3) * (p0 + 3), (n - p0 - 2) * (n - p0 - 2));
            best3 = (uint16)(uint)min((p0 + 4) * (p0 + 4), (n - p0 - 3) * (n - p0 - 3));
        }
        for (int b = live[lo / 16]; b <= hi / 16; b = live[b + 1]) {
            const int b0 = b * 16, b1 = b0 + 15;
            const int off = last < b0 ? b0 - last : p0 > b1 ? p0 - b1 : 0;
            if (bmin[b] + (uint)(off * off) > bound) {
                continue;
            }
            const int ue = min(hi, b1);
            for (int u = max(lo, b0); u <= ue; ++u) {
                const uint16 v = vload16(0, tin + u * tw);
                const int k = p0 - u;
                best0 = min(best0, v + (uint)(k * k));
                best1 = min(best1, v + (uint)((k + 1) * (k + 1)));
                best2 = min(best2, v + (uint)((k + 2) * (k + 2)));
                best3 = min(best3, v + (uint)((k + 3) * (k + 3)));
            }
        }
        const uint16 far0 = as_uint16(best0 >= (uint16)L2_FAR);
        vstore16(select(min(best0, (uint16)cap), (uint16)G_INF, far0), 0, tout + p0 * tw);
        uint16 end = best0;
        if (p0 + 1 < n) {
            const uint16 far1 = as_uint16(best1 >= (uint16)L2_FAR);
            vstore16(select(min(best1, (uint16)cap), (uint16)G_INF, far1), 0,
                     tout + (p0 + 1) * tw);
            end = best1;
        }
        if (p0 + 2 < n) {
            const uint16 far2 = as_uint16(best2 >= (uint16)L2_FAR);
            vstore16(select(min(best2, (uint16)cap), (uint16)G_INF, far2), 0,
                     tout + (p0 + 2) * tw);
            end = best2;
        }
        if (p0 + 3 < n) {
            const uint16 far3 = as_uint16(best3 >= (uint16)L2_FAR);
            vstore16(select(min(best3, (uint16)cap), (uint16)G_INF, far3), 0,
                     tout + (p0 + 3) * tw);
            end = best3;
        }
        const uint16 real = end & ~as_uint16(end >= (uint16)L2_FAR);
        const uint8 h8 = max(real.lo, real.hi);
        const uint4 h4 = max(h8.lo, h8.hi);
        const uint2 h2 = max(h4.lo, h4.hi);
        const uint m = max(h2.x, h2.y);
        // s = floor(sqrt(m)) exactly, from the float root (off by at most one).
        int s = (int)sqrt((float)m);
        s -= (uint)(s * s) > m;
        s += (uint)((s + 1) * (s + 1)) <= m;
        const int r = s + 5;
        if (r > WINDOW_MAX) {
            for (int u = 0; u < n; ++u) {
                const uint16 v = vload16(0, tin + u * tw);
                const uint16 empty = as_uint16(v >= (uint16)L2_FAR);
                vstore16(select(v, (uint16)G_INF, empty), 0, tin + u * tw);
            }
            return false;
        }
        // The next group's window and bound.
        lo = max(0, p0 + 4 - s - 2);
        hi = min(n - 1, p0 + 7 + r);
        bound = (uint)(r * r);
    }
    return true;
}
#endif
#endif

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

// floor(f / d) for any 32-bit f and d >= 1 as floor((f + 1/2) inv), inv the double nearest
// 1 / d: (f + 1/2) / d lies at least 1 / (2 d) from an integer, and the two roundings move it
// by at most (f + 1/2) / d 2^-52, less than that, so the floor needs no correction (checked
// against f / d in numpy for 6 M pairs around multiples of 2000 divisors). Integer division by
// a run-time divisor costs tens of cycles, three per voxel in `finish`.
inline uint quotient(uint f, double inv) {
    return (uint)(((double)f + 0.5) * inv);
}

#if INDICES
// Voxel i's (z, y, x) planes (`count` voxels apart) of the feature key f (-1, -1, -1 for
// UINT_MAX: no solid), keys (x * Y + y) * Z + z: yz = Y * Z, zn = Z and their reciprocals.
inline int3 index_of(uint f, uint yz, uint zn, double inv_yz, double inv_z) {
    if (f == UINT_MAX) {
        return (int3)(-1);
    }
    const uint xf = quotient(f, inv_yz);
    const uint r = f - xf * yz;
    const uint yf = quotient(r, inv_z);
    return (int3)((int)(r - yf * zn), (int)yf, (int)xf);
}
inline void store_index(__global int* idx, size_t count, size_t i, int3 q) {
    idx[i] = q.x;
    idx[count + i] = q.y;
    idx[2 * count + i] = q.z;
}
inline void write_index(__global int* idx, size_t count, size_t i, uint f, uint yz, uint zn,
                        double inv_yz, double inv_z) {
    store_index(idx, count, i, index_of(f, yz, zn, inv_yz, inv_z));
}
#endif

// Lines of length n and element stride `stride` along `axis` (1: y, 2: z): line l has x =
// lo_x + l % count_x and the other coordinate lo_o + l / count_x, and starts at
// other * mstride + x; positions [o0, o1) from the sites [i0, i1), partials capped at `cap`.
// Lines outside `skip` (the box the previous pass changed; null: none skipped) are left as
// they are. The stacks of work-item w are at scratch + w * istride, their k-th entries
// k * kstride further.
//
// With tile_w > 0 (CPU layout, per_item a multiple of count_x) up to tile_w adjacent lines of
// one x row at a time are copied into a contiguous tile (partials, and features with
// INDICES), transformed there and copied back, so that the lines' strided elements (a power
// of two apart in power-of-two worlds, all in one cache set) are read from memory once, a
// cache line at a time. Every line is read whole before any of it is written, so the input
// and output buffers may be the same (the passes then run in place): hence no `restrict`.
//
// `final` (the z pass of a full transform with tiles, not SIGNED): the tile goes out as the
// output format (`store`, as `finish` writes it) into `out` instead of partials into gout,
// and with INDICES the features as the index planes z, y, x into `idx` (the first plane
// may be `fout` itself: each line's features are in the tile before any is written), so no
// `finish` pass reads the partials again. The z pass's lines are X * Y = stride apart and X =
// mstride. `out` may be `g` (elements as wide): no `restrict`.
__kernel void col_pass(__global const GT* g, __global GT* gout, __global const GT* h,
                       __global GT* hout, __global const uint* fin, __global uint* fout,
                       __global int* restrict scratch, uint n, ulong stride, ulong mstride,
                       int lo_x, int count_x, int lo_o, int count_o, uint per_item, ulong kstride,
                       ulong istride, ST sp, int axis, __global const int* skip,
                       __global int* box, int o0, int o1, int i0, int i1, GT cap, int tile_w,
                       int final, __global OUT_T* out, __global const uchar* vox,
                       __constant uchar* rgb, __global int* idx, double dmax) {
    const size_t w = get_global_id(0);
    __global int* s = scratch + w * istride;
    __global int* t = s + (size_t)(n + 2) * kstride;
    __global int* d = t + (size_t)(n + 2) * kstride;
    const size_t lines = (size_t)count_x * count_o;
    const size_t l0 = w * per_item;
    // The previous pass marked (x, y, z); this pass's lines are indexed by x and the
    // coordinate of the axis it does not run along: z for the y pass, y for the z pass.
    const int skip_o = axis == 1 ? 4 : 2;
    if (tile_w > 0) {
        const size_t cells = (size_t)n * tile_w;
        __global GT* tin = (__global GT*)(d + (size_t)(n + 2) * kstride);
        __global GT* tout = tin + cells;
        __global uint* ftin = (__global uint*)(tout + cells);
        __global uint* ftout = ftin + cells;
        // tile_window_l2's 64-bit candidates with INDICES, 8-byte aligned (the offset so far
        // has n's parity: 3 (n + 2) ints and whole tiles of an even width).
        __global ulong* kt = (__global ulong*)(ftout + cells + (n & 1));
        const size_t l_end = min(l0 + per_item, lines);
        for (size_t c0 = l0; c0 < l_end;) {
            const int x0 = lo_x + (int)(c0 % count_x);
            const int other = lo_o + (int)(c0 / count_x);
            // The tile ends at tile_w lines, the work-item's last line or the row's end.
            const int cw = (int)min(min((size_t)tile_w, l_end - c0),
                                    (size_t)(count_x - (int)(c0 % count_x)));
            c0 += (size_t)cw;
            if (skip != 0 && (x0 + cw - 1 < skip[0] || x0 > skip[1] || other < skip[skip_o] ||
                              other > skip[skip_o + 1])) {
                continue;
            }
            if (box != 0) {
                atomic_add(&box[6], (o1 - o0) * cw);
            }
            const size_t base = (size_t)other * mstride + x0;
#if INDICES
            for (int u = i0; u < i1; ++u) {
                for (int c = 0; c < cw; ++c) {
                    ftin[u * tile_w + c] = fin[base + (size_t)u * stride + c];
                }
            }
#endif
            for (int cls = 0; cls < 1 + SIGNED; ++cls) {
                __global const GT* src = cls == 0 ? g : h;
                __global GT* dst = cls == 0 ? gout : hout;
                for (int u = i0; u < i1; ++u) {
                    for (int c = 0; c < cw; ++c) {
                        tin[u * tile_w + c] = src[base + (size_t)u * stride + c];
                    }
                }
                for (int u = o0; u < o1 && box != 0; ++u) {
                    for (int c = 0; c < cw; ++c) {
                        tout[u * tile_w + c] = dst[base + (size_t)u * stride + c];
                    }
                }
#if METRIC == 0 && UNIT
                if (box == 0) {
                    for (int c0 = 0; c0 < cw; c0 += 16) {
                        tile_sweep_l1(tin + c0, tout + c0, tile_w, min(16, cw - c0), (int)n, cls,
                                      ftin + c0, ftout + c0, cap);
                    }
                } else
#endif
                for (int c0 = 0; c0 < cw; c0 += 16) {
                    // Sub-tiles of 16 lines; the envelope per line where no vector path
                    // takes them.
                    const int c1 = min(c0 + 16, cw);
#if METRIC == 2 && UNIT && !WIDE && !INDICES && CPU_LAYOUT
                    // (Tiles are the CPU layout's: compiled out of the GPU layout's col_pass,
                    // whose registers the windows would cost.)
                    if (box == 0 && tile_w % 16 == 0 &&
                        tile_window_l2_dist(tin + c0, tout + c0, (__global uint*)s, t, tile_w,
                                            c1 - c0, (int)n, cls, cap)) {
                        continue;
                    }
#elif METRIC == 2 && UNIT && !WIDE && CPU_LAYOUT
                    if (box == 0 && tile_w % 16 == 0 &&
                        tile_window_l2(tin + c0, tout + c0, (__global uint*)s, t, tile_w,
                                       c1 - c0, (int)n, cls, cap, ftin + c0, ftout + c0, kt)) {
                        continue;
                    }
#endif
                    for (int c = c0; c < c1; ++c) {
                        line_pass(tin, tout, (size_t)c, (size_t)tile_w, (int)n, cls, sp, s, t, d,
                                  kstride, ftin, ftout, box, x0 + c, other, axis, o0, o1, i0, i1,
                                  cap);
                    }
                }
#if !SIGNED
                if (final) {
                    for (int u = o0; u < o1; ++u) {
                        for (int c = 0; c < cw; ++c) {
                            const size_t i = base + (size_t)u * stride + c;
#if OUT_KIND == 4
                            const uchar cls = vox[i];
#else
                            const uchar cls = 0;
#endif
                            store(out, rgb, cls, i, min(distance_of(tout[u * tile_w + c]), dmax));
                        }
                    }
                    continue;
                }
#endif
                for (int u = o0; u < o1; ++u) {
                    for (int c = 0; c < cw; ++c) {
                        dst[base + (size_t)u * stride + c] = tout[u * tile_w + c];
                    }
                }
            }
#if INDICES
            if (final) {
                // The key f = (xf * Y + yf) * Z + zf of the nearest target (UINT_MAX: none)
                // to its coordinates; the z pass's lines are n = Z long, stride = X * Y and
                // mstride = X apart.
                const uint zn = n, yz = (uint)(stride / mstride) * n;
                const double inv_yz = 1.0 / (double)yz, inv_z = 1.0 / (double)zn;
                const size_t count = (size_t)n * stride;
                for (int u = o0; u < o1; ++u) {
                    for (int c = 0; c < cw; ++c) {
                        const size_t i = base + (size_t)u * stride + c;
                        write_index(idx, count, i, ftout[u * tile_w + c], yz, zn, inv_yz, inv_z);
                    }
                }
                continue;
            }
            for (int u = o0; u < o1; ++u) {
                for (int c = 0; c < cw; ++c) {
                    fout[base + (size_t)u * stride + c] = ftout[u * tile_w + c];
                }
            }
#endif
        }
        return;
    }
    for (size_t l = l0; l < min(l0 + per_item, lines); ++l) {
        const int x = lo_x + (int)(l % count_x);
        const int other = lo_o + (int)(l / count_x);
        if (skip != 0 && (x < skip[0] || x > skip[1] || other < skip[skip_o] ||
                          other > skip[skip_o + 1])) {
            continue;
        }
        if (box != 0) {
            atomic_add(&box[6], o1 - o0);
        }
        const size_t base = (size_t)other * mstride + x;
        line_pass(g, gout, base, stride, (int)n, 0, sp, s, t, d, kstride, fin, fout, box, x,
                  other, axis, o0, o1, i0, i1, cap);
#if SIGNED
        line_pass(h, hout, base, stride, (int)n, 1, sp, s, t, d, kstride, fin, fout, box, x,
                  other, axis, o0, o1, i0, i1, cap);
#endif
    }
}

// Writes the output format from the final partials (and the index planes: z, y, x of the
// nearest solid, -1 without one, as SciPy's return_indices lays them out, from its key and
// the world's depth Z) for the voxels of the box lo + [0, size): the whole world, or the
// voxels an incremental update changed. One work-item per voxel in a 3-D range (x rounded up
// to the work-group size). Each reads its voxel's partials and feature before writing, so
// `out` may be `g` (same element size) and `feat` the first index plane: no `restrict` on
// them.
__kernel void finish(__global const GT* g, __global const GT* h, __global const uchar* restrict vox,
                     __constant uchar* rgb, __global OUT_T* out, __global const uint* feat,
                     __global int* idx, uint X, uint Y, ulong count, int4 lo, int4 size,
                     double dmax, uint Z) {
    if (get_global_id(0) >= (size_t)size.x) {
        return;
    }
    const int x = lo.x + (int)get_global_id(0), y = lo.y + (int)get_global_id(1),
              z = lo.z + (int)get_global_id(2);
    const size_t i = ((size_t)z * Y + y) * X + x;
    const uchar v = vox[i];
#if SIGNED
    const double d = v != 0 ? -min(distance_of(h[i]), dmax) : min(distance_of(g[i]), dmax);
#else
    const double d = min(distance_of(g[i]), dmax);
#endif
    store(out, rgb, v, i, d);
#if INDICES
    write_index(idx, count, i, feat[i], Y * Z, Z, 1.0 / ((double)Y * Z), 1.0 / Z);
#endif
}

// ---- GPU layout of the full transform: lower envelopes by bands in local memory ----
//
// For full transforms in the GPU layout (signed or not, with or without indices, any spacing:
// float, double (FP64) or 64-bit (WIDE) partials), the y and z passes run cols_banded: a
// work-group holds C adjacent lines (x fastest, so its loads and stores are coalesced) of n
// positions in local memory, and K work-items per line each build the envelope of one band of
// sites (a multiple of 32 positions) with Meijster's stack. The sites in the envelopes are bits
// of a mask, a 32-bit word per 32 positions, so that a band's words are its work-item's own: a
// site's neighbours in a list are the nearest set bits (clz), and dropping a site clears its
// bit. The mask takes 1 bit of local memory per position where a doubly linked list took 4
// bytes, so that twice as many lines share a work-group (longer coalesced rows).
// The bands are then merged pairwise in log2(K) rounds (the parallel banding of Cao, Tang, Mitra &
// Tan, "Parallel banding algorithm to compute exact distance transform with the GPU", 2010): where
// two lists meet, the left list's last site is dropped while Sep(its predecessor, it) >= Sep(it,
// the right list's first site), and the right list's first while Sep(left's last, it) >= Sep(it,
// its successor) — a dropped site is everywhere at least as far as one of its neighbours, so the
// lists' minimum is kept. In the final list every site owns the positions (Sep(predecessor, it),
// Sep(it, successor)]: its work-item names the site in `last` for every band whose first
// position it owns. Each work-item then walks the list from its band's first owner over its
// band's positions, finding each owner's end as it moves on, writing every position's partial
// (or, in the last pass, its output value): no owner array, and the work of a site that owns
// hundreds of positions is shared by the bands they lie in. The first pass is
// exact_manhattan.cl's x_rows (the 1-D distance along x, 16 bits, 0xFFFF where a row has no
// solid). With INDICES the separators break ties by the sites' keys (KEYED, as col_pass),
// compared only where the two tie rules give different separators (BKEY: the y pass's sites'
// from the x rows' targets, the z pass's from the y pass's targets): the order (partial, key) is
// strict, so the bands' envelopes and their merges keep the same owner as the sequential stack,
// and every position takes its owner's target.

// cols_banded's loads in flight per work-item (on the H100, 512^3 L2 f32: y and z passes 1.88 and
// 3.45 ms with one, 1.74 and 3.34 with 8, 1.73 and 3.32 with 16).
#define BANDED_LOADS 8

// BANDED_GLOBAL (a second build of this file): lines too long for local memory keep gl, mask and
// keyx in global memory instead, each work-group its own part of buffers the host sizes for
// every group (`banded_scratch`); the same code, its barriers fencing global memory too. Lines
// of tens of thousands of positions then still take many bands in parallel, where col_pass
// would give each line one work-item.
#ifndef BANDED_GLOBAL
#define BANDED_GLOBAL 0
#endif
// BANDED_AXIS (1 or 2; 0: either, by the arguments): a build of cols_banded for the y or the z
// pass alone, whose loops then hold no test of which pass they run.
#ifndef BANDED_AXIS
#define BANDED_AXIS 0
#endif
#if BANDED_GLOBAL
#define BAS __global
#define BANDED_FENCE (CLK_LOCAL_MEM_FENCE | CLK_GLOBAL_MEM_FENCE)
#else
#define BAS __local
#define BANDED_FENCE CLK_LOCAL_MEM_FENCE
#endif

// Position p of line c in the local arrays; word w of its line's mask.
#define LI(p) ((p) * C + c)
#define MW(w) ((w) * C + c)

// The lowest set bit of a nonzero word m, as position w * 32 + bit.
inline int lowest_site(int w, uint m) {
    return (w << 5) + 31 - (int)clz(m & (0u - m));
}

// The site in the list nearest below e and not below lo, or -1.
inline int live_before(BAS const uint* mask, uint C, uint c, int e, int lo) {
    int w = e >> 5;
    uint m = mask[MW(w)] & ((1u << (e & 31)) - 1u);
    while (m == 0) {
        if ((w << 5) <= lo) {
            return -1;
        }
        m = mask[MW(--w)];
    }
    const int r = (w << 5) + 31 - (int)clz(m);
    return r >= lo ? r : -1;
}

// The site in the list nearest above e and below hi, or -1.
inline int live_after(BAS const uint* mask, uint C, uint c, int e, int hi) {
    const int s = e + 1;
    int w = s >> 5;
    if ((w << 5) >= hi) {
        return -1;
    }
    uint m = mask[MW(w)] & (0xFFFFFFFFu << (s & 31));
    while (m == 0) {
        if ((++w << 5) >= hi) {
            return -1;
        }
        m = mask[MW(w)];
    }
    const int r = lowest_site(w, m);
    return r < hi ? r : -1;
}
#define BEFORE(e, lo) live_before(mask, C, c, (e), (lo))
#define AFTER(e, hi) live_after(mask, C, c, (e), (hi))
#define DROP(e) (mask[MW((e) >> 5)] &= ~(1u << ((e)&31)))

// A y pass site's partial from its x row's 1-D distance d (0xFFFF: none): the y pass keeps d in
// local memory (gl16, 2 bytes a position), not the partial.
inline GT part16(uint d, ST s) {
    return d == 0xFFFFu ? G_INF : offset_part((int)d, s);
}

// fpart with the sum rounded once (an fma), whatever the compiler would contract: with INDICES
// the z pass finds a site's partial from its target (banded_part), which must be the y
// pass's value.
inline GT fpart_fma(int x, int i, GT gi, ST s) {
#if UNIT || METRIC == 1
    return fpart(x, i, gi, s);
#else
    const ST a = s * (ST)abs(x - i);
    return METRIC == 2 ? fma(a, a, gi) : fma(s, (ST)abs(x - i), gi);
#endif
}

#if INDICES
// The y pass hands the z pass each voxel's nearest target as (x << 16) | y (UINT_MAX: none;
// the banded passes run where X and Y are below 0xFFFF), its `fout`. The z pass keeps these in
// local memory (kl, over gl) instead of partials, and finds a site's partial from its target
// (banded_part) exactly as the y pass computed it, so that it reads 4 bytes a voxel, not 8,
// and never reads a key from global memory.
// Site e's (x << 16) | y: in the y pass from the x of its x row's nearest target, which the
// loads put in keyx, and e; in the z pass from kl.
inline uint banded_xy(BAS const uint* kl, BAS const ushort* keyx, uint li, int e,
                      uint from16) {
    return from16 ? ((uint)keyx[li] << 16) | (uint)e : kl[li];
}
// Site e's place in the order of the keys (x * Y + y) * Z + z: in the z pass ((x << 16 | y) << 16)
// | z; in the y pass ((x << 16 | y) << 16) | y, the line's z being the same for all its sites.
#define BKEY(e) (((ulong)banded_xy(kl, keyx, LI(e), (e), from16) << 16) | (uint)(e))
// The z pass's partial of site e at line (x, y) from its y pass target xy: fpart along y of
// the x row's offset_part, as cols_banded's y pass made it.
inline GT banded_part(uint xy, uint x, uint y, ST sx, ST sy) {
    if (xy == UINT_MAX) {
        return G_INF;
    }
    return fpart_fma((int)y, (int)(xy & 0xFFFFu), offset_part(abs((int)x - (int)(xy >> 16)), sx),
                     sy);
}
// Site e's partial: from its x row's distance (gl16) in the y pass, from its target in the z
// pass.
#define GLV(e) (from16 ? part16(gl16[LI(e)], sx) : banded_part(kl[LI(e)], x, o, sx, so))
// Sep(i, u) with KEYED ties, the sites' keys found only where the two tie rules differ.
#define BSEP(i, u, gi, gu) banded_sep(kl, keyx, C, c, from16, i, u, gi, gu, sp)
inline int banded_sep(BAS const uint* kl, BAS const ushort* keyx, uint C, uint c,
                      uint from16, int i, int u, GT gi, GT gu, ST sp) {
    if (KEYED(1u, 0u) == 0) {
        return sep_tie(i, u, gi, gu, sp, 0);  // L-inf: the lower position wins
    }
    const int2 t = sep_pair(i, u, gi, gu, sp);
    return t.y != t.x && KEYED(BKEY(i), BKEY(u)) ? t.y : t.x;
}
#else
#define GLV(e) (from16 ? part16(gl16[LI(e)], sx) : gl[LI(e)])
#define BSEP(i, u, gi, gu) sep((i), (u), (gi), (gu), sp)
#endif
// Whether BSEP(i, u, gi, gu) < t: for unit L2 by a multiplication (sep_below; with keys the
// separator is one less where the division is exact and u wins the tie, so it is below t also
// where num = t den and u's key is lower), else by the separator itself.
#define BANDED_PRODUCT_TESTS (UNIT && METRIC == 2)
#if BANDED_PRODUCT_TESTS && INDICES
#define BBELOW(i, u, gi, gu, t) banded_below(kl, keyx, C, c, from16, i, u, gi, gu, t)
inline bool banded_below(BAS const uint* kl, BAS const ushort* keyx, uint C, uint c,
                         uint from16, int i, int u, GT gi, GT gu, int t) {
    const long num = l2_num(i, u, gi, gu), prod = (long)t * (2 * (long)(u - i));
    return num < prod || (num == prod && KEYED(BKEY(i), BKEY(u)));
}
#elif BANDED_PRODUCT_TESTS
#define BBELOW(i, u, gi, gu, t) sep_below((i), (u), (gi), (gu), sp, (t), 0)
#else
#define BBELOW(i, u, gi, gu, t) (BSEP(i, u, gi, gu) < (t))
#endif

// Lines of n positions, element stride `stride`, line (x, o) starting at o * mstride + x,
// x = group(0) * C + local(0), o = group(1) of O; where group(1) passes O, the lines of the
// next block of a world of stacked blocks, `bstride` elements on (its z pass: each block's
// lines apart, their borders at the block's ends). Input: `in16` (from16: the x pass's 1-D
// distances) or `in`; output: partials to `gout`, or with `final` the output format to `out`
// (with INDICES `in` and `gout` are not used, and the host may pass the x rows' buffer for them:
// they stay `restrict`, which holds as nothing is written through them then).
// `border` (the z pass of a signed field's inner transform, whose targets are the empty
// voxels): the space around the world is empty too, so each partial is at most that of the
// nearest voxel outside, straight along one axis: min(x + 1, X - x, o + 1, O - o, p + 1, n - p),
// each offset as a partial of its axis's spacing (sx along x, so along o, sp along the line;
// 1 with UNIT, where the partials are exact integers).
// That pass is `final` and writes the signed value, an empty voxel's from the first
// transform's partials `outer` (which may be `out`, of the same element size: neither is
// `restrict`; each work-item reads its voxel's before writing it).
// Local arrays (global with BANDED_GLOBAL): gl, n * C entries (position p of line c at p * C + c:
// the sites' partials, in the y pass (from16) their x rows' 16-bit distances, gl16); mask, ceil(n /
// 32) * C words (the list's sites' bits, word w of line c at w * C + c); ends, 2 * C * K ints,
// always local (each band's or merged group's first and last site, -1 when it has none; after the
// merges, `last` of a band its first position's owner). K bands of `band` positions, the least
// multiple of 32 with which they cover n (bands past n are empty). With INDICES the y pass writes
// each position's target (x << 16) | y to `fout`, not its partial, and keyx (n * C, as gl) holds
// each position's x of its row's nearest target, the targets being the world's nonzero voxels
// (`zero_targets` 0) or its zero ones (1, SciPy's convention; as x_pass's `solid`); the z pass
// reads those targets from `fin` into kl (gl's memory, then 4 bytes a cell whatever the partials'
// width) and writes the index planes `idx` of the world's `count` voxels.
__kernel void cols_banded(__global const ushort* restrict in16, __global const GT* restrict in,
                          __global GT* restrict gout, __global OUT_T* out,
                          __global const uchar* restrict vox, __constant uchar* rgb, uint X,
                          uint n, ulong stride, ulong mstride, uint from16_in, uint final_in,
                          double dmax, BAS GT* gl, BAS uint* mask, __local int* ends,
                          uint O, uint border_in,
                          __global const uint* restrict fin, __global uint* restrict fout,
                          __global int* restrict idx, ulong count, __global const GT* outer,
                          ST sx, ST so, ST sp, BAS ushort* keyx, uint zero_targets,
                          ulong bstride) {
    // The pass: fixed where the program is built for one (BANDED_AXIS 1: the y pass, from the x
    // rows' 16-bit distances, never final; 2: the z pass), else the arguments'.
    const uint from16 = BANDED_AXIS == 1 ? 1u : BANDED_AXIS == 2 ? 0u : from16_in;
    const uint final = BANDED_AXIS == 1 ? 0u : final_in;
    const uint border = BANDED_AXIS == 1 ? 0u : border_in;
    const uint C = (uint)get_local_size(0), K = (uint)get_local_size(1);
    const uint c = (uint)get_local_id(0), k = (uint)get_local_id(1);
    const uint x = (uint)get_group_id(0) * C + c;
    // Line o of its block: group(1) counts the O lines of each stacked block in turn.
    const uint o = (uint)get_group_id(1) % O;
    const bool active = x < X;
    const size_t base = (size_t)(get_group_id(1) / O) * bstride + (size_t)o * mstride + x;
    const int band = (int)(((n + K - 1) / K + 31) / 32 * 32);
    __local int* first = ends;
    __local int* last = ends + C * K;
#if BANDED_GLOBAL
    // This work-group's part of the scratch: its lines' sites (2 bytes a position in the y
    // pass, 4 with INDICES in the z pass, else a partial), mask words and (the y pass with
    // INDICES) target x.
    const size_t group = get_group_id(1) * get_num_groups(0) + get_group_id(0);
    const size_t cells = (size_t)n * C;
    const size_t site_bytes = from16 ? 2 : INDICES ? 4 : sizeof(GT);
    gl = (__global GT*)((__global uchar*)gl + group * cells * site_bytes);
    mask += group * (size_t)((n + 31) / 32) * C;
    if (INDICES && from16) {
        keyx += group * cells;
    }
#endif
    BAS ushort* gl16 = (BAS ushort*)gl;
#if INDICES
    BAS uint* kl = (BAS uint*)gl;
#endif
    // BANDED_LOADS positions per step, their loads issued before any is stored, so that a
    // work-item waits for one global load's latency per step, not per position.
    for (uint p0 = k; p0 < n; p0 += BANDED_LOADS * K) {
        uint d16[BANDED_LOADS];
#if INDICES
        uint kx[BANDED_LOADS];
#else
        GT v[BANDED_LOADS];
#endif
#pragma unroll
        for (uint j = 0; j < BANDED_LOADS; ++j) {
            const uint p = p0 + j * K;
            d16[j] = 0xFFFFu;
#if INDICES
            kx[j] = from16 ? 0u : UINT_MAX;
#else
            v[j] = G_INF;
#endif
            if (active && p < n) {
                const size_t i = base + p * stride;
                if (from16) {
                    const uint d = in16[i];
                    d16[j] = d;
#if INDICES
                    // The x of the row's target d away: on the left where the world has a
                    // target there (a solid voxel; an empty one with `zero_targets`; the x
                    // pass's ties go left), else on the right.
                    const bool left = x >= d && (vox[i - d] != 0) != (zero_targets != 0);
                    kx[j] = d == 0xFFFFu ? 0u : left ? x - d : x + d;
#endif
                } else {
#if INDICES
                    kx[j] = fin[i];
#else
                    v[j] = in[i];
#endif
                }
            }
        }
#pragma unroll
        for (uint j = 0; j < BANDED_LOADS; ++j) {
            const uint p = p0 + j * K;
            if (p < n) {
#if INDICES
                if (from16) {
                    gl16[LI(p)] = (ushort)d16[j];
                    keyx[LI(p)] = (ushort)kx[j];
                } else {
                    kl[LI(p)] = kx[j];
                }
#else
                if (from16) {
                    gl16[LI(p)] = (ushort)d16[j];
                } else {
                    gl[LI(p)] = v[j];
                }
#endif
            }
        }
    }
    const int u0 = min((int)k * band, (int)n), u1 = min(u0 + band, (int)n);
    // The band's mask words (none where it is past the line's end).
    const int w0 = u0 >> 5, w1 = u0 < u1 ? (u1 + 31) >> 5 : w0;
    for (int w = w0; w < w1; ++w) {
        mask[MW(w)] = 0;
    }
    barrier(BANDED_FENCE);

    // The band's envelope: push every site with a target, after dropping the top while the
    // new site makes it useless. top_sep caches Sep(the site below the top, the top).
    int bot = -1, top = -1, top_sep = 0;
    GT gt = G_INF;
    for (int u = u0; u < u1; ++u) {
        const GT gu = GLV(u);
        if (gu == G_INF) {
            continue;
        }
        int su = 0;
        while (top >= 0) {
            // The top stays while Sep(top, u) > top_sep; with product tests the separator is
            // divided out only for the site kept.
#if BANDED_PRODUCT_TESTS
            const bool keep = top == bot || !BBELOW(top, u, gt, gu, top_sep + 1);
            if (keep) {
                su = BSEP(top, u, gt, gu);
            }
#else
            su = BSEP(top, u, gt, gu);
            const bool keep = top == bot || top_sep < su;
#endif
            if (keep) {
                break;
            }
            DROP(top);
            top = BEFORE(top, bot);
            gt = GLV(top);
            if (top != bot) {
                const int below = BEFORE(top, bot);
                top_sep = BSEP(below, top, GLV(below), gt);
            } else {
                top_sep = 0;
            }
        }
        if (top < 0) {
            bot = u;
        } else {
            top_sep = su;
        }
        mask[MW(u >> 5)] |= 1u << (u & 31);
        top = u;
        gt = gu;
    }
    first[k * C + c] = bot;
    last[k * C + c] = top;

    // Merge the groups [k, k + span) and [k + span, k + 2 span) into the first.
    for (uint span = 1; span < K; span <<= 1) {
        barrier(BANDED_FENCE);
        if ((k & (2 * span - 1)) == 0 && k + span < K) {
            const int lb = first[k * C + c], rb = first[(k + span) * C + c];
            const int rt = last[(k + span) * C + c];
            if (lb < 0) {
                first[k * C + c] = rb;
                last[k * C + c] = rt;
            } else if (rb >= 0) {
                int l = last[k * C + c], r = rb;
                for (;;) {
                    const GT glv = GLV(l), grv = GLV(r);
                    const int slr = BSEP(l, r, glv, grv);
                    if (l != lb) {
                        const int lp = BEFORE(l, lb);
                        if (!BBELOW(lp, l, GLV(lp), glv, slr)) {
                            DROP(l);
                            l = lp;
                            continue;
                        }
                    }
                    if (r != rt) {
                        const int rn = AFTER(r, rt + 1);
                        if (BBELOW(r, rn, grv, GLV(rn), slr + 1)) {
                            DROP(r);
                            r = rn;
                            continue;
                        }
                    }
                    break;
                }
                last[k * C + c] = rt;
            }
        }
    }
    barrier(BANDED_FENCE);

    // Every site still in the list owns the positions (Sep(predecessor, it), Sep(it,
    // successor)] (`hi` carries the previous site's end when that site is the predecessor):
    // it names itself in `last` for every band whose first position it owns.
    int prev = -1, hi = -1;
    const float inv_band = 1.0f / (float)band;
    for (int w = w0; w < w1; ++w) {
        uint m = mask[MW(w)];
        while (m != 0) {
            const int e = lowest_site(w, m);
            m &= m - 1u;
            const int before = prev >= 0 ? prev : BEFORE(e, 0);
            const int after = m != 0 ? lowest_site(w, m) : AFTER(e, (int)n);
            const GT ge = GLV(e);
            const int lo = before < 0         ? 0
                           : before == prev ? hi + 1
                                            : 1 + BSEP(before, e, GLV(before), ge);
            hi = after < 0 ? (int)n - 1 : BSEP(e, after, ge, GLV(after));
            prev = e;
            const int a = max(lo, 0), z = min(hi, (int)n - 1);
            // The bands b with a <= b * band <= z; the first from a float quotient, corrected.
            int b = (int)((float)a * inv_band);
            while (b * band < a) {
                ++b;
            }
            while (b > 0 && (b - 1) * band >= a) {
                --b;
            }
            for (; b * band <= z; ++b) {
                last[b * C + c] = e;
            }
        }
    }
    barrier(BANDED_FENCE);

    const bool none = first[c] < 0;
    if (!active) {
        return;
    }
    // The band's positions from the owner of its first one along the list.
    const bool walk = !none && u0 < (int)n;
    int e = walk ? last[k * C + c] : 0;
    // The owner's partial and end (1 + its last position), its successor in the list (-1:
    // none) and that one's partial in registers, read again (from local memory) only when the
    // walk moves on to the next owner.
    GT ge = GLV(e), gs = ge;
    int succ = walk ? AFTER(e, (int)n) : -1;
    if (succ >= 0) {
        gs = GLV(succ);
    }
    uint end = succ < 0 ? n : (uint)clamp(BSEP(e, succ, ge, gs) + 1, 0, (int)n);
#if INDICES
    // Likewise its target (x << 16) | y and, in the last pass, its (z, y, x) planes' values.
    uint key = none ? UINT_MAX : banded_xy(kl, keyx, LI(e), e, from16);
    int3 place = final && !none ? (int3)(e, (int)(key & 0xFFFFu), (int)(key >> 16)) : (int3)(-1);
#endif
    for (uint p = (uint)u0; p < (uint)u1; ++p) {
        GT v = G_INF;
#if INDICES
        uint f = UINT_MAX;
#endif
        if (!none) {
            if (end <= p) {
                do {
                    e = succ;
                    ge = gs;
                    succ = AFTER(e, (int)n);
                    if (succ < 0) {
                        end = n;
                    } else {
                        gs = GLV(succ);
                        end = (uint)clamp(BSEP(e, succ, ge, gs) + 1, 0, (int)n);
                    }
                } while (end <= p);
#if INDICES
                key = banded_xy(kl, keyx, LI(e), e, from16);
                if (final) {
                    place = (int3)(e, (int)(key & 0xFFFFu), (int)(key >> 16));
                }
#endif
            }
            v = fpart_fma((int)p, e, ge, sp);
#if INDICES
            f = key;
#endif
        }
        if (border) {
            v = min(v, min(min(offset_part((int)min(x + 1, X - x), sx),
                               offset_part((int)min(o + 1, O - o), so)),
                           offset_part((int)min(p + 1, n - p), sp)));
        }
        const size_t i = base + p * stride;
        if (final) {
#if SIGNED
            // The inner transform's z pass: an empty voxel takes the first transform's
            // partial from `outer`, a solid one minus its own.
            const uchar cls = vox[i];
            const double d =
                cls != 0 ? -min(distance_of(v), dmax) : min(distance_of(outer[i]), dmax);
            store(out, rgb, cls, i, d);
#else
#if OUT_KIND == 4
            const uchar cls = vox[i];
#else
            const uchar cls = 0;
#endif
            store(out, rgb, cls, i, min(distance_of(v), dmax));
#endif
#if INDICES
            store_index(idx, count, i, place);
#endif
        } else {
#if INDICES
            fout[i] = f;
#else
            gout[i] = v;
#endif
        }
    }
}

#if INDICES && METRIC == 0 && UNIT && CPU_LAYOUT && !SIGNED
// ---- unit L1 with indices, full transforms in the CPU layout: sweeps over packed keys ----
//
// The nearest solid of lowest (x, y, z) (KEYED's ties) from two kernels that move 1 + 4 + 4 +
// 14 bytes per voxel at u16 (col_pass's partials and keys: about 40): l1_xy_keys gives each
// z-slice's voxel the nearest solid of its slice as the key (sx << 16) | sy (its distance is
// |sx - x| + |sy - y|, never stored; the key's order is (x, y)'s), written into the first
// index plane; l1_z_out sweeps z over flat strips of the planes, carrying (distance, key, z)
// in local memory, and writes the output format and the three index planes. X and Y below
// 65535 (the host checks).
//
// Ties: the x pass keeps the left one of two equally near solids (the lower x); a y or z
// sweep keeps its own voxel's candidate against the one carried from the neighbour where that
// key is lower (the forward sweeps) or not higher (the backward ones). Equal keys in a z sweep
// name the same (x, y) column, whose two solids equally near lie at z - k and z + k: the
// forward sweep's (already its own) is the lower z. So each sweep keeps the lowest key among
// its nearest targets, as tile_sweep_l1 does with whole keys.

#define L1_NONE 0xFFFFFFFFu  // the key of no target
#define L1_INF 0x3FFFFFFFu   // its distance (plus any count of steps stays below 2^31)
#define L1_NONE16 ((ushort)0xFFFF)

typedef ushort l1_ushort32 __attribute__((ext_vector_type(32)));
typedef l1_ushort32 l1_ushort32_any __attribute__((aligned(2)));
typedef ushort16 l1_ushort16_any __attribute__((aligned(2)));
typedef uint16 l1_uint16_any __attribute__((aligned(4)));
typedef int16 l1_int16_any __attribute__((aligned(4)));
typedef uchar16 l1_uchar16_any __attribute__((aligned(1)));
#define L1_LDS32(p) (*(__local const l1_ushort32_any*)(p))
#define L1_STS32(v, p) (*(__local l1_ushort32_any*)(p) = (v))
#define L1_LDS16(p) (*(__local const l1_ushort16_any*)(p))
#define L1_LDU(p) (*(__local const l1_uint16_any*)(p))
#define L1_STU(v, p) (*(__local l1_uint16_any*)(p) = (v))
#define L1_LDG(p) (*(__global const l1_uint16_any*)(p))
#define L1_STG(v, p) (*(__global l1_uint16_any*)(p) = (v))
#define L1_STGI(v, p) (*(__global l1_int16_any*)(p) = (v))
#define L1_LANES ((uint16)(0, 1, 2, 3, 4, 5, 6, 7, 8, 9, 10, 11, 12, 13, 14, 15))
#define L1_CAT_(a, b) a##b
#define L1_CAT(a, b) L1_CAT_(a, b)
typedef L1_CAT(OUT_T, 16) l1_out16_any __attribute__((aligned(1)));
#define L1_CONVERT_OUT16 L1_CAT(L1_CAT(convert_, OUT_T), 16)

inline l1_ushort32 l1_min32(l1_ushort32 a, l1_ushort32 b) { return a < b ? a : b; }
inline l1_ushort32 l1_adds32(l1_ushort32 a, l1_ushort32 b) {
    const l1_ushort32 s = a + b;
    return s < a ? (l1_ushort32)L1_NONE16 : s;
}

// The distance from (x, y) of the slice's solid named by key k (L1_INF: none), for scalars and
// vectors alike.
#define L1_KEY_DIST(k, x, y) \
    ((k) == L1_NONE ? L1_INF : abs_diff((k) >> 16, (x)) + abs_diff((k)&0xFFFFu, (y)))

// One sweep step: the voxel's own candidate (d, k) against the carried (rd, rk) one step
// further; `le` 1 where the own one wins equal keys too. Leaves the winner in (rd, rk).
#define L1_STEP(d, k, rd, rk, le)                                                   \
    do {                                                                            \
        const __typeof__(d) cand_ = (rd) + 1;                                       \
        const __typeof__((d) < cand_) own_ =                                        \
            ((d) < cand_) | (((d) == cand_) & ((le) ? (k) <= (rk) : (k) < (rk)));   \
        (rd) = own_ ? (d) : cand_;                                                  \
        (rk) = own_ ? (k) : (rk);                                                   \
    } while (0)

// Long rows with few targets (at most L1_RAMPS) take ramps between them instead of the
// doubling: l1_row_targets finds them 16 voxels at a time (a count first, so that a dense row
// leaves after a few blocks) and returns their number (L1_RAMPS + 1: more; pos then unset).
#define L1_RAMPS 16
inline uint l1_target_mask16(__global const uchar* restrict v, int solid) {
    const uchar16 bits = (uchar16)(1, 2, 4, 8, 16, 32, 64, 128, 1, 2, 4, 8, 16, 32, 64, 128);
    const ulong gather = 0x0101010101010101UL;  // sums a word's bytes into its top byte
    const uchar16 b = *(__global const l1_uchar16_any*)v;
    const ulong2 h = as_ulong2(as_uchar16(solid ? b != (uchar16)0 : b == (uchar16)0) & bits);
    return (uint)((h.s0 * gather) >> 56) | ((uint)((h.s1 * gather) >> 56) << 8);
}
inline uint l1_row_targets(__global const uchar* restrict v, uint X, int solid, uint* pos) {
    const uint full = X / 16 * 16;
    uint k = 0;
    for (uint x = 0; x < full && k <= L1_RAMPS; x += 16) {
        k += popcount(l1_target_mask16(v + x, solid));
    }
    for (uint x = full; x < X; ++x) {
        k += (v[x] != 0) == (solid != 0);
    }
    if (k > L1_RAMPS) {
        return L1_RAMPS + 1;
    }
    k = 0;
    for (uint x = 0; x < full; x += 16) {
        uint m = l1_target_mask16(v + x, solid);
        while (m != 0) {
            pos[k++] = x + 31 - clz(m & (0u - m));
            m &= m - 1;
        }
    }
    for (uint x = full; x < X; ++x) {
        if ((v[x] != 0) == (solid != 0)) {
            pos[k++] = x;
        }
    }
    return k;
}

// One work-item per z-slice. Each row's 1-D nearest target on the left and on the right by
// doubling in 16-bit lanes (L and R: after the steps 1, 2, 4, ... every voxel within 2s - 1
// of its nearest target on a side holds that distance, every other one more; the steps stop
// once the nearer of the two is below 2s everywhere; L goes from one row to another, R is
// updated in place: a load of L just behind the step's own stores would wait for them), then
// the forward y sweep's step from the row before (run_d, run_k), its keys stored into `keys`;
// then the backward y sweep reads them back (the slice's 4 bytes per voxel stay in the core's
// cache) and stores the final keys. `rows`: L, R and L's second row, each X32 = X rounded up
// to 32 entries between `pad` (>= the largest step) of L1_NONE16 on both sides; run_d, run_k:
// X16 = X rounded up to 16 each. `solid` 1: the nonzero voxels are the targets, 0: the zero
// ones (as x_pass).
__kernel void l1_xy_keys(__global const uchar* restrict vox, __global uint* restrict keys, uint X,
                         uint Y, uint pad, int solid, __local ushort* restrict rows,
                         __local uint* restrict run_d, __local uint* restrict run_k) {
    const size_t base = get_global_id(0) * (size_t)X * Y;
    const uint X32 = (X + 31) / 32 * 32;
    const uint X16 = (X + 15) / 16 * 16;
    const uint full = X / 16 * 16;
    __local ushort* L = rows + pad;
    __local ushort* R = rows + X32 + 3 * pad;
    __local ushort* L2 = rows + 2 * X32 + 5 * pad;
    for (uint i = 0; i < 3 * (X32 + 2 * pad); ++i) {
        rows[i] = L1_NONE16;
    }
    for (uint x = 0; x < X16; x += 16) {
        L1_STU((uint16)L1_INF, run_d + x);
        L1_STU((uint16)L1_NONE, run_k + x);
    }
    for (uint y = 0; y < Y; ++y) {
        __global const uchar* v = vox + base + (size_t)y * X;
        __global uint* kr = keys + base + (size_t)y * X;
        uchar16 seen = 0;
        for (uint x = 0; x < full; x += 16) {
            const uchar16 b = *(__global const l1_uchar16_any*)(v + x);
            const char16 t = solid ? b != (uchar16)0 : b == (uchar16)0;
            const ushort16 init = ~as_ushort16(convert_short16(t));
            *(__local l1_ushort16_any*)(L + x) = init;
            *(__local l1_ushort16_any*)(R + x) = init;
            seen |= as_uchar16(t);
        }
        for (uint x = full; x < X; ++x) {
            const bool t = (v[x] != 0) == (solid != 0);
            L[x] = t ? 0 : L1_NONE16;
            R[x] = t ? 0 : L1_NONE16;
            seen.s0 |= t;
        }
        const bool none = all(seen == (uchar16)0);
        uint pos[L1_RAMPS];
        const uint k = X >= 1024 && !none ? l1_row_targets(v, X, solid, pos) : L1_RAMPS + 1;
        if (k <= L1_RAMPS) {
            for (uint x = 0; x < pos[0]; ++x) {
                L[x] = L1_NONE16;
                R[x] = (ushort)(pos[0] - x);
            }
            for (uint i = 0; i + 1 < k; ++i) {
                for (uint x = pos[i]; x < pos[i + 1]; ++x) {
                    L[x] = (ushort)(x - pos[i]);
                    R[x] = (ushort)(pos[i + 1] - x);
                }
            }
            for (uint x = pos[k - 1]; x < X; ++x) {
                L[x] = (ushort)(x - pos[k - 1]);
                R[x] = L1_NONE16;
            }
        }
        for (uint s = 1; s < X && !none && k > L1_RAMPS; s <<= 1) {
            const l1_ushort32 step = (l1_ushort32)(ushort)s;
            l1_ushort32 top = 0;
            for (uint x = 0; x < X32; x += 32) {
                const l1_ushort32 l =
                    l1_min32(L1_LDS32(L + x), l1_adds32(L1_LDS32(L + x - s), step));
                const l1_ushort32 r =
                    l1_min32(L1_LDS32(R + x), l1_adds32(L1_LDS32(R + x + s), step));
                L1_STS32(l, L2 + x);
                L1_STS32(r, R + x);
                const l1_ushort32 m = l1_min32(l, r);
                top = top < m ? m : top;
            }
            __local ushort* t = L;
            L = L2;
            L2 = t;
            // Every value below 2s (a compare and a mask test, not a horizontal max).
            if (2 * s > 0xFFFFu ||
                !any(as_ulong8(top >= (l1_ushort32)(ushort)(2 * s)) != 0)) {
                break;
            }
        }
        for (uint x = 0; x < X16; x += 16) {
            uint16 rd = L1_LDU(run_d + x), rk = L1_LDU(run_k + x);
            if (none) {
                L1_STEP((uint16)L1_INF, (uint16)L1_NONE, rd, rk, 0);
            } else {
                const uint16 l = convert_uint16(L1_LDS16(L + x));
                const uint16 r = convert_uint16(L1_LDS16(R + x));
                const uint16 xs = (uint16)x + L1_LANES;
                const uint16 d = min(l, r);
                const uint16 k = d == (uint16)L1_NONE16
                                     ? (uint16)L1_NONE
                                     : ((l <= r ? xs - l : xs + r) << 16) | (uint16)y;
                L1_STEP(d == (uint16)L1_NONE16 ? (uint16)L1_INF : d, k, rd, rk, 0);
            }
            L1_STU(rd, run_d + x);
            L1_STU(rk, run_k + x);
            if (x < full) {
                L1_STG(rk, kr + x);
            }
        }
        for (uint x = full; x < X; ++x) {
            kr[x] = run_k[x];
        }
    }
    for (uint y = Y - 1; y-- > 0;) {
        __global uint* kr = keys + base + (size_t)y * X;
        for (uint x = 0; x < full; x += 16) {
            uint16 rd = L1_LDU(run_d + x), rk = L1_LDU(run_k + x);
            const uint16 k = L1_LDG(kr + x);
            L1_STEP(L1_KEY_DIST(k, (uint16)x + L1_LANES, (uint16)y), k, rd, rk, 1);
            L1_STU(rd, run_d + x);
            L1_STU(rk, run_k + x);
            L1_STG(rk, kr + x);
        }
        for (uint x = full; x < X; ++x) {
            uint rd = run_d[x], rk = run_k[x];
            const uint k = kr[x];
            L1_STEP(L1_KEY_DIST(k, x, y), k, rd, rk, 1);
            run_d[x] = rd;
            run_k[x] = rk;
            kr[x] = rk;
        }
    }
}

// The output format of distance d (L1_INF: no target, as `store` writes +inf) at voxel i.
inline void l1_store(__global OUT_T* out, __global const uchar* vox, __constant uchar* rgb,
                     size_t i, uint d) {
#if OUT_KIND == 0
    out[i] = (OUT_T)(d >= L1_INF ? OUT_MAX : min(d, (uint)OUT_MAX));
#elif OUT_KIND == 2
    out[i] = d >= L1_INF ? INFINITY : (float)d;
#elif OUT_KIND == 3
    out[i] = d >= L1_INF ? (double)INFINITY : (double)d;
#else
    out[i] = (min(d, 255u) << VF_PACKED_DISTANCE_SHIFT) | rgb[vox[i]];
#endif
}

// The z pass: each work-item sweeps `chunk` consecutive voxels of a z-plane (flat strips,
// chunk a multiple of 16) through all Z planes: forward into `tile` (two arrays of Z * chunk
// uints: distance and key), reading the keys of l1_xy_keys from idx's first plane; backward
// from there, writing the output and the index planes z, y, x (-1 without a target) over the
// keys it has read. The backward sweep's own candidate wins where the forward sweep's is
// nearer or as near with a key not higher; its target lies at or below z, the other one's
// above z (a target at or below z reached from z + 1 is 2 farther than from z itself), so the
// target's z follows from the distance. `lxy`: the strip's x and y per lane (2 * chunk uints).
// The forward sweep prefetches the keys L1_AHEAD planes ahead: its strip's lines of a plane
// lie a plane apart, beyond the hardware prefetchers' reach (long-z, strips of 32 columns
// 16 KiB apart: the sweeps without stores 99 -> 45 ms at load 5).
#define L1_AHEAD 16
__kernel void l1_z_out(__global uint* keys, __global OUT_T* restrict out,
                       __global const uchar* restrict vox, __constant uchar* rgb,
                       __global int* idx, uint X, ulong plane, uint Z, uint chunk,
                       __local uint* restrict tile, __local uint* restrict lxy) {
    const size_t c0 = get_global_id(0) * (size_t)chunk;
    if (c0 >= plane) {
        return;
    }
    const uint w = (uint)min((size_t)chunk, plane - c0);
    const uint w16 = (w + 15) / 16 * 16;
    const size_t n = plane * Z;
    __local uint* td = tile;
    __local uint* tk = tile + (size_t)Z * w16;
    __local uint* lx = lxy;
    __local uint* ly = lxy + w16;
    for (uint j = 0; j < w16; ++j) {
        const size_t i = c0 + min(j, w - 1);
        lx[j] = (uint)(i % X);
        ly[j] = (uint)(i / X);
    }
    for (uint z = 0; z < Z; ++z) {
        __global const uint* kz = keys + z * plane + c0;
        const size_t t = (size_t)z * w16;
        if (z + L1_AHEAD < Z) {
            for (uint j = 0; j < w; j += 16) {
                __builtin_prefetch(kz + L1_AHEAD * plane + j);
            }
        }
        for (uint j = 0; j < w16; j += 16) {
            uint16 k;
            if (j + 16 <= w) {
                k = L1_LDG(kz + j);
            } else {
                uint part[16];
                for (uint q = 0; q < 16; ++q) {
                    part[q] = j + q < w ? kz[j + q] : L1_NONE;
                }
                k = vload16(0, part);
            }
            const uint16 d = L1_KEY_DIST(k, L1_LDU(lx + j), L1_LDU(ly + j));
            uint16 rd = d, rk = k;
            if (z > 0) {
                rd = L1_LDU(td + t - w16 + j);
                rk = L1_LDU(tk + t - w16 + j);
                L1_STEP(d, k, rd, rk, 0);
            }
            L1_STU(rd, td + t + j);
            L1_STU(rk, tk + t + j);
        }
    }
    for (uint z = Z; z-- > 0;) {
        const size_t t = (size_t)z * w16;
        const size_t o = z * plane + c0;
        // Non-temporal stores where every plane's row is whole vectors apart.
        const bool aligned = (size_t)(idx + o) % 64 == 0 && (size_t)(idx + n + o) % 64 == 0 &&
                             (size_t)(out + o) % (16 * sizeof(OUT_T)) == 0;
        for (uint j = 0; j < w16; j += 16) {
            uint16 d = L1_LDU(td + t + j), k = L1_LDU(tk + t + j);
            int16 own = (int16)-1;
            if (z + 1 < Z) {
                const uint16 rd = L1_LDU(td + t + w16 + j);
                const uint16 rk = L1_LDU(tk + t + w16 + j);
                const uint16 cand = rd + 1;
                own = (d < cand) | ((d == cand) & (k <= rk));
                d = own ? d : cand;
                k = own ? k : rk;
                L1_STU(d, td + t + j);
                L1_STU(k, tk + t + j);
            }
            // The target's z: |z - zt| = d - (its distance within the plane), below z where
            // the forward sweep's candidate won, above where the backward one did.
            const uint16 dz = d - L1_KEY_DIST(k, L1_LDU(lx + j), L1_LDU(ly + j));
            const uint16 zz = own ? (uint16)z - dz : (uint16)z + dz;
            const int16 none = k == (uint16)L1_NONE;
            const int16 iz = none ? (int16)-1 : as_int16(zz);
            const int16 iy = none ? (int16)-1 : as_int16(k & 0xFFFFu);
            const int16 ix = none ? (int16)-1 : as_int16(k >> 16);
            if (j + 16 <= w && aligned) {
                __builtin_nontemporal_store(iz, (__global int16*)(idx + o + j));
                __builtin_nontemporal_store(iy, (__global int16*)(idx + n + o + j));
                __builtin_nontemporal_store(ix, (__global int16*)(idx + 2 * n + o + j));
#if OUT_KIND == 0
                const uint16 c = d >= (uint16)L1_INF ? (uint16)OUT_MAX : min(d, (uint16)OUT_MAX);
                __builtin_nontemporal_store(L1_CONVERT_OUT16(c),
                                            (__global L1_CAT(OUT_T, 16)*)(out + o + j));
#else
                uint e[16];
                vstore16(d, 0, e);
                for (uint q = 0; q < 16; ++q) {
                    l1_store(out, vox, rgb, o + j + q, e[q]);
                }
#endif
            } else if (j + 16 <= w) {
                L1_STGI(iz, idx + o + j);
                L1_STGI(iy, idx + n + o + j);
                L1_STGI(ix, idx + 2 * n + o + j);
#if OUT_KIND == 0
                const uint16 c = d >= (uint16)L1_INF ? (uint16)OUT_MAX : min(d, (uint16)OUT_MAX);
                *(__global l1_out16_any*)(out + o + j) = L1_CONVERT_OUT16(c);
#else
                uint e[16];
                vstore16(d, 0, e);
                for (uint q = 0; q < 16; ++q) {
                    l1_store(out, vox, rgb, o + j + q, e[q]);
                }
#endif
            } else {
                int a[16], b[16], c[16];
                uint e[16];
                vstore16(iz, 0, a);
                vstore16(iy, 0, b);
                vstore16(ix, 0, c);
                vstore16(d, 0, e);
                for (uint q = 0; j + q < w; ++q) {
                    idx[o + j + q] = a[q];
                    idx[n + o + j + q] = b[q];
                    idx[2 * n + o + j + q] = c[q];
                    l1_store(out, vox, rgb, o + j + q, e[q]);
                }
            }
        }
    }
}
#endif
