"""Label volumes (any bool or integer dtype, nonzero = solid) and arrays beyond memory."""

import numpy as np
import pytest

import voxfield

LABEL_DTYPES = [np.bool_, np.uint8, np.int8, np.uint16, np.int16, np.uint32, np.int32,
                np.uint64, np.int64, ">u2", ">i4", "<i8"]


def labels(shape, seed, dtype):
    """A random label volume whose labels span the dtype's range (negative, above 255)."""
    rng = np.random.default_rng(seed)
    solid = rng.random(shape) < 0.1
    solid.flat[0] = True
    dt = np.dtype(dtype)
    if dt.kind == "b":
        return solid.astype(dt)
    info = np.iinfo(dt)
    values = rng.integers(max(info.min, -2**40), min(info.max, 2**40), size=shape,
                          endpoint=True).astype(dt)
    values[values == 0] = 1
    values.flat[1] = info.max
    solid.flat[1] = True
    return np.where(solid, values, dt.type(0)).astype(dt)


@pytest.mark.parametrize("dtype", LABEL_DTYPES, ids=str)
def test_label_volumes_equal_their_solid_mask(dtype):
    world = labels((9, 11, 13), 3, dtype)
    mask = world != 0
    for metric in ("manhattan", "chebyshev", "euclidean"):
        np.testing.assert_array_equal(voxfield.distance_transform(world, metric=metric),
                                      voxfield.distance_transform(mask, metric=metric))
    field = voxfield.Field(world, metric="euclidean")
    np.testing.assert_array_equal(field.distances(),
                                  voxfield.distance_transform(mask, metric="euclidean"))
    # Labels 1..255 stay palette indices; other nonzero labels are material 1.
    raw = world.astype(np.float64)  # exact enough to tell 1..255 from the rest
    want = np.where((raw >= 1) & (raw <= 255), raw, np.where(raw != 0, 1, 0)).astype(np.uint8)
    np.testing.assert_array_equal(field.world(), want)


def test_label_volume_indices_and_bounds():
    world = labels((10, 12, 14), 5, np.uint16)
    mask = world != 0
    d1, i1 = voxfield.distance_transform(world, metric="euclidean", return_indices=True)
    d2, i2 = voxfield.distance_transform(mask, metric="euclidean", return_indices=True)
    np.testing.assert_array_equal(d1, d2)
    np.testing.assert_array_equal(i1, i2)
    np.testing.assert_array_equal(voxfield.distance_transform(world, max_distance=3),
                                  voxfield.distance_transform(mask, max_distance=3))


HUGE = [
    ("stride trick (2^20)^3", lambda: np.lib.stride_tricks.as_strided(
        np.zeros(1, np.uint8), shape=(2**20,) * 3, strides=(0, 0, 0))),
    ("(1, 2^17, 2^17) u8 view", lambda: np.lib.stride_tricks.as_strided(
        np.zeros(1, np.uint8), shape=(1, 2**17, 2**17), strides=(0, 0, 0))),
    ("(2^12, 2^12, 2^12) u16 view", lambda: np.lib.stride_tricks.as_strided(
        np.zeros(1, np.uint16), shape=(2**12,) * 3, strides=(0, 0, 0))),
]


@pytest.mark.parametrize("name,make", HUGE, ids=[h[0] for h in HUGE])
def test_huge_arrays_raise_memory_error_with_numbers(name, make):
    world = make()
    for call in (lambda: voxfield.distance_transform(world),
                 lambda: voxfield.distance_transform(world, metric="euclidean",
                                                     return_indices=True),
                 lambda: voxfield.Field(world)):
        with pytest.raises(MemoryError, match=r"\d+ bytes"):
            call()


def test_axis_beyond_32_bits_is_a_value_error():
    world = np.lib.stride_tricks.as_strided(np.zeros(1, np.uint8), shape=(1, 1, 2**33),
                                            strides=(0, 0, 0))
    with pytest.raises(ValueError, match="8589934592 voxels"):
        voxfield.distance_transform(world)


def test_python_messages_use_python_names():
    w = np.ones((4, 4, 4), np.uint8)
    cases = [
        (dict(max_distance=-1), "max_distance"),
        (dict(signed=True, return_indices=True), "return_indices"),
        (dict(algorithm="fim", sampling=2), "sampling"),
        (dict(algorithm="fim", return_indices=True), "return_indices"),
        (dict(algorithm="fim", signed=True), "signed"),
        (dict(algorithm="fim", metric="euclidean"), "metric"),
        (dict(algorithm="fim", max_distance=3), "max_distance"),
    ]
    for kwargs, name in cases:
        with pytest.raises(ValueError) as e:
            voxfield.distance_transform(w, **kwargs)
        text = str(e.value)
        assert name in text and "--" not in text, text
    with pytest.raises(ValueError) as e:
        voxfield.Field(w, algorithm="fim")
    assert "--" not in str(e.value) and "chunk C" not in str(e.value), str(e.value)
