// Exact global Manhattan (L1) distance transform by separable min-plus sweeps along x, y and
// z (Rosenfeld & Pfaltz 1966; the dissertation's chapter 2 defines the metric). The 1-D L1
// transform of a line is a forward sweep d[i] = min(d[i], d[i-1] + 1) plus the mirrored
// backward sweep; doing it along each axis in turn gives the exact 3-D distance.
//
// With CHEBYSHEV=1 the same sweeps give the exact L-inf (chessboard) distance at unit spacing.
// The L-inf distance is the fewest king moves (steps in {-1,0,1}^3); moves commute, so a
// shortest path can take its moves grouped by kind, each coordinate moving monotonically
// toward the target (the path stays inside the world). The 13 kinds of move are composed by
// min-plus sweeps like L1's: x moves (the rows' doubling), the y moves (a, 1, 0) for a in
// {-1,0,1} together in one y sweep that takes the minimum of the three predecessors
// x-1, x, x+1 (a chamfer step, Rosenfeld & Pfaltz 1966, within one slice), and the nine z
// moves (a, b, 1) together in one z sweep over whole planes that takes the minimum of the
// nine predecessors (x+a, y+b) in the plane before. A sweep with several predecessors
// composes their move kinds (a forward then a backward sweep covers every count of each,
// with either sign), so the whole is exact.
//
// Build options: T (work element: uchar, ushort or uint; char, short or int when SIGNED),
// T_MAX (its maximum), PACKED (1 when the output is packed32 and T is a separate uchar work
// buffer), SEG_K (values per column and work-item in cols_seg), VW (adjacent columns per
// work-item in cols_seg: 1, 2 or 4), CHEBYSHEV (0 or 1), SIGNED (0 or 1, CPU layout only).
// ROW_TARGETS_EMPTY (0 or 1): the GPU layout's x rows kernels (x_rows_map, x_rows_local,
// x_rows_long) take the zero voxels as their targets instead of the nonzero ones.
// CHUNKS (0 or 1): cols_seg and x_rows_map over lines in chunks (their `chunks` argument 1:
// publish the chunks' ends, 2: sweep from them); with 0 that argument is ignored (one chunk).
// Saturating at T_MAX is exact: min-plus with +1 commutes with min(., T_MAX).
//
// SIGNED=1: the signed L1 field in the same passes, one value per voxel. Every voxel is at
// distance 0 from its own class, so it carries only the other distance: an empty voxel
// +(distance to the nearest solid), a solid one -(distance to the nearest empty voxel), the
// output's own encoding. A step from neighbour n reads n's distance to the solids as
// max(n, 0) and to the empties as max(-n, 0), so an empty voxel c takes
// min(c, max(n, 0) + k) and a solid one max(c, min(n, 0) - k): both transforms, each exact by
// the separable argument, in one pass. Empty voxels start at T_MAX, solid ones at -T_MAX (the
// signed formats saturate at +-T_MAX); the world's surroundings are empty voxels of value
// T_MAX, which the x pass's padding already is and the y and z sweeps add as a step from
// T_MAX into the first and last line (a solid voxel there gets -1).
//
// Two layouts of the same sweeps, chosen by the host per device:
// - CPU (PoCL): xy_slices_seq gives each work-item a whole z-slice (x sweeps, then y sweeps
//   whose inner loop runs along x and vectorises), cols_strip sweeps z over strips of rows;
//   each work-item's data stays in its core's L2 between the forward and backward sweeps.
//   L-inf: z_king sweeps the z planes in one work-item (each plane from the one before).
// - GPU: x_rows_map gives each work-item 16 consecutive voxels of two rows in registers (one
//   16-byte load and one vector store each) and finds each segment's nearest targets outside
//   it from a map of the row's segments that have any, in local memory; ragged
//   rows (X not a multiple of 16) take x_rows_local, which stages a row in local memory
//   (coalesced) and scans it per work-group, and rows too long for that x_rows_long, a
//   work-item per row. cols_seg gives each work-item SEG_K consecutive
//   values of VW adjacent columns in registers (one 4- or 8-byte word per load and store
//   where X keeps the words aligned), joins the segments of a column through local memory,
//   and so reads and writes each voxel once; columns of more segments than a work-group
//   holds take it in chunks, a work-group each, in two launches (the chunks' ends, then the
//   sweeps with their carries).
//   L1 into u32 with X a multiple of 16 (FROM_BITS=1 for cols_seg): x_words writes a row as
//   32-voxel words of solid bits, each with the row's last solid before it and first solid
//   after it (8 bytes per 32 voxels instead of 2 or 4 bytes per voxel), and the y pass's
//   cols_seg expands a row's x distances from them as it loads its column segments: the
//   x pass's bytes mostly leave the DRAM traffic (read 1 byte a voxel, write 1/4).
//   (L-inf has no GPU layout here: ExactSeparable computes it.)

// The x rows kernels' targets: the nonzero voxels (the world's solids), or with
// ROW_TARGETS_EMPTY the zero ones (a signed field's inner transform, SciPy's zero targets).
#if ROW_TARGETS_EMPTY
#define IS_TARGET(b) ((b) == 0)
#else
#define IS_TARGET(b) ((b) != 0)
#endif

// A saturating +1 in the work type (saturating byte/short adds vectorise widest on CPUs).
inline T inc_t(T v) { return add_sat(v, (T)1); }

// One min-plus step of voxel c from a neighbour at distance k holding n (both neighbours lo
// and hi at once in step_pair); SIGNED: as the header says.
inline T step_k(T c, T n, T k) {
#if SIGNED
    return c > 0 ? min(c, add_sat(max(n, (T)0), k)) : max(c, sub_sat(min(n, (T)0), k));
#else
    return min(c, add_sat(n, k));
#endif
}
inline T step_pair(T c, T lo, T hi, T k) {
#if SIGNED
    return c > 0 ? min(c, add_sat(max(min(lo, hi), (T)0), k))
                 : max(c, sub_sat(min(max(lo, hi), (T)0), k));
#else
    return min(c, add_sat(min(lo, hi), k));
#endif
}
// A solid voxel's start value (0, or -T_MAX when SIGNED; an empty one starts at T_MAX).
#if SIGNED
#define T_SOLID ((T)(-(T_MAX)))
#else
#define T_SOLID ((T)0)
#endif

// One chamfer step of a row of n from its predecessor row: cur[x] = min(cur[x], 1 + the
// least of prev[x-1], prev[x], prev[x+1]) (those inside the row). A macro: the rows may be
// global or local.
#define KING_STEP(cur, prev, n)                                                            \
    do {                                                                                   \
        if ((n) == 1) {                                                                    \
            (cur)[0] = min((cur)[0], inc_t((prev)[0]));                                    \
        } else {                                                                           \
            (cur)[0] = min((cur)[0], inc_t(min((prev)[0], (prev)[1])));                    \
            for (uint x_ = 1; x_ + 1 < (n); ++x_) {                                        \
                (cur)[x_] =                                                                \
                    min((cur)[x_], inc_t(min(min((prev)[x_ - 1], (prev)[x_]), (prev)[x_ + 1]))); \
            }                                                                              \
            (cur)[(n)-1] = min((cur)[(n)-1], inc_t(min((prev)[(n)-2], (prev)[(n)-1])));    \
        }                                                                                  \
    } while (0)

#ifndef FROM_BITS
#define FROM_BITS 0
#endif
#ifndef CHUNKS
#define CHUNKS 0
#endif

#if PACKED
#define STORE_FINAL(i, d) \
    out[i] = (min((uint)(d), VF_PACKED_DISTANCE_MAX) << VF_PACKED_DISTANCE_SHIFT) | rgb[vox[i]]
#else
#define STORE_FINAL(i, d) work[i] = (T)(d)
#endif

// Long rows with few solid voxels (at most ROW_KMAX) take their 1-D transform directly:
// row_solids finds the solids 16 bytes at a time (a bit mask per 16 voxels, one step per
// solid) and row_ramps writes the distance to the nearest of them, ramps between consecutive
// ones (SIGNED: a solid voxel's distance to the nearest empty voxel, the row's ends counting
// as empty, from the run of solids around it).
#define ROW_KMAX 16

// The solid voxels among the 16 from v as a bit mask (bit i: v[i] != 0).
inline uint solid_mask16(__global const uchar* restrict v) {
    const uchar16 bits = (uchar16)(1, 2, 4, 8, 16, 32, 64, 128, 1, 2, 4, 8, 16, 32, 64, 128);
    const ulong gather = 0x0101010101010101UL;  // sums a word's bytes into its top byte
    const ulong2 h = as_ulong2(as_uchar16(vload16(0, v) != (uchar16)0) & bits);
    return (uint)((h.s0 * gather) >> 56) | ((uint)((h.s1 * gather) >> 56) << 8);
}

// The positions of the solid voxels of row v (X voxels) in pos, and their number; ROW_KMAX + 1
// (pos then unset) when there are more. A first pass only counts (no branch per solid), so
// that a dense row leaves after its first few blocks.
inline uint row_solids(__global const uchar* restrict v, uint X, uint* pos) {
    const uint full = X / 16 * 16;
    uint k = 0;
    for (uint x = 0; x < full; x += 16) {
        k += popcount(solid_mask16(v + x));
        if (k > ROW_KMAX) {
            return ROW_KMAX + 1;
        }
    }
    for (uint x = full; x < X; ++x) {
        k += v[x] != 0;
    }
    if (k == 0 || k > ROW_KMAX) {
        return min(k, (uint)ROW_KMAX + 1);
    }
    k = 0;
    for (uint x = 0; x < full; x += 16) {
        uint m = solid_mask16(v + x);
        while (m != 0) {
            pos[k++] = x + 31 - clz(m & (0u - m));
            m &= m - 1;
        }
    }
    for (uint x = full; x < X; ++x) {
        if (v[x] != 0) {
            pos[k++] = x;
        }
    }
    return k;
}

