"""VGICP pair matching in worker processes (calidar.strips.processes) gives the in-process results bit for bit."""

from __future__ import annotations

import os

import numpy as np
import pytest

import calidar.strips.calibrate as calibrate_module
import calidar.strips.outer_loop as outer_loop_module
from calidar.strips import processes
from calidar.strips.calibrate import calibrate
from calidar.strips.outer_loop import match_or_error
from calidar.strips.config import CalibrationConfig, StripSettings, Vgicp
from calidar.strips.matchers import TiePlanes
from calidar.strips.processes import map_in_processes, pair_processes, worth_processes
from calidar.strips.vgicp import VgicpSettings

from test_distribute import strips_for
from test_strips_sim import _simulate


def _pid(_):
    return os.getpid()


@pytest.fixture(scope="module")
def pool():
    with pair_processes(2) as p:
        yield p


def test_tasks_run_in_other_processes_in_task_order(pool):
    pids = map_in_processes(pool, _pid, [(k,) for k in range(6)])
    assert len(pids) == 6 and os.getpid() not in pids
    assert map_in_processes(pool, abs, [(-k,) for k in range(5)]) == [0, 1, 2, 3, 4]
    assert map_in_processes(pool, abs, []) == []


@pytest.mark.skipif("forkserver" not in __import__("multiprocessing").get_all_start_methods(),
                    reason="the workers come from a forkserver only where there is one")
def test_the_workers_start_with_what_they_import_loaded():
    """The forkserver imports ``PRELOAD`` once, before it forks the workers (issue 32, eleventh
    session: ≈ 0.9 CPU s a worker less): fresh workers hold calidar.strips.outer_loop before any
    task imports it (``eval`` of a string: nothing of calidar is unpickled)."""
    assert "calidar.strips.outer_loop" in processes.PRELOAD
    probe = "'calidar.strips.outer_loop' in __import__('sys').modules"
    with pair_processes(2) as fresh:
        assert map_in_processes(fresh, eval, [(probe,)] * 2) == [True, True]


def test_a_broken_pool_leaves_the_tasks_to_this_process():
    class Broken:
        def map(self, *args):
            from concurrent.futures.process import BrokenProcessPool
            raise BrokenProcessPool("a worker died")

    assert map_in_processes(Broken(), abs, [(-3,), (4,)]) == [3, 4]


def test_one_process_is_no_pool_and_only_large_rounds_go_to_the_workers():
    with pair_processes(1) as p:
        assert p is None
    tasks = [(Vgicp(), 1, np.zeros((400_000, 3)), 2, np.zeros((200_000, 3)))] * 2  # 1.2 M points
    assert worth_processes(tasks) and not worth_processes(tasks[:1])
    assert Vgicp.holds_gil and not TiePlanes.holds_gil


def test_vgicp_correspondences_identical_in_worker_processes(pool):
    a, b, c = strips_for(1)
    matcher = Vgicp(VgicpSettings(max_pairs=800))
    tasks = [(matcher, 1, a, 2, b), (matcher, 1, a, 3, c)]
    local = [match_or_error(*t) for t in tasks]
    remote = map_in_processes(pool, match_or_error, tasks)
    for x, y in zip(local, remote):
        assert (x.strip_a, x.strip_b) == (y.strip_a, y.strip_b) and x.n_obs == y.n_obs > 100
        assert (x.A != y.A).nnz == 0 and (x.B != y.B).nnz == 0
        assert np.array_equal(x.normal, y.normal) and np.array_equal(x.sigma_m, y.sigma_m)


def test_calibration_identical_with_pairs_in_worker_processes(monkeypatch):
    res = _simulate("uav", "cross", 0.05)
    strips = res.calibration_strips()
    config = CalibrationConfig(matchers=(Vgicp(),), solver=StripSettings(threshold_m=1e-3, max_outer=3))
    monkeypatch.setattr(calibrate_module, "PROCESSES", 1)
    local = calibrate(strips, res.nominal, config)
    monkeypatch.setattr(calibrate_module, "PROCESSES", 2)
    monkeypatch.setattr(processes, "MIN_POINTS", 0)  # this small survey's rounds go to the workers too
    used = []
    monkeypatch.setattr(outer_loop_module, "map_in_processes",
                        lambda *a: used.append(1) or processes.map_in_processes(*a))
    remote = calibrate(strips, res.nominal, config)
    assert used and local.pairs == remote.pairs and len(local.pairs) >= 4
    assert remote.solution.values == local.solution.values
    assert remote.solution.sigma == local.solution.sigma
