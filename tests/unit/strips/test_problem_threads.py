"""The strip problem's per-side and per-strip work in this process's threads (issue 32, twelfth
session): each correspondence side's centroid sums, and each strip's re-georeferencing with
scanner parameters free, computed two at a time — the same bits as one at a time, whatever the
threads' timing."""

from __future__ import annotations

import threading

import numpy as np
import pytest

import calidar.strips.problem as problem_module
from calidar.sensor import Sensor
from calidar.strips.centroids import Centroids
from calidar.strips.planes import match_pair_planes
from calidar.strips.problem import StripProblem
from strips_scene import survey


@pytest.fixture(scope="module")
def scene():
    truth = Sensor(boresight_roll=np.radians(0.03), boresight_pitch=np.radians(-0.04))
    strips = survey(truth, Sensor(), [((-250, -80, 0), 90, 500, 400), ((250, 80, 0), 270, 500, 400),
                                      ((0, 0, 0), 0, 500, 400)], n=30_000)
    corrs = [match_pair_planes(1, strips[0].points, 2, strips[1].points),
             match_pair_planes(3, strips[2].points, 2, strips[1].points),
             match_pair_planes(1, strips[0].points, 3, strips[2].points)]
    return strips, corrs


def _problem(scene, free, threads, monkeypatch):
    strips, corrs = scene
    monkeypatch.setattr(problem_module, "IN_PROCESS_THREADS", threads)
    nominal = Sensor(lever_arm_x=0.2, range_offset=0.01)
    poses = {s.id: s.pose() for s in strips}
    return StripProblem(nominal, poses, corrs, free)


def test_centroids_in_threads_equal_one_at_a_time(scene, monkeypatch):
    free = ["boresight_roll", "boresight_pitch", "boresight_yaw", "lever_arm_x", "range_scale"]
    serial = _problem(scene, free, 1, monkeypatch)
    threaded = _problem(scene, free, 2, monkeypatch)
    assert len(threaded.centroids) == len(scene[1]) == 3
    for one, two in zip(serial.centroids, threaded.centroids):
        for a, b in zip(one, two):
            for name in ("rowsum", "r", "R", "M_rho", "M_u", "const"):
                assert np.array_equal(getattr(a, name), getattr(b, name)), name
    values = {"boresight_roll": 1e-4, "lever_arm_x": 0.21, "range_scale": 2e-5}
    assert np.array_equal(serial(values), threaded(values))
    # a side swapped or the sets out of order would not compare equal
    assert not np.array_equal(serial.centroids[0][0].r, threaded.centroids[0][1].r)


def test_the_sides_are_built_two_at_a_time(scene, monkeypatch):
    """Each Centroids build waits until another one runs beside it: built one at a time (no
    threads), the first one's barrier breaks."""
    barrier, seen = threading.Barrier(2, timeout=5), set()

    class Together(Centroids):
        def __init__(self, *args):
            barrier.wait()
            seen.add(threading.get_ident())
            super().__init__(*args)

    monkeypatch.setattr(problem_module, "Centroids", Together)
    monkeypatch.setattr(problem_module, "IN_PROCESS_THREADS", 2)  # (whatever the machine's cores)
    strips, corrs = scene
    poses = {s.id: s.pose() for s in strips}
    StripProblem(Sensor(), poses, corrs, ["boresight_roll"])
    assert len(seen) == 2 and threading.get_ident() not in seen


def test_scanner_free_residuals_in_threads_equal_one_at_a_time(scene, monkeypatch):
    """Scanner parameters free: each strip's points re-georeferenced in a thread, the same
    residuals to the bit (the model check's angle columns)."""
    free = ["boresight_roll", "scan_angle_scale"]
    values = {"boresight_roll": 1e-4, "scan_angle_scale": 3e-5}
    serial = _problem(scene, free, 1, monkeypatch)
    threaded = _problem(scene, free, 2, monkeypatch)
    assert serial.centroids is None and threaded.centroids is None
    assert (serial.threads, threaded.threads) == (1, 2)
    assert np.array_equal(serial(values), threaded(values))
    assert not np.array_equal(serial(values), serial({**values, "scan_angle_scale": 0.0}))
    # the model check's problems (its rows taken from the fitted one): one thread, the same bits
    checked = StripProblem(threaded.nominal, {s.id: s.pose() for s in scene[0]}, scene[1], free,
                           same_rows=threaded)
    assert checked.threads == 1 and np.array_equal(checked(values), threaded(values))


def test_pairs_taken_and_widened_in_threads_equal_those_taken_here(scene, monkeypatch):
    """The outer loop's matching with each pair's points taken and its columns widened in its
    thread gives the correspondences of the points taken here and matched one at a time."""
    import calidar.strips.outer_loop as outer_loop
    from calidar.strips.config import StripSettings
    from calidar.strips.matchers import TiePlanes

    strips, _ = scene
    run = outer_loop.Run.start(strips, Sensor(), TiePlanes(), StripSettings())
    values = {"boresight_roll": 1e-4}
    quiet = lambda *a: None  # noqa: E731
    where, inner = [], outer_loop._match_in_thread

    def spied(*args):
        where.append(threading.get_ident())
        return inner(*args)

    monkeypatch.setattr(outer_loop, "_match_in_thread", spied)
    threaded, pairs, _ = run.match(values, 0, None, quiet)
    assert len(where) == 3 and threading.get_ident() not in where  # taken in the threads
    monkeypatch.setattr(outer_loop, "pair_threads", lambda matcher: 1)
    serial, pairs_serial, _ = run.match(values, 0, None, quiet)
    assert pairs == pairs_serial and len(serial) == len(threaded) == 3
    for c, d in zip(serial, threaded):
        assert (c.strip_a, c.strip_b) == (d.strip_a, d.strip_b)
        assert c.A.shape == d.A.shape == (c.n_obs, len(run.by_id[c.strip_a]))
        assert (c.A != d.A).nnz == 0 and (c.B != d.B).nnz == 0
        assert np.array_equal(c.normal, d.normal) and np.array_equal(c.sigma_m, d.sigma_m)
