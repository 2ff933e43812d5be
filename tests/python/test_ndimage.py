"""voxfield.ndimage against scipy.ndimage: every dtype, layout, dimension, metric, sampling
and output-array combination (PoCL, VOXFIELD_DEVICE=cpu)."""

import numpy as np
import pytest
from scipy import ndimage as sp

from voxfield import ndimage as vf

DTYPES = [np.bool_, np.uint8, np.int8, np.uint16, np.int32, np.int64, np.float32, np.float64,
          np.complex64, ">i2"]
SHAPES = [(1,), (17,), (6, 9), (1, 13), (5, 7, 8), (9, 1, 6)]


def random_input(shape, density, seed, dtype=np.uint8):
    """Nonzero with probability `density` (values of the dtype), at least one zero."""
    rng = np.random.default_rng(seed)
    a = (rng.random(shape) < density) * rng.integers(1, 100, size=shape)
    a.flat[rng.integers(0, a.size)] = 0
    return a.astype(dtype)


def layouts(a):
    """The same values as C, Fortran, negative-stride and strided-view arrays."""
    yield "C", np.ascontiguousarray(a)
    yield "F", np.asfortranarray(a)
    flipped = np.ascontiguousarray(a[(slice(None, None, -1),) * a.ndim])
    yield "negative", flipped[(slice(None, None, -1),) * a.ndim]
    big = np.zeros(tuple(2 * n for n in a.shape), a.dtype)
    big[(slice(None, None, 2),) * a.ndim] = a
    yield "view", big[(slice(None, None, 2),) * a.ndim]


def check_indices_name_a_nearest_zero(input, indices, distances, sampling=None):
    """indices point at zero elements whose distance is the one returned."""
    a = np.asarray(input)
    assert indices.dtype == np.int32 and indices.shape == (a.ndim,) + a.shape
    assert np.all(a[tuple(indices)] == 0)
    s = np.ones(a.ndim) if sampling is None else np.broadcast_to(sampling, (a.ndim,))
    d = (indices - np.indices(a.shape)).astype(np.float64)
    for axis in range(a.ndim):
        d[axis] *= s[axis]
    np.testing.assert_array_max_ulp(np.sqrt((d * d).sum(axis=0)), distances, maxulp=2)


@pytest.mark.parametrize("dtype", DTYPES, ids=str)
def test_edt_bit_for_bit_over_dtypes_layouts_and_dims(dtype):
    for i, shape in enumerate(SHAPES):
        for density in (0.5, 0.97):
            a = random_input(shape, density, 10 * i + int(density * 10), dtype)
            want = sp.distance_transform_edt(a)
            for name, b in layouts(a):
                got = vf.distance_transform_edt(b)
                assert got.dtype == np.float64 and got.shape == shape, name
                np.testing.assert_array_equal(got, want, err_msg=f"{shape} {name}")


@pytest.mark.parametrize("metric", ["chessboard", "taxicab", "cityblock", "manhattan"])
def test_cdt_equals_scipy_over_dims_and_layouts(metric):
    for i, shape in enumerate(SHAPES):
        for dtype in (np.bool_, np.int16, np.float64):
            a = random_input(shape, 0.8, 7 * i, dtype)
            want = sp.distance_transform_cdt(a, metric=metric)
            for name, b in layouts(a):
                got = vf.distance_transform_cdt(b, metric=metric)
                assert got.dtype == np.int32, name
                np.testing.assert_array_equal(got, want, err_msg=f"{shape} {name}")


def test_cdt_structuring_elements():
    a = random_input((6, 7, 8), 0.8, 3)
    for rank_conn, name in ((1, "taxicab"), (3, "chessboard")):
        st = sp.generate_binary_structure(3, rank_conn)
        np.testing.assert_array_equal(vf.distance_transform_cdt(a, metric=st),
                                      sp.distance_transform_cdt(a, metric=name))
    with pytest.raises(ValueError, match="taxicab and chessboard"):
        vf.distance_transform_cdt(a, metric=sp.generate_binary_structure(3, 2))
    with pytest.raises(RuntimeError, match="invalid metric"):
        vf.distance_transform_cdt(a, metric="euclidean")
    with pytest.raises(RuntimeError, match="sizes must be equal to 3"):
        vf.distance_transform_cdt(a, metric=np.ones((3, 3, 5)))


@pytest.mark.parametrize("sampling", [2.0, (1.5, 0.7, 2.0), (0.3, 4.0, 1.7), (1, 1, 3),
                                      [1e-3, 7.0, 1.0]])
