"""The Python module `voxfield` against SciPy's distance transforms, on PoCL (VOXFIELD_DEVICE=cpu).

Every field is compared with scipy.ndimage on random grids: manhattan with distance_transform_cdt
(taxicab), chebyshev with cdt (chessboard), euclidean with distance_transform_edt rounded to
float32, sampling with edt(sampling=...), signed fields with edt(~solid) - edt(solid) on the
world padded by one empty voxel (DESIGN §3); plus the feature transform, Field edits, .vox IO
and every kind of bad input.
"""

import os
import threading

import numpy as np
import pytest
from scipy import ndimage

import voxfield

REPO = os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__))))
ARMY = os.path.join(REPO, "data", "vox", "chr_army1.vox")

# Few distinct shapes: PoCL compiles each kernel again for each work-group shape a grid needs.
A = (13, 17, 19)
SHAPES = [A, (1, 9, 30)]


@pytest.mark.skipif("VOXFIELD_TEST_INSTALLED" not in os.environ,
                    reason="only when pip_install_check.py runs the suite on an installed package")
def test_the_installed_package_is_the_one_under_test():
    """Under pip_install_check.py the suite must import the package pip installed."""
    prefix = os.path.realpath(os.environ["VOXFIELD_TEST_INSTALLED"])
    module = os.path.realpath(voxfield.__file__)
    assert module.startswith(prefix + os.sep) and "site-packages" in module, module
    assert os.path.realpath(voxfield._core.__file__).startswith(prefix + os.sep)


def random_world(shape, density, seed):
    """uint8 (Z, Y, X) with about `density` solid voxels of random materials, at least one."""
    rng = np.random.default_rng(seed)
    world = np.where(rng.random(shape) < density, rng.integers(1, 256, size=shape), 0)
    world = world.astype(np.uint8)
    world.flat[rng.integers(0, world.size)] = 7
    return world


def worlds():
    for i, shape in enumerate(SHAPES):
        for density in (0.003, 0.3):
            yield random_world(shape, density, 1000 * i + int(density * 1000))


def l1(a):
    return np.abs(a).sum(axis=0)


def test_import_and_devices():
    assert voxfield.__version__
    devices = voxfield.devices()
    assert any(d["type"] == "cpu" for d in devices)
    for d in devices:
        for key in ("index", "name", "platform", "type", "vendor", "version", "available"):
            assert key in d
    assert [d["index"] for d in devices] == list(range(len(devices)))


def test_manhattan_equals_cdt_taxicab():
    for world in worlds():
        ours = voxfield.distance_transform(world)
        assert ours.dtype == np.uint16 and ours.shape == world.shape
        theirs = ndimage.distance_transform_cdt(world == 0, metric="taxicab")
        np.testing.assert_array_equal(ours, theirs)


def test_chebyshev_equals_cdt_chessboard():
    for world in worlds():
        ours = voxfield.distance_transform(world, metric="chebyshev")
        assert ours.dtype == np.uint16
        theirs = ndimage.distance_transform_cdt(world == 0, metric="chessboard")
        np.testing.assert_array_equal(ours, theirs)


def test_euclidean_equals_edt_within_one_ulp():
    for world in worlds():
        ours = voxfield.distance_transform(world, metric="euclidean")
        assert ours.dtype == np.float32
        theirs = ndimage.distance_transform_edt(world == 0).astype(np.float32)
        np.testing.assert_array_max_ulp(ours, theirs, maxulp=1)


def test_euclidean_sampling_equals_edt_sampling():
    world = random_world(A, 0.02, 5)
    for sampling in [(1.0, 1.0, 1.0), (2.5, 1.0, 0.5), (0.3, 4.0, 1.7)]:
        ours = voxfield.distance_transform(world, metric="euclidean", sampling=sampling)
        theirs = ndimage.distance_transform_edt(world == 0, sampling=sampling)
        np.testing.assert_array_max_ulp(ours, theirs.astype(np.float32), maxulp=1)
    scalar = voxfield.distance_transform(world, metric="euclidean", sampling=0.75)
    np.testing.assert_array_equal(
        scalar, voxfield.distance_transform(world, metric="euclidean", sampling=[0.75] * 3))


