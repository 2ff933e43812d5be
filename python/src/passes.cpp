// The host 1-D passes of the separable transforms (see passes.hpp).
#include "passes.hpp"

#include <algorithm>
#include <cmath>
#include <limits>
#include <stdexcept>
#include <thread>
#include <type_traits>
#include <vector>

namespace voxfield::python {

namespace {

constexpr double kInf = std::numeric_limits<double>::infinity();

// One line of n positions: g (partials in, +inf = none), site[i] (out) = the position whose
// candidate is least at i (-1: none), val[i] = that value. Work arrays are the caller's.
struct Line {
    std::vector<double> g, val;
    std::vector<std::int64_t> site, stack, feat;  // feat: the sites' features (optional)
    std::vector<double> cut;
    void resize(std::size_t n) {
        g.resize(n);
        val.resize(n);
        site.resize(n);
        stack.resize(n);
        cut.resize(n + 1);
    }
};

double l2_at(double gj, double s, std::int64_t i, std::int64_t j) {
    const double o = s * static_cast<double>(i - j);
    return gj + o * o;
}

double l1_at(double gj, double s, std::int64_t i, std::int64_t j) {
    return gj + s * static_cast<double>(i > j ? i - j : j - i);
}

double linf_at(double gj, double s, std::int64_t i, std::int64_t j) {
    return std::max(gj, s * static_cast<double>(i > j ? i - j : j - i));
}

// L2: the lower envelope of the parabolas (Felzenszwalb & Huttenlocher), then at every i the
// least of the envelope's site there and its neighbours on the envelope, so that rounding in
// the intersections never picks a site whose value is not the least.
void pass_l2(Line& l, std::size_t n, double s) {
    std::int64_t k = -1;
    const double s2 = 2 * s * s;
    for (std::size_t qi = 0; qi < n; ++qi) {
        const double gq = l.g[qi];
        if (gq == kInf) {
            continue;
        }
        const auto q = static_cast<std::int64_t>(qi);
        const double sq = s * static_cast<double>(q);
        const double fq = gq + sq * sq;
        double x = -kInf;
        while (k >= 0) {
            const std::int64_t v = l.stack[k];
            const double sv = s * static_cast<double>(v);
            const double fv = l.g[v] + sv * sv;
            x = (fq - fv) / (s2 * static_cast<double>(q - v));
            if (x > l.cut[k]) {
                break;
            }
            --k;
        }
        ++k;
        l.stack[k] = q;
        l.cut[k] = k == 0 ? -kInf : x;
    }
    if (k < 0) {
        std::fill(l.site.begin(), l.site.begin() + static_cast<std::ptrdiff_t>(n), -1);
        std::fill(l.val.begin(), l.val.begin() + static_cast<std::ptrdiff_t>(n), kInf);
        return;
    }
    std::int64_t e = 0;
    for (std::size_t ii = 0; ii < n; ++ii) {
        const auto i = static_cast<std::int64_t>(ii);
        while (e < k && l.cut[e + 1] < static_cast<double>(i)) {
            ++e;
        }
        std::int64_t best = l.stack[e];
        double value = l2_at(l.g[best], s, i, best);
        for (std::int64_t nb : {e - 1, e + 1}) {
            if (nb >= 0 && nb <= k) {
                const std::int64_t j = l.stack[nb];
                const double c = l2_at(l.g[j], s, i, j);
                if (c < value || (c == value && j < best)) {
                    value = c;
                    best = j;
                }
            }
        }
        l.site[ii] = best;
        l.val[ii] = value;
    }
}

// L2 with unit spacing and integer partials (below 2^52), values only: the second phase of
// Meijster, Roerdink & Hesselink (2000) in exact integer arithmetic over the line's finite
// sites, no neighbour checks needed. Returns false, writing nothing, when a partial is not
// such an integer (the caller then takes pass_l2).
bool pass_l2_unit(Line& l, std::size_t n) {
    constexpr double kLimit = 4503599627370496.0;  // 2^52
    std::vector<std::int64_t>& g = l.feat;         // the partials as integers
    g.resize(n);
    for (std::size_t i = 0; i < n; ++i) {
        const double v = l.g[i];
        if (v == kInf) {
            continue;
        }
        if (!(v >= 0 && v < kLimit) || std::floor(v) != v) {
            return false;
        }
        g[i] = static_cast<std::int64_t>(v);
    }
    const auto sn = static_cast<std::int64_t>(n);
    std::int64_t* const site = l.stack.data();
    std::int64_t* const start = l.site.data();  // where each envelope site starts to be least
    const auto f = [&](std::int64_t x, std::int64_t i) { return (x - i) * (x - i) + g[i]; };
    // The first x at which site u (> i) is strictly less than site i.
    const auto first_better = [&](std::int64_t i, std::int64_t u) {
        const std::int64_t num = u * u - i * i + g[u] - g[i], den = 2 * (u - i);
        const std::int64_t q = num / den;
        return (q * den > num ? q - 1 : q) + 1;  // floor(num / den) + 1
    };
    std::int64_t k = -1;
    for (std::int64_t u = 0; u < sn; ++u) {
        if (l.g[static_cast<std::size_t>(u)] == kInf) {
            continue;
        }
        while (k >= 0 && f(start[k], site[k]) > f(start[k], u)) {
            --k;
        }
        if (k < 0) {
            k = 0;
            site[0] = u;
            start[0] = 0;
        } else if (const std::int64_t w = first_better(site[k], u); w < sn) {
            ++k;
            site[k] = u;
            start[k] = w;
        }
    }
    if (k < 0) {
        std::fill(l.val.begin(), l.val.begin() + static_cast<std::ptrdiff_t>(n), kInf);
        return true;
    }
    for (std::int64_t x = sn - 1; x >= 0; --x) {
        l.val[static_cast<std::size_t>(x)] = static_cast<double>(f(x, site[k]));
        if (x == start[k]) {
            --k;
        }
    }
    return true;
}

// L1: the order of two sites' candidates is the same at every position beyond both, so a
// forward and a backward sweep, each keeping its best site, find the least candidate.
void pass_l1(Line& l, std::size_t n, double s) {
    std::int64_t best = -1;
    for (std::size_t ii = 0; ii < n; ++ii) {
        const auto i = static_cast<std::int64_t>(ii);
        if (l.g[ii] != kInf && (best < 0 || l.g[ii] <= l1_at(l.g[best], s, i, best))) {
            best = i;
        }
        l.site[ii] = best;
        l.val[ii] = best < 0 ? kInf : l1_at(l.g[best], s, i, best);
    }
    best = -1;
    for (std::size_t r = n; r-- > 0;) {
        const auto i = static_cast<std::int64_t>(r);
        if (l.g[r] != kInf && (best < 0 || l.g[r] < l1_at(l.g[best], s, i, best))) {
            best = i;
        }
        if (best >= 0) {
            const double c = l1_at(l.g[best], s, i, best);
            if (c < l.val[r]) {
                l.val[r] = c;
                l.site[r] = best;
            }
        }
    }
}

// L-inf, one direction: candidates j <= i on a stack of increasing j and increasing g (a later
// site with g no larger is never worse again); at i the least of max(g_j, s (i - j)) lies where
// g_j first reaches s (i - j), found by bisection, or just before it.
void linf_sweep(Line& l, std::size_t n, double s, bool forward) {
    std::int64_t k = -1;
    for (std::size_t step = 0; step < n; ++step) {
        const std::size_t ii = forward ? step : n - 1 - step;
        const auto i = static_cast<std::int64_t>(ii);
        if (l.g[ii] != kInf) {
            while (k >= 0 && l.g[l.stack[k]] >= l.g[ii]) {
                --k;
            }
            l.stack[++k] = i;
        }
        if (k < 0) {
            continue;
        }
        std::int64_t lo = 0, hi = k + 1;  // first p with g >= distance, in [0, k]
        while (lo < hi) {
            const std::int64_t mid = (lo + hi) / 2;
            const std::int64_t j = l.stack[mid];
            if (l.g[j] >= linf_at(0, s, i, j)) {
                hi = mid;
            } else {
                lo = mid + 1;
            }
        }
        for (std::int64_t p : {lo - 1, lo}) {
            if (p >= 0 && p <= k) {
                const std::int64_t j = l.stack[p];
                const double c = linf_at(l.g[j], s, i, j);
                if (c < l.val[ii] || (c == l.val[ii] && (l.site[ii] < 0 || j < l.site[ii]))) {
                    l.val[ii] = c;
                    l.site[ii] = j;
                }
            }
        }
    }
}

void pass_linf(Line& l, std::size_t n, double s) {
    std::fill(l.site.begin(), l.site.begin() + static_cast<std::ptrdiff_t>(n), -1);
    std::fill(l.val.begin(), l.val.begin() + static_cast<std::ptrdiff_t>(n), kInf);
    linf_sweep(l, n, s, true);
    linf_sweep(l, n, s, false);
}

}  // namespace

void separable_pass(Metric metric, Shape3 shape, int axis, double spacing,
                    std::span<const std::uint8_t> targets, std::span<const double> g_in,
                    std::span<double> g_out, std::span<const std::int64_t> feat_in,
                    std::span<std::int64_t> feat_out, unsigned threads) {
    if (axis < 0 || axis > 2) {
        throw std::invalid_argument("separable_pass: axis must be 0, 1 or 2");
    }
    const std::size_t count = shape.count();
    const bool first = g_in.empty();
    if ((first ? targets.size() : g_in.size()) != count || g_out.size() != count ||
        (!feat_out.empty() && feat_out.size() != count) ||
        (!first && !feat_out.empty() && feat_in.size() != count)) {
        throw std::invalid_argument("separable_pass: array sizes do not match the shape");
    }
    const std::size_t n = shape.n[axis];
    std::size_t stride = 1;
    for (int a = 2; a > axis; --a) {
        stride *= shape.n[a];
    }
    const std::size_t lines = n == 0 ? 0 : count / n;
    // Lines are taken in tiles of up to kTile neighbours (consecutive in the axes after
    // `axis`, so position i of every line of a tile is one contiguous run of memory): a pass
    // along a strided axis then reads and writes whole runs instead of one element per cache
    // line. Along the last axis (stride 1) a tile is one line.
    constexpr std::size_t kTile = 32;
    auto work = [&](std::size_t from, std::size_t to) {
        std::vector<Line> tile(std::min(kTile, stride));
        for (Line& l : tile) {
            l.resize(n);
            if (!feat_out.empty()) {
                l.feat.resize(n);
            }
        }
        for (std::size_t line = from; line < to;) {
            const std::size_t outer = line / stride, inner = line % stride;
            const std::size_t m = std::min({tile.size(), to - line, stride - inner});
            const std::size_t base = outer * n * stride + inner;  // line t starts at base + t
            for (std::size_t i = 0; i < n; ++i) {
                const std::size_t at = base + i * stride;
                for (std::size_t t = 0; t < m; ++t) {
                    tile[t].g[i] = first ? (targets[at + t] != 0 ? 0.0 : kInf) : g_in[at + t];
                }
            }
            for (std::size_t t = 0; t < m; ++t) {
                Line& l = tile[t];
                switch (metric) {
                    case Metric::euclidean:
                        if (spacing != 1.0 || !feat_out.empty() || !pass_l2_unit(l, n)) {
                            pass_l2(l, n, spacing);
                        }
                        break;
                    case Metric::manhattan:
                        pass_l1(l, n, spacing);
                        break;
                    case Metric::chebyshev:
                        pass_linf(l, n, spacing);
                        break;
                }
                // Every feature of the tile is read before any is written (feat_out may be
                // feat_in).
                for (std::size_t i = 0; !feat_out.empty() && i < n; ++i) {
                    const std::int64_t j = l.site[i];
                    const std::size_t site = base + t + static_cast<std::size_t>(j) * stride;
                    l.feat[i] =
                        j < 0 ? -1 : (first ? static_cast<std::int64_t>(site) : feat_in[site]);
                }
            }
            for (std::size_t i = 0; i < n; ++i) {
                const std::size_t at = base + i * stride;
                for (std::size_t t = 0; t < m; ++t) {
                    g_out[at + t] = tile[t].val[i];
                    if (!feat_out.empty()) {
                        feat_out[at + t] = tile[t].feat[i];
                    }
                }
            }
            line += m;
        }
    };
    threads = std::max(
        1u, std::min<unsigned>(threads, static_cast<unsigned>(std::min<std::size_t>(lines, 64))));
    if (threads <= 1) {
        work(0, lines);
        return;
    }
    std::vector<std::thread> pool;
    const std::size_t per = (lines + threads - 1) / threads;
    for (unsigned t = 0; t < threads; ++t) {
        const std::size_t from = std::min(lines, t * per), to = std::min(lines, from + per);
        pool.emplace_back(work, from, to);
    }
    for (std::thread& t : pool) {
        t.join();
    }
}

template <typename T>
void axis0_distances(Shape3 shape, std::int64_t z0, std::span<const std::uint8_t> targets,
                     std::span<const std::int64_t> before, std::span<const std::int64_t> after,
                     T none, std::span<T> out) {
    const std::size_t planes = shape.n[0], lines = shape.n[1] * shape.n[2];
    if (targets.size() != planes * lines || out.size() != targets.size() ||
        before.size() != lines || after.size() != lines) {
        throw std::invalid_argument("axis0_distances: array sizes do not match the shape");
    }
    // Forward: the last target at or before each plane; backward: the next one at or after,
    // each line's position kept per line. Lines go kLines at a time through every plane, so
    // that their positions stay in the core's cache while each plane is read in whole runs.
    constexpr std::size_t kLines = 8192;
    std::vector<std::int64_t> at(std::min(lines, kLines));
    for (std::size_t q0 = 0; q0 < lines; q0 += kLines) {
        const std::size_t m = std::min(kLines, lines - q0);
        std::copy(before.begin() + static_cast<std::ptrdiff_t>(q0),
                  before.begin() + static_cast<std::ptrdiff_t>(q0 + m), at.begin());
        for (std::size_t p = 0; p < planes; ++p) {
            const std::int64_t z = z0 + static_cast<std::int64_t>(p);
            const std::uint8_t* t = targets.data() + p * lines + q0;
            T* o = out.data() + p * lines + q0;
            for (std::size_t q = 0; q < m; ++q) {
                at[q] = t[q] != 0 ? z : at[q];
                o[q] = at[q] < 0 ? none : static_cast<T>(z - at[q]);
            }
        }
        std::copy(after.begin() + static_cast<std::ptrdiff_t>(q0),
                  after.begin() + static_cast<std::ptrdiff_t>(q0 + m), at.begin());
        for (std::size_t p = planes; p-- > 0;) {
            const std::int64_t z = z0 + static_cast<std::int64_t>(p);
            const std::uint8_t* t = targets.data() + p * lines + q0;
            T* o = out.data() + p * lines + q0;
            for (std::size_t q = 0; q < m; ++q) {
                at[q] = t[q] != 0 ? z : at[q];
                o[q] = at[q] >= 0 ? std::min(o[q], static_cast<T>(at[q] - z)) : o[q];
            }
        }
    }
}

namespace {

// Unit-spacing partials of unit_slab_field: exact integers of type G (int32 where every
// distance fits, else int64), kNone<G> where no target.
template <typename G>
constexpr G kNone = std::numeric_limits<G>::max();

// floor(num / den) for den > 0: a double division where the quotient's rounding cannot cross
// an integer (|num| < 2^31, den < 2^22: the error is below 2^-22 <= 1 / den), else integers.
inline std::int64_t floor_div(std::int64_t num, std::int64_t den) {
    if (num > -(std::int64_t{1} << 31) && num < (std::int64_t{1} << 31) &&
        den < (std::int64_t{1} << 22)) {
        // Truncated, then one down below zero (std::floor is a library call on x86-64).
        const double r = static_cast<double>(num) / static_cast<double>(den);
        const auto q = static_cast<std::int64_t>(r);
        return static_cast<double>(q) > r ? q - 1 : q;
    }
    const std::int64_t q = num / den;
    return q * den > num ? q - 1 : q;
}

// Meijster's F(x, i) and Sep(i, u) (i < u: the last x at which site i is no farther than u).
template <Metric M>
inline std::int64_t cost(std::int64_t x, std::int64_t i, std::int64_t gi) {
    const std::int64_t o = x > i ? x - i : i - x;
    if constexpr (M == Metric::euclidean) {
        return o * o + gi;
    } else {
        return std::max(o, gi);
    }
}

template <Metric M>
inline std::int64_t separator(std::int64_t i, std::int64_t gi, std::int64_t u, std::int64_t gu) {
    if constexpr (M == Metric::euclidean) {
        return floor_div(u * u - i * i + gu - gi, 2 * (u - i));
    } else {
        const std::int64_t mid = floor_div(i + u, 2);
        return gi <= gu ? std::max(i + gu, mid) : std::min(u - gi, mid);
    }
}

// One line of n partials g[i * st] (kNone: no site) into out[i * st]: the lower envelope by
// Meijster's stack (L2, L-inf) or the two sweeps (L1); `site`, `start` and `value` (the
// sites' partials) hold n ints each.
template <Metric M, typename G>
void unit_line(const G* g, std::int64_t n, std::int64_t st, G* out, std::int64_t* site,
               std::int64_t* start, std::int64_t* value) {
    constexpr G none = kNone<G>;
    if constexpr (M == Metric::manhattan) {
        G run = none;
        for (std::int64_t x = 0; x < n; ++x) {
            run = std::min(g[x * st], run == none ? none : static_cast<G>(run + 1));
            out[x * st] = run;
        }
        run = none;
        for (std::int64_t x = n; x-- > 0;) {
            run = std::min(out[x * st], run == none ? none : static_cast<G>(run + 1));
            out[x * st] = run;
        }
    } else {
        std::int64_t k = -1;
        for (std::int64_t u = 0; u < n; ++u) {
            const std::int64_t gu = g[u * st];
            if (gu == none) {
                continue;
            }
            while (k >= 0 && cost<M>(start[k], site[k], value[k]) > cost<M>(start[k], u, gu)) {
                --k;
            }
            if (k < 0) {
                k = 0;
                site[0] = u;
                start[0] = 0;
                value[0] = gu;
            } else if (const std::int64_t w = separator<M>(site[k], value[k], u, gu) + 1; w < n) {
                ++k;
                site[k] = u;
                start[k] = w;
                value[k] = gu;
            }
        }
        if (k < 0) {
            for (std::int64_t x = 0; x < n; ++x) {
                out[x * st] = none;
            }
            return;
        }
        // Each envelope site's run [start, end) in one branch-free loop.
        for (std::int64_t end = n; k >= 0; --k) {
            const std::int64_t i = site[k], gi = value[k];
            for (std::int64_t x = start[k]; x < end; ++x) {
                out[x * st] = static_cast<G>(cost<M>(x, i, gi));
            }
            end = start[k];
        }
    }
}

// A final partial as format T (see unit_slab_field).
template <Metric M, typename T, typename G>
inline T stored(G v, bool minus_one) {
    if (v == kNone<G>) {
        if constexpr (std::is_floating_point_v<T>) {
            return std::numeric_limits<T>::infinity();
        } else {
            return minus_one ? T(-1) : std::numeric_limits<T>::max();
        }
    }
    if constexpr (M == Metric::euclidean) {
        const double d = std::sqrt(static_cast<double>(v));
        if constexpr (std::is_floating_point_v<T>) {
            return static_cast<T>(d);
        } else {
            const double top = static_cast<double>(std::numeric_limits<T>::max());
            return d >= top ? std::numeric_limits<T>::max() : static_cast<T>(std::floor(d));
        }
    } else if constexpr (std::is_floating_point_v<T>) {
        return static_cast<T>(v);
    } else {
        const auto top = static_cast<std::int64_t>(std::numeric_limits<T>::max());
        return static_cast<T>(std::min(static_cast<std::int64_t>(v), top));
    }
}

// Where row y's run of columns [x_edges[k], x_edges[k + 1]) of plane p lies in piece (j, k)
// of `pieces` (j: the piece row holding y, with its first row y0 and height h).
template <typename X>
inline X* piece_row(const Pieces<X>& pieces, std::size_t j, std::size_t k, std::size_t p,
                    std::size_t y) {
    const std::size_t nk = pieces.x_edges.size() - 1;
    const std::size_t y0 = pieces.y_edges[j], h = pieces.y_edges[j + 1] - y0;
    const std::size_t w = pieces.x_edges[k + 1] - pieces.x_edges[k];
    return pieces.data[j * nk + k] + (p * h + (y - y0)) * w;
}

// The passes along axes 1 and 2 of one plane of first-pass distances `dp` (n1 x n2, `none`:
// no target), stored into plane p of `out` (see unit_slab_pieces). The work buffers are the
// caller's, sized by unit_slab_groups.
template <Metric M, typename G, typename D, typename T>
struct UnitPlane {
    std::size_t n1, n2;
    std::vector<G> g1, cols, res, row;
    std::vector<std::int64_t> site, start, value;
    static constexpr std::int64_t kCols = 16;  // columns of a plane taken together along axis 1

