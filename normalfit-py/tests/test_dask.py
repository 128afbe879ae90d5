"""normalfit.dask: lazy normals of Dask arrays equal to normalfit.normals of
the whole array, bit for bit, on a two-process LocalCluster; the tiling
check; threads per task; chunks that fail; the Zarr writer that leaves
nothing half-written.

Every result is compared at run time with normalfit.normals (or
normalfit.check_tiling) on the whole computed array, never with recorded
numbers."""

from __future__ import annotations

import itertools
import os
import threading
import time
from pathlib import Path
from typing import Any, Iterator

import numpy as np
import pytest

da = pytest.importorskip("dask.array", reason="dask is not installed (pip install 'normalfit[dask]')")
distributed = pytest.importorskip("distributed", reason="distributed is not installed (pip install 'normalfit[dask]')")
import dask  # noqa: E402
import dask.array as da  # noqa: E402

import normalfit  # noqa: E402
import normalfit.dask as nd  # noqa: E402

MODES = ("wrap", "clamp", "mirror")
IN_DTYPES = (np.uint8, np.uint16, np.float32, np.float64)
OUT_DTYPES = (np.float32, np.uint8, np.uint16)


@pytest.fixture(scope="module")
def client() -> Iterator[Any]:
    """One cluster for the module: two worker processes of one thread."""
    with distributed.LocalCluster(
        n_workers=2, processes=True, threads_per_worker=1, dashboard_address=None, memory_limit="2GiB"
    ) as cluster, distributed.Client(cluster) as c:
        yield c


def heights(shape: tuple[int, int], dtype: Any, seed: int = 0) -> np.ndarray:
    """Heights with slopes and detail on both axes (not a constant, whose
    normals any wrong read would also give)."""
    rng = np.random.default_rng(seed)
    h, w = shape
    y, x = np.mgrid[0:h, 0:w]
    smooth = 0.5 + 0.3 * np.sin(x * 0.7) * np.cos(y * 0.45) + 0.1 * rng.random(shape)
    if dtype == np.uint8:
        return (smooth * 255).astype(np.uint8)
    if dtype == np.uint16:
        return (smooth * 65535).astype(np.uint16)
    return (smooth * 3.0 - 1.0).astype(dtype)


SHAPE = (12, 15)
CHUNKINGS: list[Any] = [
    (5, 4),  # even, with a short last chunk
    ((1, 6, 2, 3), (3, 1, 8, 1, 2)),  # uneven, some smaller than any halo
    (1, 1),  # one texel each
    (2, 2),  # smaller than N = 5 and 7's halo
    (12, 15),  # one chunk
    ((12,), (1, 13, 1)),  # one chunk down, thin edges across
]


BORDER_PAIRS = list(itertools.product(MODES, MODES))


@pytest.mark.parametrize("bx,by", BORDER_PAIRS)
def test_equals_the_whole_image_for_every_border_pair(client: Any, bx: str, by: str) -> None:
    """Every chunking, each with one of N = 3, 5, 7 taken in turn from pair
    to pair (so every chunking meets every N three times over the nine
    pairs, and every pair every N); the fits and every pair of input and
    output dtypes cycled through the cases; against normalfit.normals.
    (Every chunking with every N for every pair took three times as long:
    one-texel chunks at N = 7 are a graph of some 10 000 tasks.)"""
    cases = []
    kinds = itertools.cycle(itertools.product(IN_DTYPES, OUT_DTYPES))
    fits = itertools.cycle(("orthogonal", "vertical"))
    turn = BORDER_PAIRS.index((bx, by))
    for k, chunks in enumerate(CHUNKINGS):
        patch = (3, 5, 7)[(k + turn) % 3]
        in_dtype, out_dtype = next(kinds)
        fit = next(fits)
        whole = heights(SHAPE, in_dtype, seed=patch)
        opts = dict(patch=patch, fit=fit, border=(bx, by), dtype=out_dtype, scale=2.5)
        lazy = nd.normals(da.from_array(whole, chunks=chunks), **opts)
        assert lazy.chunks[:2] == da.from_array(whole, chunks=chunks).chunks and lazy.chunks[2] == (3,)
        assert lazy.dtype == np.dtype(out_dtype)
        cases.append((lazy, normalfit.normals(whole, **opts), (chunks, fit, patch, in_dtype, out_dtype)))
    computed = dask.compute(*[c[0] for c in cases])
    for got, (_, want, what) in zip(computed, cases):
        assert got.dtype == want.dtype and np.array_equal(got, want), what