inline void row_ramps(__global T* restrict out, uint X, const uint* pos, uint k) {
    const uint first = pos[0];
    for (uint x = 0; x < first; ++x) {
        out[x] = (T)min(first - x, (uint)T_MAX);
    }
    for (uint i = 0; i + 1 < k; ++i) {
        const uint a = pos[i];
        const uint b = pos[i + 1];
        for (uint x = a; x < b; ++x) {
            out[x] = (T)min(min(x - a, b - x), (uint)T_MAX);
        }
    }
    const uint last = pos[k - 1];
    for (uint x = last; x < X; ++x) {
        out[x] = (T)min(x - last, (uint)T_MAX);
    }
#if SIGNED
    for (uint i = 0; i < k;) {
        uint j = i;  // the run of solids pos[i..j]
        while (j + 1 < k && pos[j + 1] == pos[j] + 1) {
            ++j;
        }
        for (uint r = i; r <= j; ++r) {
            out[pos[r]] = (T)(-(int)min(min(pos[r] - pos[i], pos[j] - pos[r]) + 1, (uint)T_MAX));
        }
        i = j + 1;
    }
#endif
}

// One work-item per z-slice. Along x (the contiguous axis) a sequential sweep is one long
// dependency chain, so rows are transformed by doubling instead: after the steps 1, 2, 4, ...
// < X, d[x] = min(d[x], d[x-s] + s, d[x+s] + s) has considered every offset |t| < 2*s as a
// sum of distinct powers of two, which is the exact 1-D L1 transform; every step is a
// vectorisable loop over `scratch` (two rows of X elements with T_MAX padding of `pad`
// >= X/2 on both sides). A row without solids is T_MAX throughout; rows of 1024 voxels or
// more with at most ROW_KMAX solids take row_ramps instead; and the steps stop once no voxel
// holds +-T_MAX: after the step s every voxel within 2s - 1 of a target holds its distance
// and every other one +-T_MAX, so then every voxel is final. Then the y sweeps over the
// slice (inner loops along x, vectorised).
__kernel void xy_slices_seq(__global const uchar* restrict vox, __global T* restrict work,
                            uint X, uint Y, uint pad, __local T* restrict scratch) {
    const size_t base = get_global_id(0) * (size_t)X * Y;
    const uint span = X + 2 * pad;
    // Ramps (two passes over the row's 16-voxel masks, then the fills) took longer than the
    // doubling's log2(X) vector steps on rows of 256 (random 1%: 12.5 ms against 7.3 ms for
    // the slices of 256^3); on rows of 4096 with a few solids they took a third of it.
    const bool ramps = X >= 1024;
    for (uint i = 0; i < 2 * span; ++i) {
        scratch[i] = (T)T_MAX;
    }
    for (uint y = 0; y < Y; ++y) {
        const size_t row = base + (size_t)y * X;
        uchar any = 0;
        for (uint x = 0; x < X; ++x) {
            any |= vox[row + x];
        }
        if (any == 0) {
            for (uint x = 0; x < X; ++x) {
                work[row + x] = (T)T_MAX;
            }
            continue;
        }
        if (ramps) {
            uint pos[ROW_KMAX];
            const uint k = row_solids(vox + row, X, pos);
            if (k <= ROW_KMAX) {
                row_ramps(work + row, X, pos, k);
                continue;
            }
        }
        __local T* a = scratch + pad;
        __local T* b = scratch + span + pad;
        for (uint x = 0; x < X; ++x) {
            a[x] = vox[row + x] ? T_SOLID : (T)T_MAX;
        }
        for (uint s = 1; s < max(X, 2u); s <<= 1) {  // X = 1: one step to the padding
            const T step = (T)min(s, (uint)T_MAX);
            __local const T* lo = a - s;
            __local const T* hi = a + s;
            T top = 0;  // the largest |value| of the new row (T_MAX: not all final)
            for (uint x = 0; x < X; ++x) {
                const T d = step_pair(a[x], lo[x], hi[x], step);
                b[x] = d;
#if SIGNED
                top = max(top, max(d, (T)(-d)));
#else
                top = max(top, d);
#endif
            }
            __local T* t = a;
            a = b;
            b = t;
            if (top != (T)T_MAX) {
                break;
            }
        }
        for (uint x = 0; x < X; ++x) {
            work[row + x] = a[x];
        }
    }
#if SIGNED
    // The empty surroundings before the first and after the last row.
    for (uint x = 0; x < X; ++x) {
        work[base + x] = step_k(work[base + x], (T)T_MAX, (T)1);
        const size_t last = base + (size_t)(Y - 1) * X + x;
        work[last] = step_k(work[last], (T)T_MAX, (T)1);
    }
#endif
    for (uint y = 1; y < Y; ++y) {
        const size_t row = base + (size_t)y * X;
#if CHEBYSHEV
        KING_STEP(work + row, work + row - X, X);
#else
        for (uint x = 0; x < X; ++x) {
            work[row + x] = step_k(work[row + x], work[row - X + x], (T)1);
        }
#endif
    }
    for (uint y = Y - 1; y-- > 0;) {
        const size_t row = base + (size_t)y * X;
#if CHEBYSHEV
        KING_STEP(work + row, work + row + X, X);
#else
        for (uint x = 0; x < X; ++x) {
            work[row + x] = step_k(work[row + x], work[row + X + x], (T)1);
        }
#endif
    }
}

#ifdef U
// The CPU layout's L1 on bytes (U: the output type, ushort or uint, or uchar for u8; T is
// uchar and T_MAX at most 255): the sweeps compute min(exact, T_MAX) exactly (saturation
// commutes with min-plus), in one byte per voxel instead of the output's two or four, so the
// two passes move 5 bytes per voxel instead of 7 at u16. Where a value reaches 255 and the
// output is wider (SAT_CHECK), the true distance may be larger: z_bytes sets flag[0] and the
// host runs the wide sweeps (xy_slices_seq, cols_strip_final) over the world instead. Every
// loop takes 16 bytes per step as a uchar16 (then single bytes for a ragged end): the
// compiler's own vectorisation of byte loops left rows of 64 scalar (its vector loop takes
// 128 bytes). Loads and stores go through types of alignment 1 (LD16 and ST16 in local
// memory, LD16G, ST16G and ST_U16 in global memory): PoCL's vstore16 stores byte by byte.
#define V16 uchar16
#define CONVERT_(t, n) convert_##t##n
#define CONVERT(t, n) CONVERT_(t, n)
#define VTYPE_(t, n) t##n
#define VTYPE(t, n) VTYPE_(t, n)
typedef uchar16 uchar16_any __attribute__((aligned(1)));
typedef VTYPE(U, 16) u16_any __attribute__((aligned(1)));
#define LD16(p) (*(__local const uchar16_any*)(p))
#define ST16(v, p) (*(__local uchar16_any*)(p) = (v))
#define LD16G(p) (*(__global const uchar16_any*)(p))
#define ST16G(v, p) (*(__global uchar16_any*)(p) = (v))
#define ST_U16(v, p) (*(__global u16_any*)(p) = CONVERT(U, 16)(v))
// xy_bytes' row scans and y steps take 64 bytes at a time (one AVX-512 register), in a vector
// of the compiler's (OpenCL C has none of 64 bytes): 32-byte doubling steps and 16-byte y
// steps took 2.5-3.6 ms of the slices of 256^3 on PoCL 2 cores.
typedef uchar uchar64_v __attribute__((ext_vector_type(64)));
typedef uchar64_v uchar64_any __attribute__((aligned(1)));
#define LD64(p) (*(__local const uchar64_any*)(p))
#define LD64G(p) (*(__global const uchar64_any*)(p))
#define as_uchar64_v(v) __builtin_astype((v), uchar64_v)
#define ST64(v, p) (*(__local uchar64_any*)(p) = (v))
// z_bytes' output, 64 values at a time (non-temporal stores of whole 64-byte lines).
typedef U u64_v __attribute__((ext_vector_type(64)));
typedef u64_v u64_a64 __attribute__((aligned(64)));
typedef u64_v u64_any __attribute__((aligned(1)));
#define ST64G(v, p) (*(__global uchar64_any*)(p) = (v))
inline uchar64_v min64(uchar64_v a, uchar64_v b) { return a < b ? a : b; }
inline uchar64_v max64(uchar64_v a, uchar64_v b) { return a < b ? b : a; }
inline uchar64_v add_sat64(uchar64_v a, uchar64_v b) {
    const uchar64_v s = a + b;
    return s < a ? (uchar64_v)255 : s;
}

// The offsets 0..63 of a 64-byte step, and 63..0.
#define IOTA64 \
    ((uchar64_v)(0, 1, 2, 3, 4, 5, 6, 7, 8, 9, 10, 11, 12, 13, 14, 15, 16, 17, 18, 19, 20, 21, \
                 22, 23, 24, 25, 26, 27, 28, 29, 30, 31, 32, 33, 34, 35, 36, 37, 38, 39, 40, 41, \
                 42, 43, 44, 45, 46, 47, 48, 49, 50, 51, 52, 53, 54, 55, 56, 57, 58, 59, 60, 61, \
                 62, 63))
#define RIOTA64 ((uchar64_v)63 - IOTA64)

