from typing import Any, Sequence, Union

import dask.array as da
import numpy.typing as npt

_Device = Union[None, str, int]

def distance_transform(
    world: da.Array | npt.ArrayLike,
    metric: str = ...,
    signed: bool = ...,
    sampling: float | Sequence[float] | None = ...,
    max_distance: float | None = ...,
    format: str | None = ...,
    device: _Device = ...,
) -> da.Array: ...
def distance_transform_edt(
    input: da.Array | npt.ArrayLike,
    sampling: float | Sequence[float] | None = ...,
    return_distances: bool = ...,
    return_indices: bool = ...,
    distances: Any = ...,
    indices: Any = ...,
    *,
    device: _Device = ...,
) -> da.Array: ...
def distance_transform_cdt(
    input: da.Array | npt.ArrayLike,
    metric: str = ...,
    return_distances: bool = ...,
    return_indices: bool = ...,
    distances: Any = ...,
    indices: Any = ...,
    *,
    device: _Device = ...,
) -> da.Array: ...
