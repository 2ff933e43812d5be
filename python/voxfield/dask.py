"""Distance transforms of ``dask.array`` volumes, block by block, exactly.

Every function returns a lazy dask array equal, value for value, to the one-piece result of
the same call on the whole array (:func:`voxfield.distance_transform`,
:func:`voxfield.ndimage.distance_transform_edt`, :func:`voxfield.ndimage.distance_transform_cdt`),
on any scheduler (threads, processes, a ``distributed`` cluster).

Three exact schemes:

* Bounded fields (``distance_transform(..., max_distance=D)``): each block is computed on the
  OpenCL device with a halo of ``ceil(D / sampling)`` voxels per axis (``map_overlap``; Dask
  merges blocks smaller than the halo first). A voxel's value depends only on the solids
  within D, which the halo holds, and everything beyond D saturates at D.
* Unbounded ``distance_transform`` (and ``distance_transform_edt`` with non-unit sampling):
  the separable transform on the host in slabs along axis 0 (blocks spanning every other
  axis, split where one would pass 2**27 elements). Along axis 0 the first pass of a line
  needs only the nearest target before and after each slab, so every block first gives the
  first and last target of each of its lines (from a clone of the input's graph: the input is
  read twice, and nothing waits in memory for the slabs), a cumulative maximum / minimum over
  the blocks carries them along axis 0, and each slab then computes its first pass
  (``voxfield._core.axis0_distances``) and the passes along the other axes, a few planes at a
  time (``voxfield._core.slab_passes``, float64), and writes the format. No partial distance
  moves between workers; the slabs are split back into the input's chunks. With unit sampling
  every partial is an exact integer; the passes run along axes 0, 1, 2 in turn, so sampled
  sums are SciPy's.
* ``distance_transform_edt`` (unit sampling) and ``distance_transform_cdt``: the device
  transforms every slice along axis 0 alone (a plane of a 3-D input, a row of a 2-D input; a
  1-D input whole), in blocks that span the slices whole; then one host pass along axis 0
  (blocks spanning whole lines of it) finishes the separable transform. The slices' partial
  distances are exact integers (L2: squared, recovered exactly from the device's float64
  distances), so the result equals the one-piece function bit for bit. The rechunk between
  the two stages moves the whole volume's partial distances (float32 where exact) at once:
  a cluster needs that much memory (or room to spill) across its workers.

Each line and slice is computed whole, so no result depends on the chunks.

Each task picks its device when it runs: ``device=`` if given, else ``$VOXFIELD_DEVICE`` as
the worker's environment has it, else the first GPU, else the first CPU; each worker process
keeps one OpenCL context per device. A device that a worker does not have fails that task.
"""

import functools
import math

import dask.array as da
import numpy as np
from dask.array.reductions import cumreduction
from dask.graph_manipulation import clone

from voxfield import _core

__all__ = ["distance_transform", "distance_transform_cdt", "distance_transform_edt"]

_FORMAT_DTYPES = {"u8": np.uint8, "u16": np.uint16, "u32": np.uint32, "packed32": np.uint32,
                  "i8": np.int8, "i16": np.int16, "i32": np.int32, "f32": np.float32,
                  "f64": np.float64}


def _spacing(sampling, ndim):
    """Sampling in array order, one float per axis (None: all 1)."""
    if sampling is None:
        return [1.0] * ndim
    if isinstance(sampling, (str, bytes)):
        raise TypeError("sampling must be a number or a sequence of numbers, not a string")
    s = np.asarray(sampling, dtype=np.float64)
    if s.ndim == 0:
        s = np.full(ndim, float(s))
    if s.ndim != 1 or s.size != ndim:
        raise ValueError(f"sampling must be one number or {ndim} numbers, got {sampling!r}")
    if not np.all(np.isfinite(s)) or np.any(s <= 0):
        raise ValueError(f"sampling: every value must be positive and finite, got {list(s)}")
    return [float(v) for v in s]


# The device stage's blocks hold at most this many elements (32 or 64 MiB of partials).
_SLICE_BLOCK_ELEMENTS = 1 << 23


