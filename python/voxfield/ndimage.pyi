from typing import Sequence, Union

import numpy as np
import numpy.typing as npt

_Device = Union[None, str, int]

def distance_transform_edt(
    input: npt.ArrayLike,
    sampling: float | Sequence[float] | None = ...,
    return_distances: bool = ...,
    return_indices: bool = ...,
    distances: npt.NDArray[np.float64] | None = ...,
    indices: npt.NDArray[np.int32] | None = ...,
    *,
    device: _Device = ...,
) -> (
    npt.NDArray[np.float64]
    | npt.NDArray[np.int32]
    | tuple[npt.NDArray[np.float64], npt.NDArray[np.int32]]
    | None
): ...
def distance_transform_cdt(
    input: npt.ArrayLike,
    metric: str | npt.ArrayLike = ...,
    return_distances: bool = ...,
    return_indices: bool = ...,
    distances: npt.NDArray[np.int32] | None = ...,
    indices: npt.NDArray[np.int32] | None = ...,
    *,
    device: _Device = ...,
) -> npt.NDArray[np.int32] | tuple[npt.NDArray[np.int32], npt.NDArray[np.int32]] | None: ...
