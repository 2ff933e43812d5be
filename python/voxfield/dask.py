"""Distance transforms of ``dask.array`` volumes, block by block, exactly.

Every function returns a lazy dask array equal, value for value, to the one-piece result of
the same call on the whole array (:func:`voxfield.distance_transform`,
:func:`voxfield.ndimage.distance_transform_edt`, :func:`voxfield.ndimage.distance_transform_cdt`),
on any scheduler (threads, processes, a ``distributed`` cluster).

Two exact schemes:

* Bounded fields (``distance_transform(..., max_distance=D)``): each block is computed on the
  OpenCL device with a halo of ``ceil(D / sampling)`` voxels per axis, at most the axis's
  length (``map_overlap``; Dask merges blocks smaller than the halo first). A voxel's value
  depends only on the solids within D, which the halo holds, and everything beyond D
  saturates at D.
* Unbounded fields (``distance_transform`` without ``max_distance``,
  ``distance_transform_edt`` and ``distance_transform_cdt``): the separable transform on the
  host in slabs along axis 0 (a chunk row of blocks spanning every other axis, about 640
  MiB of targets and output each at most). Along axis 0 the first pass of a line needs only
  the nearest target before and after each slab, so every block first gives the first and
  last target of each of its lines (from a clone of the input's graph: the input is read
  twice, and nothing waits in memory for the slabs), a cumulative maximum / minimum over the
  blocks carries them along axis 0, and each slab then computes its first pass and the
  passes along the other axes. With unit sampling one task per slab
  (``voxfield._core.slab_pieces``) takes the slab's blocks as they are, runs every pass in
  exact integer arithmetic a group of planes at a time and writes the output format straight
  into one piece per output chunk (L2 the square root of the exact squared distance, rounded
  once, so edt equals the one-piece function bit for bit): no block is concatenated, no slab
  is split, and each chunk of the result is its own piece of the slab's tuple. With other
  sampling the slab's first pass (``voxfield._core.axis0_distances``) and float64 passes a
  few planes at a time (``voxfield._core.slab_passes``, axes 0, 1, 2 in turn, so sampled
  sums are SciPy's), the slab split back into the input's chunks. No partial distance moves
  between workers. Each line is computed whole, so no result depends on the chunks.

Each bounded task picks its device when it runs: ``device=`` if given, else
``$VOXFIELD_DEVICE`` as the worker's environment has it, else the first GPU, else the first
CPU; each worker process keeps one OpenCL context per device. A device that a worker does not
have fails that task. The unbounded scheme uses no device (``distance_transform_edt`` and
``distance_transform_cdt`` take ``device=`` for the drop-in signature and check its form).
"""

import functools
import itertools
import math
import operator

import dask.array as da
import numpy as np
from dask.array.reductions import cumreduction
from dask.base import tokenize
from dask.graph_manipulation import clone
from dask.highlevelgraph import HighLevelGraph

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


# A slab of the unbounded scheme holds at most this many bytes of targets and output (and,
# with non-unit sampling, first pass) unless one plane is larger: a 128-plane chunk row of a
# 1024^2 float32 field whole. A slab thinner than its input chunk costs a merge (a transfer
# between workers) when the output goes back into the input's chunks, so halving this
# measured slower. With non-unit sampling the passes after the first run on _PASS_ELEMENTS
# elements at a time (float64).
_SLAB_BYTES = 5 << 27
_PASS_ELEMENTS = 1 << 21
_NONE = np.iinfo(np.int64).max  # "no target" in the cumulative minimum of first targets


def _line_ends(block, block_info=None):
    """Per line along axis 0 of a block of targets (nonzero): the global positions of its
    first and last target (-1: none), stacked as a (2, ...) int64 block."""
    return _core.axis0_ends(block, block_info[0]["array-location"][0][0])


def _distance_bytes(length):
    """Bytes per element of axis0_distances' output for an axis 0 of `length`."""
    return 2 if length < 65535 else 4


def _slab_block(slab, before, after, metric, spacing, finish, dtype, length, block_info=None):
    """The field of a slab spanning every axis but axis 0, in `dtype`, with non-unit sampling:
    the first pass along axis 0 from the slab's targets (nonzero) and the nearest targets
    before and after it on every line (`before`, `after`: one block along axis 0, -1: none),
    then the float64 ``slab_passes`` a few planes at a time and `finish` of their result."""
    z0 = block_info[0]["array-location"][0][0]
    out = np.empty(slab.shape, dtype)
    # The first pass's distances live in the tail of `out` where they fit: the planes written
    # so far end before the distances of the planes still to read begin.
    d_dtype = np.dtype(np.uint16 if _distance_bytes(length) == 2 else np.uint32)
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


