// The compiled core of the Python package `voxfield` (DESIGN §4): `voxfield._core`, whose
// public functions the package re-exports (voxfield/__init__.py), plus the host passes that
// voxfield.ndimage and voxfield.dask build on.
#include <pybind11/numpy.h>
#include <pybind11/pybind11.h>
#include <pybind11/stl.h>
#include <pybind11/stl/filesystem.h>

#include <algorithm>
#include <cmath>
#include <limits>
#include <thread>
#include <type_traits>

#include "common.hpp"
#include "passes.hpp"
#include "transform.hpp"
#include "voxfield/core/error.hpp"

namespace voxfield::python {
namespace {

Shape3 shape3(const py::array& a, const char* what) {
    if (a.ndim() < 1 || a.ndim() > 3) {
        throw py::value_error(std::string(what) + " must have 1 to 3 axes, got shape " +
                              shape_text(a));
    }
    Shape3 s;
    for (py::ssize_t i = 0; i < a.ndim(); ++i) {
        s.n[3 - a.ndim() + i] = static_cast<std::size_t>(a.shape(i));
    }
    return s;
}

unsigned host_threads(const py::object& threads) {
    if (!threads.is_none()) {
        const long t = threads.cast<long>();
        if (t < 1) {
            throw py::value_error("threads must be at least 1, got " + std::to_string(t));
        }
        return static_cast<unsigned>(std::min<long>(t, 1024));
    }
    return std::max(1u, std::thread::hardware_concurrency());
}

// One pass of the separable transform over an array of 1 to 3 axes (see passes.hpp): from
// targets (bool/integer, nonzero = target) when `first`, else from float64 partials.
py::array_t<double> pass_of(const py::object& input, int axis, const std::string& metric,
                            double spacing, bool first, const py::object& threads) {
    const Metric m = parse_metric(metric);
    const py::module_ np = py::module_::import("numpy");
    const py::array a = first ? np.attr("ascontiguousarray")(np.attr("not_equal")(input, 0))
                              : np.attr("ascontiguousarray")(input, "float64");
    const Shape3 s = shape3(a, "the block");
    if (axis < 0 || axis >= a.ndim()) {
        throw py::value_error("axis " + std::to_string(axis) + " is not an axis of shape " +
                              shape_text(a));
    }
    if (!(spacing > 0) || !std::isfinite(spacing)) {
        throw py::value_error("sampling must be positive and finite");
    }
    const int axis3 = axis + 3 - static_cast<int>(a.ndim());
    std::vector<py::ssize_t> shape(a.shape(), a.shape() + a.ndim());
    check_host_bytes(s.count() * sizeof(double), "a block of partial distances");
    py::array_t<double> out(shape);
    const unsigned t = host_threads(threads);
    const std::size_t n = s.count();
    const auto* targets = static_cast<const std::uint8_t*>(a.data());
    const auto* g_in = static_cast<const double*>(a.data());
    double* g_out = out.mutable_data();
    {
        py::gil_scoped_release release;
        voxfield::python::separable_pass(
            m, s, axis3, spacing,
            first ? std::span<const std::uint8_t>(targets, n) : std::span<const std::uint8_t>(),
            first ? std::span<const double>() : std::span<const double>(g_in, n), {g_out, n}, {},
            {}, t);
    }
    return out;
}

// A C-contiguous bool/uint8 view of targets (nonzero = target) of 1 to 3 axes, seen as
// axis 0 and the lines along it.
py::array slab_targets(const py::object& input, Shape3& s) {
    const py::module_ np = py::module_::import("numpy");
    py::array a = np.attr("ascontiguousarray")(input);
    const char kind = a.dtype().kind();
    if (a.dtype().itemsize() != 1 || (kind != 'b' && kind != 'u')) {
        a = np.attr("ascontiguousarray")(np.attr("not_equal")(a, 0));  // bool/uint8 in place
    }
    shape3(a, "the slab");  // 1 to 3 axes
    s = Shape3{};
    s.n[0] = static_cast<std::size_t>(a.shape(0));
    for (py::ssize_t i = 1; i < a.ndim(); ++i) {
        s.n[1] *= static_cast<std::size_t>(a.shape(i));
    }
    return a;
}

// The first and last target along axis 0 of every line of a block (see passes.hpp), stacked
// as a (2, ...) int64 array.
py::array_t<std::int64_t> axis0_ends_of(const py::object& input, std::int64_t z0) {
    Shape3 s;
    const py::array a = slab_targets(input, s);
    std::vector<py::ssize_t> shape{2};
    shape.insert(shape.end(), a.shape() + 1, a.shape() + a.ndim());
    py::array_t<std::int64_t> out(shape);
    const std::size_t lines = s.n[1];
    const std::span<const std::uint8_t> t(static_cast<const std::uint8_t*>(a.data()), s.count());
    std::int64_t* o = out.mutable_data();
    {
        py::gil_scoped_release release;
        voxfield::python::axis0_ends(s, z0, t, {o, lines}, {o + lines, lines});
    }
    return out;
}

// The first pass's distances along axis 0 of a slab of a longer array (see passes.hpp):
// uint16 where every distance of an array of `length` along axis 0 fits below 65535, else
// uint32; the type's largest value where a line has no target.
py::array axis0_distances_of(const py::object& input, const py::object& before,
                             const py::object& after, std::int64_t z0, std::int64_t length,
                             const py::object& into) {
    Shape3 s;
    const py::array a = slab_targets(input, s);
    const py::array_t<std::int64_t, py::array::c_style | py::array::forcecast> b(before), e(after);
    const std::size_t lines = s.n[1] * s.n[2];
    if (static_cast<std::size_t>(b.size()) != lines ||
        static_cast<std::size_t>(e.size()) != lines) {
        throw py::value_error("before and after must hold one position per line of the slab");
    }
    if (z0 < 0 || length < z0 + static_cast<std::int64_t>(s.n[0])) {
        throw py::value_error("the slab must lie within [0, length)");
    }
    std::vector<py::ssize_t> shape(a.shape(), a.shape() + a.ndim());
    const std::size_t n = s.count();
    const std::span<const std::uint8_t> t(static_cast<const std::uint8_t*>(a.data()), n);
    const std::span<const std::int64_t> bs(b.data(), lines), es(e.data(), lines);
    const auto run = [&](auto none) -> py::array {
        using T = decltype(none);
        py::array_t<T> out;
        if (into.is_none()) {
            out = py::array_t<T>(shape);
        } else {
            const py::array o = into;
            if (!py::isinstance<py::array_t<T>>(into) || !(o.flags() & py::array::c_style) ||
                !o.writeable() ||
                std::vector<py::ssize_t>(o.shape(), o.shape() + o.ndim()) != shape) {
                throw py::value_error(std::string("out must be a writable C-contiguous ") +
                                      (sizeof(T) == 2 ? "uint16" : "uint32") +
                                      " array of the slab's shape");
            }
            out = into.cast<py::array_t<T>>();
        }
        const std::span<T> o(out.mutable_data(), n);
        py::gil_scoped_release release;
        voxfield::python::axis0_distances<T>(s, z0, t, bs, es, none, o);
        return out;
    };
    if (length < 65535) {
        return run(std::numeric_limits<std::uint16_t>::max());
    }
    return run(std::numeric_limits<std::uint32_t>::max());
}

// The separable transform of a part of a slab from its first pass's distances along axis 0
// (axis0_distances' output, whole planes): the partials after the passes along every axis.
py::array_t<double> slab_passes_of(const py::array& dist, const std::string& metric,
                                   const std::vector<double>& spacing, const py::object& into,
                                   const py::object& field) {
    const Metric m = parse_metric(metric);
    const Shape3 s = shape3(dist, "the distances");
    if (spacing.size() != static_cast<std::size_t>(dist.ndim())) {
        throw py::value_error("sampling must have one value per axis");
    }
    if (!(dist.flags() & py::array::c_style)) {
        throw py::value_error("the distances must be C-contiguous");
    }
    const std::size_t n = s.count();
    std::vector<py::ssize_t> shape(dist.shape(), dist.shape() + dist.ndim());
    py::array_t<double> out;
    if (into.is_none()) {
        out = py::array_t<double>(shape);
    } else {
        const py::array o = into;
        if (!py::isinstance<py::array_t<double>>(into) || !(o.flags() & py::array::c_style) ||
            !o.writeable() || std::vector<py::ssize_t>(o.shape(), o.shape() + o.ndim()) != shape) {
            throw py::value_error("out must be a writable C-contiguous float64 array of shape " +
                                  shape_text(dist));
        }
        out = into.cast<py::array_t<double>>();
    }
    const bool f32 = py::isinstance<py::array_t<float>>(field);
    if (!field.is_none()) {
        const py::array f = field;
        if ((!f32 && !py::isinstance<py::array_t<double>>(field)) ||
            !(f.flags() & py::array::c_style) || !f.writeable() ||
            std::vector<py::ssize_t>(f.shape(), f.shape() + f.ndim()) != shape) {
            throw py::value_error(
                "field must be a writable C-contiguous float32 or float64 array of shape " +
                shape_text(dist));
        }
    }
    void* const field_out = field.is_none() ? nullptr : py::array(field).mutable_data();
    const std::span<double> g(out.mutable_data(), n);
    const auto first = [&](auto none) {
        using T = decltype(none);
        const std::span<const T> d(static_cast<const T*>(dist.data()), n);
        voxfield::python::first_pass_values<T>(m, spacing[0], d, none, g);
    };
    const bool u16 = py::isinstance<py::array_t<std::uint16_t>>(dist);
    if (!u16 && !py::isinstance<py::array_t<std::uint32_t>>(dist)) {
        throw py::type_error("the distances must be uint16 or uint32 (axis0_distances)");
    }
    py::gil_scoped_release release;
    if (u16) {
        first(std::numeric_limits<std::uint16_t>::max());
    } else {
        first(std::numeric_limits<std::uint32_t>::max());
    }
    const int offset = 3 - static_cast<int>(dist.ndim());
    for (int axis = 1; axis < static_cast<int>(dist.ndim()); ++axis) {
        voxfield::python::separable_pass(
            m, s, axis + offset, spacing[static_cast<std::size_t>(axis)], {}, g, g, {}, {}, 1);
    }
    // The field as the kernels store a float format: L2 the square root, rounded once.
    const auto store = [&](auto* f) {
        using T = std::remove_pointer_t<decltype(f)>;
        for (std::size_t i = 0; i < n; ++i) {
            f[i] = static_cast<T>(m == Metric::euclidean ? std::sqrt(g[i]) : g[i]);
        }
    };
    if (field_out != nullptr && f32) {
        store(static_cast<float*>(field_out));
    } else if (field_out != nullptr) {
        store(static_cast<double*>(field_out));
    }
    return out;
}

// The field of a part of a slab with unit spacing from its first pass's distances along axis 0
// (axis0_distances' output, whole planes), written into `out` (see unit_slab_field), which
// may hold the distances in its tail.
void slab_field_of(const py::array& dist, const std::string& metric, py::array out,
                   bool minus_one) {
    const Metric m = parse_metric(metric);
    shape3(dist, "the distances");
    const std::vector<py::ssize_t> shape(dist.shape(), dist.shape() + dist.ndim());
    if (!(dist.flags() & py::array::c_style)) {
        throw py::value_error("the distances must be C-contiguous");
    }
    if (!(out.flags() & py::array::c_style) || !out.writeable() ||
        std::vector<py::ssize_t>(out.shape(), out.shape() + out.ndim()) != shape) {
        throw py::value_error("out must be a writable C-contiguous array of shape " +
                              shape_text(dist));
    }
    // Planes along axis 0 of the other axes' lines: (n1, n2) for 3 axes, (1, n1) for 2.
    Shape3 s;
    s.n[0] = static_cast<std::size_t>(dist.shape(0));
    if (dist.ndim() == 3) {
        s.n[1] = static_cast<std::size_t>(dist.shape(1));
    }
    if (dist.ndim() >= 2) {
        s.n[2] = static_cast<std::size_t>(dist.shape(dist.ndim() - 1));
    }
    const auto with_out = [&](auto none) {
        using D = decltype(none);
        const D* d = static_cast<const D*>(dist.data());
        const auto run = [&](auto* o) {
            py::gil_scoped_release release;
            voxfield::python::unit_slab_field(m, s, d, none, o, minus_one);
        };
        void* o = out.mutable_data();
        if (py::isinstance<py::array_t<float>>(out)) {
            run(static_cast<float*>(o));
        } else if (py::isinstance<py::array_t<double>>(out)) {
            run(static_cast<double*>(o));
        } else if (py::isinstance<py::array_t<std::uint8_t>>(out)) {
            run(static_cast<std::uint8_t*>(o));
        } else if (py::isinstance<py::array_t<std::uint16_t>>(out)) {
            run(static_cast<std::uint16_t*>(o));
        } else if (py::isinstance<py::array_t<std::uint32_t>>(out)) {
            run(static_cast<std::uint32_t*>(o));
        } else if (py::isinstance<py::array_t<std::int8_t>>(out)) {
            run(static_cast<std::int8_t*>(o));
        } else if (py::isinstance<py::array_t<std::int16_t>>(out)) {
            run(static_cast<std::int16_t*>(o));
        } else if (py::isinstance<py::array_t<std::int32_t>>(out)) {
            run(static_cast<std::int32_t*>(o));
        } else {
            throw py::type_error(
                "out must be float32, float64 or an integer type of 1 to 4 "
                "bytes, not " +
                dtype_name(out.dtype()));
        }
    };
    if (py::isinstance<py::array_t<std::uint16_t>>(dist)) {
        with_out(std::numeric_limits<std::uint16_t>::max());
    } else if (py::isinstance<py::array_t<std::uint32_t>>(dist)) {
        with_out(std::numeric_limits<std::uint32_t>::max());
    } else {
        throw py::type_error("the distances must be uint16 or uint32 (axis0_distances)");
    }
}

// The whole separable transform of targets (1 to 3 axes) on the host: partial distances
// (L2: squared) after passes along every axis in order 0, 1, 2, and the linear index of each
// element's nearest target (-1 without one) when asked.
py::tuple transform_on_host(const py::object& input, const std::string& metric,
                            const std::vector<double>& sampling, bool features,
                            const py::object& threads) {
    const Metric m = parse_metric(metric);
    const py::module_ np = py::module_::import("numpy");
    const py::array a = np.attr("ascontiguousarray")(np.attr("not_equal")(input, 0));
    const Shape3 s = shape3(a, "input");
    if (sampling.size() != static_cast<std::size_t>(a.ndim())) {
        throw py::value_error("sampling must have one value per axis");
    }
    const std::size_t n = s.count();
    check_host_bytes(n * (sizeof(double) + (features ? sizeof(std::int64_t) : 0)),
                     "the transform of shape " + shape_text(a));
    std::vector<py::ssize_t> shape(a.shape(), a.shape() + a.ndim());
    py::array_t<double> g(shape);
    py::object feat = py::none();
    std::int64_t* f = nullptr;
    if (features) {
        py::array_t<std::int64_t> fa(shape);
        f = fa.mutable_data();
        feat = fa;
    }
    const unsigned t = host_threads(threads);
    const auto* targets = static_cast<const std::uint8_t*>(a.data());
    double* gd = g.mutable_data();
    const int offset = 3 - static_cast<int>(a.ndim());
    {
        py::gil_scoped_release release;
        const std::span<std::int64_t> fs =
            f != nullptr ? std::span<std::int64_t>(f, n) : std::span<std::int64_t>();
        for (int axis = 0; axis < static_cast<int>(sampling.size()); ++axis) {
            voxfield::python::separable_pass(
                m, s, axis + offset, sampling[static_cast<std::size_t>(axis)],
                axis == 0 ? std::span<const std::uint8_t>(targets, n)
                          : std::span<const std::uint8_t>(),
                axis == 0 ? std::span<const double>() : std::span<const double>(gd, n), {gd, n},
                axis == 0 ? std::span<const std::int64_t>() : std::span<const std::int64_t>(fs), fs,
                t);
        }
    }
    return py::make_tuple(g, feat);
}

}  // namespace
}  // namespace voxfield::python