    UnitPlane(std::size_t rows, std::size_t columns)
        : n1(rows),
          n2(columns),
          g1(rows * columns),
          cols(kCols * rows),
          res(kCols * rows),
          row(columns),
          site(std::max(rows, columns)),
          start(std::max(rows, columns)),
          value(std::max(rows, columns)) {}

    void run(const D* dp, D none, const Pieces<T>& out, std::size_t p, bool minus_one) {
        const auto sn1 = static_cast<std::int64_t>(n1), sn2 = static_cast<std::int64_t>(n2);
        const auto part = [none](D d) -> G {
            if (d == none) {
                return kNone<G>;
            }
            const auto v = static_cast<G>(d);
            return M == Metric::euclidean ? static_cast<G>(v * v) : v;
        };
        // Along axis 1, kCols columns at a time: their rows' runs copied side by side into
        // `cols` (column c at cols[y * kCols + c]), transformed there, copied into g1.
        for (std::int64_t x0 = 0; x0 < sn2; x0 += kCols) {
            const std::int64_t w = std::min(kCols, sn2 - x0);
            for (std::int64_t y = 0; y < sn1; ++y) {
                const D* src = dp + y * sn2 + x0;
                G* dst = cols.data() + y * kCols;
                for (std::int64_t c = 0; c < w; ++c) {
                    dst[c] = part(src[c]);
                }
            }
            if (n1 > 1) {
                for (std::int64_t c = 0; c < w; ++c) {
                    unit_line<M, G>(cols.data() + c, sn1, kCols, res.data() + c, site.data(),
                                    start.data(), value.data());
                }
            } else {
                std::copy(cols.begin(), cols.begin() + w, res.begin());
            }
            for (std::int64_t y = 0; y < sn1; ++y) {
                std::copy(res.data() + y * kCols, res.data() + y * kCols + w,
                          g1.data() + y * sn2 + x0);
            }
        }
        // Along axis 2, each row contiguous, stored in the output format into its pieces.
        const std::size_t nj = out.y_edges.size() - 1, nk = out.x_edges.size() - 1;
        for (std::size_t j = 0; j < nj; ++j) {
            for (std::size_t y = out.y_edges[j]; y < out.y_edges[j + 1]; ++y) {
                const G* line = g1.data() + y * n2;
                if (n2 > 1) {
                    unit_line<M, G>(line, sn2, 1, row.data(), site.data(), start.data(),
                                    value.data());
                    line = row.data();
                }
                for (std::size_t k = 0; k < nk; ++k) {
                    T* o = piece_row(out, j, k, p, y);
                    for (std::size_t x = out.x_edges[k]; x < out.x_edges[k + 1]; ++x) {
                        *o++ = stored<M, T, G>(line[x], minus_one);
                    }
                }
            }
        }
    }
};

// unit_slab_pieces for one metric, partial type G and first-pass distance type D: the first
// pass a group of planes at a time (the nearest target after each group found first by one
// backward sweep), each group's planes then through UnitPlane. The sweeps along axis 0 go
// piece by piece, their per-line positions kept in the pieces' order (piece i's lines at
// base[i] + its row * its width + its column), so that a piece's positions stay in the
// core's cache while its planes stream by.
template <Metric M, typename G, typename D, typename T>
void unit_slab_groups(Shape3 shape, std::int64_t z0, const Pieces<const std::uint8_t>& targets,
                      std::span<const std::int64_t> before, std::span<const std::int64_t> after,
                      const Pieces<T>& out, bool minus_one) {
    constexpr D none = std::numeric_limits<D>::max();
    const std::size_t planes = shape.n[0], n2 = shape.n[2], lines = shape.n[1] * n2;
    const std::size_t nj = targets.y_edges.size() - 1, nk = targets.x_edges.size() - 1;
    // Groups of `depth` planes: the after-group positions (8 bytes a line per group) and a
    // group's distances (sizeof(D) a line per plane) weigh about the same.
    const auto groups = static_cast<std::size_t>(
        std::clamp(std::lround(std::sqrt(static_cast<double>(planes) * sizeof(D) / 8.0)), 1L,
                   static_cast<long>(planes)));
    const std::size_t depth = (planes + groups - 1) / groups;
    // Piece (j, k): its first line in the pieces' order, first row and column, height, width.
    struct Cell {
        std::size_t base, y0, x0, h, w;
    };
    std::vector<Cell> cells;
    for (std::size_t j = 0, base = 0; j < nj; ++j) {
        for (std::size_t k = 0; k < nk; ++k) {
            const std::size_t y0 = targets.y_edges[j], x0 = targets.x_edges[k];
            const std::size_t h = targets.y_edges[j + 1] - y0, w = targets.x_edges[k + 1] - x0;
            cells.push_back({base, y0, x0, h, w});
            base += h * w;
        }
    }
    // Calls f(piece's targets, its cell) for every piece.
    const auto each = [&](auto&& f) {
        for (std::size_t i = 0; i < cells.size(); ++i) {
            f(targets.data[i], cells[i]);
        }
    };
    // A per-line array of the lines' order as the pieces' order.
    const auto in_pieces = [&](std::span<const std::int64_t> v, std::int64_t* o) {
        each([&](const std::uint8_t*, const Cell& c) {
            for (std::size_t r = 0; r < c.h; ++r) {
                std::copy_n(v.data() + (c.y0 + r) * n2 + c.x0, c.w, o + c.base + r * c.w);
            }
        });
    };
    std::vector<std::int64_t> next(groups * lines), last(lines), at(lines);
    in_pieces(before, last.data());
    in_pieces(after, at.data());
    // next[g]: per line the nearest target at or after the end of group g (-1: none).
    each([&](const std::uint8_t* t, const Cell& c) {
        const std::size_t m = c.h * c.w;
        std::int64_t* a = at.data() + c.base;
        for (std::size_t p = planes; p-- > 0;) {
            if ((p + 1) % depth == 0 || p + 1 == planes) {
                std::copy_n(a, m, next.data() + (p / depth) * lines + c.base);
            }
            const std::int64_t z = z0 + static_cast<std::int64_t>(p);
            const std::uint8_t* tp = t + p * m;
            for (std::size_t q = 0; q < m; ++q) {
                a[q] = tp[q] != 0 ? z : a[q];
            }
        }
    });
    std::vector<D> dist(std::min(depth, planes) * lines);
    UnitPlane<M, G, D, T> plane(shape.n[1], n2);
    for (std::size_t p0 = 0, g = 0; p0 < planes; p0 += depth, ++g) {
        const std::size_t p1 = std::min(planes, p0 + depth);
        each([&](const std::uint8_t* t, const Cell& c) {
            const std::size_t m = c.h * c.w;
            // Forward: the last target at or before each plane; backward: the next at or
            // after. Distances go to the group's planes in the planes' own order.
            std::int64_t* l = last.data() + c.base;
            for (std::size_t p = p0; p < p1; ++p) {
                const std::int64_t z = z0 + static_cast<std::int64_t>(p);
                const std::uint8_t* tp = t + p * m;
                D* dp = dist.data() + (p - p0) * lines + c.y0 * n2 + c.x0;
                for (std::size_t r = 0, q = 0; r < c.h; ++r) {
                    for (std::size_t x = 0; x < c.w; ++x, ++q) {
                        l[q] = tp[q] != 0 ? z : l[q];
                        dp[r * n2 + x] = l[q] < 0 ? none : static_cast<D>(z - l[q]);
                    }
                }
            }
            std::int64_t* a = next.data() + g * lines + c.base;
            for (std::size_t p = p1; p-- > p0;) {
                const std::int64_t z = z0 + static_cast<std::int64_t>(p);
                const std::uint8_t* tp = t + p * m;
                D* dp = dist.data() + (p - p0) * lines + c.y0 * n2 + c.x0;
                for (std::size_t r = 0, q = 0; r < c.h; ++r) {
                    for (std::size_t x = 0; x < c.w; ++x, ++q) {
                        a[q] = tp[q] != 0 ? z : a[q];
                        D& o = dp[r * n2 + x];
                        o = a[q] >= 0 ? std::min(o, static_cast<D>(a[q] - z)) : o;
                    }
                }
            }
        });
        for (std::size_t p = p0; p < p1; ++p) {
            plane.run(dist.data() + (p - p0) * lines, none, out, p, minus_one);
        }
    }
}

template <Metric M, typename T>
void unit_slab_metric(Shape3 shape, std::int64_t z0, std::int64_t length,
                      const Pieces<const std::uint8_t>& targets,
                      std::span<const std::int64_t> before, std::span<const std::int64_t> after,
                      const Pieces<T>& out, bool minus_one) {
    // The largest finite partial: the longest distance along axis 0 (length - 1), then the
    // passes add at most the other axes' extents (L2 their squares).
    const auto d = static_cast<std::uint64_t>(length > 0 ? length - 1 : 0);
    const std::uint64_t e1 = shape.n[1] - 1, e2 = shape.n[2] - 1;
    const std::uint64_t top = M == Metric::euclidean   ? d * d + e1 * e1 + e2 * e2
                              : M == Metric::manhattan ? d + e1 + e2
                                                       : std::max({d, e1, e2});
    const bool narrow = top < static_cast<std::uint64_t>(kNone<std::int32_t>);
    const auto run = [&](auto g, auto dist) {
        unit_slab_groups<M, decltype(g), decltype(dist), T>(shape, z0, targets, before, after, out,
                                                            minus_one);
    };
    if (length < 65535) {
        narrow ? run(std::int32_t{}, std::uint16_t{}) : run(std::int64_t{}, std::uint16_t{});
    } else {
        narrow ? run(std::int32_t{}, std::uint32_t{}) : run(std::int64_t{}, std::uint32_t{});
    }
}

}  // namespace

template <typename T>
void unit_slab_pieces(Metric metric, Shape3 shape, std::int64_t z0, std::int64_t length,
                      Pieces<const std::uint8_t> targets, std::span<const std::int64_t> before,
                      std::span<const std::int64_t> after, Pieces<T> out, bool minus_one) {
    const std::size_t lines = shape.n[1] * shape.n[2];
    const auto edges_fit = [&](const auto& p) {
        const std::size_t nj = p.y_edges.size(), nk = p.x_edges.size();
        if (nj < 2 || nk < 2 || p.y_edges.front() != 0 || p.x_edges.front() != 0 ||
            p.y_edges.back() != shape.n[1] || p.x_edges.back() != shape.n[2] ||
            p.data.size() != (nj - 1) * (nk - 1)) {
            return false;
        }
        return std::is_sorted(p.y_edges.begin(), p.y_edges.end()) &&
               std::is_sorted(p.x_edges.begin(), p.x_edges.end());
    };
    if (!edges_fit(targets) || !edges_fit(out) || before.size() != lines || after.size() != lines) {
        throw std::invalid_argument("unit_slab_pieces: pieces or lines do not match the shape");
    }
    if (z0 < 0 || length < z0 + static_cast<std::int64_t>(shape.n[0])) {
        throw std::invalid_argument("unit_slab_pieces: the slab must lie within [0, length)");
    }
    if (shape.count() == 0) {
        return;
    }
    switch (metric) {
        case Metric::euclidean:
            unit_slab_metric<Metric::euclidean, T>(shape, z0, length, targets, before, after, out,
                                                   minus_one);
            break;
        case Metric::manhattan:
            unit_slab_metric<Metric::manhattan, T>(shape, z0, length, targets, before, after, out,
                                                   minus_one);
            break;
        case Metric::chebyshev:
            unit_slab_metric<Metric::chebyshev, T>(shape, z0, length, targets, before, after, out,
                                                   minus_one);
            break;
    }
}

#define VOXFIELD_UNIT_SLAB(T)                                                                    \
    template void unit_slab_pieces<T>(Metric, Shape3, std::int64_t, std::int64_t,                \
                                      Pieces<const std::uint8_t>, std::span<const std::int64_t>, \
                                      std::span<const std::int64_t>, Pieces<T>, bool);
VOXFIELD_UNIT_SLAB(float)
VOXFIELD_UNIT_SLAB(double)
VOXFIELD_UNIT_SLAB(std::uint8_t)
VOXFIELD_UNIT_SLAB(std::uint16_t)
VOXFIELD_UNIT_SLAB(std::uint32_t)
VOXFIELD_UNIT_SLAB(std::int8_t)
VOXFIELD_UNIT_SLAB(std::int16_t)
VOXFIELD_UNIT_SLAB(std::int32_t)
#undef VOXFIELD_UNIT_SLAB

void axis0_ends(Shape3 shape, std::int64_t z0, std::span<const std::uint8_t> targets,
                std::span<std::int64_t> first, std::span<std::int64_t> last) {
    const std::size_t planes = shape.n[0], lines = shape.n[1] * shape.n[2];
    if (targets.size() != planes * lines || first.size() != lines || last.size() != lines) {
        throw std::invalid_argument("axis0_ends: array sizes do not match the shape");
    }
    // One sweep: every target is the last so far; the first is kept once set.
    std::fill(first.begin(), first.end(), -1);
    std::fill(last.begin(), last.end(), -1);
    for (std::size_t p = 0; p < planes; ++p) {
        const std::int64_t z = z0 + static_cast<std::int64_t>(p);
        const std::uint8_t* t = targets.data() + p * lines;
        for (std::size_t q = 0; q < lines; ++q) {
            last[q] = t[q] != 0 ? z : last[q];
            first[q] = t[q] != 0 && first[q] < 0 ? z : first[q];
        }
    }
}

template <typename T>
void first_pass_values(Metric metric, double spacing, std::span<const T> d, T none,
                       std::span<double> g) {
    if (g.size() != d.size()) {
        throw std::invalid_argument("first_pass_values: array sizes do not match");
    }
    const bool squared = metric == Metric::euclidean;
    for (std::size_t i = 0; i < d.size(); ++i) {
        const double o = spacing * static_cast<double>(d[i]);
        g[i] = d[i] == none ? kInf : (squared ? o * o : o);
    }
}

template void first_pass_values<std::uint16_t>(Metric, double, std::span<const std::uint16_t>,
                                               std::uint16_t, std::span<double>);
template void first_pass_values<std::uint32_t>(Metric, double, std::span<const std::uint32_t>,
                                               std::uint32_t, std::span<double>);
template void axis0_distances<std::uint16_t>(Shape3, std::int64_t, std::span<const std::uint8_t>,
                                             std::span<const std::int64_t>,
                                             std::span<const std::int64_t>, std::uint16_t,
                                             std::span<std::uint16_t>);
template void axis0_distances<std::uint32_t>(Shape3, std::int64_t, std::span<const std::uint8_t>,
                                             std::span<const std::int64_t>,
                                             std::span<const std::int64_t>, std::uint32_t,
                                             std::span<std::uint32_t>);

}  // namespace voxfield::python