// A row's x transform, 64 bytes at a time in registers (row_scan64): a step with solids takes
// a min-plus scan by doubling inside its 64 lanes (shifts of 1 .. 32 lanes, T_MAX shifted in),
// then the ramp from the carry, the value next to it in the step before (forward) or after
// (backward). A step of solids only keeps its zeros; one without solids takes the carry's
// ramp, or nothing when the carry is T_MAX (its values came from that side, so they carry
// nothing back). The old run-end ramps and doubling over the row branched per solid: on PoCL
// 2 cores, 256^3, random 10% and clustered solids took 4.4 and 3.1 ms in xy_bytes (now 2.9
// and 2.1, bench/README).
#define LANES64(o) \
    (o) + 0, (o) + 1, (o) + 2, (o) + 3, (o) + 4, (o) + 5, (o) + 6, (o) + 7, (o) + 8, (o) + 9, \
    (o) + 10, (o) + 11, (o) + 12, (o) + 13, (o) + 14, (o) + 15, (o) + 16, (o) + 17, (o) + 18, \
    (o) + 19, (o) + 20, (o) + 21, (o) + 22, (o) + 23, (o) + 24, (o) + 25, (o) + 26, (o) + 27, \
    (o) + 28, (o) + 29, (o) + 30, (o) + 31, (o) + 32, (o) + 33, (o) + 34, (o) + 35, (o) + 36, \
    (o) + 37, (o) + 38, (o) + 39, (o) + 40, (o) + 41, (o) + 42, (o) + 43, (o) + 44, (o) + 45, \
    (o) + 46, (o) + 47, (o) + 48, (o) + 49, (o) + 50, (o) + 51, (o) + 52, (o) + 53, (o) + 54, \
    (o) + 55, (o) + 56, (o) + 57, (o) + 58, (o) + 59, (o) + 60, (o) + 61, (o) + 62, (o) + 63
#define UP64(v, s) __builtin_shufflevector((uchar64_v)(uchar)T_MAX, (v), LANES64(64 - (s)))
#define DOWN64(v, s) __builtin_shufflevector((v), (uchar64_v)(uchar)T_MAX, LANES64(s))
inline uchar64_v scan_up64(uchar64_v v) {
    v = min64(v, add_sat64(UP64(v, 1), (uchar64_v)1));
    v = min64(v, add_sat64(UP64(v, 2), (uchar64_v)2));
    v = min64(v, add_sat64(UP64(v, 4), (uchar64_v)4));
    v = min64(v, add_sat64(UP64(v, 8), (uchar64_v)8));
    v = min64(v, add_sat64(UP64(v, 16), (uchar64_v)16));
    return min64(v, add_sat64(UP64(v, 32), (uchar64_v)32));
}
inline uchar64_v scan_down64(uchar64_v v) {
    v = min64(v, add_sat64(DOWN64(v, 1), (uchar64_v)1));
    v = min64(v, add_sat64(DOWN64(v, 2), (uchar64_v)2));
    v = min64(v, add_sat64(DOWN64(v, 4), (uchar64_v)4));
    v = min64(v, add_sat64(DOWN64(v, 8), (uchar64_v)8));
    v = min64(v, add_sat64(DOWN64(v, 16), (uchar64_v)16));
    return min64(v, add_sat64(DOWN64(v, 32), (uchar64_v)32));
}


// The bytes of a that are 0 as a bit mask (bit i: a[i] == 0). With AVX-512BW (PoCL builds for
// the host's CPU) the compare's mask register itself (vpmovb2m); elsewhere each 8 bytes' bits
// are summed into the top byte of their word by one multiplication.
inline ulong zero_bits64(uchar64_v a) {
#ifdef __AVX512BW__
    typedef char c64 __attribute__((ext_vector_type(64)));
    return __builtin_ia32_cvtb2mask512(__builtin_astype(a == (uchar64_v)0, c64));
#else
    const uchar64_v w = (uchar64_v)(1, 2, 4, 8, 16, 32, 64, 128, 1, 2, 4, 8, 16, 32, 64, 128,
                                     1, 2, 4, 8, 16, 32, 64, 128, 1, 2, 4, 8, 16, 32, 64, 128,
                                     1, 2, 4, 8, 16, 32, 64, 128, 1, 2, 4, 8, 16, 32, 64, 128,
                                     1, 2, 4, 8, 16, 32, 64, 128, 1, 2, 4, 8, 16, 32, 64, 128);
    const ulong8 bits = __builtin_astype(as_uchar64_v(a == (uchar64_v)0) & w, ulong8);
    return as_ulong(__builtin_convertvector((bits * 0x0101010101010101UL) >> 56, uchar8));
#endif
}
// One step of row_scan64 at p, forward from the carry before it (down: backward from the one
// after it); returns the carry for the next step.
inline uchar scan_step64(__local uchar* restrict p, uchar carry, bool down) {
    uchar64_v v = LD64(p);
    const ulong solid = zero_bits64(v);
    if (solid == ~0UL) {
        return 0;
    }
    if (solid != 0) {
        v = down ? scan_down64(v) : scan_up64(v);
    } else if (carry >= (uchar)T_MAX) {
        return carry;
    }
    v = min64(v, add_sat64((down ? RIOTA64 : IOTA64) + (uchar64_v)1, (uchar64_v)carry));
    ST64(v, p);
    return down ? v[0] : v[63];
}
inline void row_scan64(__local uchar* restrict a, uint n) {
    uchar carry = (uchar)T_MAX;
    for (uint j = 0; j < n; ++j) {
        carry = scan_step64(a + 64 * j, carry, false);
    }
    carry = (uchar)T_MAX;
    for (uint j = n; j-- > 0;) {
        carry = scan_step64(a + 64 * j, carry, true);
    }
}

inline uchar hmax16(V16 v) {
    const uchar8 m8 = max(v.lo, v.hi);
    const uchar4 m4 = max(m8.lo, m8.hi);
    return max(max(m4.s0, m4.s1), max(m4.s2, m4.s3));
}


// A y step's predecessor of the 64 bytes at p + x: the voxel above (L1) or the least of
// the three above (L-inf's moves (a, 1, 0), as KING_STEP).
#if CHEBYSHEV
#define Y_FROM64(p, x) min64(min64(LD64((p) + (x)-1), LD64((p) + (x))), LD64((p) + (x) + 1))
#else
#define Y_FROM64(p, x) LD64((p) + (x))
#endif

// xy_bytes: one work-item per z-slice of the voxels, as xy_slices_seq: each row's x transform
// (row_scan64, in `line`: X64 = X rounded up to 64 bytes), then the forward y step from the row
// before, into the local copy of the slice (`slice`), then the backward y sweep there, writing
// w8. `line` and the slice's rows have 16 bytes of T_MAX each side (L-inf's y steps read the
// voxels beside a row's ends; the first row's step reads `line` itself). The bytes of a row
// past X start at T_MAX, so they only relay values between real voxels at no less than their
// distance (in L1 and L-inf alike), and leave those exact. A row without solids is T_MAX
// throughout and skips the scan. CHEBYSHEV: the y steps take the least of the three voxels
// above (below), as xy_slices_seq's KING_STEP. It also clears flag[0] for the next kernel (the
// kernels run in order).
__kernel void xy_bytes(__global const uchar* restrict vox, __global uchar* restrict w8,
                       __global uint* restrict flag, uint X, uint Y, __local uchar* restrict line,
                       __local uchar* restrict slice) {
    const size_t base = get_global_id(0) * (size_t)X * Y;
    const uint X64 = (X + 63) / 64 * 64;  // a whole number of 64-byte steps
    const uint S = X64 + 32;                // a slice row: 16 bytes of T_MAX, X64, 16 of T_MAX
    const uint full = X / 16 * 16;
    const uint full64 = X / 64 * 64;
    __local uchar* const row = line + 16;
    if (get_global_id(0) == 0) {
        flag[0] = 0;
    }
    ST16((V16)T_MAX, line);
    ST16((V16)T_MAX, row + X64);
    for (uint y = 0; y < Y; ++y) {
        ST16((V16)T_MAX, slice + y * S);
        ST16((V16)T_MAX, slice + y * S + 16 + X64);
    }
    for (uint y = 0; y < Y; ++y) {
        __global const uchar* src = vox + base + (size_t)y * X;
        __local uchar* dst = slice + y * S + 16;
        uchar64_v any64 = 0;
        for (uint x = 0; x < full64; x += 64) {
            const uchar64_v v = LD64G(src + x);
            ST64(min64(as_uchar64_v(v == (uchar64_v)0), (uchar64_v)T_MAX), row + x);
            any64 = max64(any64, v);
        }
        V16 seen = max(max(any64.lo.lo, any64.lo.hi), max(any64.hi.lo, any64.hi.hi));
        for (uint x = full64; x < full; x += 16) {
            const V16 v = LD16G(src + x);
            ST16(min(as_uchar16(v == (V16)0), (V16)T_MAX), row + x);
            seen = max(seen, v);
        }
        for (uint x = full; x < X64; ++x) {
            const uchar v = x < X ? src[x] : (uchar)0;
            row[x] = v ? (uchar)0 : (uchar)T_MAX;
            seen.s0 = max(seen.s0, v);
        }
        if (hmax16(seen) != 0) {
            row_scan64(row, X64 / 64);
        }
        // The forward y sweep's step from the row before (still in L1).
        __local const uchar* prev = y > 0 ? dst - S : row;
        for (uint x = 0; x < X64; x += 64) {
            ST64(min64(LD64(row + x), add_sat64(Y_FROM64(prev, x), (uchar64_v)1)), dst + x);
        }
    }
    for (uint y = Y; y-- > 0;) {
        __local uchar* cur = slice + y * S + 16;
        __local const uchar* next = y + 1 < Y ? cur + S : cur;
        __global uchar* o = w8 + base + (size_t)y * X;
        // Whole vectors (the bytes past X too, for the row above), stored to w8 up to X.
        for (uint x = 0; x < X64; x += 64) {
            ST64(min64(LD64(cur + x), add_sat64(Y_FROM64(next, x), (uchar64_v)1)), cur + x);
        }
        // Plain stores: w8 stays in the last-level cache for z_bytes (non-temporal stores sent
        // it to memory, and z_bytes read it back from there).
        for (uint x = 0; x < full64; x += 64) {
            *(__global uchar64_any*)(o + x) = LD64(cur + x);
        }
        for (uint x = full64; x < full; x += 16) {
            ST16G(LD16(cur + x), o + x);
        }
        for (uint x = full; x < X; ++x) {
            o[x] = cur[x];
        }
    }
}