def test_sampling_is_array_order_for_l1_and_linf():
    """A brute-force scan: sampling (z, y, x) scales the offset along array axis 0, 1, 2."""
    world = random_world(A, 0.01, 9)
    sampling = np.array([3.0, 0.5, 1.25])
    solids = np.argwhere(world != 0)
    cells = np.indices(world.shape).reshape(3, -1).T
    offsets = np.abs(cells[:, None, :] - solids[None, :, :]) * sampling
    for metric, reduce in (("manhattan", np.sum), ("chebyshev", np.max)):
        want = reduce(offsets, axis=2).min(axis=1).reshape(world.shape)
        ours = voxfield.distance_transform(world, metric=metric, sampling=tuple(sampling),
                                           format="f64")
        assert ours.dtype == np.float64
        np.testing.assert_allclose(ours, want, rtol=0, atol=1e-12)
        # The default format with a non-unit sampling is f32.
        assert voxfield.distance_transform(world, metric=metric, sampling=sampling).dtype == \
            np.float32


def test_return_indices_name_a_nearest_solid():
    for world in worlds():
        for metric in ("manhattan", "chebyshev", "euclidean"):
            field, idx = voxfield.distance_transform(world, metric=metric, return_indices=True)
            assert idx.dtype == np.int32 and idx.shape == (3,) + world.shape
            assert (world[idx[0], idx[1], idx[2]] != 0).all()
            offset = idx - np.indices(world.shape)
            if metric == "manhattan":
                np.testing.assert_array_equal(l1(offset), field)
            elif metric == "chebyshev":
                np.testing.assert_array_equal(np.abs(offset).max(axis=0), field)
            else:
                d = np.sqrt((offset.astype(np.float64) ** 2).sum(axis=0)).astype(np.float32)
                np.testing.assert_array_max_ulp(d, field, maxulp=1)
                edt = ndimage.distance_transform_edt(world == 0, return_indices=True)[0]
                np.testing.assert_array_max_ulp(field, edt.astype(np.float32), maxulp=1)


def test_return_indices_with_sampling():
    world = random_world(A, 0.03, 21)
    sampling = (2.0, 0.5, 1.0)
    field, idx = voxfield.distance_transform(world, metric="euclidean", sampling=sampling,
                                             return_indices=True)
    offset = (idx - np.indices(world.shape)) * np.array(sampling)[:, None, None, None]
    d = np.sqrt((offset ** 2).sum(axis=0)).astype(np.float32)
    np.testing.assert_array_max_ulp(d, field, maxulp=1)


def padded_signed(world, transform):
    solid = np.pad(world != 0, 1, constant_values=False)
    inner = (slice(1, -1),) * 3
    return (transform(~solid) - transform(solid))[inner]


def test_signed_equals_padded_edt_difference():
    full = np.ones(A, np.uint8)
    for world in list(worlds()) + [full]:
        ours = voxfield.distance_transform(world, metric="euclidean", signed=True)
        assert ours.dtype == np.float32
        want = padded_signed(world, ndimage.distance_transform_edt).astype(np.float32)
        np.testing.assert_array_max_ulp(ours, want, maxulp=1)
        assert (ours != 0).all()
    for metric, cdt in (("manhattan", "taxicab"), ("chebyshev", "chessboard")):
        for world in list(worlds()) + [full]:
            ours = voxfield.distance_transform(world, metric=metric, signed=True)
            assert ours.dtype == np.int16
            want = padded_signed(world, lambda m: ndimage.distance_transform_cdt(m, metric=cdt))
            np.testing.assert_array_equal(ours, want)


def test_bounded_fields_saturate_at_max_distance():
    for world in worlds():
        mask = world == 0
        ours = voxfield.distance_transform(world, max_distance=4)
        assert ours.dtype == np.uint16
        cdt = ndimage.distance_transform_cdt(mask, metric="taxicab")
        np.testing.assert_array_equal(ours, np.minimum(cdt, 4))
        ours = voxfield.distance_transform(world, metric="euclidean", max_distance=2.5)
        edt = np.minimum(ndimage.distance_transform_edt(mask), 2.5).astype(np.float32)
        np.testing.assert_array_max_ulp(ours, edt, maxulp=1)