def _check_device(device):
    """The form of device= (None, a string, a non-negative integer); which device it names
    is resolved by each task on its worker."""
    if isinstance(device, bool) or not (device is None
                                        or isinstance(device, (str, int, np.integer))):
        raise TypeError("device must be None, 'cpu', 'gpu' or an index from "
                        f"voxfield.devices(), not {type(device).__name__}")
    if isinstance(device, (int, np.integer)) and device < 0:
        raise ValueError(f"device index {device} is negative: use an index from "
                         "voxfield.devices()")


def _exact_partial_dtype(metric, shape):
    """float32 where every finite partial distance of a slice of `shape` is an integer below
    2**24 (held exactly), else float64."""
    extents = [n - 1 for n in shape]
    if metric == "euclidean":
        top = sum(e * e for e in extents)
    elif metric == "manhattan":
        top = sum(extents)
    else:
        top = max(extents, default=0)
    return np.dtype(np.float32 if top < 1 << 24 else np.float64)


def _slices_on_device(block, metric, device, dtype):
    """Partial distances (L2: squared) of a block of targets (bool): each slice along axis 0
    transformed alone on the device (a 1-D block: the whole line). Exact integers (+inf
    where a slice has no target) in `dtype`."""
    out = np.empty(block.shape, dtype)
    slices = [(Ellipsis, block)] if block.ndim == 1 else enumerate(block)
    for index, s in slices:
        if s.size == 0:
            continue
        d = _core.distance_transform(s.reshape((1,) * (3 - s.ndim) + s.shape), metric, False,
                                     None, False, None, "f64", "exact", device)
        d = d.reshape(s.shape)
        if metric == "euclidean":
            # sqrt of an integer below 2**52, squared and rounded: the integer again.
            d = np.rint(d * d)
        out[index] = d
    return out


def _finished(g, finish, dtype):
    out = np.empty(g.shape, dtype)
    finish(g, out)
    return out


def _pass_and_finish(block, metric, finish, dtype):
    """The host pass along axis 0 from partial distances, then `finish` of the result."""
    return _finished(_core.separable_pass(block, 0, metric, 1.0, False, 1), finish, dtype)


def _finish_slices(block, metric, device, partial, finish, dtype):
    g = _slices_on_device(block, metric, device, partial).astype(np.float64)
    return _finished(g, finish, dtype)