def test_edt_sampling_within_two_ulp(sampling):
    for seed, density in ((1, 0.5), (2, 0.95), (3, 0.999)):
        a = random_input((11, 12, 13), density, seed)
        want = sp.distance_transform_edt(a, sampling=sampling)
        got, idx = vf.distance_transform_edt(a, sampling=sampling, return_indices=True)
        np.testing.assert_array_max_ulp(got, want, maxulp=2)
        check_indices_name_a_nearest_zero(a, idx, got, sampling)
    for shape in ((20,), (9, 10)):
        a = random_input(shape, 0.7, 4)
        s = sampling if np.ndim(sampling) == 0 else list(sampling)[:len(shape)]
        np.testing.assert_array_max_ulp(vf.distance_transform_edt(a, sampling=s),
                                        sp.distance_transform_edt(a, sampling=s), maxulp=2)


def test_unit_sampling_given_explicitly_is_bit_for_bit():
    a = random_input((10, 11, 12), 0.9, 9)
    np.testing.assert_array_equal(vf.distance_transform_edt(a, sampling=(1, 1, 1)),
                                  sp.distance_transform_edt(a))


def test_indices_name_a_nearest_zero_for_both_transforms():
    for i, shape in enumerate(SHAPES):
        a = random_input(shape, 0.8, 100 + i)
        d, idx = vf.distance_transform_edt(a, return_indices=True)
        want_d, want_i = sp.distance_transform_edt(a, return_indices=True)
        np.testing.assert_array_equal(d, want_d)
        np.testing.assert_array_equal(idx, want_i)
        for metric, norm in (("taxicab", 1), ("chessboard", np.inf)):
            d, idx = vf.distance_transform_cdt(a, metric=metric, return_indices=True)
            assert idx.dtype == np.int32 and idx.shape == (a.ndim,) + a.shape
            assert np.all(a[tuple(idx)] == 0)
            off = idx - np.indices(a.shape)
            np.testing.assert_array_equal(np.linalg.norm(off, ord=norm, axis=0)
                                          if a.ndim else off, d)


def test_output_arrays_as_scipy():
    a = random_input((7, 8, 9), 0.8, 5)
    want_d, want_i = sp.distance_transform_edt(a, return_indices=True)
    dist = np.empty(a.shape, np.float64)
    assert vf.distance_transform_edt(a, distances=dist) is None
    np.testing.assert_array_equal(dist, want_d)
    ind = np.empty((3,) + a.shape, np.int32)
    dist2 = np.empty(a.shape, np.float64)
    assert vf.distance_transform_edt(a, return_indices=True, distances=dist2, indices=ind) is None
    np.testing.assert_array_equal(dist2, want_d)
    np.testing.assert_array_equal(ind, want_i)
    ind2 = np.empty((3,) + a.shape, np.int32)
    got = vf.distance_transform_edt(a, return_indices=True, indices=ind2)
    np.testing.assert_array_equal(got, want_d)
    np.testing.assert_array_equal(ind2, ind)
    only = vf.distance_transform_edt(a, return_distances=False, return_indices=True)
    np.testing.assert_array_equal(only, ind)
    cd = np.empty(a.shape, np.int32)
    assert vf.distance_transform_cdt(a, distances=cd) is None
    np.testing.assert_array_equal(cd, sp.distance_transform_cdt(a))
    ci = np.empty((3,) + a.shape, np.int32)
    got = vf.distance_transform_cdt(a, metric="taxicab", return_indices=True, indices=ci)
    np.testing.assert_array_equal(got, sp.distance_transform_cdt(a, metric="taxicab"))


def test_output_arrays_written_in_place_or_copied_into():
    # C-contiguous output arrays are the device's output; other layouts get a copy. Either way
    # they hold SciPy's values, with and without a zero in the input, in 1 to 3 dimensions.
    for shape in ((13,), (6, 9), (5, 7, 8)):
        for density in (0.8, 1.0):
            a = random_input(shape, density, 6) if density < 1 else np.ones(shape, np.uint8)
            want_e = sp.distance_transform_edt(a)
            for metric in ("taxicab", "chessboard"):
                want_c = sp.distance_transform_cdt(a, metric=metric)
                for name, cd in layouts(np.zeros(shape, np.int32)):
                    cd[...] = 7
                    assert vf.distance_transform_cdt(a, metric=metric, distances=cd) is None
                    np.testing.assert_array_equal(cd, want_c, err_msg=f"{name} {metric}")
                np.testing.assert_array_equal(vf.distance_transform_cdt(a, metric=metric),
                                              want_c)
            for name, dist in layouts(np.zeros(shape)):
                dist[...] = 7
                assert vf.distance_transform_edt(a, distances=dist) is None
                np.testing.assert_array_equal(dist, want_e, err_msg=f"{name} {shape}")
            np.testing.assert_array_equal(vf.distance_transform_edt(a), want_e)
    core = __import__("voxfield")._core
    world = np.zeros((2, 3, 4), np.uint8)
    world[1, 2, 3] = 1
    into = np.empty((2, 3, 4), np.float32)
    got = core.distance_transform(world, "euclidean", format="f32", out=into)
    assert got is into or np.shares_memory(got, into)
    np.testing.assert_array_equal(into, sp.distance_transform_edt(world == 0).astype(np.float32))
    for bad, error, match in ((np.empty((2, 3, 4)), ValueError, "dtype"),
                              (np.empty((2, 4, 3), np.float32), ValueError, "shape"),
                              (np.empty((4, 3, 2), np.float32).T, ValueError, "C-contiguous"),
                              ([0.0] * 24, TypeError, "numpy array")):
        with pytest.raises(error, match=match):
            core.distance_transform(world, "euclidean", format="f32", out=bad)


