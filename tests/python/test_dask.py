"""voxfield.dask equals the one-piece results exactly: bounded fields (map_overlap, halos
larger than a block), unbounded ones (separable passes), chunks that do not divide the array,
on the threaded scheduler and on a distributed.LocalCluster with two workers."""

import numpy as np
import pytest

da = pytest.importorskip("dask.array")
import dask  # noqa: E402

import voxfield  # noqa: E402
import voxfield.dask as vd  # noqa: E402
from voxfield import ndimage  # noqa: E402

SHAPE = (23, 19, 29)
CHUNKS = [(7, 5, 11), (23, 19, 29), (4, 19, 6), (10, 3, 29)]


def world(density, seed, dtype=np.uint8):
    rng = np.random.default_rng(seed)
    w = np.where(rng.random(SHAPE) < density, rng.integers(1, 300, size=SHAPE), 0)
    w.flat[rng.integers(0, w.size)] = 5
    return w.astype(dtype)


def threaded(x):
    return x.compute(scheduler="threads")


@pytest.mark.parametrize("chunks", CHUNKS)
def test_unbounded_equals_one_piece(chunks):
    w = world(0.01, 1, np.uint16)
    dw = da.from_array(w, chunks=chunks)
    for metric in ("manhattan", "chebyshev", "euclidean"):
        for fmt in (None, "f64", "u8", "i32"):
            got = threaded(vd.distance_transform(dw, metric=metric, format=fmt))
            want = voxfield.distance_transform(w, metric=metric, format=fmt)
            assert got.dtype == want.dtype
            np.testing.assert_array_equal(got, want, err_msg=f"{metric} {fmt} {chunks}")


@pytest.mark.parametrize("chunks", CHUNKS)
def test_bounded_equals_one_piece_with_halos_larger_than_blocks(chunks):
    w = world(0.02, 2)
    dw = da.from_array(w, chunks=chunks)
    for metric, bound, sampling, signed in (("manhattan", 3, None, False),
                                            ("euclidean", 7.5, None, False),
                                            ("chebyshev", 6, (1, 2, 0.5), False),
                                            ("euclidean", 4, None, True)):
        got = threaded(vd.distance_transform(dw, metric=metric, max_distance=bound,
                                             sampling=sampling, signed=signed))
        want = voxfield.distance_transform(w, metric=metric, max_distance=bound,
                                           sampling=sampling, signed=signed)
        np.testing.assert_array_equal(got, want, err_msg=f"{metric} {bound} {chunks}")


def test_bounded_halos_longer_than_the_axes():
    # ceil(D / sampling) past an axis's length: the halo is the whole axis (map_overlap refuses
    # a depth larger than the array).
    w = world(0.005, 4)
    dw = da.from_array(w, chunks=(8, 19, 10))
    for metric, bound, sampling in (("euclidean", 30, None), ("manhattan", 20, (1, 2, 0.5)),
                                    ("chebyshev", 25, (0.3, 1.7, 2.9))):
        got = threaded(vd.distance_transform(dw, metric=metric, max_distance=bound,
                                             sampling=sampling))
        want = voxfield.distance_transform(w, metric=metric, max_distance=bound,
                                           sampling=sampling)
        np.testing.assert_array_equal(got, want, err_msg=f"{metric} {bound}")


@pytest.mark.parametrize("chunks", CHUNKS)
def test_ndimage_functions_equal_one_piece(chunks):
    a = world(0.9, 3)
    da_a = da.from_array(a, chunks=chunks)
    for sampling in (None, (1.5, 0.7, 2.0)):
        got = threaded(vd.distance_transform_edt(da_a, sampling=sampling))
        np.testing.assert_array_equal(got, ndimage.distance_transform_edt(a, sampling=sampling))
    for metric in ("taxicab", "chessboard"):
        got = threaded(vd.distance_transform_cdt(da_a, metric=metric))
        np.testing.assert_array_equal(got, ndimage.distance_transform_cdt(a, metric=metric))


