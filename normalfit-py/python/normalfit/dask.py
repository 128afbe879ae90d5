"""normalfit on Dask arrays: normal maps of rasters larger than one
machine's memory, equal to the whole image's, bit for bit.

Each chunk's normals are computed by the library's window fit
(``normalfit::FitRequest::window``) from the chunk and the halo the library
plans (``normalfit::fit::HaloPlan``: r = patch // 2 texels), taken from the
strips its eight neighbours copy out: two tasks a chunk.
Every texel's sums come from its own patch alone, so the result is exactly
``normalfit.normals`` of the whole array, whatever the chunking.

>>> import dask.array as da, numpy as np, normalfit, normalfit.dask
>>> heights = da.random.default_rng(1).random((512, 768), chunks=(100, 300)).astype(np.float32)
>>> n = normalfit.dask.normals(heights, patch=5, border=("wrap", "mirror"), dtype=np.uint16)
>>> n.shape, n.chunks[2]
((512, 768, 3), (3,))
>>> bool((n.compute() == normalfit.normals(heights.compute(), patch=5, border=("wrap", "mirror"), dtype=np.uint16)).all())
True

Requires the ``dask`` extra (``dask[array]``; ``distributed`` for a
cluster, ``zarr`` for :func:`read_zarr` and :func:`to_zarr`). See
docs/dask.md for the border mapping, threads, errors and figures.
"""

from __future__ import annotations

import os
import shutil
import time
import uuid
from functools import partial
from pathlib import Path
from collections.abc import Sequence
from typing import Any

import dask
import dask.array as da
from dask.highlevelgraph import HighLevelGraph
import numpy as np

from . import _normalfit, _pixel_size
from ._normalfit import TilingReport

__all__ = ["check_tiling", "normals", "read_zarr", "to_zarr"]


def _chunk_error(e: BaseException, what: str) -> BaseException:
    """``e`` with ``what`` (the chunk) before its message, as the same
    exception type when it takes one message (ValueError, TypeError,
    MemoryError, OSError, ...), else a RuntimeError; both pickle, so a
    worker's failure reaches the client as it is."""
    message = f"{what}: {e}"
    try:
        new = type(e)(message)
    except Exception:  # a type whose constructor wants other arguments
        new = RuntimeError(message)
    return new


def _where(block_info: Any) -> tuple[tuple[int, int], tuple[int, int], tuple[int, int]]:
    """The block index and the (start, stop) rows and columns of the chunk
    that ``block_info`` (Dask's, of the output) describes."""
    out = block_info[None]
    (i, j) = out["chunk-location"][:2]
    (rows, cols) = out["array-location"][:2]
    return (i, j), (rows[0], rows[1]), (cols[0], cols[1])


def _describe(index: tuple[int, int], rows: tuple[int, int], cols: tuple[int, int]) -> str:
    return f"chunk {index} (rows {rows[0]} to {rows[1] - 1}, columns {cols[0]} to {cols[1] - 1})"


def _merged(chunks: tuple[int, ...], depth: int) -> tuple[int, ...]:
    """Chunks of at least ``depth`` texels (a chunk's halo on a side comes
    from its one neighbour there), made by joining neighbours; unchanged
    when every chunk already has ``depth``."""
    if all(c >= depth for c in chunks):
        return chunks
    merged: list[int] = []
    run = 0
    for c in chunks:
        run += c
        if run >= depth:
            merged.append(run)
            run = 0
    if run:
        if merged:
            merged[-1] += run
        else:
            merged.append(run)
    return tuple(merged)


def _halo_strips(block: np.ndarray, depth: tuple[int, int]) -> dict[tuple[int, int], np.ndarray]:
    """The parts of a chunk its neighbours' halos take, copied out (so a
    neighbour's task receives them, not the chunk): keyed (rows, columns),
    0 the first ``depth`` lines of that axis, 1 all of them, 2 the last;
    (1, 1), the chunk itself, is not one. An axis without depth gives
    only its 1s."""
    (dy, dx) = depth
    rows = {0: slice(0, dy), 1: slice(None), 2: slice(block.shape[0] - dy, None)}
    cols = {0: slice(0, dx), 1: slice(None), 2: slice(block.shape[1] - dx, None)}
    return {
        (a, b): block[rows[a], cols[b]].copy()
        for a in ((0, 1, 2) if dy else (1,))
        for b in ((0, 1, 2) if dx else (1,))
        if (a, b) != (1, 1)
    }