def test_empty_world_saturates():
    world = np.zeros(A, np.uint8)
    assert (voxfield.distance_transform(world) == 65535).all()
    assert (voxfield.distance_transform(world, format="u8") == 255).all()
    assert (voxfield.distance_transform(world, format="u32") == 2**32 - 1).all()
    assert np.isposinf(voxfield.distance_transform(world, metric="euclidean")).all()
    field, idx = voxfield.distance_transform(world, metric="chebyshev", return_indices=True)
    assert (field == 65535).all() and (idx == -1).all()
    # SciPy's cdt has no zero to measure to here and returns -1: the one case that differs.
    assert (ndimage.distance_transform_cdt(world == 0, metric="taxicab") == -1).all()


def test_every_format_has_its_dtype_and_saturates():
    world = np.zeros((2, 3, 300), np.uint8)
    world[1, 2, 0] = 5
    exact = ndimage.distance_transform_cdt(world == 0, metric="taxicab")
    for fmt, dtype, top in (("u8", np.uint8, 255), ("u16", np.uint16, 65535),
                            ("u32", np.uint32, 2**32 - 1)):
        ours = voxfield.distance_transform(world, format=fmt)
        assert ours.dtype == dtype
        np.testing.assert_array_equal(ours, np.minimum(exact, top))
    for fmt, dtype in (("i8", np.int8), ("i16", np.int16), ("i32", np.int32), ("f32", np.float32),
                       ("f64", np.float64)):
        ours = voxfield.distance_transform(world, format=fmt, signed=fmt.startswith("i"))
        assert ours.dtype == dtype
    np.testing.assert_array_equal(voxfield.distance_transform(world, format="f64"), exact)
    signed = voxfield.distance_transform(world, format="i8", signed=True)
    np.testing.assert_array_equal(signed, np.minimum(np.where(world != 0, -1, exact), 127))


def test_packed32_holds_distance_and_palette_colour(tmp_path):
    world = random_world(A, 0.1, 3)
    path = str(tmp_path / "default.vox")
    voxfield.save_vox(path, world)
    palette = voxfield.load_vox(path)[1].astype(np.uint32)
    rgb332 = (palette[:, 0] >> 5) << 5 | (palette[:, 1] >> 5) << 2 | (palette[:, 2] >> 6)
    rgb332[0] = 0
    ours = voxfield.distance_transform(world, format="packed32")
    assert ours.dtype == np.uint32
    d = ndimage.distance_transform_cdt(world == 0, metric="taxicab")
    np.testing.assert_array_equal(ours >> 8, np.minimum(d, 255))
    np.testing.assert_array_equal(ours & 0xFF, rgb332[world])


def test_dissertation_algorithms_give_the_global_field():
    world = random_world(A, 0.01, 77)
    exact = voxfield.distance_transform(world)
    for algorithm in ("brute", "fim", "fim-host", "jfa-fim"):
        np.testing.assert_array_equal(voxfield.distance_transform(world, algorithm=algorithm),
                                      exact)
    # jfa is approximate: it only ever names a real solid, so it never under-estimates.
    assert (voxfield.distance_transform(world, algorithm="jfa") >= exact).all()


def test_input_layouts_and_dtypes():
    world = random_world(A, 0.05, 11)
    want = voxfield.distance_transform(world)
    np.testing.assert_array_equal(voxfield.distance_transform(world.astype(np.uint16)), want)
    np.testing.assert_array_equal(voxfield.distance_transform(world.astype(np.uint32)), want)
    np.testing.assert_array_equal(voxfield.distance_transform(world.astype(">u2")), want)
    np.testing.assert_array_equal(voxfield.distance_transform(world != 0), want)
    np.testing.assert_array_equal(voxfield.distance_transform((world != 0).tolist()), want)
    np.testing.assert_array_equal(voxfield.distance_transform(np.asfortranarray(world)), want)
    big = np.zeros((26, 17, 38), np.uint8)
    big[::2, :, ::2] = world
    np.testing.assert_array_equal(voxfield.distance_transform(big[::2, :, ::2]), want)
    t = world.transpose(2, 1, 0)
    np.testing.assert_array_equal(voxfield.distance_transform(t),
                                  voxfield.distance_transform(np.ascontiguousarray(t)))
    before = world.copy()
    voxfield.distance_transform(world)
    np.testing.assert_array_equal(world, before)


def test_field_outlives_its_input_and_owns_its_memory():
    # uint8 worlds take the sweeps, which read the array in place and write the returned
    # array's own memory: it must stay valid and writable after the input and the field go.
    world = random_world(A, 0.05, 17)
    for metric, scipy_metric in (("manhattan", "taxicab"), ("chebyshev", "chessboard")):
        want = ndimage.distance_transform_cdt(world == 0, metric=scipy_metric)
        source = world.copy()
        field = voxfield.distance_transform(source, metric=metric)
        del source
        assert field.flags.writeable and field.flags.c_contiguous
        tail = field[1:]
        field[0, 0, 0] = 9999
        del field
        np.testing.assert_array_equal(tail, want[1:])


