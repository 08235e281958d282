"""calidar tpu end to end: the files with total_thu/total_tvu, every other attribute kept, the
calibration's covariance raising the σ, and clear errors for bad inputs."""

from __future__ import annotations

import json
from dataclasses import replace

import laspy
import numpy as np
import pytest

import calidar


@pytest.fixture(scope="module")
def sim(tmp_path_factory):
    cfg = calidar.survey_config("uav", seed=5, density=0.1, directions="cross")
    res = calidar.simulate_survey(replace(cfg, scene=replace(cfg.scene, width_m=150.0, length_m=150.0)))
    return res.write(tmp_path_factory.mktemp("tpu") / "sim")


def test_tpu_writes_extra_bytes_and_keeps_the_points(cli, sim, tmp_path):
    strips = sorted((sim / "strips").glob("*.laz"))
    out = tmp_path / "tpu"
    code, stdout, err = cli("tpu", *strips, "-t", sim / "sbet.out", "--sensor", sim / "sensor.toml", "--out", out)
    assert code == 0, err
    doc = json.loads((out / "tpu.json").read_text())
    assert doc["accuracy"]["source"] == str(sim / "smrmsg.out") and doc["calibration"] is None
    for s in strips:
        a, b = laspy.read(s), laspy.read(out / s.name)
        assert list(b.point_format.extra_dimension_names) == ["total_thu", "total_tvu"]
        for name in ("X", "Y", "Z", "gps_time", "classification", "return_number", "intensity", "point_source_id"):
            np.testing.assert_array_equal(a[name], b[name])
        assert np.all((b.total_tvu > 0.005) & (b.total_tvu < 1.0)) and np.all(b.total_thu > 0)
    assert "TVU median" in stdout and "Per-point uncertainty (TPU)" in (out / "report.html").read_text()
    # with a calibration's covariance the uncertainty can only grow
    solution = tmp_path / "solution.json"
    solution.write_text(json.dumps({"parameters": {"boresight_roll": {"value": 0.0, "sigma": 0.01, "unit": "deg",
                                                                      "free": True}},
                                    "correlation": {"names": ["boresight_roll"], "matrix": [[1.0]]}}))
    code, _, err = cli("tpu", strips[0], "-t", sim / "sbet.out", "--sensor", sim / "sensor.toml", "--out",
                       tmp_path / "tpu2", "--calibration", solution)
    assert code == 0, err
    a, b = laspy.read(out / strips[0].name), laspy.read(tmp_path / "tpu2" / strips[0].name)
    added = np.sqrt(np.maximum(b.total_thu.astype(float) ** 2 - a.total_thu.astype(float) ** 2, 0.0))
    # 0.01° of roll at the UAV's 80–110 m ranges: 1.4–1.9 cm across the track
    assert np.all(b.total_thu >= a.total_thu - 1e-6) and 0.012 < np.median(added) < 0.022, np.median(added)


@pytest.mark.parametrize("content, message", [
    ("{", "not valid JSON"),
    ('{"parameters": {}}', "expected a calidar solution.json"),
    ('{"parameters": {"x": {}}, "correlation": {"names": ["x"], "matrix": [[1]]}}', "no estimated sensor parameter"),
])
def test_bad_calibration_file_is_one_line(cli, sim, tmp_path, content, message):
    bad = tmp_path / "solution.json"
    bad.write_text(content)
    strip = sorted((sim / "strips").glob("*.laz"))[0]
    code, _, err = cli("tpu", strip, "-t", sim / "sbet.out", "--sensor", sim / "sensor.toml", "--out", tmp_path / "o",
                       "--calibration", bad)
    assert code == 1 and message in err and str(bad) in err and len(err.strip().splitlines()) == 1, err
    assert not (tmp_path / "o").exists()


def test_bad_options_are_usage_or_input_errors(cli, sim, tmp_path):
    strip = sorted((sim / "strips").glob("*.laz"))[0]
    code, _, err = cli("tpu", strip, "-t", sim / "sbet.out", "--sensor", sim / "sensor.toml", "--out", tmp_path / "o",
                       "--range-sigma", "-1")
    assert code == 1 and "--range-sigma" in err
    code, _, err = cli("tpu", strip, "--sensor", sim / "sensor.toml", "--out", tmp_path / "o")
    assert code == 2 and "--trajectory" in err