// z_bytes: the z pass, from w8 into the output. Each work-item sweeps `chunk` contiguous
// values of a z-plane (a flat strip: whole rows, no per-row work) through all Z planes,
// forward into `scratch` (chunk * Z bytes, the strip's columns contiguous) and backward from
// there into `out`, so w8 is read once and the output written once; SAT_CHECK: sets flag[0]
// where a value is 255. The forward sweep prefetches the strip Z_AHEAD planes ahead: a strip
// of a small plane (long-z: 256 bytes, 4 KiB apart) is beyond the hardware prefetchers (its
// z pass 5.2 -> 3.6 ms, load 3.5).
#define Z_AHEAD 8
__kernel void z_bytes(__global const uchar* restrict w8, __global U* restrict out,
                      __global uint* restrict flag, ulong plane, uint Z, uint chunk,
                      __local uchar* restrict scratch) {
    const size_t c0 = get_global_id(0) * (size_t)chunk;
    const uint w = (uint)min((size_t)chunk, (size_t)plane - c0);
    const uint w16 = w / 16 * 16;
    const uint w64 = w / 64 * 64;
    for (uint z = 0; z < Z; ++z) {
        __global const uchar* v = w8 + z * plane + c0;
        __local uchar* cur = scratch + z * w;
        if (z + Z_AHEAD < Z) {
            for (uint i = 0; i < w; i += 64) {
                __builtin_prefetch(v + Z_AHEAD * plane + i);
            }
        }
        // The previous plane's values; T_MAX before the first (read from cur, then replaced).
        __local const uchar* prev = z > 0 ? cur - w : cur;
        const uchar64_v none64 = z > 0 ? (uchar64_v)0 : (uchar64_v)T_MAX;
        for (uint i = 0; i < w64; i += 64) {
            const uchar64_v p = max64(LD64(prev + i), none64);
            ST64(min64(LD64G(v + i), add_sat64(p, (uchar64_v)1)), cur + i);
        }
        const V16 none = z > 0 ? (V16)0 : (V16)T_MAX;
        for (uint i = w64; i < w16; i += 16) {
            const V16 p = max(LD16(prev + i), none);
            ST16(min(LD16G(v + i), add_sat(p, (V16)1)), cur + i);
        }
        for (uint i = w16; i < w; ++i) {
            const uchar p = z > 0 ? prev[i] : (uchar)T_MAX;
            cur[i] = min(v[i], inc_t(p));
        }
    }
    V16 top = 0;
    uchar64_v top64 = 0;
    for (uint z = Z; z-- > 0;) {
        __global U* o = out + z * plane + c0;
        __local uchar* cur = scratch + z * w;
        __local const uchar* next = z + 1 < Z ? cur + w : cur;
        if ((size_t)o % 64 == 0) {
            for (uint i = 0; i < w64; i += 64) {
                const uchar64_v d = min64(LD64(cur + i), add_sat64(LD64(next + i), (uchar64_v)1));
                ST64(d, cur + i);
                __builtin_nontemporal_store(__builtin_convertvector(d, u64_v),
                                            (__global u64_a64*)(o + i));
                top64 = max64(top64, d);
            }
            for (uint i = w64; i < w16; i += 16) {
                const V16 d = min(LD16(cur + i), add_sat(LD16(next + i), (V16)1));
                ST16(d, cur + i);
                ST_U16(d, o + i);
                top = max(top, d);
            }
        } else if ((size_t)o % sizeof(VTYPE(U, 16)) == 0) {
            for (uint i = 0; i < w16; i += 16) {
                const V16 d = min(LD16(cur + i), add_sat(LD16(next + i), (V16)1));
                ST16(d, cur + i);
                __builtin_nontemporal_store(CONVERT(U, 16)(d), (__global VTYPE(U, 16)*)(o + i));
                top = max(top, d);
            }
        } else {
            for (uint i = 0; i < w16; i += 16) {
                const V16 d = min(LD16(cur + i), add_sat(LD16(next + i), (V16)1));
                ST16(d, cur + i);
                ST_U16(d, o + i);
                top = max(top, d);
            }
        }
        for (uint i = w16; i < w; ++i) {
            const uchar d = min(cur[i], inc_t(next[i]));
            cur[i] = d;
            o[i] = (U)d;
            top.s0 = max(top.s0, d);
        }
    }
    top = max(top, max(max(top64.lo.lo, top64.lo.hi), max(top64.hi.lo, top64.hi.hi)));
    if (SAT_CHECK && hmax16(top) == (uchar)255) {
        flag[0] = 1;
    }
}
#endif

#if CHEBYSHEV
// The L-inf z moves (a, b, +-1), a, b in {-1,0,1}, all nine at once: a forward sweep over
// the z planes, each voxel taking 1 + the least of the nine voxels around it in the plane
// before (those inside the world), then the mirrored backward sweep. Unrolled, the forward
// sweep gives min over k >= 0 of k + the xy value of a voxel within k of (x, y) in both
// coordinates at z - k, which for a target k planes below is max(k, |dx|, |dy|), its L-inf
// distance; the backward sweep adds the targets above. The planes depend on each other in
// turn, so one work-item walks the whole volume; the loops over a row vectorise, and the
// column minima of the previous plane's three rows go through `cm` (X + 2 elements, T_MAX at
// both ends). `final` writes the output format.
__kernel void z_king(__global T* restrict work, __global uint* restrict out,
                     __global const uchar* restrict vox, __constant uchar* rgb, uint X, uint Y,
                     uint Z, uint final, __local T* restrict cm) {
    if (get_global_id(0) != 0) {
        return;
    }
    const size_t plane = (size_t)X * Y;
    __local T* c = cm + 1;
    c[-1] = (T)T_MAX;
    c[X] = (T)T_MAX;
    for (uint dir = 0; dir < 2; ++dir) {
        for (uint i = 1; i < Z; ++i) {
            const uint z = dir == 0 ? i : Z - 1 - i;
            __global T* cur = work + z * plane;
            __global const T* prev = dir == 0 ? cur - plane : cur + plane;
            for (uint y = 0; y < Y; ++y) {
                __global const T* p0 = prev + (size_t)y * X;
                __global const T* pl = y > 0 ? p0 - X : p0;
                __global const T* ph = y + 1 < Y ? p0 + X : p0;
                for (uint x = 0; x < X; ++x) {
                    c[x] = min(min(pl[x], p0[x]), ph[x]);
                }
                __global T* r = cur + (size_t)y * X;
                for (uint x = 0; x < X; ++x) {
                    r[x] = min(r[x], inc_t(min(min(c[(int)x - 1], c[x]), c[x + 1])));
                }
            }
        }
    }
#if PACKED
    for (size_t i = 0; final && i < plane * Z; ++i) {
        STORE_FINAL(i, work[i]);
    }
#endif
}

#ifdef U
// z_king on bytes (the byte program, T = uchar): the same sweeps over the planes, 64 bytes per
// vector step, then 16 (a ragged end one at a time), each row written to the output in the backward
// sweep once final (the last plane after the forward sweep). flag[0]: a value of 255 where
// the output is wider (SAT_CHECK; the host then runs the wide sweeps).
__kernel void z_king_bytes(__global uchar* restrict work, __global U* restrict out,
                           __global uint* restrict flag, uint X, uint Y, uint Z,
                           __local uchar* restrict cm) {
    if (get_global_id(0) != 0) {
        return;
    }
    const size_t plane = (size_t)X * Y;
    const uint full = X / 16 * 16;
    const uint full64 = X / 64 * 64;
    __local uchar* c = cm + 1;
    c[-1] = (uchar)T_MAX;
    c[X] = (uchar)T_MAX;
    V16 top = 0;
    uchar64_v top64 = 0;
    for (uint dir = 0; dir < 2; ++dir) {
        for (uint i = 0; i < Z; ++i) {
            const uint z = dir == 0 ? i : Z - 1 - i;
            __global uchar* cur = work + z * plane;
            __global const uchar* prev = dir == 0 ? cur - plane : cur + plane;
            for (uint y = 0; y < Y; ++y) {
                __global uchar* r = cur + (size_t)y * X;
                if (i > 0) {
                    __global const uchar* p0 = prev + (size_t)y * X;
                    __global const uchar* pl = y > 0 ? p0 - X : p0;
                    __global const uchar* ph = y + 1 < Y ? p0 + X : p0;
                    for (uint x = 0; x < full64; x += 64) {
                        ST64(min64(min64(LD64G(pl + x), LD64G(p0 + x)), LD64G(ph + x)), c + x);
                    }
                    for (uint x = full64; x < full; x += 16) {
                        ST16(min(min(LD16G(pl + x), LD16G(p0 + x)), LD16G(ph + x)), c + x);
                    }
                    for (uint x = full; x < X; ++x) {
                        c[x] = min(min(pl[x], p0[x]), ph[x]);
                    }
                    for (uint x = 0; x < full64; x += 64) {
                        const uchar64_v m =
                            min64(min64(LD64(c + x - 1), LD64(c + x)), LD64(c + x + 1));
                        ST64G(min64(LD64G(r + x), add_sat64(m, (uchar64_v)1)), r + x);
                    }
                    for (uint x = full64; x < full; x += 16) {
                        const V16 m = min(min(LD16(c + x - 1), LD16(c + x)), LD16(c + x + 1));
                        ST16G(min(LD16G(r + x), add_sat(m, (V16)1)), r + x);
                    }
                    for (uint x = full; x < X; ++x) {
                        r[x] = min(r[x], inc_t(min(min(c[(int)x - 1], c[x]), c[x + 1])));
                    }
                }
                if (dir == 1) {
                    __global U* o = out + z * plane + (size_t)y * X;
                    for (uint x = 0; x < full64; x += 64) {
                        const uchar64_v d = LD64G(r + x);
                        *(__global u64_any*)(o + x) = __builtin_convertvector(d, u64_v);
                        top64 = max64(top64, d);
                    }
                    for (uint x = full64; x < full; x += 16) {
                        const V16 d = LD16G(r + x);
                        ST_U16(d, o + x);
                        top = max(top, d);
                    }
                    for (uint x = full; x < X; ++x) {
                        o[x] = (U)r[x];
                        top.s0 = max(top.s0, r[x]);
                    }
                }
            }
        }
    }
    top = max(top, max(max(top64.lo.lo, top64.lo.hi), max(top64.hi.lo, top64.hi.hi)));
    flag[0] = SAT_CHECK && hmax16(top) == (uchar)255;
}
#endif