@pytest.mark.parametrize("in_dtype", IN_DTYPES)
@pytest.mark.parametrize("out_dtype", OUT_DTYPES)
def test_every_dtype_pair_with_relief_and_options(client: Any, in_dtype: Any, out_dtype: Any) -> None:
    """Relief takes the whole image's width, not a chunk's; convention and
    invert pass through."""
    whole = heights((40, 57), in_dtype, seed=3)
    opts = dict(patch=9, relief=0.02, convention="directx", invert=True, border="mirror,wrap", dtype=out_dtype)
    lazy = nd.normals(da.from_array(whole, chunks=(11, 16)), **opts)
    assert np.array_equal(lazy.compute(), normalfit.normals(whole, **opts))


def test_residual_is_a_pair_of_lazy_arrays(client: Any) -> None:
    whole = heights((30, 26), np.float32)
    n, r = nd.normals(da.from_array(whole, chunks=(4, 9)), patch=5, border=("clamp", "wrap"), residual=True,
                      dtype=np.uint16)
    got_n, got_r = dask.compute(n, r)
    want_n, want_r = normalfit.normals(whole, patch=5, border=("clamp", "wrap"), residual=True, dtype=np.uint16)
    assert got_n.dtype == np.uint16 and got_r.dtype == np.float32
    assert np.array_equal(got_n, want_n) and np.array_equal(got_r, want_r)


@pytest.mark.parametrize("border", ["wrap", "clamp", ("mirror", "wrap")])
def test_holes_chunked_equal_the_whole_array(client: Any, border: Any) -> None:
    """A nodata value and NaN, scattered and in a block across chunk
    edges: each chunk's halo carries its neighbours' holes, so the lazy
    normals and residual equal normalfit.normals(nodata=...) of the whole
    array, bit for bit, NaN where missing; the fit on the valid points is
    not the plain fit's near a hole (holes are not read as heights)."""
    rng = np.random.default_rng(7)
    whole = heights((23, 31), np.float64, seed=5)
    whole[rng.random(whole.shape) < 0.08] = -9999.0
    whole[9:14, 10:17] = -9999.0  # across the chunk edges at rows 10 and columns 12
    whole[2, 3] = np.nan
    for patch, chunks in ((3, (5, 6)), (5, (10, 12)), (7, ((1, 9, 13), (12, 19)))):
        opts = dict(patch=patch, border=border, nodata=-9999.0, residual=True, fit="orthogonal")
        n, r = nd.normals(da.from_array(whole, chunks=chunks), **opts)
        got_n, got_r = dask.compute(n, r)
        want_n, want_r = normalfit.normals(whole, **opts)
        missing = np.isnan(want_n[..., 0])
        assert missing[9:14, 10:17].all() and missing[2, 3] and 0 < missing.mean() < 0.9, (patch, chunks)
        assert np.array_equal(got_n, want_n, equal_nan=True), (patch, chunks)
        assert np.array_equal(got_r, want_r, equal_nan=True), (patch, chunks)
        filled = np.where(np.isfinite(whole) & (whole != -9999.0), whole, 0.0)
        plain = normalfit.normals(filled, patch=patch, border=border)
        assert not np.allclose(plain[~missing], got_n[~missing]), "holes read as heights"
    with pytest.raises(ValueError, match="nodata needs dtype float32"):
        nd.normals(da.from_array(whole, chunks=(5, 6)), nodata=-9999.0, dtype=np.uint8)


@pytest.mark.parametrize("border", ["wrap", ("clamp", "mirror")])
def test_binomial_weights_by_blocks_chunked_equal_the_whole_array(client: Any, border: Any) -> None:
    """Binomial weights from N = 37 on are summed by FFT in blocks aligned
    on the image: each chunk holds its blocks' inputs, a halo the library
    plans chunk by chunk (up to r + B - 1 a side, B = 88 at N = 41), so the
    lazy normals equal the whole array's bit for bit, holes included."""
    whole = heights((70, 130), np.float64, seed=3) * 100.0 + 400.0
    whole[30:33, 50:60] = -9999.0
    for patch, chunks in ((41, (25, 40)), (65, ((10, 45, 15), (31, 99)))):
        opts = dict(patch=patch, border=border, weights="binomial", nodata=-9999.0, fit="vertical")
        got = nd.normals(da.from_array(whole, chunks=chunks), **opts).compute()
        want = normalfit.normals(whole, **opts)
        assert np.array_equal(got, want, equal_nan=True), (patch, chunks)
        plain = normalfit.normals(whole, **{**opts, "weights": "uniform"})
        assert not np.allclose(plain, want, equal_nan=True), "the weights made no difference"


