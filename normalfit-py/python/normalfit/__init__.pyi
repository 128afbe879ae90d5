"""Type stubs of normalfit (the functions are in __init__.py, the classes native)."""

from typing import Any, Literal, final

import numpy as np
import numpy.typing as npt

from . import _normalfit as _normalfit

__version__: str
__all__ = ["AxisReport", "TilingReport", "check_tiling", "normals"]

_Border = Literal["wrap", "clamp", "mirror"]
_Heights = npt.NDArray[np.uint8] | npt.NDArray[np.uint16] | npt.NDArray[np.float32] | npt.NDArray[np.float64]

@final
class AxisReport:
    """One axis of a tiling report."""

    @property
    def score(self) -> float: ...
    @property
    def seamless(self) -> bool: ...

@final
class TilingReport:
    """The tiling check's verdict on an array."""

    @property
    def kind(self) -> Literal["height", "normal"]: ...
    @property
    def x(self) -> AxisReport: ...
    @property
    def y(self) -> AxisReport: ...
    @property
    def seamless(self) -> bool: ...
    @property
    def width(self) -> int: ...
    @property
    def height(self) -> int: ...
    @property
    def suggested_borders(self) -> tuple[_Border, _Border]: ...

def normals(
    heights: _Heights,
    *,
    patch: int = 3,
    fit: Literal["orthogonal", "vertical"] = "orthogonal",
    border: str | tuple[_Border, _Border] = "wrap",
    convention: Literal["opengl", "gl", "directx", "dx"] = "opengl",
    scale: float | None = None,
    relief: float | None = None,
    invert: bool = False,
    dtype: npt.DTypeLike = ...,
    residual: bool = False,
    out: npt.NDArray[Any] | None = None,
    threads: int | None = None,
) -> Any: ...
def check_tiling(
    image: _Heights,
    *,
    threshold: float = 1.5,
    kind: Literal["auto", "height", "normal"] = "auto",
) -> TilingReport: ...