#endif

// Sweeps columns of length N (element stride `stride`) over a strip of `strip` adjacent x
// positions; get_global_id(1) picks the line of columns at offset m * mstride. The forward
// sweep copies the strip into `scratch` (strip * N elements, contiguous), so the backward
// sweep reads it from cache: rows of a power-of-two world sit a power-of-two apart and would
// all fall into the same cache sets. cols_strip_final writes the output format. SIGNED: EDGE
// adds the empty surroundings' step to the first and last line.
#if SIGNED
#define EDGE(v) step_k((v), (T)T_MAX, (T)1)
#else
#define EDGE(v) (v)
#endif
#define COLS_STRIP(NAME, STORE)                                                            \
    __kernel void NAME(__global T* restrict work, __global uint* restrict out,             \
                       __global const uchar* restrict vox, __constant uchar* rgb, uint X,  \
                       uint N, ulong stride, ulong mstride, uint strip,                    \
                       __local T* restrict scratch) {                                      \
        const uint x0 = (uint)get_global_id(0) * strip;                                    \
        const uint w = min(x0 + strip, X) - x0;                                            \
        const size_t base = get_global_id(1) * mstride + x0;                               \
        for (uint i = 0; i < w; ++i) {                                                     \
            scratch[i] = EDGE(work[base + i]);                                             \
        }                                                                                  \
        for (uint n = 1; n < N; ++n) {                                                     \
            const size_t row = base + n * stride;                                          \
            __local T* cur = scratch + n * w;                                              \
            __local const T* prev = cur - w;                                               \
            for (uint i = 0; i < w; ++i) {                                                 \
                const T v = n + 1 == N ? EDGE(work[row + i]) : work[row + i];              \
                cur[i] = step_k(v, prev[i], (T)1);                                         \
            }                                                                              \
        }                                                                                  \
        {                                                                                  \
            const size_t row = base + (N - 1) * stride;                                    \
            __local const T* cur = scratch + (N - 1) * w;                                  \
            for (uint i = 0; i < w; ++i) {                                                 \
                STORE(row + i, cur[i]);                                                    \
            }                                                                              \
        }                                                                                  \
        for (uint n = N - 1; n-- > 0;) {                                                   \
            const size_t row = base + n * stride;                                          \
            __local T* cur = scratch + n * w;                                              \
            __local const T* next = cur + w;                                               \
            for (uint i = 0; i < w; ++i) {                                                 \
                const T d = step_k(cur[i], next[i], (T)1);                                 \
                cur[i] = d;                                                                \
                STORE(row + i, d);                                                         \
            }                                                                              \
        }                                                                                  \
    }

#define STORE_WORK(i, d) work[i] = (d)
COLS_STRIP(cols_strip, STORE_WORK)
COLS_STRIP(cols_strip_final, STORE_FINAL)

// The GPU layout's rows too long for x_rows_map and for x_rows_local's local memory: a
// work-item per row, both sweeps in place in `work`, any length.
__kernel void x_rows_long(__global const uchar* restrict vox, __global T* restrict work, uint X,
                          uint rows) {
    const size_t r = get_global_id(0);
    if (r >= rows) {
        return;
    }
    const size_t base = r * X;
    T c = (T)T_MAX;
    for (uint x = 0; x < X; ++x) {
        c = IS_TARGET(vox[base + x]) ? (T)0 : min(add_sat(c, (T)1), (T)T_MAX);
        work[base + x] = c;
    }
    for (uint x = X - 1; x-- > 0;) {
        c = min(work[base + x], add_sat(c, (T)1));
        work[base + x] = c;
    }
}

// Rows along x, `per_row` work-items per row and get_local_size(0) / per_row rows per
// work-group. A row's occupancy is staged in local memory (coalesced), each work-item
// scans a contiguous segment for its last and first solid, a Hillis-Steele scan over the
// row's segments gives every segment the nearest solid on either side, and the distances are
// written back coalesced. Local arrays are indexed through pad_idx so that work-items reading
// segment-strided addresses hit different banks.
inline uint pad_idx(uint i) { return i + (i >> 5); }

__kernel void x_rows_local(__global const uchar* restrict vox, __global T* restrict work,
                           uint X, uint rows, uint per_row, __local uchar* occ,
                           __local uint* dist, __local int* last, __local int* first) {
    const uint L = per_row;
    const uint lid = (uint)get_local_id(0) % L;
    const uint r = (uint)get_local_id(0) / L;
    const size_t row = get_group_id(0) * (get_local_size(0) / L) + r;
    const bool active = row < rows;
    const uint span = pad_idx(X) + 1;
    __local uchar* o = occ + r * span;
    __local uint* d = dist + r * span;
    __local int* lr = last + r * L;
    __local int* fr = first + r * L;
    const size_t base = row * X;
    for (uint x = lid; x < X; x += L) {
        o[pad_idx(x)] = active && IS_TARGET(vox[base + x]);
    }
    barrier(CLK_LOCAL_MEM_FENCE);
    const uint seg = (X + L - 1) / L;
    const uint a = min(lid * seg, X);
    const uint b = min(a + seg, X);
    int l = -1;
    int f = INT_MAX;
    for (uint x = a; x < b; ++x) {
        if (o[pad_idx(x)]) {
            l = (int)x;
            f = min(f, (int)x);
        }
    }
    lr[lid] = l;
    fr[lid] = f;
    barrier(CLK_LOCAL_MEM_FENCE);
    for (uint off = 1; off < L; off <<= 1) {
        const int lo = lid >= off ? lr[lid - off] : -1;
        const int hi = lid + off < L ? fr[lid + off] : INT_MAX;
        barrier(CLK_LOCAL_MEM_FENCE);
        lr[lid] = max(lr[lid], lo);
        fr[lid] = min(fr[lid], hi);
        barrier(CLK_LOCAL_MEM_FENCE);
    }
    l = lid > 0 ? lr[lid - 1] : -1;
    for (uint x = a; x < b; ++x) {
        if (o[pad_idx(x)]) {
            l = (int)x;
        }
        d[pad_idx(x)] = l < 0 ? T_MAX : min((uint)((int)x - l), (uint)T_MAX);
    }
    f = lid + 1 < L ? fr[lid + 1] : INT_MAX;
    for (uint x = b; x > a;) {
        --x;
        if (o[pad_idx(x)]) {
            f = (int)x;
        }
        if (f != INT_MAX) {
            d[pad_idx(x)] = min(d[pad_idx(x)], min((uint)(f - (int)x), (uint)T_MAX));
        }
    }
    barrier(CLK_LOCAL_MEM_FENCE);
    if (active) {
        for (uint x = lid; x < X; x += L) {
            work[base + x] = (T)d[pad_idx(x)];
        }
    }
}

// Bit i set where voxel i of the 16 is a target (IS_TARGET: solid, unless ROW_TARGETS_EMPTY).
inline uint solid_bits16(uchar16 a) {
    uchar t[16];
    vstore16(a, 0, t);
    uint m = 0;
#pragma unroll
    for (uint i = 0; i < 16; ++i) {
        m |= (uint)IS_TARGET(t[i]) << i;
    }
    return m;
}

// A row's W segments joined in local memory: on entry l[s] holds segment s's last solid
// position (`below` when it has none) and f[s] its first (`above` when none); every work-item
// of the group calls this (it has barriers). On return l[s] is the row's last solid at or
// before segment s's end and f[s] its first at or after its start (Hillis-Steele steps, log2 W).
inline void join_row_bounds(__local int* l, __local int* f, uint s, uint W, int below,
                            int above) {
    barrier(CLK_LOCAL_MEM_FENCE);
    for (uint off = 1; off < W; off <<= 1) {
        const int lo = s >= off ? l[s - off] : below;
        const int hi = s + off < W ? f[s + off] : above;
        barrier(CLK_LOCAL_MEM_FENCE);
        l[s] = max(l[s], lo);
        f[s] = min(f[s], hi);
        barrier(CLK_LOCAL_MEM_FENCE);
    }
}

// The x pass as bits (GPU layout, unsigned L1, X a multiple of 16 and below 65535): work-item
// (s, r) reads voxels [32s, 32s + 32) of row r of its group (two aligned 16-byte loads; the last
// word of a row of 16 mod 32 voxels has 16) and writes words[row * W + s] = (bit i set where
// voxel 32s + i is solid, (L + 1) | R << 16), with L the row's last solid voxel before the word
// (-1 when none) and R its first after it (0xFFFF when none): a scan over the row's W words in
// local memory, as in x_rows_local. row_dist expands a voxel's x distance from its word.
#if !SIGNED

__kernel void x_words(__global const uchar* restrict vox, __global uint2* restrict words, uint X,
                      uint rows, __local int* lr, __local int* fr) {
    const uint W = (uint)get_local_size(0);
    const uint s = (uint)get_local_id(0);
    const uint r = (uint)get_local_id(1);
    const size_t row = get_group_id(1) * get_local_size(1) + r;
    const bool active = row < rows;
    const size_t base = (active ? row : 0) * X + s * 32;
    uint bits = solid_bits16(*(__global const uchar16*)(vox + base));
    if (s * 32 + 16 < X) {
        bits |= solid_bits16(*(__global const uchar16*)(vox + base + 16)) << 16;
    }
    __local int* l = lr + r * W;
    __local int* f = fr + r * W;
    l[s] = bits != 0 ? (int)(s * 32 + 31 - clz(bits)) : -1;
    f[s] = bits != 0 ? (int)(s * 32 + 31 - clz(bits & (0u - bits))) : INT_MAX;
    join_row_bounds(l, f, s, W, -1, INT_MAX);
    const int before = s > 0 ? l[s - 1] : -1;
    const int after = s + 1 < W ? f[s + 1] : INT_MAX;
    if (active) {
        words[row * W + s] =
            (uint2)(bits, (uint)(before + 1) | (uint)min(after, 0xFFFF) << 16);
    }
}