def test_threads_share_a_device():
    world = random_world(A, 0.01, 13)
    want = ndimage.distance_transform_cdt(world == 0, metric="taxicab")
    results = [None] * 4

    def work(i):
        results[i] = voxfield.distance_transform(world, device="cpu")

    threads = [threading.Thread(target=work, args=(i,)) for i in range(len(results))]
    for t in threads:
        t.start()
    for t in threads:
        t.join()
    for r in results:
        np.testing.assert_array_equal(r, want)


def test_device_forms():
    world = random_world(A, 0.1, 2)
    want = voxfield.distance_transform(world)
    cpu = next(d["index"] for d in voxfield.devices() if d["type"] == "cpu")
    for device in ("cpu", cpu, str(cpu), np.int64(cpu)):
        np.testing.assert_array_equal(voxfield.distance_transform(world, device=device), want)


def test_field_edits_match_a_fresh_transform():
    world = random_world(A, 0.005, 31)
    field = voxfield.Field(world)
    np.testing.assert_array_equal(field.distances(), voxfield.distance_transform(world))
    stats = field.edit("place", "cube", (1, 2, 3), 0, material=9)
    assert stats["voxels_changed"] == 1 and stats["edits"] == 1
    assert field.world()[3, 2, 1] == 9  # center is (x, y, z): array index [z, y, x]
    steps = [("place", "sphere", (10, 9, 11), 4, 3), ("erase", "cube", (12, 9, 11), 2, 1),
             ("paint", "sphere", (8, 8, 8), 5, 200), ("place", "cube", (-2, 30, 5), 4, 1),
             ("erase", "sphere", (1, 2, 3), 0, 1)]
    for op, shape, center, radius, material in steps:
        field.edit(op, shape, center, radius, material)
        current = field.world()
        np.testing.assert_array_equal(field.distances(), voxfield.distance_transform(current))
    assert (current[field.world() != 0] != 0).all()
    stats = field.apply_edits("# comment\nplace sphere 5 5 5 3 4\n\nerase cube 5 5 5 1\n"
                              "paint cube 0 0 0 30 17  # everything solid turns 17\n")
    assert stats["edits"] == 3
    current = field.world()
    assert set(np.unique(current)) <= {0, 17}
    np.testing.assert_array_equal(field.distances(), voxfield.distance_transform(current))
    # The input array is not shared with the field.
    assert not np.array_equal(world, current)


def test_field_every_metric_sampling_and_sign():
    world = random_world(A, 0.01, 51)
    cases = [dict(metric="chebyshev"), dict(metric="euclidean"),
             dict(metric="euclidean", sampling=(2.0, 0.5, 1.0)), dict(signed=True),
             dict(max_distance=3), dict(metric="euclidean", max_distance=2.5),
             dict(metric="euclidean", signed=True), dict(sampling=1.5, format="f64")]
    for kwargs in cases:
        field = voxfield.Field(world, **kwargs)
        np.testing.assert_array_equal(field.distances(),
                                      voxfield.distance_transform(world, **kwargs))
        for op, shape, center, radius in (("place", "sphere", (9, 8, 6), 3),
                                          ("erase", "cube", (8, 8, 6), 1)):
            field.edit(op, shape, center, radius)
            got = field.distances()
            want = voxfield.distance_transform(field.world(), **kwargs)
            assert got.dtype == want.dtype
            np.testing.assert_array_equal(got, want, err_msg=str(kwargs))


def test_field_formats_and_chunk_local():
    world = random_world(A, 0.01, 41)
    for fmt, dtype in (("u8", np.uint8), ("u32", np.uint32), ("packed32", np.uint32)):
        field = voxfield.Field(world, format=fmt)
        field.edit("place", "sphere", (4, 4, 4), 2)
        got = field.distances()
        assert got.dtype == dtype
        np.testing.assert_array_equal(got, voxfield.distance_transform(field.world(), format=fmt))
    # Chunk-local (16^3 chunks, everything outside a chunk solid): each chunk of a 16^3 world
    # is the world, so its field is the global one with the world surrounded by solid.
    world = random_world((16, 16, 16), 0.01, 43)
    field = voxfield.Field(world, algorithm="brute-chunked")
    field.edit("place", "sphere", (4, 4, 4), 2)
    walled = np.pad(field.world(), 1, constant_values=1)
    want = voxfield.distance_transform(walled)[1:-1, 1:-1, 1:-1]
    np.testing.assert_array_equal(field.distances(), want)