def _separable(targets, metric, spacing, dtype, finish=None, minus_one=False):
    """The lazy field of a dask array of targets (nonzero), chunked as `targets` and of
    `dtype`, by slabs along axis 0 (the module docstring's second scheme): each slab's first
    pass needs, per line, only the nearest targets before and after it, which a cumulative
    maximum / minimum of the blocks' first and last targets gives. With unit sampling the
    slabs write `dtype` themselves (`minus_one`: -1 where nothing is reachable); otherwise
    `finish` maps their float64 partials (L2: squared) into it."""
    chunks = targets.chunks
    if targets.dtype.itemsize != 1 or targets.dtype.kind not in "bu":
        targets = targets != 0  # bool and uint8 blocks are read as they are
    if targets.size == 0:
        return da.zeros(targets.shape, dtype, chunks=chunks)
    plane = max(1, math.prod(targets.shape[1:]))
    item = np.dtype(dtype).itemsize
    unit = all(v == 1.0 for v in spacing)
    dbytes = _distance_bytes(targets.shape[0])
    # Unit sampling: the slab's blocks and pieces (the first pass a few planes at a time);
    # else targets, output and the first pass (in the output's tail where it fits).
    per_element = 1 + item + (0 if unit or (item >= dbytes and item % dbytes == 0) else dbytes)
    depth = max(1, _SLAB_BYTES // (plane * per_element))
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
    if unit:
        g = _unit_slabs(t, before, after, metric, dtype, minus_one)
    else:
        g = t.rechunk(whole).map_blocks(_slab_block, before, after, metric, spacing, finish,
                                        dtype, targets.shape[0], dtype=dtype)
    return g.rechunk(chunks)


def _slab_pieces(blocks, before, after, z0, length, metric, dtype, y_edges, x_edges, minus_one):
    """The field of one slab with unit sampling, in `dtype`, from its blocks of targets (a
    row-major list over the other axes' chunks) and its lines' nearest targets before and
    after it: a tuple of one C-contiguous piece per block, of the block's shape."""
    out = [np.empty(b.shape, dtype) for b in blocks]
    _core.slab_pieces(blocks, before, after, z0, length, metric, out, y_edges, x_edges,
                      minus_one)
    return tuple(out)


def _unit_slabs(t, before, after, metric, dtype, minus_one):
    """The lazy field of targets `t` (one chunk row per slab along axis 0) with unit sampling,
    chunked as `t`: one task per slab computes every piece of it (``_slab_pieces``: the blocks
    of the slab go in as they are, the pieces come out in the chunks of `t`, so no block is
    concatenated, split or copied), one key per piece picks it from the slab's tuple."""
    token = tokenize(t, before, after, metric, np.dtype(dtype), minus_one)
    slab_name, name = "slab-pieces-" + token, "slab-field-" + token
    inner = t.chunks[1:]
    # The other axes seen as (rows, columns) of each plane, as _core.slab_pieces takes them.
    yx = ([(1,)] * (2 - len(inner)) + list(inner))[-2:]
    y_edges, x_edges = ([int(e) for e in np.cumsum((0,) + c)] for c in yx)
    cells = list(itertools.product(*(range(len(c)) for c in inner)))
    zeros = (0,) * len(inner)
    offsets = np.cumsum((0,) + t.chunks[0])
    dsk = {}
    for s in range(len(t.chunks[0])):
        dsk[(slab_name, s)] = (_slab_pieces, [(t.name, s) + c for c in cells],
                               (before.name, s) + zeros, (after.name, s) + zeros,
                               int(offsets[s]), t.shape[0], metric, np.dtype(dtype), y_edges,
                               x_edges, minus_one)
        for i, c in enumerate(cells):
            dsk[(name, s) + c] = (operator.getitem, (slab_name, s), i)
    graph = HighLevelGraph.from_collections(name, dsk, dependencies=[t, before, after])
    return da.Array(graph, name, chunks=t.chunks, dtype=dtype)


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
        # Within D of a voxel along an axis; no more than the axis (a halo past it is refused).
        depth = {a: min(int(math.ceil(bound / spacing[a])), w.shape[a]) for a in range(3)}
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
    return _separable(w, metric, spacing, dtype, functools.partial(_field_of, metric=metric))


def _field_of(g, out, metric):
    """The field (into `out`, in its format) of partial distances after every pass (L2:
    squared; `g` is overwritten)."""
    if metric == "euclidean":
        np.sqrt(g, out=g)
    _store(g, out)


def _or_no_target_edt(d, spacing, block_info=None):
    """A block of edt distances, or where the input has no zero at all (the block is +inf
    then, as every block is) SciPy's edt of it: measured to the point (-1, 0, ..., 0)."""
    if d.size == 0 or not np.isinf(d.flat[0]):
        return d
    loc = block_info[0]["array-location"]
    grids = np.indices(d.shape, dtype=np.float64)
    total = np.zeros(d.shape, np.float64)
    for axis in range(d.ndim):
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
        Checked for its form only (:func:`voxfield.ndimage.distance_transform_edt`'s
        signature): the slabs run on the host, exact integers with unit sampling, float64
        with other sampling (as the one-piece function does).

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
    d = _separable(targets, "euclidean", spacing, np.float64,
                   functools.partial(_field_of, metric="euclidean"))
    return d.map_blocks(_or_no_target_edt, spacing, dtype=np.float64)


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
        Checked for its form only (the one-piece function's signature): the slabs run on
        the host in exact integer arithmetic.

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
    # -1 where nothing is reachable: everywhere when the input has no zero (as SciPy).
    return _separable(a == 0, m, [1.0] * a.ndim, np.int32, minus_one=True)