// The x distance of voxel x of a row from the row's word holding it (x_words), up to T_MAX.
inline T row_dist(uint2 w, uint x) {
    const uint i = x & 31;
    const uint le = w.x & (0xFFFFFFFFu >> (31 - i));
    const uint ge = w.x & (0xFFFFFFFFu << i);
    uint d = UINT_MAX;
    if (le != 0) {
        d = clz(le) + i - 31;
    } else if ((w.y & 0xFFFF) != 0) {
        d = x + 1 - (w.y & 0xFFFF);
    }
    if (ge != 0) {
        d = min(d, 31 - clz(ge & (0u - ge)) - i);
    } else if ((w.y >> 16) != 0xFFFF) {
        d = min(d, (w.y >> 16) - x);
    }
    return (T)min(d, (uint)T_MAX);
}
#endif

// Inclusive min-plus scans of a line's segment summaries, in place in local memory: after
// them fo[s] = min over t <= s of fo[t] + K (s - t) (the forward sweep's value at the end of
// segment s) and bo[s] = min over t >= s of bo[t] + K (t - s), by Hillis-Steele steps (log2 of
// the segments, not one step per segment). IDX maps a segment to its local slot.
#define SCAN_SEGS(TY, fo, bo, IDX, s, segs, K)                                             \
    for (uint d_ = 1; d_ < (segs); d_ <<= 1) {                                             \
        const TY step_ = (TY)min((uint)(K)*d_, (uint)T_MAX); /* no wrap in narrow types */ \
        const TY f_ = (s) >= d_ ? add_sat(fo[IDX((s)-d_)], step_) : (TY)T_MAX;             \
        const TY b_ = (s) + d_ < (segs) ? add_sat(bo[IDX((s) + d_)], step_) : (TY)T_MAX;   \
        barrier(CLK_LOCAL_MEM_FENCE);                                                      \
        fo[IDX(s)] = min(fo[IDX(s)], f_);                                                  \
        bo[IDX(s)] = min(bo[IDX(s)], b_);                                                  \
        barrier(CLK_LOCAL_MEM_FENCE);                                                      \
    }

// The work vector of cols_seg: VW adjacent columns per work-item (VW = 1, 2 or 4), loaded
// and stored as one aligned word.
#define VEC_(t, n) t##n
#define VEC(t, n) VEC_(t, n)
#if VW == 1
#define TV T
#else
#define TV VEC(T, VW)
#endif

// cols_seg sweeps in 32-bit lanes (CV; CS one lane) where T_MAX < 2^31: a step min(v, c + 1)
// of values at most T_MAX cannot wrap there, so it needs no saturating add in the narrow type
// (which NVIDIA's compiler emulates in several instructions a lane); T = uint up to 2^32 - 1
// keeps add_sat. Values go back to TV (at most T_MAX) for local memory and stores.
#define CAT_(a, b) a##b
#define CAT(a, b) CAT_(a, b)
#if SIGNED || T_MAX > 0x7FFFFFFF
#define CV TV
#define CV_INC(x) add_sat((x), (CV)1)
#define CS T
#define CS_INC(x) add_sat((x), (CS)1)
#else
#define CS uint
#define CS_INC(x) ((x) + 1u)
#if VW == 1
#define CV uint
#else
#define CV VEC(uint, VW)
#endif
#define CV_INC(x) ((x) + (CV)1)
#endif
// x + d in CV lanes (d at most T_MAX): as CV_INC, no wrap where the lanes are 32-bit.
#if SIGNED || T_MAX > 0x7FFFFFFF
#define CV_ADD(x, d) add_sat((x), (CV)(d))
#define CS_ADD(x, d) add_sat((x), (CS)(d))
#else
#define CV_ADD(x, d) ((x) + (CV)(d))
#define CS_ADD(x, d) ((x) + (CS)(d))
#endif
#define TO_CV(x) CAT(convert_, CV)(x)
#define TO_TV(x) CAT(convert_, TV)(x)

#if PACKED
inline void store_final_vec(__global uint* restrict out, __global const uchar* restrict vox,
                            __constant uchar* rgb, size_t i, TV d) {
#if VW == 1
    STORE_FINAL(i, d);
#else
    STORE_FINAL(i, d.s0);
    STORE_FINAL(i + 1, d.s1);
#if VW == 4
    STORE_FINAL(i + 2, d.s2);
    STORE_FINAL(i + 3, d.s3);
#endif
#endif
}
#endif

// Columns of length N <= SEG_K * get_local_size(1): work-item (c, s) of a work-group holds
// values [s*SEG_K, (s+1)*SEG_K) of the VW columns at x = VW * (group * cw + c) in
// registers (X is a multiple of VW). Each segment publishes the value its forward sweep
// reaches at its end and its backward sweep at its start (with no carry), SCAN_SEGS folds
// every segment's into the later (earlier) ones' in log2(segments) steps, and each work-item
// sweeps again from the carries of its neighbours. Every loop over
// v has a constant trip count and is unrolled, so v stays in registers. The sweeps run in CV
// lanes (above); the local arrays and the stores hold TV.
// Longer columns take chunks of segs * SEG_K values, a work-group each (group(1) the chunk,
// num_groups(1) of them), in two launches: `chunks` 1 publishes each chunk's forward value at
// its last position and backward value at its first (no carry from other chunks; ends[2 (col G
// + g)] and ends[2 (col G + g) + 1], col = the work-item's place in dimensions 0 and 2) and
// writes nothing else; `chunks` 2 then sweeps each chunk from those carries too, walking the
// chunks before it (after it) a chunk length at a time. Without CHUNKS: one chunk, `chunks`
// and ends unused. The chunks' code is built only with CHUNKS=1, their own program: in every
// build its branches, though not taken, made the H100's 512^3 u16 y and z passes take 0.59 ms
// against 0.42 (u8 0.52 against 0.32; 1024^3 u16 5.03 against 4.07).
__kernel void cols_seg(__global T* restrict work, __global uint* restrict out,
                       __global const uchar* restrict vox, __constant uchar* rgb, uint X,
                       uint N, ulong stride, ulong mstride, uint final, __local TV* fout,
                       __local TV* bout, __global TV* ends, uint chunks
#if FROM_BITS
                       ,
                       __global const uint2* restrict words, uint W
#endif
) {
    const uint cw = (uint)get_local_size(0);
    const uint segs = (uint)get_local_size(1);
    const uint lc = (uint)get_local_id(0);
    const uint s = (uint)get_local_id(1);
    const uint x = ((uint)get_group_id(0) * cw + lc) * VW;
    const bool active = x < X;
    const size_t base = x + get_global_id(2) * mstride;
#if CHUNKS
    const uint g = (uint)get_group_id(1), G = (uint)get_num_groups(1);
#else
    const uint g = 0;
#endif
    const uint n0 = (g * segs + s) * SEG_K;
    CV v[SEG_K];
#if FROM_BITS
    // The y pass over x_words' rows: row (z, y) is z * N + y, the VW columns share a word.
    __global const uint2* wz = words + get_global_id(2) * N * W + x / 32;
#pragma unroll
    for (uint k = 0; k < SEG_K; ++k) {
        if (active && n0 + k < N) {
            const uint2 w = wz[(size_t)(n0 + k) * W];
#if VW == 1
            v[k] = TO_CV(row_dist(w, x));
#elif VW == 2
            v[k] = TO_CV((TV)(row_dist(w, x), row_dist(w, x + 1)));
#else
            v[k] = TO_CV(
                (TV)(row_dist(w, x), row_dist(w, x + 1), row_dist(w, x + 2), row_dist(w, x + 3)));
#endif
        } else {
            v[k] = (CV)T_MAX;
        }
    }
#else
#pragma unroll
    for (uint k = 0; k < SEG_K; ++k) {
        v[k] = (active && n0 + k < N)
                   ? TO_CV(*(__global const TV*)(work + base + (n0 + k) * stride))
                   : (CV)T_MAX;
    }
#endif
    CV fo = (CV)T_MAX;
    CV bo = (CV)T_MAX;
#pragma unroll
    for (uint k = 0; k < SEG_K; ++k) {
        fo = min(CV_INC(fo), v[k]);
        bo = min(CV_INC(bo), v[SEG_K - 1 - k]);
    }
    fout[s * cw + lc] = TO_TV(fo);
    bout[s * cw + lc] = TO_TV(bo);
    barrier(CLK_LOCAL_MEM_FENCE);
#define COL_SLOT(t) ((t)*cw + lc)
    SCAN_SEGS(TV, fout, bout, COL_SLOT, s, segs, SEG_K)
#if CHUNKS
    __global TV* col_ends =
        ends + 2 * (get_global_id(2) * get_global_size(0) + get_global_id(0)) * G;
    if (chunks == 1) {
        if (s + 1 == segs) {
            col_ends[2 * g] = fout[COL_SLOT(s)];
        }
        if (s == 0) {
            col_ends[2 * g + 1] = bout[COL_SLOT(0)];
        }
        return;
    }
    // With chunks, the carries of the chunks before (after) this one too, walked a chunk's
    // length at a time, then moved to this segment's start (end).
    const uint len = min(segs * SEG_K, (uint)T_MAX);
#endif
    CV c = s > 0 ? TO_CV(fout[COL_SLOT(s - 1)]) : (CV)T_MAX;
#if CHUNKS
    CV f = (CV)T_MAX;
    for (uint h = 0; h < g; ++h) {
        f = min(CV_ADD(f, len), TO_CV(col_ends[2 * h]));
    }
    c = min(c, CV_ADD(f, min(s * SEG_K, (uint)T_MAX)));
#endif
#pragma unroll
    for (uint k = 0; k < SEG_K; ++k) {
        c = min(v[k], CV_INC(c));
        v[k] = c;
    }
    c = s + 1 < segs ? TO_CV(bout[COL_SLOT(s + 1)]) : (CV)T_MAX;
#if CHUNKS
    CV b = (CV)T_MAX;
    for (uint h = G - 1; h > g; --h) {
        b = min(CV_ADD(b, len), TO_CV(col_ends[2 * h + 1]));
    }
    c = min(c, CV_ADD(b, min((segs - 1 - s) * SEG_K, (uint)T_MAX)));
#endif
#pragma unroll
    for (uint j = 0; j < SEG_K; ++j) {
        c = min(v[SEG_K - 1 - j], CV_INC(c));
        v[SEG_K - 1 - j] = c;
    }
#pragma unroll
    for (uint k = 0; k < SEG_K; ++k) {
        if (active && n0 + k < N) {
            const size_t i = base + (n0 + k) * stride;
#if PACKED
            if (final) {
                store_final_vec(out, vox, rgb, i, TO_TV(v[k]));
            } else {
                *(__global TV*)(work + i) = TO_TV(v[k]);
            }
#else
            *(__global TV*)(work + i) = TO_TV(v[k]);
#endif
        }
    }
}