def test_ndimage_functions_in_one_and_two_dimensions_and_without_zeros():
    a2 = world(0.9, 4)[0]
    d2 = da.from_array(a2, chunks=(4, 7))
    np.testing.assert_array_equal(threaded(vd.distance_transform_edt(d2)),
                                  ndimage.distance_transform_edt(a2))
    a1 = a2[3]
    np.testing.assert_array_equal(threaded(vd.distance_transform_cdt(da.from_array(a1, 6))),
                                  ndimage.distance_transform_cdt(a1))
    ones = np.ones((5, 6, 7))
    d = da.from_array(ones, chunks=(2, 4, 3))
    np.testing.assert_array_equal(threaded(vd.distance_transform_edt(d, sampling=2)),
                                  ndimage.distance_transform_edt(ones, sampling=2))
    np.testing.assert_array_equal(threaded(vd.distance_transform_cdt(d)),
                                  ndimage.distance_transform_cdt(ones))


def test_ndimage_functions_check_the_form_of_device():
    # Their unbounded scheme runs on the host: device= is SciPy-drop-in signature, its form
    # checked at once.
    a = world(0.85, 7)
    d = da.from_array(a, chunks=(6, 19, 8))
    cpu = next(dev["index"] for dev in voxfield.devices() if dev["type"] == "cpu")
    want_edt = ndimage.distance_transform_edt(a)
    want_cdt = ndimage.distance_transform_cdt(a, metric="taxicab")
    for device in ("cpu", cpu, str(cpu), np.int64(cpu)):
        np.testing.assert_array_equal(threaded(vd.distance_transform_edt(d, device=device)),
                                      want_edt)
        np.testing.assert_array_equal(
            threaded(vd.distance_transform_cdt(d, metric="taxicab", device=device)), want_cdt)
    for x in (a[0], a[0, 2]):  # a 2-D input, a 1-D input
        dx = da.from_array(x, chunks=5)
        np.testing.assert_array_equal(threaded(vd.distance_transform_edt(dx)),
                                      ndimage.distance_transform_edt(x))
        for metric in ("taxicab", "chessboard"):
            np.testing.assert_array_equal(threaded(vd.distance_transform_cdt(dx, metric=metric)),
                                          ndimage.distance_transform_cdt(x, metric=metric))
    for bad, error in ((True, TypeError), (1.5, TypeError), (-1, ValueError)):
        for function in (vd.distance_transform_edt, vd.distance_transform_cdt):
            with pytest.raises(error, match="device"):
                function(d, device=bad)


def test_host_pass_equals_brute_force_on_partials():
    # The passes between blocks take partial distances: integer ones with unit spacing (the
    # exact integer L2 pass), any others with any spacing; +inf where a line has no target.
    rng = np.random.default_rng(8)
    for trial in range(200):
        n, m = int(rng.integers(1, 40)), int(rng.integers(1, 6))
        spacing = 1.0 if trial % 4 else float(rng.uniform(0.3, 3.0))
        g = rng.integers(0, int(rng.choice([2, 10, 1000, 10**6])), size=(m, n)).astype(float)
        if trial % 7 == 0:
            g += 0.5
        g[rng.random((m, n)) < rng.random()] = np.inf
        i = np.arange(n)
        for metric, cost in (("euclidean", lambda d: (spacing * d) ** 2),
                             ("manhattan", lambda d: spacing * np.abs(d))):
            got = voxfield._core.separable_pass(g, 1, metric, spacing, False)
            want = np.min(g[:, None, :] + cost(i[:, None] - i[None, :]), axis=2)
            np.testing.assert_allclose(got, want, rtol=1e-12, err_msg=f"{metric} {g}")
            if spacing == 1.0:
                np.testing.assert_array_equal(got, want)


def test_lazy_and_refusals():
    dw = da.from_array(world(0.01, 5), chunks=8)
    out = vd.distance_transform(dw, metric="euclidean")
    assert isinstance(out, da.Array) and out.chunks == dw.chunks and out.dtype == np.float32
    with pytest.raises(ValueError, match="max_distance"):
        vd.distance_transform(dw, signed=True)
    with pytest.raises(ValueError, match="max_distance"):
        vd.distance_transform(dw, max_distance=-1)
    with pytest.raises(TypeError, match="string"):
        vd.distance_transform(dw, sampling="123")
    with pytest.raises(ValueError, match="distances only"):
        vd.distance_transform_edt(dw, return_indices=True)
    with pytest.raises(TypeError, match="float64"):
        vd.distance_transform(dw.astype(np.float64))