def test_vox_round_trip(tmp_path):
    world, palette = voxfield.load_vox(ARMY)
    assert world.dtype == np.uint8 and world.ndim == 3 and (world != 0).any()
    assert palette.dtype == np.uint8 and palette.shape == (256, 4)
    path = tmp_path / "army.vox"
    voxfield.save_vox(path, world, palette)
    again, again_palette = voxfield.load_vox(str(path))
    np.testing.assert_array_equal(again, world)
    np.testing.assert_array_equal(again_palette, palette)
    custom = palette.copy()
    custom[1] = (1, 2, 3, 4)
    voxfield.save_vox(path, world.astype(np.uint16), custom.astype(np.int64))
    np.testing.assert_array_equal(voxfield.load_vox(path)[1][1], (1, 2, 3, 4))


BAD_WORLDS = [
    (np.zeros((4, 4), np.uint8), ValueError, "3-D"),
    (np.zeros((2, 2, 2, 2), np.uint8), ValueError, "3-D"),
    (np.zeros((2, 2, 2), np.float64), TypeError, "float64"),
    (np.zeros((2, 2, 2), np.complex64), TypeError, "complex64"),
    (np.zeros((2, 2, 2), object), TypeError, "object"),
    (np.zeros((2, 2, 2), "U1"), TypeError, "str"),
    (None, TypeError, "NoneType"),
    ([[[1.5, 2]]], TypeError, "float64"),
    (7, ValueError, "3-D"),
]


@pytest.mark.parametrize("world,error,match", BAD_WORLDS)
def test_bad_worlds(world, error, match):
    with pytest.raises(error, match=match):
        voxfield.distance_transform(world)
    with pytest.raises(error, match=match):
        voxfield.Field(world)


def test_zero_size_worlds_give_empty_fields_and_no_field():
    for shape in [(0, 3, 3), (3, 3, 0), (0, 0, 0)]:
        world = np.zeros(shape, np.uint16)
        field = voxfield.distance_transform(world, metric="euclidean")
        assert field.shape == shape and field.dtype == np.float32
        field, idx = voxfield.distance_transform(world, return_indices=True)
        assert field.shape == shape and field.dtype == np.uint16
        assert idx.shape == (3,) + shape and idx.dtype == np.int32
        with pytest.raises(ValueError, match="empty axis"):
            voxfield.Field(world)


def test_value_over_255_names_the_voxel_where_palette_values_are_needed(tmp_path):
    world = np.zeros((3, 4, 5), np.uint16)
    world[2, 1, 3] = 256
    for call in (lambda w: voxfield.distance_transform(w, format="packed32"),
                 lambda w: voxfield.Field(w, format="packed32"),
                 lambda w: voxfield.save_vox(tmp_path / "w.vox", w)):
        with pytest.raises(ValueError, match=r"256 at voxel \(x=3, y=1, z=2\)"):
            call(world)
    assert not list(tmp_path.iterdir())