// Stores a work-item's 16 values (an unrolled private array) as one aligned vector.
inline void store_row16(__global T* restrict dst, const T* v) {
    VEC(T, 16) d;
    d.s0 = v[0];
    d.s1 = v[1];
    d.s2 = v[2];
    d.s3 = v[3];
    d.s4 = v[4];
    d.s5 = v[5];
    d.s6 = v[6];
    d.s7 = v[7];
    d.s8 = v[8];
    d.s9 = v[9];
    d.sa = v[10];
    d.sb = v[11];
    d.sc = v[12];
    d.sd = v[13];
    d.se = v[14];
    d.sf = v[15];
    *(__global VEC(T, 16)*)dst = d;
}

// The GPU layout's x and y passes of a world whose z-slice fits local memory (a sparse
// field's edit block, small worlds): a work-group per slice loads its voxels (coalesced),
// sweeps its rows along x and then its columns along y in local memory, and stores the slice
// (coalesced): one launch for two passes. Unsigned. Two kernels: xy_slice_local sweeps a line
// a work-item (the fewest instructions: for many slices, where the device is kept full);
// xy_slice_segments 16 values of a line a work-item (sweep_local_segments: the shortest chain,
// for as many slices as the device has compute units or fewer, a sparse field's edit block;
// `ends` holds two values per such segment of the pass with more). On an H100 a radius-8 edit's
// block (52^3, u8) took 11.4-12.1 us by segments against 13.1-15.3 by lines, and the long-z
// world's 32768 slices (64 x 64, u16) 0.56-0.65 ms against 0.43-0.45.
// Rows lie SX elements apart in local memory: X, or where rows X apart would put many of a
// warp's work-items (a row each in xy_slice_local) in one bank, more (the host's choice): with
// rows of 64 u16 voxels (128 bytes) all 32 were in one bank, and the long-z world's (64 x 64 x
// 32768) x and y passes took 2.3 ms on an H100 against 0.43 padded.
// Element j of a slice (rows of X) in local memory whose rows lie SX apart.
inline uint slice_at(uint j, uint X, uint SX) { return SX == X ? j : j / X * SX + j % X; }

// A work-group's slice into local memory: 0 where solid, T_MAX where empty.
inline void load_slice(__global const uchar* restrict vox, uint X, uint Y, uint SX,
                       __local T* sl) {
    const uint lid = (uint)get_local_id(0), n = (uint)get_local_size(0);
    const uint plane = X * Y;
    const size_t base = get_group_id(0) * (size_t)plane;
    // Four loads in flight per work-item before their stores (a loop of one load and its store
    // would wait a global load's latency per step).
    for (uint i = lid; i < plane; i += 4 * n) {
        uchar a[4];
#pragma unroll
        for (uint u = 0; u < 4; ++u) {
            a[u] = i + u * n < plane ? vox[base + i + u * n] : (uchar)0;
        }
#pragma unroll
        for (uint u = 0; u < 4; ++u) {
            const uint j = i + u * n;
            if (j < plane) {
                sl[slice_at(j, X, SX)] = a[u] != 0 ? (T)0 : (T)T_MAX;
            }
        }
    }
}

// The work-group's slice from local memory into `work`.
inline void store_slice(__global T* restrict work, uint X, uint Y, uint SX,
                        __local const T* sl) {
    const uint lid = (uint)get_local_id(0), n = (uint)get_local_size(0);
    const uint plane = X * Y;
    const size_t base = get_group_id(0) * (size_t)plane;
    for (uint i = lid; i < plane; i += n) {
        work[base + i] = sl[slice_at(i, X, SX)];
    }
}

// The 1-D L1 transform of a line of n values `step` apart in local memory, in place: a forward
// and a backward min-plus sweep in CS lanes.
inline void sweep_local_line(__local T* line, uint n, uint step) {
    CS c = (CS)T_MAX;
    for (uint i = 0; i < n; ++i) {
        c = min((CS)line[i * step], CS_INC(c));
        line[i * step] = (T)c;
    }
    c = (CS)T_MAX;
    for (uint i = n; i-- > 0;) {
        c = min((CS)line[i * step], CS_INC(c));
        line[i * step] = (T)c;
    }
}

// xy_slice_local's sweeps of a loaded slice, then its store (sparse_slices.cl's too).
inline void sweep_and_store_lines(__global T* restrict work, uint X, uint Y, uint SX,
                                  __local T* sl) {
    const uint lid = (uint)get_local_id(0), n = (uint)get_local_size(0);
    for (uint y = lid; y < Y; y += n) {
        sweep_local_line(sl + y * SX, X, 1);
    }
    barrier(CLK_LOCAL_MEM_FENCE);
    for (uint x = lid; x < X; x += n) {
        sweep_local_line(sl + x, Y, SX);
    }
    barrier(CLK_LOCAL_MEM_FENCE);
    store_slice(work, X, Y, SX, sl);
}

__kernel void xy_slice_local(__global const uchar* restrict vox, __global T* restrict work,
                             uint X, uint Y, uint SX, __local T* sl) {
    load_slice(vox, X, Y, SX, sl);
    barrier(CLK_LOCAL_MEM_FENCE);
    sweep_and_store_lines(work, X, Y, SX, sl);
}

// The 1-D L1 transform of `lines` lines of n values in local memory (value i of line l at
// l * lstep + i * step), in place, in segments of SK values: each work-item takes segments
// (w: segment w % nseg of line w / nseg where `seg_fastest`, else line w % lines, segment w /
// lines) and sweeps them in registers. Where a line has several segments, each first publishes
// its reach past its ends (`ends`, two per segment: the forward sweep's value at its last value
// and the backward's at its first, within the segment), a work-item per line turns those into
// every segment's carries (the forward sweep's value just before it, over the whole line, and
// the backward's of the raw values just after it), and each segment is swept again from them:
// forward from its carry, then backward over the forward values from the other (which gives
// min over j of v_j + |i - j|, as sweeping the whole line does).
#define SK 16

// Work-item w's segment in sweep_local_segments: its values into v (T_MAX past the line's end),
// its length into *len and its place among the segments (line * nseg + segment) into *e;
// returns where its first value lies.
inline __local T* load_segment(__local T* sl, uint w, uint lines, uint n, uint nseg, uint step,
                               uint lstep, bool seg_fastest, uint* len, uint* e, CS* v) {
    const uint l = seg_fastest ? w / nseg : w % lines;
    const uint s = seg_fastest ? w % nseg : w / lines;
    const uint start = s * SK;
    *len = min((uint)SK, n - start);
    *e = l * nseg + s;
    __local T* p = sl + l * lstep + start * step;
#pragma unroll
    for (uint k = 0; k < SK; ++k) {
        v[k] = k < *len ? (CS)p[k * step] : (CS)T_MAX;
    }
    return p;
}

inline void sweep_local_segments(__local T* sl, uint lines, uint n, uint step, uint lstep,
                                 bool seg_fastest, __local T* ends) {
    const uint lid = (uint)get_local_id(0), gsize = (uint)get_local_size(0);
    const uint nseg = (n + SK - 1) / SK, total = lines * nseg;
    if (nseg > 1) {
        for (uint w = lid; w < total; w += gsize) {
            uint len, e;
            CS v[SK];
            load_segment(sl, w, lines, n, nseg, step, lstep, seg_fastest, &len, &e, v);
            CS f = (CS)T_MAX, b = (CS)T_MAX;
#pragma unroll
            for (uint k = 0; k < SK; ++k) {
                f = k < len ? min(v[k], CS_INC(f)) : f;
                b = min(v[SK - 1 - k], CS_INC(b));
            }
            ends[2 * e] = (T)f;
            ends[2 * e + 1] = (T)b;
        }
        barrier(CLK_LOCAL_MEM_FENCE);
        for (uint l = lid; l < lines; l += gsize) {
            __local T* e = ends + 2 * l * nseg;
            CS c = (CS)T_MAX;
            for (uint s = 0; s < nseg; ++s) {
                const CS out = (CS)e[2 * s];
                e[2 * s] = (T)c;
                c = min(out, CS_ADD(c, min((uint)SK, n - s * SK)));
            }
            c = (CS)T_MAX;
            for (uint s = nseg; s-- > 0;) {
                const CS out = (CS)e[2 * s + 1];
                e[2 * s + 1] = (T)c;
                c = min(out, CS_ADD(c, min((uint)SK, n - s * SK)));
            }
        }
        barrier(CLK_LOCAL_MEM_FENCE);
    }
    for (uint w = lid; w < total; w += gsize) {
        uint len, e;
        CS v[SK];
        __local T* p = load_segment(sl, w, lines, n, nseg, step, lstep, seg_fastest, &len, &e, v);
        CS c = nseg > 1 ? (CS)ends[2 * e] : (CS)T_MAX;
#pragma unroll
        for (uint k = 0; k < SK; ++k) {
            c = min(v[k], CS_INC(c));
            v[k] = c;
        }
        // The backward carry enters at the segment's last value (a short last segment: its
        // padding's T_MAX values change nothing).
        c = nseg > 1 ? (CS)ends[2 * e + 1] : (CS)T_MAX;
#pragma unroll
        for (uint k = SK; k-- > 0;) {
            c = k < len ? min(v[k], CS_INC(c)) : c;
            v[k] = c;
        }
#pragma unroll
        for (uint k = 0; k < SK; ++k) {
            if (k < len) {
                p[k * step] = (T)v[k];
            }
        }
    }
}