def _fit_chunk(
    core: np.ndarray,
    around: list[list[dict[tuple[int, int], np.ndarray] | None]],
    *,
    where: tuple[tuple[int, int], tuple[int, int], tuple[int, int]],
    halo: tuple[int, int, int, int],
    image: tuple[int, int],
    options: dict[str, Any],
) -> np.ndarray:
    """One chunk's normals from the chunk and, round it, the halo the
    library plans for it (``halo``: left, right, top, bottom), taken from
    the neighbours' strips ``around[1 + di][1 + dj]`` (the neighbour di
    rows of chunks down and dj columns right, wrapping where the border
    does; None where no halo is read)."""
    index, rows, cols = where
    try:
        (left, right, top, bottom) = halo
        (h, w) = core.shape
        held = np.empty((h + top + bottom, w + left + right), core.dtype)
        held[top:top + h, left:left + w] = core
        # Along each axis: the neighbour before gives its last lines (its
        # strips' 2s), the chunk's own lines are all of them (1s), the
        # neighbour after gives its first (0s): (strip part, how many
        # lines, where they go in the window).
        parts_y = ((2, top, 0), (1, h, top), (0, bottom, top + h))
        parts_x = ((2, left, 0), (1, w, left), (0, right, left + w))
        for di, (a, lines_y, at_y) in enumerate(parts_y):
            for dj, (b, lines_x, at_x) in enumerate(parts_x):
                if (di, dj) == (1, 1) or lines_y == 0 or lines_x == 0:
                    continue
                strips = around[di][dj]
                if strips is None:
                    raise ValueError(f"no neighbouring chunk holds the halo at {(di - 1, dj - 1)}")
                strip = strips[(a, b)]
                # A strip holds the most any chunk reads; this one may read fewer.
                take_y = slice(strip.shape[0] - lines_y, None) if a == 2 else slice(0, lines_y)
                take_x = slice(strip.shape[1] - lines_x, None) if b == 2 else slice(0, lines_x)
                held[at_y:at_y + lines_y, at_x:at_x + lines_x] = strip[take_y, take_x]
        result = _normalfit.window_normals(
            held, image, (cols[0], rows[0]), halo, options["patch"], options["fit"],
            options["border"], options["convention"], options["scale"], options["relief"], options["invert"],
            options["dtype"], options["residual"], options["threads"], options["nodata"], options["detail"],
            options["units"], options["pixel_size"], options["weights"], **(options["product"] or {}),
        )
    except Exception as e:
        raise _chunk_error(e, _describe(index, rows, cols)) from e
    if options["residual"]:
        n, res = result
        packed = np.empty(n.shape[:2] + (4,), np.float64)
        packed[..., :3] = n
        packed[..., 3] = res
        return packed
    return result  # type: ignore[no-any-return]


