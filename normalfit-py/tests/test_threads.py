"""The GIL is released while the library works, and threads= bounds the pool.

Every verdict here is one of order, not of speed: a busy machine may make
a call slow, never make a test fail. What could only be timed lives in
bench/bench.py (two calls at once against one)."""

from __future__ import annotations

import threading
import time
from pathlib import Path

import numpy as np
import pytest

import normalfit
from normalfit import _normalfit

SIZE = 2048
# Attempts at catching two events in an order that only a released GIL
# allows. One attempt succeeds on an idle machine; a loaded machine may
# need a few; with the GIL held no number of attempts could.
ATTEMPTS = 20


def big() -> np.ndarray:
    return np.random.default_rng(5).integers(0, 65536, (SIZE, SIZE), dtype=np.uint16)


def test_other_python_threads_run_during_a_call() -> None:
    """A stamping thread records the time while a call runs. Holding the
    GIL, the call would let no Python code run between its start and its
    end but for the moments it takes to read its arguments and build its
    result, a few per cent of the call (each is a copy of the array);
    released, the other thread runs at any time. So a stamp in the call's
    middle half proves the GIL released there."""
    heights = big()
    for attempt in range(ATTEMPTS):
        stamps: list[float] = []
        stop = threading.Event()

        def stamper() -> None:
            while not stop.is_set():
                stamps.append(time.perf_counter())
                time.sleep(0.0005)

        thread = threading.Thread(target=stamper)
        thread.start()
        start = time.perf_counter()
        normalfit.normals(heights, threads=1)
        end = time.perf_counter()
        stop.set()
        thread.join()
        quarter = (end - start) / 4
        if any(start + quarter < t < end - quarter for t in stamps):
            return
    pytest.fail(f"in {ATTEMPTS} calls no other Python thread ran in the middle half of a call: the GIL is held")


def test_two_threads_convert_at_once() -> None:
    """Two Python threads call at once with threads=7 (a size no other test
    uses). A call borrows a kept pool of its size or, when none is free,
    makes one: a second pool of 7 can only be made while the first is
    borrowed, that is, while the other call runs. Held GIL, the calls run
    one after the other and one pool ever suffices."""
    heights = big()
    assert 7 not in _normalfit._kept_pools()
    for attempt in range(ATTEMPTS):
        barrier = threading.Barrier(2)
        failures: list[BaseException] = []

        def one() -> None:
            barrier.wait()
            try:
                normalfit.normals(heights, threads=7)
            except BaseException as e:  # noqa: BLE001 - shown by the assertion below
                failures.append(e)

        workers = [threading.Thread(target=one) for _ in range(2)]
        for t in workers:
            t.start()
        for t in workers:
            t.join()
        assert not failures, failures
        sevens = _normalfit._kept_pools().count(7)
        assert sevens in (1, 2), f"{sevens} pools of 7 kept after attempt {attempt}"
        if sevens == 2:
            return
    pytest.fail(f"in {ATTEMPTS} attempts two calls never overlapped: the GIL is held")


def pool_threads() -> set[str]:
    """The names of the process's threads that the pools of threads= run
    (rayon names them normalfit-<i>). A thread that ends while the list is
    read (an interpreter helper, a pool being dropped) is no pool thread of
    ours: Linux answers ENOENT or ESRCH for it, both OSError."""
    names = set()
    for task in Path("/proc/self/task").iterdir():
        try:
            name = (task / "comm").read_text().strip()
        except OSError:
            continue
        if name.startswith("normalfit-"):
            names.add(f"{task.name}:{name}")
    return names


def test_thread_pools_are_reused() -> None:
    """threads=3 four times: the first call may make a pool of 3, the next
    three take it again (the list of kept pools does not change), and the
    results match rayon's global pool bit for bit."""
    heights = np.random.default_rng(2).random((64, 64)).astype(np.float32)
    want = normalfit.normals(heights)
    assert np.array_equal(normalfit.normals(heights, threads=3), want)
    kept = _normalfit._kept_pools()
    assert kept.count(3) >= 1
    for _ in range(3):
        assert np.array_equal(normalfit.normals(heights, threads=3), want)
    assert _normalfit._kept_pools() == kept


@pytest.mark.skipif(not Path("/proc/self/task").is_dir(), reason="lists threads through Linux's /proc")
def test_a_kept_pool_starts_no_thread_again() -> None:
    """The same, seen by the operating system: the threads named
    normalfit-<i> are those of the kept pools (pools are never dropped),
    and more calls on a kept pool of 5 start none."""
    heights = np.random.default_rng(3).random((256, 256)).astype(np.float32)
    normalfit.normals(heights, threads=5)
    # A thread names itself when it first runs, which a busy machine may
    # delay: wait until every kept pool's threads have (ten seconds at most).
    for _ in range(1000):
        before = pool_threads()
        if len(before) == sum(_normalfit._kept_pools()):
            break
        time.sleep(0.01)
    assert len(before) == sum(_normalfit._kept_pools()), (sorted(before), _normalfit._kept_pools())
    for _ in range(3):
        normalfit.normals(heights, threads=5)
    assert pool_threads() == before