// xy_slice_segments' sweeps of a loaded slice, then its store (sparse_slices.cl's too).
inline void sweep_and_store_segments(__global T* restrict work, uint X, uint Y, uint SX,
                                     __local T* sl, __local T* ends) {
    sweep_local_segments(sl, Y, X, 1, SX, true, ends);
    barrier(CLK_LOCAL_MEM_FENCE);
    sweep_local_segments(sl, X, Y, SX, 1, false, ends);
    barrier(CLK_LOCAL_MEM_FENCE);
    store_slice(work, X, Y, SX, sl);
}

__kernel void xy_slice_segments(__global const uchar* restrict vox, __global T* restrict work,
                                uint X, uint Y, uint SX, __local T* sl, __local T* ends) {
    load_slice(vox, X, Y, SX, sl);
    barrier(CLK_LOCAL_MEM_FENCE);
    sweep_and_store_segments(work, X, Y, SX, sl, ends);
}

// Rows along x for X a multiple of XK = 16, two rows a work-item: work-item (s, r) holds
// voxels [16s, 16s + 16) of rows r and r + R of its group's 2R rows in registers (one aligned
// 16-byte load each; get_local_size(0) = X / 16 segments a row). No scan joins a row's
// segments: each work-item publishes its segments' target bits (`masks`) and whether they have
// any (`flags`, a byte a segment, rows padded to whole 16-byte chunks), and after one barrier
// finds its carries from the row's flags packed 64 at a time into a map (row_carries), sweeps
// its 16 voxels from them and stores them as one aligned vector. (On an H100, 1024^3 u16: 1.28
// ms against 1.96 for a Hillis-Steele scan of the segments' ends, 10 barriers, a row an item.)
#define XK 16

// Segments [64w, 64w + 64) of a row as bits, from its flags (chunks: the row's 16-byte chunks).
inline ulong segment_map(__local const uint4* flags, uint w, uint chunks) {
    ulong m = 0;
    for (uint j = 0; j < 4 && 4 * w + j < chunks; ++j) {
        // Each byte is 0 or 1: the multiplication moves byte b's bit to bit 24 + b.
        const uint4 q = flags[4 * w + j];
        const uint p = (((q.x * 0x01020408u) >> 24) & 0xFu) |
                       (((q.y * 0x01020408u) >> 20) & 0xF0u) |
                       (((q.z * 0x01020408u) >> 16) & 0xF00u) |
                       (((q.w * 0x01020408u) >> 12) & 0xF000u);
        m |= (ulong)p << (16 * j);
    }
    return m;
}

inline uint lowest_bit(ulong m) { return 63u - (uint)clz(m & (0ul - m)); }

// Segment s's carries: the forward sweep's value just before it (x0 - 1 - the row's last target
// before x0) and the backward sweep's just after it, T_MAX where there is none (or it does not
// fit). A row in chunks (chunk c of nc, x positions relative to the chunk's first): where the
// chunk has no such target, the nearest from the other chunks' ends (x: last target, y: first;
// -1 and INT_MAX where a chunk has none), walked a chunk at a time.
inline void row_carries(__local const ushort* masks, __local const uint4* flags, uint segs,
                        uint s, __global const int2* ends, uint c, uint nc, T* cf, T* cb) {
    const uint chunks = (segs + 15) / 16, words = (segs + 63) / 64;
    const uint w0 = s / 64, b = s % 64;
    const ulong own = segment_map(flags, w0, chunks);
    const int x0 = (int)(s * XK);
    const int cx = (int)(c * segs * XK);
    ulong m = own & ((1ul << b) - 1ul);
    uint w = w0;
    while (m == 0 && w > 0) {
        m = segment_map(flags, --w, chunks);
    }
    int last = INT_MIN;
    if (m != 0) {
        const uint t = 64 * w + 63u - (uint)clz(m);
        last = (int)(t * XK) + 31 - (int)clz((uint)masks[t]);
    } else {
        for (uint k = c; k-- > 0 && last == INT_MIN;) {
            last = ends[k].x >= 0 ? ends[k].x - cx : INT_MIN;
        }
    }
    *cf = last == INT_MIN ? (T)T_MAX : (T)min((uint)(x0 - 1 - last), (uint)T_MAX);
    m = b < 63 ? own & (~0ul << (b + 1)) : 0ul;
    w = w0;
    while (m == 0 && w + 1 < words) {
        m = segment_map(flags, ++w, chunks);
    }
    int first = INT_MAX;
    if (m != 0) {
        const uint t = 64 * w + lowest_bit(m);
        first = (int)(t * XK) + (int)lowest_bit((ulong)masks[t]);
    } else {
        for (uint k = c + 1; k < nc && first == INT_MAX; ++k) {
            first = ends[k].y != INT_MAX ? ends[k].y - cx : INT_MAX;
        }
    }
    *cb = first == INT_MAX ? (T)T_MAX : (T)min((uint)(first - x0 - (int)XK), (uint)T_MAX);
}

// A chunk's last and first target (x relative to the chunk; -1 and INT_MAX where it has none).
inline int2 chunk_ends(__local const ushort* masks, __local const uint4* flags, uint segs) {
    const uint chunks = (segs + 15) / 16, words = (segs + 63) / 64;
    int2 e = (int2)(-1, INT_MAX);
    for (uint w = words; w-- > 0 && e.x < 0;) {
        const ulong m = segment_map(flags, w, chunks);
        if (m != 0) {
            const uint t = 64 * w + 63u - (uint)clz(m);
            e.x = (int)(t * XK) + 31 - (int)clz((uint)masks[t]);
        }
    }
    for (uint w = 0; w < words && e.y == INT_MAX; ++w) {
        const ulong m = segment_map(flags, w, chunks);
        if (m != 0) {
            const uint t = 64 * w + lowest_bit(m);
            e.y = (int)(t * XK) + (int)lowest_bit((ulong)masks[t]);
        }
    }
    return e;
}

// A segment's 16 voxels swept from its carries (T_MAX where not a target, 0 where one is).
inline void sweep_segment(uint m, T cf, T cb, T* v) {
#pragma unroll
    for (uint k = 0; k < XK; ++k) {
        cf = (m >> k & 1u) != 0 ? (T)0 : min(add_sat(cf, (T)1), (T)T_MAX);
        v[k] = cf;
    }
#pragma unroll
    for (uint j = 0; j < XK; ++j) {
        cb = min(v[XK - 1 - j], add_sat(cb, (T)1));
        v[XK - 1 - j] = cb;
    }
}

__kernel void x_rows_map(__global const uchar* restrict vox, __global T* restrict work, uint X,
                         uint rows, __local ushort* masks, __local uint4* flag_chunks,
                         __global int2* restrict ends, uint chunks) {
    const uint segs = (uint)get_local_size(0);
    const uint s = (uint)get_local_id(0);
    const uint R = (uint)get_local_size(1);
#if CHUNKS
    const uint c = (uint)get_group_id(0), nc = (uint)get_num_groups(0);
#else
    const uint c = 0, nc = 0;
#endif
    const uint g = c * segs + s;  // the segment's index in its row
    const uint stride = (segs + 15) / 16 * 16;
    __local uchar* flags = (__local uchar*)flag_chunks;
    uint m[2];
    size_t base[2];
    bool active[2];
    size_t row[2];
    for (uint h = 0; h < 2; ++h) {
        row[h] = get_group_id(1) * 2 * R + get_local_id(1) + h * R;
        active[h] = row[h] < rows && g < X / XK;
        base[h] = (active[h] ? row[h] * X + g * XK : 0);
        const uchar16 o = *(__global const uchar16*)(vox + base[h]);
        m[h] = active[h] ? solid_bits16(o) : 0u;
    }
    for (uint h = 0; h < 2; ++h) {
        const uint r = (uint)get_local_id(1) + h * R;
        masks[r * segs + s] = (ushort)m[h];
        flags[r * stride + s] = m[h] != 0 ? 1 : 0;
        for (uint p = segs + s; p < stride; p += segs) {
            flags[r * stride + p] = 0;
        }
    }
    barrier(CLK_LOCAL_MEM_FENCE);
    for (uint h = 0; h < 2; ++h) {
        const uint r = (uint)get_local_id(1) + h * R;
#if CHUNKS
        if (chunks == 1) {
            if (s == 0 && row[h] < rows) {
                int2 e = chunk_ends(masks + r * segs, flag_chunks + r * (stride / 16), segs);
                const int cx = (int)(c * segs * XK);
                ends[row[h] * nc + c] = (int2)(e.x >= 0 ? e.x + cx : -1,
                                               e.y != INT_MAX ? e.y + cx : INT_MAX);
            }
            continue;
        }
#endif
        T cf, cb;
        // (nc is 0 without CHUNKS: no other chunk's ends.)
        row_carries(masks + r * segs, flag_chunks + r * (stride / 16), segs, s, ends + row[h] * nc,
                    c, nc, &cf, &cb);
        T v[XK];
        sweep_segment(m[h], cf, cb, v);
        if (active[h]) {
            store_row16(work + base[h], v);
        }
    }
}

