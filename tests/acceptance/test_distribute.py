"""Pair matching on a Dask LocalCluster gives the same results as in-process (to 1e-9)."""

from __future__ import annotations

import json

import numpy as np
import pytest

from calidar.errors import CalibrationError, InputError
from calidar.strips.distribute import cluster_client, map_pairs
from calidar.strips.calibrate import calibrate
from calidar.strips.config import CalibrationConfig, StripSettings, Vgicp
from calidar.strips.vgicp import VgicpSettings, match_pair_vgicp

from test_strips_sim import _simulate
from test_vgicp import disturb, sample


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
    tasks = [(1, a, 2, b, VgicpSettings(max_pairs=800)), (1, a, 3, c, VgicpSettings(max_pairs=800))]
    local = map_pairs(match_pair_vgicp, tasks)
    remote = map_pairs(match_pair_vgicp, tasks, client=client)
    for x, y in zip(local, remote):
        assert (x.strip_a, x.strip_b) == (y.strip_a, y.strip_b) and x.n_obs == y.n_obs > 100
        assert (x.A != y.A).nnz == 0 and (x.B != y.B).nnz == 0
        np.testing.assert_allclose(y.normal, x.normal, rtol=0, atol=1e-9)


def test_calibration_identical_in_process_and_on_a_local_cluster():
    res = _simulate("uav", "cross", 0.05)
    strips = res.calibration_strips()
    config = CalibrationConfig(matchers=(Vgicp(),), solver=StripSettings(threshold_m=1e-3, max_outer=3))
    local = calibrate(strips, res.nominal, config)
    remote = calibrate(strips, res.nominal, config, workers=2)  # its own cluster
    assert local.pairs == remote.pairs and len(local.pairs) >= 4
    for name, value in local.solution.values.items():
        assert abs(remote.solution.values[name] - value) < 1e-9, name
    truth = res.truth.parameters()
    assert abs(local.solution.values["boresight_roll"] - truth["boresight_roll"]) < np.radians(0.01)


def test_scheduler_address_and_bad_options(client, monkeypatch):
    a, b, _ = strips_for(2)
    tasks = [(1, a, 2, b, VgicpSettings(max_pairs=300))]
    via_address = map_pairs(match_pair_vgicp, tasks, scheduler=client.scheduler.address)
    local = map_pairs(match_pair_vgicp, tasks)
    assert via_address[0].n_obs == local[0].n_obs and (via_address[0].A != local[0].A).nnz == 0
    with pytest.raises(CalibrationError, match="not both"):
        map_pairs(weighted_centroid, [], scheduler="tcp://127.0.0.1:1", workers=2)
    with pytest.raises(InputError, match=r"--workers: expected an integer in \[1, 256\]"):
        map_pairs(weighted_centroid, [], workers=0)
    monkeypatch.setattr("calidar.strips.distribute.CONNECT_TIMEOUT_S", 1.0)
    with pytest.raises(CalibrationError, match="cannot reach the Dask scheduler at tcp://127.0.0.1:9"):
        map_pairs(weighted_centroid, [], scheduler="tcp://127.0.0.1:9")


def test_cli_boresight_vgicp_with_local_workers(cli, tmp_path):
    res = _simulate("uav", "cross", 0.05)
    sim = res.write(tmp_path / "sim")
    out = tmp_path / "cal"
    code, stdout, err = cli("boresight", *sorted((sim / "strips").glob("*.laz")), "--trajectory", sim / "sbet.out",
                            "--sensor", sim / "sensor.toml", "--method", "vgicp", "--workers", "2",
                            # the UAV's 2 cm GNSS noise moves the angles: modelled, as UAV_TRAJECTORY
                            "--trajectory-sigma", "0.02,0.002", "--trajectory-block", "2",
                            "--trajectory-correlation", "20,20", "--truth", sim / "truth.json", "--out", out)
    assert code == 0, err
    assert "Dask tasks — read footprints:" in stdout and "overlap quality:" in stdout
    doc = json.loads((out / "solution.json").read_text())
    assert doc["strips"]["method"] == "vgicp" and len(doc["strips"]["pairs"]) >= 4
    for name in ("boresight_roll", "boresight_pitch", "boresight_yaw"):
        p = doc["parameters"][name]
        assert abs(p["error"]) < 3 * p["sigma"], (name, p)
    code, _, err = cli("boresight", *sorted((sim / "strips").glob("*.laz")), "--trajectory", sim / "sbet.out",
                       "--sensor", sim / "sensor.toml", "--method", "vgicp", "--scheduler", "tcp://127.0.0.1:1",
                       "--workers", "2", "--out", tmp_path / "x")
    assert code == 1 and "not both" in err and "Traceback" not in err


def test_boresight_on_a_local_cluster_equals_in_process_and_reports_what_tasks_sent_back(tmp_path):
    """Every file read (footprints, kept points), pair match and overlap-quality read is a task on
    the cluster; the solution and quality stages equal the in-process run's to 1e-9."""
    from calidar.pipelines.boresight import calibrate_strips
    from calidar.pipelines.strip_config import StripConfig
    from calidar.strips.config import TrajectorySettings

    sim = _simulate("uav", "cross", 0.05).write(tmp_path / "sim")
    strips = sorted((sim / "strips").glob("*.laz"))
    config = StripConfig(CalibrationConfig(trajectory=TrajectorySettings(2.0, sigma=(0.02, np.radians(0.002)))))
    runs = {w: calibrate_strips(strips, sim / "sbet.out", sim / "sensor.toml", config, workers=w) for w in (None, 2)}
    for w, run in runs.items():
        run.write(tmp_path / f"cal{w}")
    here, there = (r.results["planes"].solution for r in runs.values())
    assert here.values.keys() == there.values.keys()
    assert max(abs(here.values[k] - there.values[k]) for k in here.values) < 1e-9
    for st_here, st_there in zip(runs[None].quality["planes"], runs[2].quality["planes"]):
        assert [(q.a, q.b, q.n_cells) for q in st_here.pairs] == [(q.a, q.b, q.n_cells) for q in st_there.pairs]
        assert max(abs(a.median_dz_m - b.median_dz_m) for a, b in zip(st_here.pairs, st_there.pairs) if a.n_cells) < 1e-9
    sent = json.loads((tmp_path / "cal2" / "solution.json").read_text())["run"]["dask_tasks"]
    files = len(strips)
    assert {k: v["tasks"] for k, v in sent.items()} == {
        "read footprints": files, "read kept points": files, "match pair": sent["match pair"]["tasks"],
        "overlap quality": files * (1 + (sent["overlap quality"]["tasks"] > files))}
    assert sent["match pair"]["tasks"] >= 3 and all(v["max_bytes_per_task"] < 20e6 for v in sent.values())
    assert "dask_tasks" not in json.loads((tmp_path / "calNone" / "solution.json").read_text())["run"]
    report = (tmp_path / "cal2" / "report.html").read_text()
    assert "Dask tasks: read footprints: " in report and "Dask tasks" not in (tmp_path / "calNone" / "report.html").read_text()