def test_a_patch_wider_than_the_image(client: Any) -> None:
    """N = 15 on a 6 x 5 image: indices keep mapping by the border's rule."""
    whole = heights((5, 6), np.float64)
    for border in MODES:
        for chunks in ((1, 1), (2, 3), (5, 6)):
            got = nd.normals(da.from_array(whole, chunks=chunks), patch=15, border=border).compute()
            assert np.array_equal(got, normalfit.normals(whole, patch=15, border=border)), (border, chunks)


@pytest.mark.parametrize("border", ["wrap", "clamp", ("mirror", "wrap")])
def test_the_graph_is_two_tasks_a_chunk(border: Any) -> None:
    """Beside the input's tasks, each chunk's strips for its neighbours'
    halos and its fit, nothing more (map_overlap made 25 a chunk under
    wrap, whose scheduling took a third of a cluster's processor time:
    docs/dask.md); and each input chunk is made once."""
    whole = heights((40, 30), np.float32)
    array, made = counted(whole, (10, 10))
    lazy = nd.normals(array, patch=5, border=border)
    added = set(dict(lazy.__dask_graph__())) - set(dict(array.__dask_graph__()))
    assert len(added) == 2 * 4 * 3, sorted(map(str, added))[:8]
    with dask.config.set(scheduler="synchronous"):
        got = lazy.compute()
    assert sorted(made) == sorted(itertools.product(range(4), range(3)))
    assert np.array_equal(got, normalfit.normals(whole, patch=5, border=border))


def test_options_are_checked_when_the_graph_is_made() -> None:
    array = da.zeros((8, 8), chunks=4, dtype=np.float32)
    with pytest.raises(ValueError, match="auto"):
        nd.normals(array, border="auto")
    with pytest.raises(ValueError, match="auto"):
        nd.normals(array, border=("wrap", "auto"))
    with pytest.raises(ValueError, match="patch"):
        nd.normals(array, patch=4)
    with pytest.raises(ValueError, match="dtype"):
        nd.normals(array, dtype=np.int32)
    with pytest.raises(TypeError, match="int16"):
        nd.normals(da.zeros((8, 8), chunks=4, dtype=np.int16))
    with pytest.raises(TypeError, match="2-D"):
        nd.normals(da.zeros((8, 8, 3), chunks=4, dtype=np.float32))
    # An array without texels is refused when the graph is made, with the
    # whole-array fit's words (issue 32: it made a graph of nothing).
    for shape in [(0, 5), (5, 0), (0, 0)]:
        message = f"invalid option: image is {shape[1]}×{shape[0]}: both sides must be at least 1"
        with pytest.raises(ValueError, match=f"^{message}$"):
            normalfit.normals(np.zeros(shape, np.float32))
        with pytest.raises(ValueError, match=f"^{message}$"):
            nd.normals(da.zeros(shape, chunks=4, dtype=np.float32))
        with pytest.raises(ValueError, match=f"^{message}$"):
            nd.check_tiling(da.zeros(shape, chunks=4, dtype=np.float32))


@pytest.mark.parametrize(("hole", "chunks"), [((590, 10), (128, 200)), ((300, 595), (600, 600)), ((7, 5), (4, 4))])
def test_check_tiling_refuses_non_finite_heights_it_reads(hole: tuple[int, int], chunks: tuple[int, int]) -> None:
    """As normalfit.check_tiling of the whole array: a NaN or infinite
    height among the lines read raises ValueError naming its texel (they
    were scored as 0, issue 32); one the check does not read is not
    judged."""
    size = 600 if hole[0] > 100 else 12
    whole = np.random.default_rng(3).random((size, size), dtype=np.float32)
    for bad in (np.nan, np.inf):
        holed = whole.copy()
        holed[hole[1], hole[0]] = bad
        message = rf"^height at texel \(x {hole[0]}, y {hole[1]}\) is NaN or infinite$"
        with pytest.raises(ValueError, match=message):
            normalfit.check_tiling(holed)
        with pytest.raises(ValueError, match=message):
            nd.check_tiling(da.from_array(holed, chunks=chunks))
    if size == 600:
        unread = whole.copy()
        unread[300, 300] = np.nan
        nd.check_tiling(da.from_array(unread, chunks=chunks))