def test_local_cluster_with_two_workers():
    distributed = pytest.importorskip("distributed")
    w = world(0.01, 6)
    dw = da.from_array(w, chunks=(9, 8, 12))
    with distributed.LocalCluster(n_workers=2, threads_per_worker=1, processes=True,
                                  dashboard_address=None, silence_logs=50) as cluster, \
            distributed.Client(cluster) as client:
        client.run(lambda: __import__("os").environ.__setitem__("VOXFIELD_DEVICE", "cpu"))
        bounded = vd.distance_transform(dw, metric="euclidean", max_distance=5)
        unbounded = vd.distance_transform(dw, metric="manhattan")
        edt = vd.distance_transform_edt(dw == 0)
        cdt = vd.distance_transform_cdt(dw == 0, metric="chessboard")
        got_b, got_u, got_e, got_c = dask.compute(bounded, unbounded, edt, cdt)
        workers = client.run(lambda: __import__("os").getpid())
        assert len(workers) == 2
        # Each device task reads its worker's $VOXFIELD_DEVICE (this process keeps "cpu");
        # device= overrides it.
        client.run(lambda: __import__("os").environ.__setitem__("VOXFIELD_DEVICE", "bogus"))
        with pytest.raises(ValueError, match="bogus"):
            vd.distance_transform(dw, metric="euclidean", max_distance=5).compute()
        got_d = vd.distance_transform(dw, metric="euclidean", max_distance=5,
                                      device="cpu").compute()
    np.testing.assert_array_equal(got_b, voxfield.distance_transform(w, metric="euclidean",
                                                                     max_distance=5))
    np.testing.assert_array_equal(got_u, voxfield.distance_transform(w))
    np.testing.assert_array_equal(got_e, ndimage.distance_transform_edt(w == 0))
    np.testing.assert_array_equal(got_d, got_b)
    np.testing.assert_array_equal(got_c, ndimage.distance_transform_cdt(w == 0))


@pytest.mark.parametrize("chunks", [(1, 19, 29), (5, 4, 29), (23, 1, 7)])
def test_unbounded_slabs_across_many_blocks(chunks, monkeypatch):
    # Slabs one to a few planes thick (the cap split below a block's depth), the passes a
    # plane or two at a time with a shorter last group, and targets far away along axis 0:
    # the nearest target before / after each slab comes from slabs several blocks away.
    monkeypatch.setattr(vd, "_SLAB_BYTES", 19 * 29 * 3 * 4)
    monkeypatch.setattr(vd, "_PASS_ELEMENTS", 19 * 29 * 2)
    rng = np.random.default_rng(11)
    for case in range(4):
        w = np.zeros(SHAPE, np.uint8)
        if case == 0:
            w[rng.integers(0, 2), rng.integers(0, 19), rng.integers(0, 29)] = 1
        elif case == 1:
            w[[0, 22], 3, 4] = 1
            w[11, :, 7] = 2
        elif case == 2:
            w[rng.random(SHAPE) < 0.002] = 9
        # case 3: no solid at all
        dw = da.from_array(w, chunks=chunks)
        for metric in ("manhattan", "chebyshev", "euclidean"):
            for fmt in (None, "u8"):
                got = threaded(vd.distance_transform(dw, metric=metric, format=fmt))
                want = voxfield.distance_transform(w, metric=metric, format=fmt)
                np.testing.assert_array_equal(got, want, err_msg=f"{case} {metric} {fmt}")
        a = w == 0
        np.testing.assert_array_equal(threaded(vd.distance_transform_edt(dw == 0)),
                                      ndimage.distance_transform_edt(a), err_msg=f"{case}")
        for metric in ("taxicab", "chessboard"):
            np.testing.assert_array_equal(
                threaded(vd.distance_transform_cdt(dw == 0, metric=metric)),
                ndimage.distance_transform_cdt(a, metric=metric), err_msg=f"{case} {metric}")


