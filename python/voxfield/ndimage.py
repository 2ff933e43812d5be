"""Drop-in replacements for ``scipy.ndimage``'s distance transforms, on OpenCL devices.

Change one import (``from voxfield import ndimage``) and keep the calls: the functions have
SciPy's signatures, semantics (the distance from each nonzero element of ``input`` to the
nearest zero element; elements outside the array are not zeros), dtypes (``edt`` float64,
``cdt`` int32, indices int32 of shape ``(input.ndim,) + input.shape``), output arrays and error
types, for 1-D, 2-D and 3-D inputs of any dtype and layout, zero-size inputs included. Each
also takes ``device=`` (None: ``$VOXFIELD_DEVICE``, else the first GPU, else the first CPU;
'cpu', 'gpu' or an index from :func:`voxfield.devices`).

Exactness: ``distance_transform_edt`` with unit sampling is bit for bit SciPy's float64 result
(exact integer squared distances, then one float64 square root). With other sampling it runs
the separable passes on the host in float64 (the device's sampled kernels carry float32
partial distances) and adds the axes' terms in SciPy's order, within 2 ulp of SciPy.
``indices`` always name a nearest zero element, and ``edt``'s equal SciPy's: of equally near
zeros SciPy's passes (along the first axis, then the middle, then the last, each taking the
lowest position of equally near sites) name the one of lowest (last, middle, first)
coordinates, and so do the device's passes with unit sampling (they compare the sites'
features by that key) and the host passes with other sampling (SciPy's order of axes and
float64 sums). ``cdt``'s indices come from the device's passes, taxicab's with the same
ties and chessboard's with the lower position along each pass, where SciPy's chamfer sweeps
break ties their own way (a share of the elements differs; the distances are equal).
Bool and integer inputs go to the device as they are (a uint8 or bool array is read in place
on a CPU device, its zero elements the targets); other dtypes as ``input == 0``.

Departures from SciPy: inputs of more than 3 axes raise ``ValueError``; ``cdt`` takes the
metrics 'chessboard' and 'taxicab' (also as their 3x..x3 structuring elements), other
structuring elements raise ``ValueError``; a string ``sampling`` (which SciPy reads as one
number per character) raises ``TypeError``; a 0-d input is taken as 1-d by both functions
(SciPy's ``cdt`` fails on it).
"""

import numpy as np

from voxfield import _core

__all__ = ["distance_transform_cdt", "distance_transform_edt"]


def _arg_check(distances_out, indices_out, return_distances, return_indices):
    """SciPy's checks and messages (RuntimeError) on what to return."""
    errors = []
    if not return_distances and not return_indices:
        errors.append("at least one of return_distances/return_indices must be True")
    if distances_out and not return_distances:
        errors.append("return_distances must be True if distances is supplied")
    if indices_out and not return_indices:
        errors.append("return_indices must be True if indices is supplied")
    if errors:
        raise RuntimeError(", ".join(errors))


def _as_input(input):
    """The input as an array of 1 to 3 axes (0-d taken as 1-d)."""
    a = np.atleast_1d(np.asarray(input))
    if a.ndim > 3:
        raise ValueError(
            f"voxfield.ndimage handles 1-D to 3-D input, got {a.ndim} axes (shape {a.shape})")
    return a


def _sampling(sampling, ndim):
    """SciPy's sampling rules: None, one number, or one number per axis; as floats."""
    if sampling is None:
        return None
    if isinstance(sampling, (str, bytes)):
        raise TypeError("sampling must be a number or a sequence of numbers, not a string")
    s = np.asarray(sampling, dtype=np.float64)
    if s.ndim == 0:
        s = np.full(ndim, float(s))
    elif s.ndim != 1 or s.size != ndim:
        raise RuntimeError("sequence argument must have length equal to input rank")
    if not np.all(np.isfinite(s)) or np.any(s <= 0):
        raise ValueError(f"sampling: every value must be positive and finite, got {list(s)}")
    return s


def _as_3d(a):
    return a.reshape((1,) * (3 - a.ndim) + a.shape)


def _result(return_distances, dt, dt_inplace, return_indices, ft, ft_inplace):
    out = []
    if return_distances and not dt_inplace:
        out.append(dt)
    if return_indices and not ft_inplace:
        out.append(ft)
    if len(out) == 2:
        return tuple(out)
    if len(out) == 1:
        return out[0]
    return None


def _indices_from_linear(feat, shape):
    """int32 (ndim, *shape) coordinates of linear indices (-1 stays -1 on every plane)."""
    out = np.empty((len(shape),) + tuple(shape), dtype=np.int32)
    none = feat < 0
    coords = np.unravel_index(np.where(none, 0, feat), shape)
    for axis, c in enumerate(coords):
        out[axis] = np.where(none, -1, c)
    return out