@pytest.mark.parametrize("seamless", [True, False])
def test_check_tiling_equals_the_whole_array_check(client: Any, seamless: bool) -> None:
    """The report of normalfit.check_tiling on the whole array, and the
    borders normalfit.normals(border="auto") then uses."""
    rng = np.random.default_rng(7)
    if seamless:
        whole = rng.random((96, 130), dtype=np.float32)  # noise tiles
    else:
        whole = np.tile(np.linspace(0, 1, 130, dtype=np.float32), (96, 1)) + 0.01 * rng.random((96, 130),
                                                                                                 dtype=np.float32)
    array = da.from_array(whole, chunks=(17, 40))
    got = nd.check_tiling(array)
    want = normalfit.check_tiling(whole)
    for field in ("kind", "seamless", "width", "height", "suggested_borders"):
        assert getattr(got, field) == getattr(want, field), field
    assert (got.x.score, got.x.seamless, got.y.score, got.y.seamless) == (
        want.x.score, want.x.seamless, want.y.score, want.y.seamless)
    assert got.seamless == seamless
    # Its borders, passed on, are what border="auto" gives.
    auto = normalfit.normals(whole, patch=5, border="auto")
    assert np.array_equal(nd.normals(array, patch=5, border=got.suggested_borders).compute(), auto)


@pytest.mark.parametrize("seamless", [True, False])
def test_check_tiling_skips_holes(seamless: bool) -> None:
    """With nodata, its texels and NaN are holes (docs/tiling.md): an array
    with holes at both seams keeps the verdict of the array without them,
    and normalfit.normals(border="auto", nodata=...) picks the same
    borders. Read as heights, the −9999 at the x seam would be a seam."""
    rng = np.random.default_rng(11)
    whole = rng.random((96, 130), dtype=np.float32)
    if not seamless:
        whole += np.linspace(0, 3, 130, dtype=np.float32)
    holed = whole.copy()
    holed[::7, 0] = -9999.0
    holed[3::5, -1] = -9999.0
    holed[0, ::6] = np.nan
    holed[40:60, 50:70] = -9999.0
    array = da.from_array(holed, chunks=(17, 40))
    got = nd.check_tiling(array, nodata=-9999.0)
    want = nd.check_tiling(da.from_array(whole, chunks=(17, 40)))
    assert (got.x.seamless, got.y.seamless) == (want.x.seamless, want.y.seamless) == (seamless, True)
    assert np.isfinite(got.x.score) and np.isfinite(got.y.score)
    auto = normalfit.normals(holed, patch=5, border="auto", nodata=-9999.0)
    fixed = normalfit.normals(holed, patch=5, border=got.suggested_borders, nodata=-9999.0)
    assert np.array_equal(auto, fixed, equal_nan=True)
    as_heights = nd.check_tiling(da.from_array(np.nan_to_num(holed, nan=0.5), chunks=(17, 40)))
    assert not as_heights.x.seamless


def counted(whole: np.ndarray, chunks: Any) -> tuple[Any, list[tuple[int, int]]]:
    """A Dask array of `whole` that records each chunk it makes."""
    made: list[tuple[int, int]] = []
    lock = threading.Lock()

    def chunk(block: np.ndarray, block_info: Any = None) -> np.ndarray:
        with lock:
            made.append(tuple(block_info[None]["chunk-location"]))
        return block

    return da.from_array(whole, chunks=chunks).map_blocks(chunk, dtype=whole.dtype), made


def test_check_tiling_on_a_small_array_computes_each_chunk_once() -> None:
    """An array no larger than 512 along an axis is read whole along it (the
    check's reference is every pair then): each chunk is made once."""
    whole = heights((40, 30), np.uint16)
    array, made = counted(whole, (7, 12))
    with dask.config.set(scheduler="synchronous"):
        got = nd.check_tiling(array, threshold=2.0)
    assert sorted(made) == sorted(itertools.product(range(6), range(3)))
    want = normalfit.check_tiling(whole, threshold=2.0)
    assert (got.x.score, got.y.score) == (want.x.score, want.y.score)
    with pytest.raises(ValueError, match="kind"):
        nd.check_tiling(array, kind="normal")