W = np.ones(A, np.uint8)
BAD_OPTIONS = [
    (dict(metric="hamming"), ValueError, "unknown metric"),
    (dict(format="u12"), ValueError, "u12"),
    (dict(algorithm="magic"), ValueError, "unknown algorithm"),
    (dict(device="tpu"), ValueError, "tpu"),
    (dict(device=999), ValueError, "999"),
    (dict(device=-1), ValueError, "negative"),
    (dict(device=2**70), ValueError, str(2**70)),
    (dict(device=1.5), TypeError, "float"),
    (dict(sampling=(1, 1)), ValueError, "3 numbers"),
    (dict(sampling=(1, 1, 1, 1)), ValueError, "3 numbers"),
    (dict(sampling=[[1, 1, 1]]), ValueError, "3 numbers"),
    (dict(sampling=(1, -1, 1)), ValueError, "positive"),
    (dict(sampling=0), ValueError, "positive"),
    (dict(sampling=(1, float("nan"), 1)), ValueError, "positive"),
    (dict(sampling="abc"), TypeError, "sampling"),
    (dict(sampling=object()), TypeError, "sampling"),
    (dict(max_distance=0), ValueError, "^max_distance must be a positive number, not 0$"),
    (dict(max_distance=-2.5), ValueError, "max_distance"),
    (dict(max_distance=float("nan")), ValueError, "max_distance"),
    (dict(max_distance="4"), TypeError, "max_distance"),
    (dict(max_distance=[4]), TypeError, ""),
    (dict(max_distance=4, algorithm="fim"), ValueError, "^max_distance: algorithm='fim'"),
    (dict(signed=True, format="u16"), ValueError, "signed format"),
    (dict(signed=True, return_indices=True), ValueError, "signed=False or return_indices=False"),
    (dict(sampling="123"), TypeError, "not a string"),
    (dict(sampling=b"1"), TypeError, "not a string"),
    (dict(sampling=(1, 1, 1e39)), ValueError, "float32"),
    (dict(metric="euclidean", algorithm="fim"), ValueError, "manhattan"),
    (dict(algorithm="jfa", return_indices=True), ValueError, "exact"),
]


@pytest.mark.parametrize("kwargs,error,match", BAD_OPTIONS)
def test_bad_options(kwargs, error, match):
    with pytest.raises(error, match=match):
        voxfield.distance_transform(W, **kwargs)


def test_bad_field_arguments():
    with pytest.raises(ValueError, match="unknown metric"):
        voxfield.Field(W, metric="hamming")
    with pytest.raises(ValueError, match="u12"):
        voxfield.Field(W, format="u12")
    with pytest.raises(ValueError, match="signed format"):
        voxfield.Field(W, signed=True, format="u16")
    with pytest.raises(ValueError, match="positive"):
        voxfield.Field(W, sampling=(1, 0, 1))
    with pytest.raises(ValueError, match="manhattan"):
        voxfield.Field(W, metric="chebyshev", algorithm="brute-chunked")
    with pytest.raises(ValueError, match="chunk"):
        voxfield.Field(W, algorithm="fim")
    field = voxfield.Field(W)
    before = field.distances()
    bad_edits = [
        (("melt", "sphere", (1, 1, 1), 1), ValueError, "unknown edit op"),
        (("place", "torus", (1, 1, 1), 1), ValueError, "unknown brush shape"),
        (("place", "sphere", (1, 1), 1), ValueError, "center"),
        (("place", "sphere", (1, 1, 1), -1), ValueError, "radius"),
        (("place", "sphere", (1, 1, 1), 1, 0), ValueError, "material"),
        (("place", "sphere", (1, 1, 1), 1, 256), ValueError, "material"),
        (("place", "sphere", (1.5, 1, 1), 1), TypeError, ""),
    ]
    for args, error, match in bad_edits:
        with pytest.raises(error, match=match):
            field.edit(*args)
    with pytest.raises(ValueError, match="edits:2:"):
        field.apply_edits("erase cube 1 1 1 0\nerase blob 1 1 1 0\n")
    np.testing.assert_array_equal(field.world(), W)
    np.testing.assert_array_equal(field.distances(), before)


def test_bad_vox_io(tmp_path):
    with pytest.raises(ValueError, match="missing.vox"):
        voxfield.load_vox(tmp_path / "missing.vox")
    (tmp_path / "junk.vox").write_bytes(b"not a vox file")
    with pytest.raises(ValueError):
        voxfield.load_vox(tmp_path / "junk.vox")
    with pytest.raises(ValueError, match="256"):
        voxfield.save_vox(tmp_path / "big.vox", np.ones((2, 2, 257), np.uint8))
    with pytest.raises(ValueError):
        voxfield.save_vox(tmp_path / "no" / "such" / "folder.vox", W)
    with pytest.raises(ValueError, match=r"\(256, 4\)"):
        voxfield.save_vox(tmp_path / "p.vox", W, np.zeros((255, 4), np.uint8))
    with pytest.raises(TypeError, match="float"):
        voxfield.save_vox(tmp_path / "p.vox", W, np.zeros((256, 4), np.float32))
    with pytest.raises(ValueError, match="outside 0..255"):
        voxfield.save_vox(tmp_path / "p.vox", W, np.full((256, 4), 300))
    assert not any(p.name.startswith("p.vox") for p in tmp_path.iterdir())