PYBIND11_MODULE(_core, m) {
    namespace vp = voxfield::python;
    namespace ocl = voxfield::ocl;
    namespace py = pybind11;
    m.doc() =
        "The compiled core of voxfield: OpenCL distance transforms of voxel worlds. Use the "
        "package `voxfield` (which re-exports the public functions with their documentation), "
        "`voxfield.ndimage` and `voxfield.dask`.";
    m.attr("__version__") = VOXFIELD_VERSION;
    // The docstrings start with hand-written signatures that name the return values.
    py::options options;
    options.disable_function_signatures();

    py::register_exception_translator([](std::exception_ptr p) {
        try {
            if (p) {
                std::rethrow_exception(p);
            }
        } catch (const voxfield::InputError& e) {
            PyErr_SetString(PyExc_ValueError, e.what());
        } catch (const ocl::ClError& e) {
            PyErr_SetString(PyExc_RuntimeError, e.what());
        } catch (const ocl::BuildError& e) {
            PyErr_SetString(PyExc_RuntimeError, e.what());
        }
    });

    m.def("devices", &vp::devices,
          "devices() -> list of dict\n\n"
          "Every OpenCL device of every platform, as `voxfield devices --json` lists them.");
    m.def(
        "device_type",
        [](const py::object& device) { return vp::device_for(device)->context.info().type; },
        py::arg("device") = py::none(),
        "device_type(device=None) -> str\n\n"
        "The type ('cpu', 'gpu', ...) of the device a call with this device= uses (resolved "
        "once, as every call resolves it).");
    m.def("distance_transform", &vp::distance_transform, py::arg("world"),
          py::arg("metric") = "manhattan", py::arg("signed") = false,
          py::arg("sampling") = py::none(), py::arg("return_indices") = false,
          py::arg("max_distance") = py::none(), py::arg("format") = py::none(),
          py::arg("algorithm") = "exact", py::arg("device") = py::none(),
          py::arg("out") = py::none(), py::arg("targets") = "nonzero",
          "distance_transform(world, metric='manhattan', signed=False, sampling=None, "
          "return_indices=False, max_distance=None, format=None, algorithm='exact', "
          "device=None, out=None, targets='nonzero') -> ndarray, or (ndarray, indices)\n\n"
          "See voxfield.distance_transform. `out`: a writable C-contiguous array of the "
          "field's shape and dtype that receives the field (and is returned) instead of a new "
          "one. `targets`: 'nonzero' (the world's solid voxels) or 'zero' (the distance to the "
          "nearest zero voxel, as scipy.ndimage measures it; unsigned fields only).");
    py::class_<vp::Field>(m, "Field", "See voxfield.Field.")
        .def(py::init<const py::object&, const std::string&, const py::object&, const std::string&,
                      const std::optional<std::string>&, const py::object&, bool,
                      const py::object&>(),
             py::arg("world"), py::arg("metric") = "manhattan", py::arg("device") = py::none(),
             py::arg("algorithm") = "exact", py::arg("format") = py::none(), py::kw_only(),
             py::arg("sampling") = py::none(), py::arg("signed") = false,
             py::arg("max_distance") = py::none())
        .def("edit", &vp::Field::edit, py::arg("op"), py::arg("shape"), py::arg("center"),
             py::arg("radius"), py::arg("material") = 1)
        .def("apply_edits", &vp::Field::apply_edits, py::arg("text"))
        .def("undo", &vp::Field::undo)
        .def("redo", &vp::Field::redo)
        .def_property_readonly("can_undo", &vp::Field::can_undo,
                               "bool: Whether undo() has an edit call to take back.")
        .def_property_readonly("can_redo", &vp::Field::can_redo,
                               "bool: Whether redo() has an undone call to apply again.")
        .def("step_sand", &vp::Field::step_sand, py::arg("steps") = 1, py::kw_only(),
             py::arg("seed") = 1, py::arg("sand") = voxfield::SandRules{}.sand,
             py::arg("water") = voxfield::SandRules{}.water)
        .def_property_readonly(
            "sand_steps", &vp::Field::sand_steps,
            "int: How many step_sand() steps this Field has run (the next step's number).")
        .def("distances", &vp::Field::distances)
        .def("world", &vp::Field::world);
    m.def("load_vox", &vp::load_vox, py::arg("path"), "load_vox(path) -> (world, palette)");
    m.def("save_vox", &vp::save_vox, py::arg("path"), py::arg("world"),
          py::arg("palette") = py::none(), "save_vox(path, world, palette=None)");
    m.def("separable_pass", &vp::pass_of, py::arg("input"), py::arg("axis"), py::arg("metric"),
          py::arg("spacing"), py::arg("first"), py::arg("threads") = py::none(),
          "separable_pass(input, axis, metric, spacing, first, threads=None) -> ndarray\n\n"
          "One 1-D pass of the separable transform along `axis` of a 1- to 3-D array, on the "
          "host in float64: from targets (nonzero = target) when `first`, else from the "
          "previous pass's partial distances (L2: squared).");
    m.def("axis0_distances", &vp::axis0_distances_of, py::arg("targets"), py::arg("before"),
          py::arg("after"), py::arg("z0"), py::arg("length"), py::arg("out") = py::none(),
          "axis0_distances(targets, before, after, z0, length, out=None) -> ndarray\n\n"
          "The distance along axis 0, in voxels, from every element of a slab [z0, z0 + n) of "
          "an array of `length` along axis 0 to the nearest target (nonzero) on its line, given "
          "per line the nearest target's position before the slab and after it (negative: "
          "none): uint16 where length < 65535, else uint32, the type's largest value where "
          "the line has none; into `out` (that type, the slab's shape) when given.");
    m.def("axis0_ends", &vp::axis0_ends_of, py::arg("targets"), py::arg("z0"),
          "axis0_ends(targets, z0) -> ndarray\n\n"
          "The first and the last target (nonzero) along axis 0 of every line of a block whose "
          "plane 0 is plane z0 of a longer array, as positions in that array (-1: none), "
          "stacked as a (2, ...) int64 array.");
    m.def("slab_passes", &vp::slab_passes_of, py::arg("distances"), py::arg("metric"),
          py::arg("sampling"), py::arg("out") = py::none(), py::arg("field") = py::none(),
          "slab_passes(distances, metric, sampling, out=None, field=None) -> ndarray\n\n"
          "The partial distances (L2: squared), float64, after every pass of the separable "
          "transform of whole planes of a slab, from axis0_distances' output for them: the "
          "first pass's values along axis 0, then a host pass along each other axis; into "
          "`out` (float64, the distances' shape) when given; `field` (float32 or float64, that "
          "shape): also the field there (L2: the square root), rounded once.");
    m.def("slab_field", &vp::slab_field_of, py::arg("distances"), py::arg("metric"), py::arg("out"),
          py::arg("minus_one") = false,
          "slab_field(distances, metric, out, minus_one=False) -> None\n\n"
          "The field of whole planes of a slab with unit sampling, from axis0_distances' "
          "output for them: the passes along the other axes in exact integer arithmetic, "
          "written into `out` (the distances' shape; float32, float64 or an integer type) as "
          "the kernels store that format; `minus_one`: -1 where no target is reachable (SciPy's "
          "cdt). `out` may hold the distances in its tail.");
    m.def("host_transform", &vp::transform_on_host, py::arg("input"), py::arg("metric"),
          py::arg("sampling"), py::arg("features"), py::arg("threads") = py::none(),
          "host_transform(input, metric, sampling, features, threads=None) -> (g, features)\n\n"
          "The separable transform of targets (nonzero = target) on the host in float64: "
          "distances (L2: squared) and, when asked, the linear index of each element's "
          "nearest target (-1 without one).");
}