@pytest.mark.parametrize(
    "shape, chunks",
    [
        ((1100, 1300), (100, 100)),  # both axes cut: the 256 lines at each edge
        ((1100, 1300), (300, 250)),  # strips inside chunks
        ((700, 300), (64, 100)),  # narrow: whole rows, y cut
        ((300, 700), (64, 100)),  # short: every row, x cut
        ((513, 514), (97, 55)),  # just above 512 on both axes
    ],
)
def test_check_tiling_reads_only_the_edge_strips(shape: tuple[int, int], chunks: tuple[int, int]) -> None:
    """Only the chunks that hold a texel of the first or last 256 columns or
    rows of a long axis are made, each once, and the report is the
    whole-array check's, bit for bit, for a map that tiles and one that
    does not."""
    (h, w) = shape
    rng = np.random.default_rng(h * 7 + w)
    for seamless in (True, False):
        y, x = np.mgrid[0:h, 0:w]
        whole = (np.sin(2 * np.pi * 3 * x / w) * np.cos(2 * np.pi * 2 * y / h)).astype(np.float32)
        whole += 0.05 * rng.random(shape, dtype=np.float32)
        if not seamless:
            whole += (x / w).astype(np.float32)  # a ramp: a jump at the x seam
        array, made = counted(whole, chunks)
        with dask.config.set(scheduler="synchronous"):
            got = nd.check_tiling(array)
        want = normalfit.check_tiling(whole)
        assert (got.x.score, got.y.score, got.seamless) == (want.x.score, want.y.score, want.seamless)
        assert not got.x.seamless if not seamless else got.seamless
        rows_at = np.cumsum((0, *array.chunks[0]))
        cols_at = np.cumsum((0, *array.chunks[1]))

        def near_edge(lo: int, hi: int, n: int) -> bool:
            return n <= 512 or lo < 256 or hi > n - 256

        needed = {
            (i, j)
            for i in range(len(rows_at) - 1)
            for j in range(len(cols_at) - 1)
            if (w <= 512 or near_edge(cols_at[j], cols_at[j + 1], w))
            or (w > 512 and near_edge(rows_at[i], rows_at[i + 1], h))
        }
        assert len(made) == len(set(made)), "a chunk made twice"
        assert set(made) == needed
        if w > 1000 and h > 1000:
            assert len(needed) < array.numblocks[0] * array.numblocks[1], "the middle chunks are left alone"
        made.clear()


def test_a_task_uses_one_thread_by_default(client: Any) -> None:
    """A task runs the library on a pool of 1 thread unless threads= says
    otherwise: in a worker, after a computation, the library keeps
    pools of one thread only, and no thread named normalfit-1 runs
    (test_threads.py names pool threads the same way). Verdicts of order,
    not of time: the CPU a task takes is for bench/, not a test."""

    def run(threads: int | None) -> tuple[list[int], list[str]]:
        from normalfit import _normalfit

        whole = heights((1536, 1536), np.float32)
        array = da.from_array(whole, chunks=(768, 1536))
        lazy = nd.normals(array, patch=9) if threads is None else nd.normals(array, patch=9, threads=threads)
        lazy.compute(scheduler="synchronous")
        names = []
        for task in Path("/proc/self/task").iterdir():
            try:
                names.append((task / "comm").read_text().strip())
            except OSError:  # a thread that ended while the list was read
                continue
        return _normalfit._kept_pools(), sorted(n for n in names if n.startswith("normalfit-"))

    if not Path("/proc/self/task").is_dir():
        pytest.skip("counts threads through Linux's /proc")
    # No earlier test passes threads=: every pool a worker keeps is of one.
    kept, pool = client.submit(run, None, pure=False).result()
    assert set(kept) == {1} and "normalfit-1" not in pool, (kept, pool)
    # The control: threads=2 does keep a pool of two, whose second thread
    # is normalfit-1.
    kept2, pool2 = client.submit(run, 2, pure=False).result()
    assert 2 in kept2, kept2
    # A thread names itself when it first runs; the pool may have finished
    # the work before normalfit-1 did, so its name is not asserted.


def test_a_failing_chunk_names_itself(client: Any) -> None:
    whole = heights((30, 40), np.float32)
    whole[17, 25] = np.nan  # in chunk (1, 2) of chunks (10, 10)
    lazy = nd.normals(da.from_array(whole, chunks=10), patch=5)
    with pytest.raises(ValueError, match=r"chunk \(1, 2\) \(rows 10 to 19, columns 20 to 29\): .*x 25, y 17"):
        lazy.compute()