def test_unbounded_with_sampling_equals_the_host_transform():
    # With non-unit sampling the one-piece device field carries float32 partials; the Dask
    # field is the float64 separable transform (passes along axes 0, 1, 2) rounded once.
    w = world(0.01, 12)
    for chunks in ((7, 5, 11), (23, 19, 29)):
        dw = da.from_array(w, chunks=chunks)
        for sampling in ((1.5, 0.7, 2.0), 0.3):
            s = [float(v) for v in np.broadcast_to(sampling, 3)]
            for metric in ("manhattan", "chebyshev", "euclidean"):
                g, _ = voxfield._core.host_transform(w, metric, s, False)
                want = np.sqrt(g) if metric == "euclidean" else g
                got = threaded(vd.distance_transform(dw, metric=metric, sampling=sampling,
                                                     format="f64"))
                np.testing.assert_array_equal(got, want, err_msg=f"{metric} {sampling}")
                got32 = threaded(vd.distance_transform(dw, metric=metric, sampling=sampling))
                np.testing.assert_array_equal(got32, want.astype(np.float32))


def test_edt_with_sampling_in_one_two_and_three_dimensions():
    rng = np.random.default_rng(13)
    for shape, chunks, sampling in (((37,), (5,), 0.7), ((37,), (37,), 2.5),
                                    ((17, 23), (4, 23), (1.5, 0.4)),
                                    ((17, 23), (17, 5), (0.9, 3.0)),
                                    ((9, 11, 13), (2, 4, 13), (2.0, 1.0, 0.5)),
                                    ((0, 5), (1, 5), 2.0), ((4, 0, 3), (1, 1, 1), 0.5)):
        a = rng.random(shape) < 0.9
        if a.size:
            a.flat[rng.integers(0, a.size)] = 0
        got = threaded(vd.distance_transform_edt(da.from_array(a, chunks=chunks),
                                                 sampling=sampling))
        np.testing.assert_array_equal(got, ndimage.distance_transform_edt(a, sampling=sampling),
                                      err_msg=f"{shape} {chunks} {sampling}")


def test_axis0_distances_and_slab_passes_equal_brute_force():
    rng = np.random.default_rng(14)
    core = voxfield._core
    for trial in range(60):
        n0, n1, n2 = (int(v) for v in rng.integers(1, 9, size=3))
        length = int(rng.integers(n0, n0 + 20))
        z0 = int(rng.integers(0, length - n0 + 1))
        full = rng.random((length, n1, n2)) < rng.choice([0.0, 0.05, 0.3])
        slab = full[z0:z0 + n0]
        pos = np.arange(length)[:, None, None]
        big = np.iinfo(np.int64).max
        before = np.max(np.where(full[:z0], pos[:z0], -1), axis=0, initial=-1)
        after = np.min(np.where(full[z0 + n0:], pos[z0 + n0:], big), axis=0, initial=big)
        after = np.where(after == big, -1, after)
        d = core.axis0_distances(slab.astype(np.uint8) * 3, before, after, z0,
                                 length if trial % 2 else 70000)
        assert d.dtype == (np.uint16 if trial % 2 else np.uint32)
        gap = np.abs(pos[:, None] - np.arange(z0, z0 + n0)[None, :, None, None])
        nearest = np.min(np.where(full[:, None], gap, big), axis=0)
        none = np.iinfo(d.dtype).max
        np.testing.assert_array_equal(d, np.where(nearest == big, none, nearest))
        into = np.full(slab.shape, 7, d.dtype)
        core.axis0_distances(slab, before, after, z0, length if trial % 2 else 70000, into)
        np.testing.assert_array_equal(into, d)
        ends = core.axis0_ends(slab, z0)
        has = slab.any(axis=0)
        zs = np.arange(z0, z0 + n0)[:, None, None]
        first = np.min(np.where(slab, zs, big), axis=0)
        np.testing.assert_array_equal(ends[0], np.where(has, first, -1))
        np.testing.assert_array_equal(ends[1], np.max(np.where(slab, zs, -1), axis=0))
        s = [float(v) for v in rng.uniform(0.3, 3.0, size=3)] if trial % 3 else [1.0] * 3
        for metric in ("manhattan", "chebyshev", "euclidean"):
            out = np.empty(d.shape)
            got = core.slab_passes(d, metric, s, out)
            assert got is not None and np.shares_memory(got, out)
            g0 = s[0] * d.astype(np.float64)
            g = np.where(d == none, np.inf, g0 * g0 if metric == "euclidean" else g0)
            for axis in (1, 2):
                g = core.separable_pass(g, axis, metric, s[axis], False)
            np.testing.assert_array_equal(out, g, err_msg=f"{metric} {s}")
            field = np.sqrt(g) if metric == "euclidean" else g
            for dtype in (np.float32, np.float64):
                f = np.empty(d.shape, dtype)
                core.slab_passes(d, metric, s, out, f)
                np.testing.assert_array_equal(f, field.astype(dtype))
    with pytest.raises(ValueError, match="one position per line"):
        core.axis0_distances(np.ones((2, 3, 4), bool), np.zeros(3), np.zeros(12), 0, 2)
    with pytest.raises(ValueError, match="within"):
        core.axis0_distances(np.ones((2, 3, 4), bool), np.zeros(12), np.zeros(12), 1, 2)
    with pytest.raises(ValueError, match="out must be"):
        core.axis0_distances(np.ones((2, 3), bool), np.zeros(3), np.zeros(3), 0, 2,
                             np.empty((2, 3), np.uint32))
    with pytest.raises(TypeError, match="uint16 or uint32"):
        core.slab_passes(np.zeros((2, 3), np.int16), "manhattan", [1.0, 1.0])
    with pytest.raises(ValueError, match="field must be"):
        core.slab_passes(np.zeros((2, 3), np.uint16), "manhattan", [1.0, 1.0], None,
                         np.empty((2, 3), np.int32))
    with pytest.raises(ValueError, match="out must be"):
        core.slab_passes(np.zeros((2, 3), np.uint16), "manhattan", [1.0, 1.0], np.empty((3, 2)))


