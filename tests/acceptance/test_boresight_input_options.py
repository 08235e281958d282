"""``calidar boresight`` with the shared input options (issue 17): a projected text trajectory in
the real Houston export's layout (``--trajectory-crs EPSG:32615 --trajectory-heading grid``) and
strips whose global-encoding bit lies about their GPS times (``--time-system adjusted``)."""

from __future__ import annotations

import json

import pytest
from test_houston_trajectory import ERRORS, HOUSTON_DEG, UTM_15N, write_houston_layout

from calidar.io.las import read_las, week_seconds_to_adjusted_standard, write_las
from calidar.pipelines.inputs import load_trajectory
from calidar.sim.survey import simulate_survey, survey_config

GPS_WEEK = 2300


def _lying_strips(paths, out_dir):
    """The strips with adjusted standard GPS times, their global-encoding bit saying week seconds."""
    out_dir.mkdir()
    lying = []
    for p in paths:
        las = read_las(p)
        lying.append(write_las(out_dir / p.name, las.xyz, las.crs,
                               gps_time=week_seconds_to_adjusted_standard(las.gps_time, GPS_WEEK),
                               scan_angle_deg=las.scan_angle_deg, point_source_id=las.point_source_id,
                               return_number=las.return_number, number_of_returns=las.number_of_returns,
                               classification=las.classification, time_system="gps_week_seconds"))
    return lying


def test_boresight_with_a_houston_text_trajectory_and_a_lying_time_bit(cli, tmp_path):
    res = simulate_survey(survey_config("uav", seed=3, density=0.2, origin_deg=HOUSTON_DEG, errors=ERRORS,
                                        range_noise_m=0.03))
    sim = res.write(tmp_path / "sim")
    traj = write_houston_layout(load_trajectory(sim / "sbet.out"), tmp_path / "traj.txt")
    strips = _lying_strips(sorted((sim / "strips").glob("*.laz")), tmp_path / "lying")
    common = [*strips, "--trajectory", traj, "--sensor", sim / "sensor.toml", "--trajectory-crs", UTM_15N,
              "--trajectory-heading", "grid", "--trajectory-accuracy", sim / "smrmsg.out"]
    code, _, err = cli("boresight", *common, "--out", tmp_path / "wrong")
    assert code == 1 and "GPS times outside the trajectory" in err and "Traceback" not in err, err
    assert not (tmp_path / "wrong").exists()
    code, out, err = cli("boresight", *common, "--time-system", "adjusted", "--truth", sim / "truth.json",
                         "--out", tmp_path / "out")
    assert code == 0, err
    doc = json.loads((tmp_path / "out" / "solution.json").read_text())
    for k in ERRORS:
        p = doc["parameters"][k]
        assert abs(p["error"]) < 3 * p["sigma"], (k, p)
    assert all("--time-system adjusted" in st["reproduce"] for st in doc["overlap_quality"])
    assert "--trajectory-crs EPSG:32615" in doc["overlap_quality"][1]["reproduce"]
    assert doc["overlap_quality"][0]["pairs"][0]["points_a"][0]["rule"] == "ground"
    assert "Points used: ground: class 2." in (tmp_path / "out" / "report.html").read_text()


def test_real_houston_export_reads_with_the_trajectory_options(cli, real_data):
    txt = real_data / "houston_trajectory" / "sbet_047_IGS08-UTM15N-Ellipsoid-trim.txt"
    code, out, err = cli("info", txt, "--trajectory-crs", UTM_15N, "--trajectory-heading", "grid", "--json")
    assert code == 0, err
    doc = json.loads(out)
    assert doc["records"] == 14600 and doc["roll_deg"][0] == pytest.approx(-18.533, abs=1e-3)
    assert 29.71 < doc["lat_deg"][0] < doc["lat_deg"][1] < 29.72 and -95.37 < doc["lon_deg"][0] < -95.36
    code, out, err = cli("info", txt, "--trajectory-crs", UTM_15N, "--crs", UTM_15N)
    assert code == 1 and "--trajectory-crs" in err and "Traceback" not in err