def normals(
    array: Any,
    *,
    patch: int = 3,
    fit: str = "orthogonal",
    border: str | tuple[str, str] = "wrap",
    convention: str = "opengl",
    scale: float | None = None,
    relief: float | None = None,
    invert: bool = False,
    dtype: Any = np.float32,
    residual: bool = False,
    threads: int | None = 1,
    nodata: float | None = None,
    detail: Sequence[tuple[int, float]] | None = None,
    units: str = "texels",
    pixel_size: Any = None,
    weights: str = "uniform",
    _product: dict[str, Any] | None = None,
) -> Any:
    """The normal map of a 2-D Dask array of heights, lazily: a (rows,
    columns, 3) Dask array chunked like ``array`` (one chunk of 3 on the
    last axis), equal bit for bit to ``normalfit.normals`` of the whole
    computed array with the same options.

    array: a 2-D dask.array (or anything ``dask.array.asarray`` takes) of
        uint8, uint16, float32 or float64, in normalfit.normals's units.
    patch, fit, convention, scale, relief, invert, dtype, detail, weights: as for
        normalfit.normals (with detail, the halo is the largest size's) (dtype float32 unit vectors, or uint8 / uint16
        encoded RGB).
    border: "wrap", "clamp" or "mirror", for both axes or as an (x, y)
        pair (or "x,y"). Wrap takes the halo of a chunk at the image's edge
        from the chunk at the far edge; under clamp and mirror the halo
        stops at the image's edge and the library maps the reads beyond it
        (a reflection such as Dask's ``reflect`` repeats the edge texel,
        the contract's mirror does not). "auto" is
        refused (ValueError): it needs the whole array's tiling check; run
        ``check_tiling(array)`` and pass its ``suggested_borders`` (the
        borders normalfit.normals(border="auto") picks, exactly).
    residual: also return the fit's residual: the result is then
        (normals, residual), lazy arrays of one graph (compute them
        together, ``dask.compute(n, r)``, to run it once).
    nodata: holes, as for normalfit.normals: texels of this value (and
        NaN or infinite ones; ``float("nan")`` for NaN alone) are missing,
        each patch is fitted to its valid points, and a missing texel's
        normal (and residual) is NaN; needs dtype float32. The halo holds
        the holes of the neighbouring chunks, so chunked equals whole, bit
        for bit, holes included.
    units, pixel_size: map units, as for normalfit.normals: the whole
        array's spacing, an (x, y) pair or one (x, y) per row (a (rows, 2)
        array); each chunk's rows take their own rows' spacing, so chunked
        equals whole here too.
    threads: threads of the library's pool in each task. Default 1: Dask
        already runs one task per worker thread, so a worker uses the
        threads it was given and no more. None: every core (rayon's global
        pool), for a single-threaded scheduler.

    Chunks smaller than the halo: a chunk's halo on a side comes from its
    one neighbour there, so each chunk must hold r texels; an axis with a
    smaller chunk is rechunked by joining
    neighbours for the fit, and the result rechunked back to the input's
    chunks. An axis in one chunk takes no halo (the library maps every
    border's reads into the chunk).

    The options and the array's shape are checked now (ValueError,
    TypeError as for normalfit.normals: an array without texels raises
    ValueError, as there). A chunk that fails when computed (a NaN height, a
    wrong dtype) raises, from its task, the library's exception with the
    chunk's block index and rows and columns before its message.
    """
    array = da.asarray(array)
    if array.ndim != 2:
        raise TypeError(f"array must be a 2-D dask array of heights, got {array.ndim}-D")
    (h, w) = (int(array.shape[0]), int(array.shape[1]))
    bx, by = _normalfit.border_names(border)
    # Checked now, by the library, without a fit: every option, the
    # array's dtype, the output dtype, and border auto's refusal; and the
    # most its halo reaches on a side, r (more for binomial weights by
    # blocks), beyond the image's edges along an axis that
    # wraps (x, y).
    pixel_size = _pixel_size(pixel_size)
    r, (beyond_x, beyond_y) = _normalfit.window_plan(
        (w, h),
        array.dtype, patch, fit, border, convention, scale, relief, invert, dtype, threads, nodata, detail,
        units, pixel_size, weights,
    )
    out_dtype = np.dtype(dtype)
    # A terrain product (normalfit.xarray's slope, aspect, hillshade): one
    # value a texel, float32, or uint8 for the hillshade.
    if _product is not None:
        out_dtype = np.dtype(np.uint8 if _product["product"] == "hillshade" else np.float32)
    chunks = tuple(_merged(c, r) for c in array.chunks)
    work = array if chunks == array.chunks else array.rechunk(chunks)
    # An axis in one chunk takes no halo (the library plans none: every
    # read maps into the chunk).
    depth = tuple(0 if len(c) == 1 else r for c in chunks)
    periodic = (beyond_y and depth[0] > 0, beyond_x and depth[1] > 0)
    options = dict(
        patch=patch, fit=fit, border=(bx, by), convention=convention, scale=scale, relief=relief, invert=invert,
        dtype=out_dtype, residual=residual, threads=threads, nodata=nodata,
        detail=None if detail is None else list(detail), units=units, pixel_size=pixel_size, weights=weights,
        product=None if _product is None else dict(_product),
    )
    packed_dtype = np.dtype(np.float64) if residual else out_dtype
    result = _map(work, depth, periodic, chunks, (w, h), options, packed_dtype)
    if chunks != array.chunks:
        result = result.rechunk(array.chunks if _product is not None else array.chunks + ((4 if residual else 3),))
    if residual:
        return result[..., :3].astype(out_dtype), result[..., 3].astype(np.float32)
    return result


