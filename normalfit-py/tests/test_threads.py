"""The GIL is released while the library works, and threads= bounds the pool."""

from __future__ import annotations

import statistics
import threading
import time
from pathlib import Path

import numpy as np
import pytest

import normalfit

SIZE = 2048


def big() -> np.ndarray:
    return np.random.default_rng(5).integers(0, 65536, (SIZE, SIZE), dtype=np.uint16)


def test_other_python_threads_run_during_a_call() -> None:
    """A counting thread keeps counting while a call runs. With the GIL
    held it would count only in the slices of the switch interval around
    the call (about 5 % of its rate, measured); released, at about its
    rate alone. The bound, a fifth of that rate, leaves room for a busy
    machine."""
    heights = big()
    count = 0
    stop = threading.Event()

    def counter() -> None:
        nonlocal count
        while not stop.is_set():
            count += 1

    thread = threading.Thread(target=counter)
    thread.start()
    time.sleep(0.02)
    before, start = count, time.perf_counter()
    time.sleep(0.1)
    rate = (count - before) / (time.perf_counter() - start)
    before, start = count, time.perf_counter()
    normalfit.normals(heights, threads=1)
    seconds = time.perf_counter() - start
    during = count - before
    stop.set()
    thread.join()
    share = during / (rate * seconds)
    print(f"\n{SIZE}² on 1 thread: {seconds * 1000:.0f} ms; the other thread counted at {share:.0%} of its rate alone")
    assert share > 0.2


def pool_threads() -> int:
    """The process's threads that rayon pools of threads= started."""
    def named(task: Path) -> bool:
        try:
            return (task / "comm").read_text().startswith("normalfit-")
        except FileNotFoundError:  # a thread that ended while being listed
            return False

    return sum(named(task) for task in Path("/proc/self/task").iterdir())


@pytest.mark.skipif(not Path("/proc/self/task").is_dir(), reason="counts threads through Linux's /proc")
def test_two_threads_convert_at_once() -> None:
    """Two Python threads call at once, with threads=7 (a size no other
    test uses). A call takes a kept pool of its size or, when none is free,
    makes one: so one pool of 7 threads is made if the calls ran one after
    the other (as they would with the GIL held), two if they overlapped.
    That holds however busy the machine is; the wall times, which do not,
    are printed: two calls at once take about one call's time on an idle
    machine with two cores free."""
    heights = big()
    before = pool_threads()
    barrier = threading.Barrier(2)

    def one() -> None:
        barrier.wait()
        normalfit.normals(heights, threads=7)

    workers = [threading.Thread(target=one) for _ in range(2)]
    for t in workers:
        t.start()
    for t in workers:
        t.join()
    made = pool_threads() - before
    assert made == 14, f"{made} pool threads made: the calls did not overlap"

    def timed(work) -> float:  # type: ignore[no-untyped-def]
        start = time.perf_counter()
        work()
        return time.perf_counter() - start

    def single() -> None:
        normalfit.normals(heights, threads=1)

    def pair() -> None:
        ts = [threading.Thread(target=single) for _ in range(2)]
        for t in ts:
            t.start()
        for t in ts:
            t.join()

    runs = [(timed(single), timed(pair)) for _ in range(5)]
    one_call = statistics.median(r[0] for r in runs)
    two_calls = statistics.median(r[1] for r in runs)
    print(f"\none {SIZE}² call (threads=1): {one_call * 1000:.0f} ms; two at once: {two_calls * 1000:.0f} ms "
          f"({two_calls / one_call:.2f}×; medians of 5)")


def test_thread_pools_are_reused() -> None:
    """threads=n twice: the second call does not start threads again (the
    pool is kept), and results match rayon's global pool bit for bit."""
    heights = np.random.default_rng(2).random((64, 64)).astype(np.float32)
    want = normalfit.normals(heights)
    before = threading.active_count()
    for _ in range(3):
        assert np.array_equal(normalfit.normals(heights, threads=3), want)
    # rayon's threads are not Python threads: nothing leaks into threading.
    assert threading.active_count() == before