@pytest.fixture
def zarr() -> Any:
    """zarr, or the test is skipped (the other tests need only dask)."""
    return pytest.importorskip("zarr", reason="zarr is not installed (pip install 'normalfit[dask]')")


def test_read_zarr_names_the_chunk_that_cannot_be_read(client: Any, zarr: Any, tmp_path: Path) -> None:
    whole = heights((24, 24), np.float32)
    store = tmp_path / "heights.zarr"
    da.from_array(whole, chunks=8).to_zarr(os.fspath(store))
    array = nd.read_zarr(store)
    assert array.chunks == ((8, 8, 8), (8, 8, 8))
    assert np.array_equal(nd.normals(array, patch=3).compute(), normalfit.normals(whole, patch=3))
    # Corrupt one chunk's file: chunk (2, 1).
    files = [p for p in store.rglob("*") if p.is_file() and p.parent.name == "2" and p.name == "1"]
    assert files, sorted(str(p.relative_to(store)) for p in store.rglob("*"))
    files[0].write_bytes(b"not a compressed chunk")
    with pytest.raises(Exception, match=r"heights\.zarr: chunk \(2, 1\) \(rows 16 to 23, columns 8 to 15\)"):
        nd.normals(array, patch=3).compute()


def test_to_zarr_writes_every_chunk_unless_told_otherwise(client: Any, zarr: Any, tmp_path: Path) -> None:
    # Zarr skips a chunk equal to the fill value when asked to (its own
    # default): to_zarr writes them all, and a caller's config still rules.
    values = np.zeros((16, 16), np.float32)
    values[8:, 8:] = 1.0
    for config, stored in [(None, 4), ({"write_empty_chunks": False}, 1)]:
        target = tmp_path / f"{stored}.zarr"
        kwargs = {} if config is None else {"config": config}
        nd.to_zarr(da.from_array(values, chunks=8), target, **kwargs)
        chunks = [p for p in target.rglob("*") if p.is_file() and p.parent.parent.name == "c"]
        assert len(chunks) == stored, sorted(str(p.relative_to(target)) for p in target.rglob("*"))
        assert np.array_equal(np.asarray(zarr.open_array(os.fspath(target), mode="r")[...]), values)


def test_to_zarr_writes_whole_or_not_at_all(client: Any, zarr: Any, tmp_path: Path) -> None:
    whole = heights((32, 48), np.uint16)
    target = tmp_path / "normals.zarr"
    good = nd.normals(da.from_array(whole, chunks=(8, 16)), patch=5, dtype=np.uint16)
    assert nd.to_zarr(good, target) == target
    assert np.array_equal(np.asarray(zarr.open_array(os.fspath(target), mode="r")[...]),
                          normalfit.normals(whole, patch=5, dtype=np.uint16))
    assert sorted(p.name for p in tmp_path.iterdir()) == ["normals.zarr"]
    with pytest.raises(FileExistsError):
        nd.to_zarr(good, target)
    # A chunk that fails: nothing new appears, the old store stays whole.
    bad = whole.astype(np.float32)
    bad[20, 24] = np.inf  # in chunk (2, 1) and no other's halo
    failing = nd.normals(da.from_array(bad, chunks=(8, 16)), patch=5, dtype=np.uint16)
    with pytest.raises(ValueError, match=r"chunk \(2, 1\)"):
        nd.to_zarr(failing, target, overwrite=True)
    with pytest.raises(ValueError, match=r"chunk \(2, 1\)"):
        nd.to_zarr(failing, tmp_path / "other.zarr")
    assert sorted(p.name for p in tmp_path.iterdir()) == ["normals.zarr"]
    assert np.array_equal(np.asarray(zarr.open_array(os.fspath(target), mode="r")[...]),
                          normalfit.normals(whole, patch=5, dtype=np.uint16))
    # Replaced on success.
    nd.to_zarr(nd.normals(da.from_array(whole, chunks=16), patch=3, dtype=np.uint16), target, overwrite=True)
    assert np.array_equal(np.asarray(zarr.open_array(os.fspath(target), mode="r")[...]),
                          normalfit.normals(whole, patch=3, dtype=np.uint16))
    assert sorted(p.name for p in tmp_path.iterdir()) == ["normals.zarr"]
