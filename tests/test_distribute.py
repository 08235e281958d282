"""Pair matching on a Dask LocalCluster gives the same results as in-process."""

from __future__ import annotations

import numpy as np
import pytest

from calidar.errors import CalibrationError
from calidar.strips.distribute import cluster_client, map_pairs
from calidar.strips.vgicp import VgicpSettings, match_pairs_vgicp

from test_vgicp import ROT_TRUE, SHIFT_TRUE, disturb, rigid_solve, sample


def weighted_centroid(points, weights):
    """A small real computation: weighted centroid (m) of (N, 3) points."""
    return (weights[:, None] * points).sum(axis=0) / weights.sum()


@pytest.fixture(scope="module")
def client():
    with cluster_client(workers=2) as c:
        yield c


def strips_for(seed):
    rng = np.random.default_rng(seed)
    a = sample(30_000, rng)
    b = disturb(sample(30_000, rng))
    c = sample(30_000, rng, x_range=(-30, 100)) + [0.0, 0.0, 0.1]
    return a, b, c


def test_map_pairs_keeps_task_order_in_process_and_on_a_cluster(client):
    rng = np.random.default_rng(0)
    tasks = [(rng.normal(size=(200_000, 3)), rng.random(200_000)) for _ in range(3)]  # > SCATTER_BYTES
    local = map_pairs(weighted_centroid, tasks)
    remote = map_pairs(weighted_centroid, tasks, client=client)
    assert [r.shape for r in remote] == [(3,)] * 3
    np.testing.assert_allclose(np.array(remote), np.array(local), rtol=0, atol=1e-12)


def test_vgicp_correspondences_identical_on_a_local_cluster(client):
    a, b, c = strips_for(1)
    pairs = [(1, a, 2, b), (1, a, 3, c), (2, b, 3, c)]
    settings = VgicpSettings(max_pairs=800)
    local, skipped_local = match_pairs_vgicp(pairs, settings)
    remote, skipped_remote = match_pairs_vgicp(pairs, settings, client=client)
    assert skipped_local == skipped_remote
    assert len(local) == len(remote) == 3
    for x, y in zip(local, remote):
        assert (x.strip_a, x.strip_b) == (y.strip_a, y.strip_b)
        assert (x.A != y.A).nnz == 0 and (x.B != y.B).nnz == 0
        np.testing.assert_allclose(y.normal, x.normal, rtol=0, atol=1e-9)


def test_iterated_calibration_identical_in_process_and_with_workers():
    rng = np.random.default_rng(11)
    a = sample(30_000, rng)
    b = disturb(sample(30_000, rng))
    start = np.degrees(ROT_TRUE) + [0.2, -0.2, 0.2]
    local = rigid_solve(a, b, start, "point_to_plane")
    remote = rigid_solve(a, b, start, "point_to_plane", workers=2)  # its own LocalCluster, closed after
    assert local.extra["vgicp_rounds"] == remote.extra["vgicp_rounds"]
    for name, value in local.values.items():
        assert abs(remote.values[name] - value) < 1e-9, name
    assert abs(local.values["tz"] - SHIFT_TRUE[2]) < 0.03  # and it is the right answer


def test_scheduler_address_and_bad_options(client, monkeypatch):
    a, b, _ = strips_for(2)
    via_address, _ = match_pairs_vgicp([(1, a, 2, b)], VgicpSettings(max_pairs=300), scheduler=client.scheduler.address)
    local, _ = match_pairs_vgicp([(1, a, 2, b)], VgicpSettings(max_pairs=300))
    assert (via_address[0].A != local[0].A).nnz == 0
    with pytest.raises(CalibrationError, match="not both"):
        map_pairs(weighted_centroid, [], scheduler="tcp://127.0.0.1:1", workers=2)
    with pytest.raises(CalibrationError, match="at least 1"):
        map_pairs(weighted_centroid, [], workers=0)
    monkeypatch.setattr("calidar.strips.distribute.CONNECT_TIMEOUT_S", 1.0)
    with pytest.raises(CalibrationError, match="cannot reach the Dask scheduler at tcp://127.0.0.1:9"):
        map_pairs(weighted_centroid, [], scheduler="tcp://127.0.0.1:9")