def _map(
    work: Any,
    depth: tuple[int, int],
    periodic: tuple[bool, bool],
    chunks: tuple[tuple[int, ...], ...],
    image: tuple[int, int],
    options: dict[str, Any],
    dtype: np.dtype[Any],
) -> Any:
    """The graph: one task per chunk copies out the strips its neighbours'
    halos take (``_halo_strips``), one fits each chunk from the chunk and
    its eight neighbours' strips (``_fit_chunk``). Two tasks a chunk,
    where ``dask.array.map_overlap`` made 25 under wrap and 8 under clamp
    on a 4 × 4 grid (a slice of each neighbour, the joins, and wrap's
    boundary chunks and their own overlaps), whose scheduling took a
    third of the cluster's processor time (docs/dask.md)."""
    # A terrain product is one value a texel (2-D chunks); normals add an
    # axis of 3 components (4 with the residual).
    if options["product"] is not None:
        out_chunks: tuple[tuple[int, ...], ...] = chunks
        meta = np.empty((0, 0), dtype)
        what = "terrain"
    else:
        out_chunks = (chunks[0], chunks[1], (4 if options["residual"] else 3,))
        meta = np.empty((0, 0, 0), dtype)
        what = "normals"
    token = dask.base.tokenize(work, depth, periodic, image, sorted(options.items()))
    name, strips = f"normalfit-{what}-{token}", f"normalfit-halo-{token}"
    (ni, nj) = (len(chunks[0]), len(chunks[1]))
    starts = [np.cumsum((0, *c)).tolist() for c in chunks]
    layer: dict[Any, Any] = {}
    if depth != (0, 0):
        for i in range(ni):
            for j in range(nj):
                layer[(strips, i, j)] = (_halo_strips, (work.name, i, j), depth)

    def neighbour(k: int, step: int, n: int, wraps: bool) -> int | None:
        if step == 0:
            return k
        if 0 <= k + step < n:
            return k + step
        return (k + step) % n if wraps and n > 1 else None

    for i in range(ni):
        for j in range(nj):
            rows = (starts[0][i], starts[0][i + 1])
            cols = (starts[1][j], starts[1][j + 1])
            halo = _normalfit.window_halo(
                image, (cols[0], rows[0]), (cols[1] - cols[0], rows[1] - rows[0]), options["patch"],
                options["border"], options["detail"], options["weights"],
            )
            (left, right, top, bottom) = halo
            if max(top, bottom) > depth[0] or max(left, right) > depth[1]:
                raise ValueError(f"the library's halo {halo} for {_describe((i, j), rows, cols)} exceeds {depth}")
            reads = ((top > 0, True, bottom > 0), (left > 0, True, right > 0))
            around: list[list[Any]] = []
            for di in (-1, 0, 1):
                line: list[Any] = []
                for dj in (-1, 0, 1):
                    ii = neighbour(i, di, ni, periodic[0])
                    jj = neighbour(j, dj, nj, periodic[1])
                    read = (di, dj) != (0, 0) and reads[0][di + 1] and reads[1][dj + 1]
                    line.append((strips, ii, jj) if read and ii is not None and jj is not None else None)
                around.append(line)
            key = (name, i, j) if options["product"] is not None else (name, i, j, 0)
            fit = partial(_fit_chunk, where=((i, j), rows, cols), halo=halo, image=image, options=options)
            layer[key] = (fit, (work.name, i, j), around)
    graph = HighLevelGraph.from_collections(name, layer, dependencies=[work])
    return da.Array(graph, name, out_chunks, meta=meta)


