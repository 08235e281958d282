"""``calidar boresight`` starts the VGICP pair workers' forkserver while it reads the strips (issue
32, eleventh session): only for a matcher that holds the GIL, without a cluster, on files that hold
at least ``processes.MIN_POINTS`` points by their headers; a file it cannot read is left to the
ingest's error."""

from __future__ import annotations

from types import SimpleNamespace

import pytest

import calidar.io.las as las
from calidar.errors import InputError
from calidar.pipelines.boresight import _start_pair_workers
from calidar.pipelines.strip_config import StripConfig
from calidar.strips import processes
from calidar.strips.config import CalibrationConfig, TiePlanes, Vgicp


@pytest.fixture
def started(monkeypatch):
    calls = []
    monkeypatch.setattr(processes, "start_server", calls.append)

    def header(path):
        if "missing" in str(path):
            raise InputError(path, None, "LAS/LAZ file not found")
        return SimpleNamespace(point_count=700_000)

    monkeypatch.setattr(las, "las_header", header)
    return calls


def _config(*matchers):
    return StripConfig(CalibrationConfig(matchers=matchers))


def test_started_for_vgicp_by_the_headers_point_counts(started):
    _start_pair_workers(["a.laz", "b.laz"], _config(Vgicp()), SimpleNamespace(client=None))
    _start_pair_workers(["a.laz", "b.laz"], _config(TiePlanes(), Vgicp()),
                        SimpleNamespace(client=None))
    assert started == [1_400_000, 1_400_000]


def test_not_for_tie_planes_a_cluster_or_an_unreadable_file(started):
    _start_pair_workers(["a.laz", "b.laz"], _config(TiePlanes()), SimpleNamespace(client=None))
    _start_pair_workers(["a.laz"], _config(Vgicp()), SimpleNamespace(client=object()))
    _start_pair_workers(["a.laz", "missing.laz"], _config(Vgicp()), SimpleNamespace(client=None))
    assert started == []


def test_start_server_needs_min_points(monkeypatch):
    """Below MIN_POINTS no forkserver is asked for (a round that small stays in this process)."""
    import multiprocessing.forkserver as forkserver

    asked = []
    monkeypatch.setattr(forkserver, "ensure_running", lambda: asked.append(1))
    processes.start_server(processes.MIN_POINTS - 1)
    assert asked == []
    processes.start_server(processes.MIN_POINTS)
    assert asked == ([1] if "forkserver" in __import__("multiprocessing").get_all_start_methods()
                     else [])
