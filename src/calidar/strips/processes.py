"""Pair matching on this machine's cores in worker processes, for matchers that hold the GIL.

small_gicp 1.0.1 holds the GIL during its calls (docs/validation.md, issue 32: a Python thread got
42 ticks in 88 s of ``KdTree``/``align`` calls; no newer release on PyPI on 28 Nov 2026), so two
threads cannot overlap two pairs' VGICP matching; two processes can. Each pair is matched by the
same code on the same inputs in a worker as in this process (one small_gicp thread:
bit-reproducible), so the correspondences, and everything after them, are identical; only the pairs'
points travel (pickled, ≈ 14 MB a pair of 300 000-point strips) and their correspondences come back,
in task order.

The workers come from a ``forkserver`` (``spawn`` where there is none): never forked from this
process, whose reader and BLAS threads a fork would leave half-copied. The forkserver imports what
the workers need (:data:`PRELOAD`, ≈ 0.9 CPU s) once, before it forks them, and is started early
(:func:`start_server`, while the strips are read); the workers start on the first task and serve
every outer iteration of a calibration. A round of pairs with fewer than :data:`MIN_POINTS` points
stays in this process, where that start would cost more than the second core gains. A pool that
cannot start or loses a worker leaves the round to this process.
"""

from __future__ import annotations

import os
from collections.abc import Callable, Iterator, Sequence
from contextlib import contextmanager
from typing import Any

#: worker processes for GIL-holding pair matching (this machine's cores, at most 2: the figure
#: measured)
PROCESSES = min(2, os.cpu_count() or 1)
#: a round's pairs hold at least this many points (both sides, all pairs) to go to the workers
MIN_POINTS = 1_000_000
#: what a worker imports to run its tasks (the pair matchers and their libraries): imported once, in
#: the forkserver before it forks the workers, instead of in each worker (≈ 0.9 CPU s each)
PRELOAD = ("calidar.strips.outer_loop",)


@contextmanager
def pair_processes(processes: int = PROCESSES) -> Iterator[Any]:
    """A pool of ``processes`` worker processes (started on its first task, shut down on exit), or
    None for fewer than two."""
    if processes < 2:
        yield None
        return
    from concurrent.futures import ProcessPoolExecutor

    pool = ProcessPoolExecutor(processes, mp_context=_context())
    try:
        yield pool
    finally:
        pool.shutdown(wait=True, cancel_futures=True)


def start_server(points: int) -> None:
    """Start the forkserver now for a survey of ``points`` points (the files' headers) that may
    fill a round for the workers (at least :data:`MIN_POINTS`): it imports :data:`PRELOAD` while
    this process reads the strips, and the pool forks its workers from it at once. Nothing where
    there is no forkserver (the pool then starts its workers itself, on its first task)."""
    if points < MIN_POINTS or _context().get_start_method() != "forkserver":
        return
    from multiprocessing import forkserver

    forkserver.ensure_running()


def _context():
    """The workers' start context: ``forkserver`` preloading :data:`PRELOAD` (``spawn`` where
    there is no forkserver)."""
    import multiprocessing as mp

    method = "forkserver" if "forkserver" in mp.get_all_start_methods() else "spawn"
    context = mp.get_context(method)
    if method == "forkserver":
        context.set_forkserver_preload(list(PRELOAD))
    return context


def worth_processes(tasks: Sequence[tuple], min_points: int | None = None) -> bool:
    """Whether a round's tasks hold enough points (every 2-D array argument's rows; ``min_points``,
    default :data:`MIN_POINTS`) for the workers."""
    points = sum(len(a) for t in tasks for a in t if hasattr(a, "ndim") and a.ndim == 2)
    return points >= (MIN_POINTS if min_points is None else min_points)


def map_in_processes(pool: Any, func: Callable[..., Any], tasks: Sequence[tuple]) -> list[Any]:
    """``[func(*task) for task in tasks]`` on the pool's workers, in task order (a task's exception
    is raised here); in this process when the workers cannot run them (none could start, or one
    died: the pool is broken), with the same results."""
    from concurrent.futures.process import BrokenProcessPool

    if not tasks:
        return []
    try:
        return list(pool.map(func, *zip(*tasks)))
    except (BrokenProcessPool, OSError):
        return [func(*task) for task in tasks]
