from os import PathLike
from typing import Any, Sequence, Union

import numpy as np
import numpy.typing as npt

__version__: str

_Device = Union[None, str, int]
_Sampling = Union[None, float, Sequence[float]]

def devices() -> list[dict[str, Any]]: ...
def distance_transform(
    world: npt.ArrayLike,
    metric: str = ...,
    signed: bool = ...,
    sampling: _Sampling = ...,
    return_indices: bool = ...,
    max_distance: float | None = ...,
    format: str | None = ...,
    algorithm: str = ...,
    device: _Device = ...,
) -> np.ndarray | tuple[np.ndarray, npt.NDArray[np.int32]]: ...

class Field:
    def __init__(
        self,
        world: npt.ArrayLike,
        metric: str = ...,
        device: _Device = ...,
        algorithm: str = ...,
        format: str | None = ...,
        *,
        sampling: _Sampling = ...,
        signed: bool = ...,
        max_distance: float | None = ...,
    ) -> None: ...
    def edit(
        self, op: str, shape: str, center: Sequence[int], radius: int, material: int = ...
    ) -> dict[str, Any]: ...
    def apply_edits(self, text: str) -> dict[str, Any]: ...
    def distances(self) -> np.ndarray: ...
    def world(self) -> npt.NDArray[np.uint8]: ...

def load_vox(path: str | PathLike[str]) -> tuple[npt.NDArray[np.uint8], npt.NDArray[np.uint8]]: ...
def save_vox(
    path: str | PathLike[str], world: npt.ArrayLike, palette: npt.ArrayLike | None = ...
) -> None: ...