def check_tiling(
    array: Any, *, threshold: float = 1.5, kind: str = "auto", nodata: float | None = None
) -> TilingReport:
    """Whether a 2-D Dask array of heights tiles: the report of
    ``normalfit.check_tiling`` on the whole computed array, and the
    ``suggested_borders`` that ``normalfit.normals(border="auto")`` picks.

    Reads only the edge strips the check needs: the seams are compared
    with the pairs of neighbouring lines near them (the first and last 256
    columns and rows of an axis longer than 512; every line of a shorter
    one; docs/tiling.md), so only the chunks those strips touch are
    computed, each once, one row of chunks at a time (the next while the
    library measures the current). The client holds the check's
    O(width + height) profiles and two rows of the strips' chunks, never
    the array. The library's streaming check (``tiling::HeightSeams``, what
    ``border="auto"`` uses) measures them, with the same bits as the
    whole-array check.

    array: a 2-D dask.array of uint8, uint16, float32 or float64 heights.
    threshold: as for normalfit.check_tiling. kind: "auto" or "height"
    (a 2-D array is a height map; "normal" is refused).

    nodata: holes (docs/tiling.md): texels whose stored value is nodata,
    and NaN or infinite ones, are not heights; every pair that reads one
    is skipped. An axis whose seam holds no pair of two valid texels
    scores inf and is not seamless.

    Without nodata, a NaN or infinite height among the lines read raises
    ValueError naming its texel, as normalfit.check_tiling does for the
    whole array; one elsewhere is not read, so not judged. An array
    without texels raises ValueError.
    """
    array = da.asarray(array)
    if array.ndim != 2:
        raise TypeError(f"array must be a 2-D dask array of heights, got {array.ndim}-D")
    if kind not in ("auto", "height"):
        raise ValueError(f"invalid option: kind of a 2-D array of heights must be auto or height, got {kind!r}")
    (h, w) = (int(array.shape[0]), int(array.shape[1]))
    # Without nodata, a NaN or infinite height among the lines read raises
    # ValueError, as normalfit.check_tiling of the whole array does.
    seams = _normalfit._HeightSeams(w, h, nodata is None, None if nodata is None else float(nodata))
    # The library says which lines it reads: every row's edge columns
    # (the whole row of a narrow array) and the edge rows whole (none when
    # the columns are whole rows: they serve both axes).
    columns = [array[:, a:b] for (a, b) in seams.edge_columns if b > a]
    strip = da.concatenate(columns, axis=1) if len(columns) > 1 else (columns[0] if columns else None)
    edge_rows = [(a, b) for (a, b) in seams.edge_rows if b > a]
    # One step per row of chunks: the columns of its rows and the edge rows
    # among them, computed together so that a chunk under both is made once.
    bounds = np.cumsum((0, *array.chunks[0]))
    steps = []
    for lo, hi in zip(bounds[:-1], bounds[1:]):
        cols = strip[lo:hi] if strip is not None else None
        rows = [array[max(a, lo) : min(b, hi)] for (a, b) in edge_rows if max(a, lo) < min(b, hi)]
        steps.append((cols, rows))
    from concurrent.futures import ThreadPoolExecutor

    with ThreadPoolExecutor(1) as pool:
        pending = pool.submit(_computed_step, steps[0]) if steps else None
        for i in range(len(steps)):
            assert pending is not None
            cols, rows = pending.result()
            pending = pool.submit(_computed_step, steps[i + 1]) if i + 1 < len(steps) else None
            if cols is not None:
                seams.push_columns(cols)
            for part in rows:
                seams.push_rows(part)
    return seams.finish(threshold)


def _computed_step(step: tuple[Any, list[Any]]) -> tuple[np.ndarray | None, list[np.ndarray]]:
    """One step of check_tiling's strips, computed in one graph."""
    cols, rows = step
    parts = ([cols] if cols is not None else []) + rows
    done = dask.compute(*parts) if parts else ()
    if cols is not None:
        return done[0], list(done[1:])
    return None, list(done)


def read_zarr(path: str | os.PathLike[str], *, component: str | None = None, chunks: Any = None) -> Any:
    """A 2-D Zarr array as a Dask array whose every chunk, when read, names
    itself in any error: a chunk that cannot be read (a corrupt or
    unreadable chunk file) raises the read's exception type with the
    chunk's block index, rows and columns and the store's path before the
    message. chunks: Dask chunks (default: the Zarr array's)."""
    import zarr

    store = os.fspath(path)
    z = zarr.open_array(store, mode="r", path=component) if component else zarr.open_array(store, mode="r")
    if z.ndim != 2:
        raise TypeError(f"{store}: a 2-D array of heights is needed, got {z.ndim}-D")
    normalized = da.core.normalize_chunks(chunks if chunks is not None else z.chunks, z.shape, dtype=z.dtype)
    return da.map_blocks(
        _read_block,
        chunks=normalized,
        dtype=z.dtype,
        meta=np.empty((0, 0), z.dtype),
        name="normalfit-read-" + dask.base.tokenize(store, component, normalized),
        store=store,
        component=component,
    )