def distance_transform_edt(input, sampling=None, return_distances=True, return_indices=False,
                           distances=None, indices=None, *, device=None):
    """Exact Euclidean distance transform, as ``scipy.ndimage.distance_transform_edt``.

    Parameters
    ----------
    input : array_like
        1-D to 3-D, any dtype: the distance of every nonzero element to the nearest zero
        element is computed.
    sampling : float or sequence of float, optional
        Spacing of elements along each axis (array order); one number for every axis.
    return_distances : bool
        Whether to return the distance transform.
    return_indices : bool
        Whether to return the feature transform (the index of a nearest zero element).
    distances : ndarray of float64, optional
        Output array for the distances (same shape as input); then not returned.
    indices : ndarray of int32, optional
        Output array of shape ``(input.ndim,) + input.shape`` for the feature transform; then
        not returned.
    device : None, 'cpu', 'gpu' or int
        The OpenCL device (see :mod:`voxfield.ndimage`).

    Returns
    -------
    distances : ndarray of float64
        Unless ``return_distances`` is False or ``distances`` was given.
    indices : ndarray of int32
        With ``return_indices`` unless ``indices`` was given.
    None
        When both went into output arrays.

    Raises
    ------
    RuntimeError
        SciPy's errors: nothing to return, an output array of the wrong shape or dtype, a
        sampling sequence of the wrong length.
    ValueError, TypeError
        More than 3 axes, a non-positive or string sampling, a bad device.
    """
    ft_inplace = isinstance(indices, np.ndarray)
    dt_inplace = isinstance(distances, np.ndarray)
    _arg_check(dt_inplace, ft_inplace, return_distances, return_indices)
    a = _as_input(input)
    s = _sampling(sampling, a.ndim)
    shape = a.shape
    if ft_inplace:
        if indices.shape != (a.ndim,) + shape:
            raise RuntimeError("indices array has wrong shape")
        if indices.dtype.type != np.int32:
            raise RuntimeError("indices array must be int32")
    if dt_inplace:
        if distances.shape != shape:
            raise RuntimeError("distances array has wrong shape")
        if distances.dtype.type != np.float64:
            raise RuntimeError("distances array must be float64")

    ft = None
    device_path = s is None or bool(np.all(s == 1.0))
    out = None
    if a.size == 0:
        dt = np.zeros(shape, np.float64)
        ft = np.zeros((a.ndim,) + shape, np.int32)
    elif device_path:
        # Straight into the caller's distances where the device can write them in place.
        into = _writable_in_place(distances) if dt_inplace and return_distances else None
        world, targets = _zero_targets(a)
        out = _core.distance_transform(_as_3d(world), "euclidean", False, None,
                                       bool(return_indices), None, "f64", "exact", device,
                                       out=None if into is None else _as_3d(into),
                                       targets=targets)
        field = out[0] if return_indices else out
        if return_indices:
            ft = out[1][3 - a.ndim:].reshape((a.ndim,) + shape)
        dt = field.reshape(shape)
    if a.size != 0 and (not device_path and a.all() or
                        device_path and np.isinf(dt.flat[0])):
        # No zero at all (the device's field is +inf then): SciPy's feature transform is -1
        # on axis 0, 0 on the others, and the distances are measured to that point.
        ft = np.zeros((a.ndim,) + shape, np.int32)
        ft[0] = -1
        d = (ft - np.indices(shape, dtype=np.int32)).astype(np.float64)
        if s is not None:
            for axis in range(a.ndim):
                d[axis] *= s[axis]
        np.multiply(d, d, d)
        dt = np.sqrt(np.add.reduce(d, axis=0))
    elif a.size != 0 and not device_path:
        spacing = [1.0] * a.ndim if s is None else [float(v) for v in s]
        g, feat = _core.host_transform(np.equal(a, 0), "euclidean", spacing,
                                       bool(return_indices))
        dt = np.sqrt(g)
        if return_indices:
            ft = _indices_from_linear(feat, shape)

    if dt_inplace and return_distances and not np.may_share_memory(dt, distances):
        np.copyto(distances, dt)
    if ft_inplace and return_indices:
        np.copyto(indices, ft)
    return _result(return_distances, dt, dt_inplace, return_indices, ft, ft_inplace)


def _zero_targets(a):
    """(world, targets) for _core.distance_transform measuring to the zero elements of `a`:
    bool and integer arrays as they are with targets='zero' (the device reads a uint8 or bool
    array in place and takes its zero bytes as the targets), others as ``a == 0`` (nonzero
    targets)."""
    if a.dtype.kind in "biu":
        return a, "zero"
    return np.equal(a, 0), "nonzero"