def brute_force(targets, metric):
    """Distances from every element to the nearest target (inf: none), by brute force."""
    pts = np.argwhere(targets)
    grid = np.indices(targets.shape).reshape(targets.ndim, -1).T
    if len(pts) == 0:
        return np.full(targets.shape, np.inf)
    diff = np.abs(grid[:, None, :] - pts[None, :, :])
    if metric == "euclidean":
        v = np.sqrt((diff * diff).sum(axis=-1).min(axis=1).astype(np.float64))
    elif metric == "manhattan":
        v = diff.sum(axis=-1).min(axis=1).astype(np.float64)
    else:
        v = diff.max(axis=-1).min(axis=1).astype(np.float64)
    return v.reshape(targets.shape)


def _cuts(rng, n):
    """Random edges splitting [0, n) into pieces (some may be empty)."""
    return sorted([0, n] + [int(v) for v in rng.integers(0, n + 1, size=int(rng.integers(0, 3)))])


def _slab_pieces(core, t, z0, z1, metric, dtype, rng, minus_one=False, length=None):
    """_core.slab_pieces of planes [z0, z1) of targets t (1 to 3 axes) in random pieces, the
    nearest targets before / after the slab found by brute force; the pieces put together."""
    length = t.shape[0] if length is None else length
    t3 = t.reshape(t.shape[:1] + (1,) * (3 - t.ndim) + t.shape[1:])
    lines = t3.reshape(t.shape[0], -1)
    before = np.full(lines.shape[1], -1, np.int64)
    after = np.full(lines.shape[1], -1, np.int64)
    for q in range(lines.shape[1]):
        b, a = np.nonzero(lines[:z0, q])[0], np.nonzero(lines[z1:, q])[0]
        before[q] = b[-1] if len(b) else -1
        after[q] = a[0] + z1 if len(a) else -1
    ye = _cuts(rng, t3.shape[1]) if t.ndim == 3 else [0, 1]
    xe = _cuts(rng, t3.shape[2]) if t.ndim >= 2 else [0, 1]
    cells = [(slice(ye[j], ye[j + 1]), slice(xe[k], xe[k + 1]))
             for j in range(len(ye) - 1) for k in range(len(xe) - 1)]
    blocks = [np.ascontiguousarray(t3[z0:z1, ys, xs]) for ys, xs in cells]
    if t.ndim < 3:  # the pieces' own shapes: (planes, columns) or (planes,)
        blocks = [b.reshape((b.shape[0],) + b.shape[3 - t.ndim:]) for b in blocks]
    out = [np.full(b.shape, 7, dtype) for b in blocks]
    core.slab_pieces(blocks, before, after, z0, length, metric, out, ye, xe, minus_one)
    whole = np.empty((z1 - z0,) + t3.shape[1:], dtype)
    for (ys, xs), o in zip(cells, out):
        whole[:, ys, xs] = o.reshape(whole[:, ys, xs].shape)
    return whole.reshape((z1 - z0,) + t.shape[1:])


