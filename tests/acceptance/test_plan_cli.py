"""calidar plan end to end: a plan over the built-in scene (good), over flat ground (pitch and heading
unseen: FAIL, exit 3), over a DEM, plan.json and report.html, and --simulate confirming a plan."""

from __future__ import annotations

import json

import numpy as np
import pytest

HEADER = "line,start_x,start_y,end_x,end_y,height_agl_m,speed_mps\n"
FOUR = HEADER + "1,-30,-60,-30,60,80,8\n2,-30,60,-30,-60,80,8\n3,30,-60,30,60,80,8\n4,30,60,30,-60,80,8\n5,60,0,-60,0,80,8\n"


@pytest.fixture(scope="module")
def inputs(tmp_path_factory):
    from calidar.sensor import Sensor

    root = tmp_path_factory.mktemp("plan")
    (root / "lines.csv").write_text(FOUR)
    Sensor(lever_arm_x=0.05, lever_arm_z=0.12).write(root / "sensor.toml")
    return root


def test_plan_over_the_scene_writes_its_outputs(cli, inputs, tmp_path):
    out = tmp_path / "out"
    code, stdout, err = cli("plan", inputs / "lines.csv", "--sensor", inputs / "sensor.toml", "--out", out,
                            "--terrain", "scene:uav:3", "--pulse-rate", "2000", "--estimate", "boresight")
    assert code == 0, err + stdout
    doc = json.loads((out / "plan.json").read_text())
    assert not doc["poor"] and [p["parameter"] for p in doc["parameters"]] == ["boresight_roll", "boresight_pitch",
                                                                             "boresight_yaw"]
    for p in doc["parameters"]:
        assert 0 < p["sigma_error_si"] <= p["sigma_reported_si"] * 1.001 and p["determined"]
    assert len(doc["pairs"]) == 10 and all(p["tie_planes"] > 100 for p in doc["pairs"])
    assert doc["suggestions"] and doc["verdict"]["status"] == "pass"
    html = (out / "report.html").read_text()
    assert "Predicted σ" in html and "Suggested lines" in html and "<img" in html
    assert "PASS" in stdout and "suggested line" in stdout


def test_flat_ground_cannot_show_pitch_or_heading(cli, inputs, tmp_path):
    """A GeoJSON plan over flat ground: level surfaces show no horizontal shift (exit 3: a poor plan)."""
    lines = inputs / "lines.geojson"
    feats = [{"type": "Feature", "geometry": {"type": "LineString", "coordinates": [[x, -60 * s], [x, 60 * s]]},
              "properties": {"height_agl_m": 80, "speed_mps": 8}} for x, s in ((-30, 1), (-30, -1), (30, 1))]
    lines.write_text(json.dumps({"type": "FeatureCollection", "features": feats}))
    out = tmp_path / "flat"
    code, stdout, err = cli("plan", lines, "--sensor", inputs / "sensor.toml", "--out", out, "--no-suggest",
                            "--pulse-rate", "2000")
    assert code == 3, err + stdout
    doc = json.loads((out / "plan.json").read_text())
    assert doc["poor"] and not doc["suggestions"]
    by = {p["parameter"]: p for p in doc["parameters"]}
    assert by["boresight_roll"]["determined"] and not by["boresight_yaw"]["determined"]
    assert "FAIL" in stdout


def test_plan_over_a_dem(cli, inputs, tmp_path):
    """A DEM GeoTIFF (a tilted plane with a ridge, projected metres): slopes show pitch and heading."""
    import rasterio
    from rasterio.transform import from_origin

    x = np.arange(-150, 150, 2.0)
    gx, gy = np.meshgrid(x, -x)
    z = (0.15 * gx + 8.0 * np.sin(gy / 25.0)).astype("float32")
    dem = tmp_path / "dem.tif"
    with rasterio.open(dem, "w", driver="GTiff", width=z.shape[1], height=z.shape[0], count=1, dtype="float32",
                       crs="EPSG:32632", transform=from_origin(-151.0, 151.0, 2.0, 2.0)) as dst:
        dst.write(z, 1)
    out = tmp_path / "dem"
    code, stdout, err = cli("plan", inputs / "lines.csv", "--sensor", inputs / "sensor.toml", "--out", out,
                            "--terrain", dem, "--pulse-rate", "2000", "--no-suggest")
    assert code in (0, 3), err + stdout
    doc = json.loads((out / "plan.json").read_text())
    assert doc["terrain"] == "DEM dem.tif"
    assert all(p["sigma_error_si"] is not None and p["sigma_error_si"] > 0 for p in doc["parameters"])


@pytest.mark.slow
def test_simulate_confirms_the_plan(cli, inputs, tmp_path):
    """--simulate 2: two surveys of the plan simulated and calibrated; the report shows them."""
    out = tmp_path / "sim"
    code, stdout, err = cli("plan", inputs / "lines.csv", "--sensor", inputs / "sensor.toml", "--out", out,
                            "--terrain", "scene:uav:3", "--pulse-rate", "2000", "--no-suggest", "--simulate", "2")
    assert code == 0, err + stdout
    sim = json.loads((out / "plan.json").read_text())["simulation"]
    assert sim["runs"] == 2 and len(sim["per_run"]) == 2
    for name, rms in sim["rms_error"].items():
        assert rms < 5 * next(p["sigma_error_si"] for p in json.loads((out / "plan.json").read_text())["parameters"]
                              if p["parameter"] == name)
    assert "Confirmed by simulation" in (out / "report.html").read_text()


def test_plan_for_a_palmer_scanner(cli, inputs, tmp_path):
    """A sensor.toml naming a Palmer scanner: its oval sets the swath (--fov is a linear scanner's), each
    point is seen ahead and back; four lines 14 m apart over the scene are predicted with finite σ."""
    from calidar.scanners.palmer import PalmerScanner
    from calidar.sensor import Sensor

    sensor = tmp_path / "palmer.toml"
    Sensor(lever_arm_x=0.05, lever_arm_z=0.12, scanner=PalmerScanner()).write(sensor)
    lines = tmp_path / "lines.csv"
    lines.write_text(HEADER + "1,-7,-60,-7,60,80,8\n2,-7,60,-7,-60,80,8\n3,7,-60,7,60,80,8\n4,7,60,7,-60,80,8\n")
    out = tmp_path / "palmer"
    code, stdout, err = cli("plan", lines, "--sensor", sensor, "--out", out, "--terrain", "scene:uav:3",
                            "--pulse-rate", "2000", "--no-suggest")
    assert code == 0, err + stdout
    doc = json.loads((out / "plan.json").read_text())
    assert doc["instrument"]["half_fov_deg"] == pytest.approx(10.55, abs=0.1)
    assert all(p["determined"] and p["sigma_reported_si"] > 0 for p in doc["parameters"])