def _writable_in_place(array):
    """`array` when the device can write it as it is (C-contiguous, aligned, writable),
    else None (the result is then copied into it)."""
    flags = array.flags
    if flags.c_contiguous and flags.aligned and flags.writeable:
        return array
    return None


def _cdt_metric(metric, ndim):
    """'manhattan' or 'chebyshev' for SciPy's metric argument."""
    if isinstance(metric, str):
        if metric in ("taxicab", "cityblock", "manhattan"):
            return "manhattan"
        if metric == "chessboard":
            return "chebyshev"
        raise RuntimeError("invalid metric provided")
    try:
        m = np.asarray(metric, dtype=np.int8)
    except Exception as e:
        raise RuntimeError("invalid metric provided") from e
    for size in m.shape:
        if size != 3:
            raise RuntimeError("metric sizes must be equal to 3")
    if m.ndim != ndim:
        raise RuntimeError("metric rank must equal the input rank")
    grid = np.indices((3,) * ndim) - 1
    steps = np.abs(grid).sum(axis=0)
    if np.array_equal(m != 0, steps <= 1):
        return "manhattan"
    if np.all(m != 0):
        return "chebyshev"
    raise ValueError("voxfield.ndimage.distance_transform_cdt computes the taxicab and "
                     "chessboard metrics; for other structuring elements use "
                     "scipy.ndimage.distance_transform_cdt")


def distance_transform_cdt(input, metric="chessboard", return_distances=True,
                           return_indices=False, distances=None, indices=None, *, device=None):
    """Chamfer distance transform, as ``scipy.ndimage.distance_transform_cdt``.

    The taxicab and chessboard chamfer distances are the exact L1 and L-inf distances, which
    the device computes directly.

    Parameters
    ----------
    input : array_like
        1-D to 3-D, any dtype: the distance of every nonzero element to the nearest zero
        element is computed.
    metric : {'chessboard', 'taxicab', 'cityblock', 'manhattan'} or array_like
        'taxicab' (synonyms 'cityblock', 'manhattan') or 'chessboard', or the 3x..x3
        structuring element of one of them.
    return_distances, return_indices : bool
        What to return.
    distances : ndarray of int32, optional
        Output array for the distances; then not returned.
    indices : ndarray of int32, optional
        Output array of shape ``(input.ndim,) + input.shape``; then not returned.
    device : None, 'cpu', 'gpu' or int
        The OpenCL device (see :mod:`voxfield.ndimage`).

    Returns
    -------
    distances : ndarray of int32
        -1 everywhere when the input has no zero element (as SciPy).
    indices : ndarray of int32
        With ``return_indices`` unless ``indices`` was given.
    None
        When both went into output arrays.

    Raises
    ------
    RuntimeError
        SciPy's errors: nothing to return, an invalid metric, an output array of the wrong
        shape or dtype.
    ValueError
        More than 3 axes, a structuring element other than taxicab's or chessboard's.
    """
    ft_inplace = isinstance(indices, np.ndarray)
    dt_inplace = isinstance(distances, np.ndarray)
    _arg_check(dt_inplace, ft_inplace, return_distances, return_indices)
    a = _as_input(input)
    m = _cdt_metric(metric, a.ndim)
    shape = a.shape
    if dt_inplace:
        if distances.dtype.type != np.int32:
            raise RuntimeError("distances must be of int32 type")
        if distances.shape != shape:
            raise RuntimeError("distances has wrong shape")
    if ft_inplace:
        if indices.dtype.type != np.int32:
            raise RuntimeError("indices array must be int32")
        if indices.shape != (a.ndim,) + shape:
            raise RuntimeError("indices array has wrong shape")

    targets = np.equal(a, 0)
    ft = None
    if a.size == 0 or return_indices and not targets.any():
        dt = np.full(shape, -1, np.int32)
        ft = np.indices(shape, dtype=np.int32)
    else:
        # u32 (the sweeps' format; i32 would take the slower separable kernels): with a zero
        # in the input every distance is below 2^31, so its bits are the int32 values; with
        # none every element saturates at 2^32 - 1, which is SciPy's -1.
        into = _writable_in_place(distances) if dt_inplace and return_distances else None
        out = _core.distance_transform(_as_3d(targets), m, False, None, bool(return_indices),
                                       None, "u32", "exact", device,
                                       out=None if into is None else _as_3d(into.view(np.uint32)))
        if return_indices:
            field, idx = out
            ft = idx[3 - a.ndim:].reshape((a.ndim,) + shape)
        else:
            field = out
        dt = field.view(np.int32).reshape(shape)

    if dt_inplace and return_distances and not np.may_share_memory(dt, distances):
        np.copyto(distances, dt)
    if ft_inplace and return_indices:
        np.copyto(indices, ft)
    return _result(return_distances, dt, dt_inplace, return_indices, ft, ft_inplace)