def test_zero_size_and_no_zero_inputs_as_scipy():
    for shape in ((0,), (0, 3), (2, 0, 4)):
        a = np.zeros(shape)
        for f in (vf.distance_transform_edt, vf.distance_transform_cdt):
            g = getattr(sp, f.__name__)
            got, gi = f(a, return_indices=True)
            want, wi = g(a, return_indices=True)
            assert got.dtype == want.dtype and got.shape == want.shape
            assert gi.dtype == wi.dtype and gi.shape == wi.shape
    for shape in ((3,), (2, 3), (2, 2, 3)):
        a = np.ones(shape)
        for kw in ({}, {"sampling": 2}):
            got, gi = vf.distance_transform_edt(a, return_indices=True, **kw)
            want, wi = sp.distance_transform_edt(a, return_indices=True, **kw)
            np.testing.assert_array_equal(got, want)
            np.testing.assert_array_equal(gi, wi)
        got, gi = vf.distance_transform_cdt(a, return_indices=True)
        want, wi = sp.distance_transform_cdt(a, return_indices=True)
        np.testing.assert_array_equal(got, want)
        np.testing.assert_array_equal(gi, wi)
    np.testing.assert_array_equal(vf.distance_transform_edt(np.array(3)),
                                  sp.distance_transform_edt(np.array(3)))


def test_array_likes():
    a = [[1, 1, 0], [1, 1, 1], [0, 1, 1]]
    np.testing.assert_array_equal(vf.distance_transform_edt(a), sp.distance_transform_edt(a))
    np.testing.assert_array_equal(vf.distance_transform_cdt(a), sp.distance_transform_cdt(a))
    np.testing.assert_array_equal(vf.distance_transform_edt([True, False, True]),
                                  sp.distance_transform_edt([True, False, True]))


ERRORS = [
    (dict(return_distances=False), RuntimeError, "at least one"),
    (dict(distances=np.zeros((4, 5), np.float64), return_distances=False), RuntimeError,
     "return_distances must be True"),
    (dict(indices=np.zeros((2, 4, 5), np.int32)), RuntimeError, "return_indices must be True"),
    (dict(distances=np.zeros((4, 5), np.float32)), RuntimeError, "must be float64"),
    (dict(distances=np.zeros((5, 4))), RuntimeError, "wrong shape"),
    (dict(return_indices=True, indices=np.zeros((2, 4, 5), np.int64)), RuntimeError,
     "must be int32"),
    (dict(return_indices=True, indices=np.zeros((3, 4, 5), np.int32)), RuntimeError,
     "wrong shape"),
    (dict(sampling=(1, 2, 3)), RuntimeError, "length equal to input rank"),
    (dict(sampling="12"), TypeError, "string"),
    (dict(sampling=(1, 0)), ValueError, "positive"),
    (dict(device="tpu"), ValueError, "tpu"),
]


@pytest.mark.parametrize("kwargs,error,match", ERRORS)
def test_edt_errors(kwargs, error, match):
    a = random_input((4, 5), 0.8, 1)
    with pytest.raises(error, match=match):
        vf.distance_transform_edt(a, **kwargs)
    scipy_kwargs = {k: v for k, v in kwargs.items() if k != "device"}
    if error is RuntimeError:
        with pytest.raises(RuntimeError):
            sp.distance_transform_edt(a, **scipy_kwargs)


