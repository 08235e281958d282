"""Tie-plane pairs matched two at a time in threads (issue 32, ninth session): each pair once, in
task order, the same correspondences as one at a time; VGICP (holding the GIL) stays at one."""

from __future__ import annotations

import threading

import numpy as np
import pytest

from calidar.strips.distribute import IN_PROCESS_THREADS, map_pairs
from calidar.strips.matchers import TiePlanes, Vgicp
from calidar.strips.outer_loop import match_or_error, pair_threads
from calidar.strips.planes import PlaneSettings

HALF, CELL = 20.0, 2.0


def _together(barrier, k):
    """Returns only when another task reached the barrier too (serial tasks: BrokenBarrierError)."""
    barrier.wait()
    return k, threading.get_ident()


def test_threads_run_two_pairs_at_once_each_once_in_order():
    barrier = threading.Barrier(2, timeout=10)
    got = map_pairs(_together, [(barrier, k) for k in range(6)], threads=2)
    assert [k for k, _ in got] == list(range(6))
    assert len({t for _, t in got}) == 2
    with pytest.raises(threading.BrokenBarrierError):  # one at a time: nobody to meet
        map_pairs(_together, [(threading.Barrier(2, timeout=0.2), 0)], threads=1)


def _strips(seed: int) -> dict[int, np.ndarray]:
    """Four strips of 1 600 m² of tilted 2 m facets, each its own 1 cm noise and shift."""
    rng = np.random.default_rng(seed)
    n = int(2 * HALF / CELL)
    height, grad = rng.normal(0.0, 0.5, (n, n)), rng.uniform(-0.3, 0.3, (n, n, 2))
    out = {}
    for i in range(1, 5):
        xy = rng.uniform(-HALF, HALF, (6400, 2))
        ij = np.clip(np.floor((xy + HALF) / CELL).astype(int), 0, n - 1)
        local = xy - (-HALF + CELL * (ij + 0.5))
        z = height[ij[:, 0], ij[:, 1]] + np.einsum("ij,ij->i", grad[ij[:, 0], ij[:, 1]], local)
        out[i] = np.column_stack([xy, z + rng.normal(0.0, 0.01, xy.shape[0])]) + 0.02 * i
    return out


def _same(c, d) -> bool:
    arrays = ("normal", "sigma_m", "dof", "side_variance", "side_dof")
    return ((c.strip_a, c.strip_b) == (d.strip_a, d.strip_b)
            and (c.A != d.A).nnz == 0 and (c.B != d.B).nnz == 0
            and all(np.array_equal(getattr(c, a), getattr(d, a)) for a in arrays))


def test_tie_planes_in_threads_equal_one_at_a_time():
    pts = _strips(3)
    matcher = TiePlanes(PlaneSettings(cell_m=CELL))
    tasks = [(matcher, a, pts[a], b, pts[b]) for a in pts for b in pts if a < b]
    serial = map_pairs(match_or_error, tasks, threads=1)
    threaded = map_pairs(match_or_error, tasks, threads=2)
    assert len(threaded) == len(serial) == 6
    assert all(c.A.shape[0] > 20 for c in serial)
    assert all(_same(c, d) for c, d in zip(serial, threaded))
    # a pair dropped, doubled or out of order would not compare equal
    assert not _same(serial[0], threaded[1])


def test_threads_by_matcher():
    assert pair_threads(TiePlanes()) == IN_PROCESS_THREADS
    assert pair_threads(Vgicp()) == 1
