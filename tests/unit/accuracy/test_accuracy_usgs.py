"""The USGS Lidar Base Specification in ``calidar accuracy`` (issue 28): the absolute vertical
accuracy judged against the quality levels' thresholds (written here as read for this test:
NVA RMSEz QL0 ≤ 5 cm, QL1/QL2 ≤ 10 cm, QL3 ≤ 20 cm; VVA 95th percentile QL0 ≤ 15 cm, QL1/QL2 ≤ 30
cm, QL3 ≤ 60 cm), and with --swaths the swath checks, which must be calidar quality's own figures
on the same files (one code, not a copy)."""

from __future__ import annotations

import json
from types import SimpleNamespace

import numpy as np
import pytest

from calidar.accuracy.usgs import usgs_findings
from calidar.io.las import PointOptions, write_las
from calidar.pipelines.accuracy import AccuracySettings, measure_accuracy, swath_checks
from calidar.strips.usgs import absolute_checks

from test_accuracy_known_answer import X0, Y0, _checkpoints, _strips, plane

NVA = {"QL0": 0.05, "QL1": 0.10, "QL2": 0.10, "QL3": 0.20}
VVA = {"QL0": 0.15, "QL1": 0.30, "QL2": 0.30, "QL3": 0.60}


@pytest.mark.parametrize("nva, vva", [(0.03, 0.10), (0.05, 0.16), (0.074, 0.29), (0.15, 0.45), (0.25, 0.7)])
def test_absolute_levels_follow_the_table(nva, vva):
    a, v = absolute_checks(nva, 30, vva, 20)
    assert a.levels_met == [ql for ql, t in NVA.items() if nva <= t]
    assert v.levels_met == [ql for ql, t in VVA.items() if vva <= t]
    assert (a.n_cells, v.n_cells) == (30, 20)
    assert a.status == (f"meets {a.levels_met[0]}" if a.levels_met else "meets no quality level")


def _assessment(rmse, vva95=None, swaths=None):
    acc = SimpleNamespace(rmse_m=rmse, n_nva=30, vva95_m=vva95, n_vva=0 if vva95 is None else 20)
    return SimpleNamespace(accuracy=acc, usgs_swaths=swaths)


def test_the_verdict_names_the_level_met_and_warns_below_ql3():
    f = {x.check: x for x in usgs_findings(_assessment(0.0767, 0.19))}
    absolute = f["USGS absolute accuracy"]
    assert absolute.status == "pass"
    assert "NVA RMSEz 7.7 cm at 30 checkpoints meets QL1/QL2 (≤ 10 cm)" in absolute.detail
    assert "VVA 95th percentile 19.0 cm at 20 meets QL1/QL2 (≤ 30 cm)" in absolute.detail
    assert f["USGS swath checks"].status == "note" and "--swaths" in f["USGS swath checks"].action
    worst = {x.check: x for x in usgs_findings(_assessment(0.23))}["USGS absolute accuracy"]
    assert worst.status == "warn" and "meets no quality level" in worst.detail and "20 cm" in worst.action


def test_the_absolute_check_uses_the_reported_rmse_with_the_survey_term(tmp_path):
    a = measure_accuracy(_strips(tmp_path), _checkpoints(tmp_path / "cp.csv"))
    f = {x.check: x for x in usgs_findings(a)}
    # 7.4 cm of data ⊕ 2 cm of survey = 7.67 cm: QL1/QL2, not QL0
    assert "NVA RMSEz 7.7 cm at 30 checkpoints meets QL1/QL2" in f["USGS absolute accuracy"].detail
    doc = a.to_dict()["usgs"]
    assert doc["absolute"]["checks"][0]["value_m"] == pytest.approx(np.hypot(0.074, 0.02), abs=2e-4)
    assert "2025" in doc["absolute"]["specification"] and "swaths" not in doc


def _noisy_strips(folder, rng):
    """Two overlapping lines of ground points on the plane with 1.5 cm noise, the second 3 cm high."""
    paths = []
    for k, (xa, xb) in enumerate(((0.0, 120.0), (80.0, 200.0))):
        gx, gy = np.meshgrid(np.arange(xa, xb, 0.5), np.arange(0.0, 200.0, 0.5))
        x, y = X0 + gx.ravel(), Y0 + gy.ravel() + 0.1 * k
        z = plane(x, y) + 0.03 * k + rng.normal(0.0, 0.015, x.size)
        paths.append(write_las(folder / f"line_{k + 1}.laz", np.c_[x, y, z], "EPSG:32632",
                               gps_time=np.arange(x.size) * 1e-4 + 1e3 * k, scan_angle_deg=np.zeros(x.size),
                               point_source_id=k + 1, classification=np.full(x.size, 2, np.uint8)))
    return paths


def test_swath_checks_are_calidar_qualitys_own(tmp_path, cli):
    from calidar.pipelines.quality import measure
    from calidar.strips.usgs import usgs_checks

    strips = _noisy_strips(tmp_path, np.random.default_rng(3))
    _checkpoints(tmp_path / "cp.csv")
    code, out, err = cli("accuracy", *strips, "--checkpoints", tmp_path / "cp.csv", "--out", tmp_path / "out", "--swaths")
    assert code == 0, err
    doc = json.loads((tmp_path / "out" / "accuracy.json").read_text())["usgs"]["swaths"]
    _, _, pairs, _, _, lines = measure(strips)
    expected = usgs_checks(pairs, lines)
    assert [c["value_m"] for c in doc["checks"]] == pytest.approx([c.value_m for c in expected], rel=1e-9)
    rmsdz = doc["checks"][1]["value_m"]
    assert rmsdz == pytest.approx(np.hypot(0.03, 0.015), rel=0.15)  # the 3 cm step ⊕ the noise in the cells' planes
    assert doc["meets"] == "QL1" and "interswath RMSDz" in out
    html = (tmp_path / "out" / "report.html").read_text()
    assert "USGS Lidar Base Specification" in html and "interswath max |dz|" in html


def test_swath_checks_do_not_apply_to_one_line(tmp_path):
    one = _noisy_strips(tmp_path, np.random.default_rng(4))[:1]
    s = swath_checks(one, None, PointOptions())
    assert s.checks == [] and "one flight line" in s.note
    f = {x.check: x for x in usgs_findings(_assessment(0.05, swaths=s))}["USGS swath checks"]
    assert f.status == "note" and f.detail.startswith("do not apply: found one flight line")