def test_slab_pieces_equal_brute_force():
    # Unit sampling, exact integers: every metric, 1 to 3 axes, slabs within a longer axis 0,
    # random pieces (some empty), every output type as the kernels store it, -1 where nothing
    # is reachable for cdt; int64 partials where squared distances pass 2**31.
    rng = np.random.default_rng(15)
    core = voxfield._core
    for trial in range(120):
        shape = tuple(int(v) for v in rng.integers(1, 12, size=int(rng.integers(1, 4))))
        t = rng.random(shape) < rng.choice([0.0, 0.01, 0.1, 0.5, 0.9])
        z0 = int(rng.integers(0, shape[0]))
        z1 = int(rng.integers(z0 + 1, shape[0] + 1))
        for metric in ("euclidean", "manhattan", "chebyshev"):
            v = brute_force(t, metric)[z0:z1]
            for dtype in (np.float64, np.float32, np.uint8, np.uint16, np.int8, np.int32):
                got = _slab_pieces(core, t, z0, z1, metric, dtype, rng)
                if np.dtype(dtype).kind == "f":
                    want = v.astype(dtype)
                else:
                    want = np.minimum(np.floor(v), np.iinfo(dtype).max).astype(dtype)
                np.testing.assert_array_equal(got, want, err_msg=f"{shape} {metric} {dtype}")
            cdt = _slab_pieces(core, t, z0, z1, metric, np.int32, rng, True)
            np.testing.assert_array_equal(cdt, np.where(np.isinf(v), -1, v).astype(np.int32))
    # A slab of a long axis 0 whose targets lie 60000 planes away: uint32 first-pass
    # distances and squares past 2**31.
    t = np.zeros((2, 3, 4), bool)
    t[1, 2, 3] = True
    after = np.full(12, -1, np.int64)
    after[0] = 60001
    out = [np.empty(t.shape)]
    core.slab_pieces([t], np.full(12, -1, np.int64), after, 0, 70000, "euclidean", out, [0, 3],
                     [0, 4])
    z, y, x = np.indices(t.shape)
    want = np.minimum((z - 1) ** 2 + (y - 2) ** 2 + (x - 3) ** 2,
                      (60001 - z) ** 2.0 + y ** 2 + x ** 2)
    np.testing.assert_array_equal(out[0], np.sqrt(want))
    ends = np.full(12, -1, np.int64)
    with pytest.raises(ValueError, match="one piece per cell"):
        core.slab_pieces([t], ends, ends, 0, 2, "manhattan", [], [0, 3], [0, 4])
    with pytest.raises(ValueError, match="does not fit its cell"):
        core.slab_pieces([t], ends, ends, 0, 2, "manhattan", [np.empty(t.shape)], [0, 2], [0, 4])
    with pytest.raises(ValueError, match="out piece 0"):
        core.slab_pieces([t], ends, ends, 0, 2, "manhattan", [np.empty((2, 3))], [0, 3], [0, 4])
    with pytest.raises(ValueError, match="one position per line"):
        core.slab_pieces([t], ends[:3], ends, 0, 2, "manhattan", [np.empty(t.shape)], [0, 3],
                         [0, 4])
    with pytest.raises(ValueError, match="within"):
        core.slab_pieces([t], ends, ends, 1, 2, "manhattan", [np.empty(t.shape)], [0, 3], [0, 4])
    with pytest.raises(TypeError, match="out must be"):
        core.slab_pieces([t], ends, ends, 0, 2, "manhattan", [np.empty(t.shape, np.int64)],
                         [0, 3], [0, 4])
