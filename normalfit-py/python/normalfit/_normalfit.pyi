"""The native module: every argument positional (normalfit's functions name them)."""

from typing import Any

from normalfit import AxisReport as AxisReport, TilingReport as TilingReport

__all__ = ["normals", "check_tiling", "AxisReport", "TilingReport", "__version__"]

__version__: str

def normals(
    heights: Any,
    patch: Any,
    fit: str,
    border: Any,
    convention: str,
    scale: float | None,
    relief: float | None,
    invert: bool,
    dtype: Any,
    residual: bool,
    out: Any | None,
    threads: int | None,
) -> Any: ...
def check_tiling(image: Any, threshold: float, kind: str) -> TilingReport: ...