def _read_block(*, store: str, component: str | None, block_info: Any = None) -> np.ndarray:
    index, rows, cols = _where(block_info)
    try:
        import zarr

        z = zarr.open_array(store, mode="r", path=component) if component else zarr.open_array(store, mode="r")
        block: np.ndarray = np.asarray(z[rows[0]:rows[1], cols[0]:cols[1]])
        return block
    except Exception as e:
        raise _chunk_error(e, f"{store}: {_describe(index, rows, cols)}") from e


def _executing(dask_worker: Any) -> int:
    """How many tasks a worker's threads are running now (run on each
    worker by ``Client.run``)."""
    state = getattr(dask_worker, "state", dask_worker)
    return len(getattr(state, "executing", ()))


def _store(writes: Any) -> None:
    """Runs the writes; when one fails, returns (raising) only once no
    other write of them still runs, so that removing the store after it
    is final. On a distributed Client: the writes are cancelled and their
    tasks waited for, up to a minute: a cancelled task leaves the
    scheduler's lists at once, but a worker's thread runs it to its end,
    and it may write a chunk then. Dask renames the tasks it fuses, so
    ours cannot be told from others by key: the wait is for every task
    the workers are running. On Dask's local schedulers, the failure is
    raised as they raise it."""
    try:
        from distributed import default_client

        client = default_client()
    except (ImportError, ValueError):
        dask.compute(writes)
        return
    future = client.compute(writes)
    try:
        future.result()
    except BaseException:
        client.cancel(future)
        deadline = time.monotonic() + 60
        while time.monotonic() < deadline and any(client.run(_executing).values()):
            time.sleep(0.05)
        raise


def to_zarr(array: Any, path: str | os.PathLike[str], *, overwrite: bool = False, **kwargs: Any) -> Path:
    """Computes ``array`` into a Zarr store at ``path``, whole or not at
    all: the chunks are written to a temporary store beside ``path``
    (``.<name>.tmp-<random>``, same folder, so same file system), which is
    renamed into place only once every chunk is written. On any failure
    (a chunk's exception, an interrupt) the temporary store is removed and
    ``path`` is untouched.

    overwrite: replace an existing ``path`` (moved aside, the new store
        renamed in, the old one removed); else an existing ``path`` is a
        FileExistsError before anything is computed.
    kwargs: passed to ``dask.array.to_zarr`` (e.g. ``compute`` is always
        True here; ``zarr_format``, codecs, ...). Every chunk is written,
        whatever it holds (Zarr's ``write_empty_chunks``, unless ``config``
        says otherwise): Zarr would otherwise compare each chunk with the
        fill value before compressing it, which took a fifth to a third of
        the CPU of writing a normal map (docs/dask.md), whose chunks never
        equal it.

    Returns ``path`` as a Path.
    """
    target = Path(path)
    if target.exists() and not overwrite:
        raise FileExistsError(f"{target}: exists (pass overwrite=True to replace it)")
    if kwargs.pop("compute", True) is not True:
        raise ValueError("to_zarr computes: the rename into place needs every chunk written")
    config = kwargs.get("config")
    if config is None or isinstance(config, dict):
        kwargs["config"] = {"write_empty_chunks": True, **(config or {})}
    tmp = target.parent / f".{target.name}.tmp-{uuid.uuid4().hex}"
    try:
        _store(da.to_zarr(array, os.fspath(tmp), compute=False, **kwargs))
    except BaseException:
        shutil.rmtree(tmp, ignore_errors=True)
        raise
    if target.exists():
        old = target.parent / f".{target.name}.old-{uuid.uuid4().hex}"
        os.rename(target, old)
        try:
            os.rename(tmp, target)
        except BaseException:
            os.rename(old, target)
            shutil.rmtree(tmp, ignore_errors=True)
            raise
        shutil.rmtree(old, ignore_errors=True)
    else:
        try:
            os.rename(tmp, target)
        except BaseException:
            shutil.rmtree(tmp, ignore_errors=True)
            raise
    return target