def _unit_transform(targets, metric, device, finish, dtype):
    """Lazy `finish` of the distances (L2: squared) of a dask array of targets (bool) with
    unit sampling, chunked as `targets` and of `dtype`: the slices along axis 0 on the device,
    then one host pass along axis 0 (the module docstring's third scheme). `finish` maps a
    float64 block to `dtype` element by element."""
    chunks = targets.chunks
    if targets.ndim == 1:
        partial = _exact_partial_dtype(metric, targets.shape)
        whole = targets.rechunk(-1)
        return whole.map_blocks(_finish_slices, metric, device, partial, finish, dtype,
                                dtype=dtype).rechunk(chunks)
    partial = _exact_partial_dtype(metric, targets.shape[1:])
    slice_elements = math.prod(targets.shape[1:])
    depth = max(1, min(targets.shape[0], _SLICE_BLOCK_ELEMENTS // max(1, slice_elements)))
    g = targets.rechunk({a: (depth if a == 0 else -1) for a in range(targets.ndim)})
    g = g.map_blocks(_slices_on_device, metric, device, partial, dtype=partial)
    g = g.rechunk({a: (-1 if a == 0 else chunks[a]) for a in range(targets.ndim)})
    g = g.map_blocks(_pass_and_finish, metric, finish, dtype, dtype=dtype)
    return g.rechunk(chunks)


# A slab of the unbounded scheme holds at most this many elements (unless one plane is
# larger); its passes after the first run on this many elements at a time (float64).
_SLAB_ELEMENTS = 1 << 27
_PASS_ELEMENTS = 1 << 21
_NONE = np.iinfo(np.int64).max  # "no target" in the cumulative minimum of first targets


def _line_ends(block, block_info=None):
    """Per line along axis 0 of a block of targets (bool): the global positions of its first
    and last target (-1: none), stacked as a (2, ...) int64 block."""
    return _core.axis0_ends(block, block_info[0]["array-location"][0][0])


def _slab_block(slab, before, after, metric, spacing, finish, dtype, length, block_info=None):
    """`finish` of the distances (L2: squared) of a slab spanning every axis but axis 0: the
    first pass along axis 0 from the slab's targets and the nearest targets before and after
    it on every line (`before`, `after`: one block along axis 0, -1: none), then the host
    passes along the other axes, a few planes at a time."""
    z0 = block_info[0]["array-location"][0][0]
    out = np.empty(slab.shape, dtype)
    # The first pass's distances live in the tail of `out` where they fit: the planes written
    # so far end before the distances of the planes still to read begin.
    d_dtype = np.dtype(np.uint16 if length < 65535 else np.uint32)
    tail = None
    if out.itemsize >= d_dtype.itemsize and out.itemsize % d_dtype.itemsize == 0:
        tail = out.reshape(-1).view(np.uint8)[out.nbytes - d_dtype.itemsize * out.size:]
        tail = tail.view(d_dtype).reshape(slab.shape)
    d = _core.axis0_distances(slab, before[0], after[0], z0, length, tail)
    plane = max(1, math.prod(slab.shape[1:]))
    step = max(1, _PASS_ELEMENTS // plane)
    scratch = np.empty((min(step, slab.shape[0]),) + slab.shape[1:])  # filled afresh each time
    for a in range(0, slab.shape[0], step):
        part = d[a:a + step]
        if out.dtype.kind == "f" and getattr(finish, "func", None) is _field_of:  # straight in
            _core.slab_passes(part, metric, spacing, scratch[:len(part)], out[a:a + step])
        else:
            finish(_core.slab_passes(part, metric, spacing, scratch[:len(part)]),
                   out[a:a + step])
    return out


def _shift(x, fill, forward):
    """x (one element per block along axis 0) moved one element along axis 0, `fill`
    entering at the front (forward) or the back."""
    edge = da.full((1,) + x.shape[1:], fill, dtype=x.dtype, chunks=((1,),) + x.chunks[1:])
    if x.shape[0] == 1:
        return edge
    return da.concatenate([edge, x[:-1]] if forward else [x[1:], edge], axis=0)


def _separable(targets, metric, spacing, finish, dtype):
    """Lazy `finish` of the distances (L2: squared) of a dask array of targets (bool),
    chunked as `targets` and of `dtype`, by slabs along axis 0 (the module docstring's second
    scheme): each slab's first pass needs, per line, only the nearest targets before and after
    it, which a cumulative maximum / minimum of the blocks' first and last targets gives."""
    chunks = targets.chunks
    if targets.dtype != bool:
        targets = targets != 0
    if targets.size == 0:
        return da.zeros(targets.shape, dtype, chunks=chunks)
    plane = max(1, math.prod(targets.shape[1:]))
    depth = max(1, _SLAB_ELEMENTS // plane)
    slab_chunks = tuple(p for c in chunks[0] for p in [depth] * (c // depth) + [c % depth] if p)
    t = targets.rechunk({0: slab_chunks})
    # The ends come from a clone of the input's graph (read twice), so that no worker holds
    # the input blocks from the ends' computation until the slabs' turn comes; merged to one
    # block per slab at once, so that the scans below take a few tasks per slab.
    whole = {a: -1 for a in range(1, targets.ndim)}
    ends = clone(t).map_blocks(_line_ends, dtype=np.int64,
                               chunks=((2,) * len(slab_chunks),) + t.chunks[1:]).rechunk(whole)
    first, last = ends[0::2], ends[1::2]
    before = cumreduction(np.maximum.accumulate, np.maximum, -1, last, axis=0, dtype=np.int64)
    before = _shift(before, -1, True)
    first = da.where(first < 0, _NONE, first)
    after = cumreduction(np.minimum.accumulate, np.minimum, _NONE, first[::-1], axis=0,
                         dtype=np.int64)[::-1]
    after = _shift(da.where(after == _NONE, -1, after), -1, False)
    g = t.rechunk(whole).map_blocks(_slab_block, before, after, metric, spacing, finish, dtype,
                                    targets.shape[0], dtype=dtype)
    return g.rechunk(chunks)


def _store(d, out):
    """A float64 block of distances (>= 0; overwritten) into `out` in a field format, as the
    kernels store it: integers rounded down and saturated, floats rounded to nearest."""
    if out.dtype.kind != "f":
        np.floor(d, out=d)
        np.minimum(d, float(np.iinfo(out.dtype).max), out=d)
    out[...] = d


def _default_format(metric, spacing, signed):
    unit = all(s == 1.0 for s in spacing)
    if metric == "euclidean" or not unit:
        return "f32"
    return "i16" if signed else "u16"


def _bounded_block(block, metric, signed, sampling, max_distance, fmt, device):
    return _core.distance_transform(block, metric, signed, sampling, False, max_distance, fmt,
                                    "exact", device)


def distance_transform(world, metric="manhattan", signed=False, sampling=None,
                       max_distance=None, format=None, device=None):
    """:func:`voxfield.distance_transform` of a dask array, lazily and exactly.

    Parameters
    ----------
    world : dask.array.Array or array_like, shape (Z, Y, X)
        A label volume (bool or any integer dtype, nonzero = solid), chunked any way.
    metric : {'manhattan', 'chebyshev', 'euclidean'}
    signed : bool
        Signed fields need ``max_distance`` here (bounded blocks).
    sampling : float or sequence of 3 floats, optional
        Voxel spacing in array order (z, y, x).
    max_distance : float, optional
        Bounded field: blocks on the device with a halo of ``ceil(max_distance / sampling)``.
        None: the unbounded field by the separable passes on the host.
    format : str, optional
        As for :func:`voxfield.distance_transform` (default u16 / i16 / f32 likewise).
    device : None, 'cpu', 'gpu' or int
        The device each task uses (None: ``$VOXFIELD_DEVICE`` of the worker, else its first
        GPU, else its first CPU); bounded fields only.

    Returns
    -------
    dask.array.Array
        Chunked as ``world``, of the format's dtype. Without ``max_distance`` and with
        non-unit sampling the values are the float64 separable transform rounded to the
        format, which can differ from the one-piece device field by the float32 rounding of
        its partial distances.
    """
    w = da.asarray(world)
    if w.ndim != 3:
        raise ValueError(f"world must be a 3-D array of shape (Z, Y, X), got shape {w.shape}")
    if not (w.dtype.kind in "bui"):
        raise TypeError(f"world dtype {w.dtype} is not supported: expected bool or an integer "
                        "type (a label volume: 0 = empty, nonzero = solid)")
    spacing = _spacing(sampling, 3)
    if metric not in ("manhattan", "chebyshev", "euclidean"):
        raise ValueError(f"unknown metric '{metric}': expected manhattan, chebyshev or euclidean")
    fmt = format if format is not None else _default_format(metric, spacing, signed)
    if fmt not in _FORMAT_DTYPES:
        raise ValueError(f"unknown format '{fmt}': expected one of {', '.join(_FORMAT_DTYPES)}")
    dtype = np.dtype(_FORMAT_DTYPES[fmt])
    if max_distance is not None:
        if isinstance(max_distance, (str, bytes)):
            raise TypeError("max_distance must be None or a number, not a string")
        bound = float(max_distance)
        if not (math.isfinite(bound) and bound > 0):
            raise ValueError(f"max_distance must be a positive number, not {max_distance}")
        depth = {a: int(math.ceil(bound / spacing[a])) for a in range(3)}
        # Checks every argument once, eagerly, on a one-voxel world.
        _core.distance_transform(np.zeros((1, 1, 1), np.uint8), metric, signed, sampling,
                                 False, bound, fmt, "exact", device)
        return w.map_overlap(_bounded_block, depth=depth, boundary="none", trim=True,
                             dtype=dtype, metric=metric, signed=signed, sampling=sampling,
                             max_distance=bound, fmt=fmt, device=device)
    if signed:
        raise ValueError("signed=True on a dask array needs max_distance (signed fields are "
                         "computed as bounded blocks)")
    if fmt == "packed32":
        raise ValueError("format='packed32' on a dask array needs max_distance (the palette "
                         "colour is written by the device)")
    return _separable(w, metric, spacing, functools.partial(_field_of, metric=metric),
                      dtype)


def _field_of(g, out, metric):
    """The field (into `out`, in its format) of partial distances after every pass (L2:
    squared; `g` is overwritten)."""
    if metric == "euclidean":
        np.sqrt(g, out=g)
    _store(g, out)


def _no_target_edt(block, spacing, block_info=None):
    """SciPy's edt of an input without zeros: measured to the point (-1, 0, ..., 0)."""
    loc = block_info[0]["array-location"]
    grids = np.indices(block.shape, dtype=np.float64)
    total = np.zeros(block.shape, np.float64)
    for axis in range(block.ndim):
        coord = grids[axis] + loc[axis][0]
        t = (coord + 1 if axis == 0 else coord) * spacing[axis]
        total += t * t
    return np.sqrt(total)


def _refuse_outputs(return_distances, return_indices, distances, indices):
    if not return_distances or return_indices or distances is not None or indices is not None:
        raise ValueError("voxfield.dask returns the distances only (return_distances=True, "
                         "return_indices=False, no output arrays)")


def distance_transform_edt(input, sampling=None, return_distances=True, return_indices=False,
                           distances=None, indices=None, *, device=None):
    """:func:`voxfield.ndimage.distance_transform_edt` of a dask array, lazily and exactly.

    Parameters
    ----------
    input : dask.array.Array or array_like
        1-D to 3-D, any dtype, chunked any way: the distance of every nonzero element to the
        nearest zero element.
    sampling : float or sequence of float, optional
        Spacing along each axis (array order).
    return_distances, return_indices, distances, indices
        SciPy's signature; only the distances are returned here (``return_indices=True`` or
        output arrays raise ``ValueError``).
    device : None, 'cpu', 'gpu' or int
        The device each task uses with unit sampling (None: ``$VOXFIELD_DEVICE`` of the
        worker, else its first GPU, else its first CPU): the slices along axis 0 run there.
        Other sampling runs every pass on the host in float64, as the one-piece function does.

    Returns
    -------
    dask.array.Array of float64
        Chunked as ``input``; equal bit for bit to the one-piece
        :func:`voxfield.ndimage.distance_transform_edt`.
    """
    _refuse_outputs(return_distances, return_indices, distances, indices)
    _check_device(device)
    a = da.asarray(input)
    if a.ndim < 1 or a.ndim > 3:
        raise ValueError(f"voxfield.dask handles 1-D to 3-D input, got shape {a.shape}")
    spacing = _spacing(sampling, a.ndim)
    targets = a == 0
    if all(v == 1.0 for v in spacing):
        d = _unit_transform(targets, "euclidean", device, np.sqrt, np.float64)
    else:
        d = _separable(targets, "euclidean", spacing,
                       functools.partial(_field_of, metric="euclidean"), np.float64)
    quirk = da.map_blocks(_no_target_edt, targets, spacing, dtype=np.float64)
    return da.where(targets.any(), d, quirk)


def distance_transform_cdt(input, metric="chessboard", return_distances=True,
                           return_indices=False, distances=None, indices=None, *, device=None):
    """:func:`voxfield.ndimage.distance_transform_cdt` of a dask array, lazily and exactly.

    Parameters
    ----------
    input : dask.array.Array or array_like
        1-D to 3-D, any dtype, chunked any way.
    metric : {'chessboard', 'taxicab', 'cityblock', 'manhattan'}
    return_distances, return_indices, distances, indices
        SciPy's signature; only the distances are returned here.
    device : None, 'cpu', 'gpu' or int
        The device each task uses (None: ``$VOXFIELD_DEVICE`` of the worker, else its first
        GPU, else its first CPU): the slices along axis 0 run there.

    Returns
    -------
    dask.array.Array of int32
        Chunked as ``input``; -1 everywhere when the input has no zero element (as SciPy).
    """
    _refuse_outputs(return_distances, return_indices, distances, indices)
    _check_device(device)
    a = da.asarray(input)
    if a.ndim < 1 or a.ndim > 3:
        raise ValueError(f"voxfield.dask handles 1-D to 3-D input, got shape {a.shape}")
    if metric in ("taxicab", "cityblock", "manhattan"):
        m = "manhattan"
    elif metric == "chessboard":
        m = "chebyshev"
    else:
        raise RuntimeError("invalid metric provided")
    return _unit_transform(a == 0, m, device, _cdt_of, np.int32)


def _cdt_of(g, out):
    """int32 distances (into `out`); +inf only where the input has no zero at all: -1 there,
    as SciPy."""
    out[...] = np.where(np.isinf(g), -1.0, g)
