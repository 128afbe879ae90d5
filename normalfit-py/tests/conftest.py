"""What the tests share: the command line to compare with, and image files."""

from __future__ import annotations

import os
import struct
import subprocess
from pathlib import Path

import numpy as np
import png  # pypng: reads and writes 16-bit PNG exactly
import pytest

ROOT = Path(__file__).resolve().parents[2]
"""The repository's root (normalfit-py/tests/ is two levels down)."""

CONFORMANCE = ROOT.parent / "shared" / "conformance" / "cases"
"""The contract's check cases, beside the clone as in CI."""


@pytest.hookimpl(hookwrapper=True)
def pytest_runtest_makereport(item: pytest.Item, call: pytest.CallInfo[None]):  # type: ignore[no-untyped-def]
    """In CI (``CI`` set), which installs everything the tests need (the
    binary, Blender, mypy, the contract's cases beside the clone), a skip
    is a failure: no test passes there by not running. Elsewhere a skip
    stays a skip, with its reason (``pytest -rs``)."""
    outcome = yield
    report = outcome.get_result()
    if os.environ.get("CI") and report.skipped and not hasattr(report, "wasxfail"):
        report.outcome = "failed"
        report.longrepr = f"skipped in CI, where what it needs is installed: {report.longrepr}"


def cli_binary() -> Path | None:
    """$NORMALFIT_BIN, else the newer of target/release and target/debug's
    normalfit (built from the same tree as the wheel, in CI)."""
    if "NORMALFIT_BIN" in os.environ:
        return Path(os.environ["NORMALFIT_BIN"])
    built = [p for p in (ROOT / "target" / "release" / "normalfit", ROOT / "target" / "debug" / "normalfit") if p.exists()]
    return max(built, key=lambda p: p.stat().st_mtime) if built else None


@pytest.fixture(scope="session")
def cli() -> Path:
    binary = cli_binary()
    if binary is None:
        pytest.skip("no normalfit binary: cargo build --release first (or set NORMALFIT_BIN)")
    return binary


def run_cli(binary: Path, *args: object) -> subprocess.CompletedProcess[str]:
    result = subprocess.run([str(binary), *map(str, args)], capture_output=True, text=True, timeout=300)
    assert result.returncode == 0, f"normalfit {' '.join(map(str, args))}: exit {result.returncode}: {result.stderr}"
    return result


def read_png(path: Path) -> np.ndarray:
    """(H, W) for gray, (H, W, C) for colour, in the file's own dtype."""
    width, height, rows, info = png.Reader(filename=str(path)).read()
    dt = np.uint16 if info["bitdepth"] > 8 else np.uint8
    planes = info["planes"]
    pixels = np.vstack([np.asarray(row, dtype=dt) for row in rows]).reshape(height, width, planes)
    return pixels[:, :, 0] if planes == 1 else pixels


def write_png(path: Path, image: np.ndarray) -> None:
    """A gray (H, W) or RGB (H, W, 3) uint8/uint16 image."""
    bitdepth = 16 if image.dtype == np.uint16 else 8
    height, width = image.shape[:2]
    greyscale = image.ndim == 2
    rows = image.reshape(height, -1)
    png.Writer(width, height, greyscale=greyscale, bitdepth=bitdepth).write(open(path, "wb"), rows.tolist())


def write_float_tiff(path: Path, heights: np.ndarray, nodata: str | None = None) -> None:
    """A one-channel 32-bit float TIFF, uncompressed, one strip: the float
    input the command line reads, written with nothing but struct; with
    GDAL's GDAL_NODATA tag when nodata is given."""
    height, width = heights.shape
    data = np.ascontiguousarray(heights, dtype="<f4").tobytes()
    text = b"" if nodata is None else nodata.encode() + b"\x00"
    entries = [
        (256, 4, 1, width),  # ImageWidth
        (257, 4, 1, height),  # ImageLength
        (258, 3, 1, 32),  # BitsPerSample
        (259, 3, 1, 1),  # Compression: none
        (262, 3, 1, 1),  # Photometric: black is zero
        (273, 4, 1, 0),  # StripOffsets, patched below
        (277, 3, 1, 1),  # SamplesPerPixel
        (278, 4, 1, height),  # RowsPerStrip
        (279, 4, 1, len(data)),  # StripByteCounts
        (339, 3, 1, 3),  # SampleFormat: IEEE float
    ]
    if text:
        entries.append((42113, 2, len(text), 0))  # GDAL_NODATA: ASCII, patched below
    ifd_size = 2 + 12 * len(entries) + 4
    text_offset = 8 + ifd_size
    data_offset = text_offset + len(text)
    out = bytearray(b"II*\x00" + struct.pack("<I", 8) + struct.pack("<H", len(entries)))
    for tag, kind, count, value in entries:
        value = {273: data_offset, 42113: text_offset}.get(tag, value)
        packed = struct.pack("<H", value) + b"\x00\x00" if kind == 3 else struct.pack("<I", value)
        out += struct.pack("<HHI", tag, kind, count) + packed
    out += struct.pack("<I", 0) + text + data
    path.write_bytes(bytes(out))
