#pragma once
// The separable transforms' 1-D passes on the host, in double precision (DESIGN §4): what
// voxfield.dask runs block by block with each block spanning whole lines of one axis, and what
// voxfield.ndimage runs for float64 distances with non-unit sampling (the device's sampled
// kernels carry float32 partial distances).
//
// A pass along one axis turns per-voxel partial distances g into
//   L2:    g'(i) = min_j g(j) + (s (i - j))^2      (squared distances)
//   L1:    g'(i) = min_j g(j) + s |i - j|
//   L-inf: g'(i) = min_j max(g(j), s |i - j|)
// over the positions j of the voxel's line; the first pass starts from the targets (g = 0 on
// a target, +inf elsewhere). After passes along every axis, g is the distance to the nearest
// target (L2: its square). Each candidate's value is computed as written above, so for unit
// sampling every value is an exact integer and any order of axes gives the same field; the
// sum order of an L2 value is that of its passes (SciPy adds axis 0, 1, 2 in turn).
#include <cstddef>
#include <cstdint>
#include <span>

#include "voxfield/core/metric.hpp"

namespace voxfield::python {

// A C-contiguous array of up to 3 axes seen as (n0, n1, n2).
struct Shape3 {
    std::size_t n[3] = {1, 1, 1};
    std::size_t count() const { return n[0] * n[1] * n[2]; }
};

// One pass along `axis` of `shape`: from `targets` (nonzero = target; `g_in` empty) or from
// the partials `g_in`, into `g_out` (may equal g_in). `feat_in`/`feat_out` (optional, empty to
// skip): the linear index of each voxel's nearest target, -1 without one; the first pass
// makes it from the targets. `threads` >= 1 lines in parallel.
void separable_pass(Metric metric, Shape3 shape, int axis, double spacing,
                    std::span<const std::uint8_t> targets, std::span<const double> g_in,
                    std::span<double> g_out, std::span<const std::int64_t> feat_in,
                    std::span<std::int64_t> feat_out, unsigned threads);

// The first pass's distances along axis 0, in voxels, of a slab [z0, z0 + shape.n[0]) of a
// longer array (voxfield.dask's unbounded scheme): for every voxel the distance to the nearest
// target on its line, from the slab's `targets` (nonzero = target) and, per line of the slab
// (shape.n[1] * shape.n[2] of them, in order), the global position of the nearest target
// before the slab (`before`, negative: none) and after it (`after`, negative: none). `out`
// gets the distance, or `none` (which must exceed every distance) where the line has no target.
template <typename T>
void axis0_distances(Shape3 shape, std::int64_t z0, std::span<const std::uint8_t> targets,
                     std::span<const std::int64_t> before, std::span<const std::int64_t> after,
                     T none, std::span<T> out);

// An array of shape (n0, n1, n2) held in pieces (voxfield.dask's blocks of a slab): piece
// j * (x_edges.size() - 1) + k holds rows [y_edges[j], y_edges[j + 1]) and columns
// [x_edges[k], x_edges[k + 1]) of every plane, C-contiguous (n0, rows, columns).
template <typename X>
struct Pieces {
    std::span<X* const> data;
    std::span<const std::size_t> y_edges, x_edges;
};

// voxfield.dask's unbounded slab [z0, z0 + shape.n[0]) of an array of `length` planes, with
// unit spacing, in exact integer arithmetic: the first pass along axis 0 from the slab's
// `targets` (nonzero) and each line's nearest targets before / after the slab (`before`,
// `after`, as for axis0_distances), then the passes along axes 1 and 2 of each plane
// (Meijster, Roerdink & Hesselink's second phase, 32- or 64-bit partials), a group of planes
// at a time (no slab-sized buffer), stored into `out` as the kernels store format T: floats
// the distance (L2: the square root of the exact squared distance, rounded once), integers
// its floor saturated at T's largest value; with `minus_one` (SciPy's cdt) -1 where no target
// is reachable. `targets` and `out` may be pieced differently.
template <typename T>
void unit_slab_pieces(Metric metric, Shape3 shape, std::int64_t z0, std::int64_t length,
                      Pieces<const std::uint8_t> targets, std::span<const std::int64_t> before,
                      std::span<const std::int64_t> after, Pieces<T> out, bool minus_one);

// The first and the last target (nonzero) along axis 0 of every line of a block of
// shape.n[0] planes of shape.n[1] * shape.n[2] lines, as global positions z0 + plane; -1
// where a line has none.
void axis0_ends(Shape3 shape, std::int64_t z0, std::span<const std::uint8_t> targets,
                std::span<std::int64_t> first, std::span<std::int64_t> last);

// The first pass's partial distances from those distances in voxels along its axis (`none`:
// no target, +inf): L2 (spacing d)^2, L1 and L-inf spacing d, as separable_pass computes them.
template <typename T>
void first_pass_values(Metric metric, double spacing, std::span<const T> d, T none,
                       std::span<double> g);

}  // namespace voxfield::python