def test_cdt_errors_and_more_than_three_axes():
    a = random_input((4, 5), 0.8, 1)
    with pytest.raises(RuntimeError, match="int32 type"):
        vf.distance_transform_cdt(a, distances=np.zeros((4, 5)))
    with pytest.raises(RuntimeError, match="wrong shape"):
        vf.distance_transform_cdt(a, distances=np.zeros((5, 4), np.int32))
    with pytest.raises(RuntimeError, match="at least one"):
        vf.distance_transform_cdt(a, return_distances=False)
    with pytest.raises(ValueError, match="1-D to 3-D"):
        vf.distance_transform_edt(np.ones((2, 2, 2, 2)))
    with pytest.raises(ValueError, match="1-D to 3-D"):
        vf.distance_transform_cdt(np.ones((2, 2, 2, 2)))


def test_device_keyword():
    a = random_input((5, 6, 7), 0.8, 2)
    want = sp.distance_transform_edt(a)
    for device in (None, "cpu", 0):
        np.testing.assert_array_equal(vf.distance_transform_edt(a, device=device), want)


def test_indices_break_ties_as_scipy():
    """SciPy's sites among equally near zeros: the device's passes with unit sampling, the
    host passes with other sampling; dense worlds are full of ties."""
    for i, shape in enumerate(SHAPES + [(16, 16, 16), (40, 1, 37), (3, 200, 5), (24, 30, 28)]):
        for density in (0.5, 0.8, 0.95):
            a = random_input(shape, density, 200 + i)
            for sampling in (None, 2.0, (1, 1, 3)[-len(shape):]):
                got_d, got_i = vf.distance_transform_edt(a, sampling=sampling,
                                                         return_indices=True, device="cpu")
                want_d, want_i = sp.distance_transform_edt(a, sampling=sampling,
                                                           return_indices=True)
                np.testing.assert_array_equal(got_i, want_i, err_msg=f"{shape} {sampling}")
                np.testing.assert_array_equal(got_d, want_d)


@pytest.mark.parametrize("dtype", DTYPES, ids=str)
def test_indices_on_the_device_over_dtypes_layouts_and_dims(dtype):
    """Unit sampling with indices, every dtype, layout and dimension, into given outputs:
    SciPy's distances and indices bit for bit (the device's in-place index planes are tested
    in tests/cl/separable_test.cpp)."""
    for i, shape in enumerate(SHAPES + [(70, 3, 40), (2, 90, 33)]):
        for density in (0.02, 0.5, 0.97):
            a = random_input(shape, density, 300 + 10 * i + int(density * 10), dtype)
            want, want_i = sp.distance_transform_edt(a, return_indices=True)
            for name, b in layouts(a):
                d, idx = vf.distance_transform_edt(b, return_indices=True, device="cpu")
                np.testing.assert_array_equal(d, want, err_msg=f"{shape} {name}")
                np.testing.assert_array_equal(idx, want_i, err_msg=f"{shape} {name}")
                dist = np.full(shape, 7.0)
                ind = np.full((len(shape),) + shape, 7, np.int32)
                assert vf.distance_transform_edt(b, return_indices=True, distances=dist,
                                                 indices=ind, device="cpu") is None
                np.testing.assert_array_equal(dist, want, err_msg=f"{shape} {name}")
                np.testing.assert_array_equal(ind, idx, err_msg=f"{shape} {name}")


def test_core_zero_targets():
    """_core.distance_transform(targets='zero') measures to the zero voxels: read in place
    (uint8, bool), or through an inverted copy (wider labels, the L1 / L-inf sweeps)."""
    core = __import__("voxfield")._core
    rng = np.random.default_rng(17)
    world = (rng.random((9, 23, 31)) < 0.3) * rng.integers(1, 300, size=(9, 23, 31))
    for dtype in (np.uint8, np.bool_, np.int16, np.uint32):
        w = world.astype(dtype)
        inverted = (w == 0).astype(np.uint8)
        for metric, fmt in (("euclidean", "f64"), ("euclidean", "f32"), ("manhattan", "u32"),
                            ("chebyshev", "u16"), ("manhattan", "f64")):
            want = core.distance_transform(inverted, metric, format=fmt, device="cpu")
            got = core.distance_transform(w, metric, format=fmt, device="cpu", targets="zero")
            np.testing.assert_array_equal(got, want, err_msg=f"{dtype} {metric} {fmt}")
        wd, wi = core.distance_transform(inverted, "euclidean", format="f64",
                                         return_indices=True, device="cpu")
        gd, gi = core.distance_transform(w, "euclidean", format="f64", return_indices=True,
                                         device="cpu", targets="zero")
        np.testing.assert_array_equal(gd, wd)
        np.testing.assert_array_equal(gi, wi)
    with pytest.raises(ValueError, match="targets"):
        core.distance_transform(inverted, "euclidean", targets="solid")
    with pytest.raises(ValueError, match="signed=False"):
        core.distance_transform(inverted, "euclidean", signed=True, targets="zero")
