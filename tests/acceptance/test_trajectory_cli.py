"""`calidar trajectory`: a simulated survey's flight path reconstructed from its strips alone, within
stated tolerances of the trajectory the strips were georeferenced with; readable by the other
commands; robust to damaged times and return numbers; clear errors for what the method cannot use."""

from __future__ import annotations

import json
from dataclasses import replace

import laspy
import numpy as np
import pytest

from calidar.io.las import write_las
from calidar.io.sbet import read_sbet
from calidar.io.trajectory import read_trajectory
from calidar.sensor import Sensor
from calidar.trajrec.result import compare, error_summary

CRS = "EPSG:32632"


@pytest.fixture(scope="module")
def survey(tmp_path_factory):
    from calidar.sim.survey import simulate_survey, survey_config

    cfg = survey_config("uav", seed=3, density=0.1, vegetation=0.3)
    cfg = replace(cfg, scene=replace(cfg.scene, width_m=220.0, length_m=150.0))
    return simulate_survey(cfg).write(tmp_path_factory.mktemp("sim") / "survey")


def _errors(folder, path):
    sensor = Sensor.read(folder / "sensor.toml")
    return error_summary(compare(read_trajectory(path), read_sbet(folder / "sbet.out"),
                                 (sensor.lever_arm_x, sensor.lever_arm_y, sensor.lever_arm_z)))


def test_simulated_survey_within_tolerance_and_readable(cli, survey, tmp_path):
    strips = sorted((survey / "strips").glob("*.laz"))
    # the simulator's scanner is exact (encoder and scan plane), and this user knows it: priors 0
    code, out, err = cli("trajectory", *strips, "--out", tmp_path / "traj.csv", "--sensor-out", tmp_path / "s.toml",
                         "--encoder-sigma", "0,0", "--scan-plane-sigma", "0,0")
    assert code == 0, err
    sensor = Sensor.read(tmp_path / "s.toml")
    assert sensor.crs == CRS and sensor.lever_arm_x == sensor.boresight_yaw == 0.0
    assert (tmp_path / "report.html").stat().st_size > 10_000 and "Line 1" in (tmp_path / "report.html").read_text()
    e = _errors(survey, tmp_path / "traj.csv")
    # the goal of issue #30: median position ≤ 0.10 m, heading ≤ 0.05°; here (80 m above ground) far better
    assert e["position_3d_m"]["median"] < 0.01 and e["position_3d_m"]["p95"] < 0.05
    assert e["heading_deg"]["median"] < 0.01 and e["roll_deg"]["median"] < 0.01 and e["pitch_deg"]["median"] < 0.01
    z = e["rms_error_over_sigma"]  # σ honest: neither far too small nor uselessly large
    assert all(0.2 < v < 2.0 for v in z.values()), z
    assert read_trajectory(tmp_path / "traj.csv").extra.keys() >= {"sigma_north", "sigma_heading"}
    code, out, err = cli("trajectory", *strips, "--out", tmp_path / "sbet.out", "--report", tmp_path / "r2.html")
    assert code == 0, err
    e2 = _errors(survey, tmp_path / "sbet.out")
    assert e2["position_3d_m"]["median"] < 0.01
    # by default the encoder's and the scan plane's priors (0.1°) are in the attitude σ: what points cannot know
    assert e2["heading_deg"]["median"] < 0.01 and e2["roll_deg"]["median"] < 0.01
    assert "not determined by the points, their prior σ in the σ columns: scan-angle offset 0.1°" in err + out
    code, out, err = cli("info", tmp_path / "sbet.out")
    assert code == 0 and "trajectory" in out
    # --compare: the errors against a known trajectory (at its own point: the IMU, 0.13 m from the scanner here)
    code, out, err = cli("trajectory", *strips, "--out", tmp_path / "c" / "t.csv", "--compare", survey / "sbet.out",
                         "--json")
    assert code == 0, err
    assert 0.05 < json.loads(out)["comparison"]["position_3d_m"]["median"] < 0.2
    z = _errors(survey, tmp_path / "c" / "t.csv")["rms_error_over_sigma"]  # default priors: σ ≥ 0.1° in attitude
    assert all(z[k] < 0.2 for k in ("roll", "pitch", "heading")) and all(0.2 < z[k] < 2.0 for k in ("north", "east")), z
    assert "Against a known trajectory" in (tmp_path / "c" / "report.html").read_text()


def _damaged(src, dst, rng):
    """The strip with 1 % of GPS times zeroed, 0.5 % replaced by times elsewhere in the line, every
    return numbered 1, and no point source id."""
    las = laspy.read(src)
    t = np.array(las.gps_time)
    n = t.size
    t[rng.choice(n, n // 100, replace=False)] = 0.0
    wrong = rng.choice(n, n // 200, replace=False)
    t[wrong] = rng.uniform(t[t > 0].min(), t.max(), wrong.size)
    las.gps_time = t
    las.return_number = np.ones(n, np.uint8)
    las.point_source_id = np.zeros(n, np.uint16)
    las.write(dst)


def test_damaged_times_and_return_numbers(cli, survey, tmp_path):
    rng = np.random.default_rng(1)
    strips = sorted((survey / "strips").glob("*.laz"))
    damaged = []
    for k, s in enumerate(strips):
        _damaged(s, tmp_path / s.name, rng)
        damaged.append(tmp_path / s.name)
    code, out, err = cli("trajectory", *damaged, "--out", tmp_path / "out" / "traj.csv", "--json")
    assert code == 0, err
    assert "GPS time ≤ 0" in out and "repeat a return number" in out and "split at time gaps" in out
    e = _errors(survey, tmp_path / "out" / "traj.csv")
    assert e["position_3d_m"]["median"] < 0.02 and e["heading_deg"]["median"] < 0.02


def _write(path, xyz, t, scan, nret):
    return write_las(path, xyz, CRS, gps_time=t, scan_angle_deg=scan, point_source_id=1,
                     return_number=np.ones(t.size, np.uint8), number_of_returns=nret)


def test_bad_inputs_say_what_the_method_needs(cli, tmp_path):
    n = 20000
    t = np.linspace(100.0, 110.0, n)
    xyz = np.c_[500000 + 100 * np.sin(t * 300), 5200000 + 60 * t, np.full(n, 400.0)]
    ones = np.ones(n, np.uint8)
    # no usable scan angles, one return a pulse
    p = _write(tmp_path / "flat.laz", xyz, t, np.zeros(n), ones)
    code, out, err = cli("trajectory", p, "--out", tmp_path / "a.csv")
    assert code == 1 and "scan-angle field" in err and "multi-return pulses" in err
    # a single short line
    p = _write(tmp_path / "short.laz", xyz[:400], t[:400], np.zeros(400), ones[:400])
    code, out, err = cli("trajectory", p, "--out", tmp_path / "b.csv")
    assert code == 1 and "s of points; the method needs ≥ 0.5 s" in err
    # no GPS time at all (point format 0)
    las = laspy.create(point_format=0, file_version="1.2")
    las.x, las.y, las.z = xyz[:10, 0], xyz[:10, 1], xyz[:10, 2]
    las.write(tmp_path / "notime.las")
    code, out, err = cli("trajectory", tmp_path / "notime.las", "--out", tmp_path / "c.csv")
    assert code == 1 and "needs each point's GPS time" in err
    # GPS times all zero
    p = _write(tmp_path / "zero.laz", xyz, np.zeros(n), np.zeros(n), ones)
    code, out, err = cli("trajectory", p, "--out", tmp_path / "d.csv")
    assert code == 1 and "GPS time ≤ 0" in err
    # one pulse per line (every point its own point source id)
    las = laspy.read(tmp_path / "flat.laz")
    las.point_source_id = np.arange(n, dtype=np.uint16)
    las.write(tmp_path / "onepulse.laz")
    code, out, err = cli("trajectory", tmp_path / "onepulse.laz", "--out", tmp_path / "e.csv")
    assert code == 1 and "no flight line" in err
    code, out, err = cli("trajectory", tmp_path / "flat.laz", "--out", tmp_path / "f.csv", "--scanner", "nope")
    assert code == 2 and "Usage" in err
    code, out, err = cli("trajectory", tmp_path / "flat.laz", "--out", tmp_path / "f.csv", "--format", "las")
    assert code == 2 and "--format" in err
    assert not any((tmp_path / n).exists() for n in ("a.csv", "b.csv", "c.csv", "d.csv", "e.csv", "f.csv"))


@pytest.mark.slow
def test_strips_delivered_without_their_trajectory_are_adjusted_as_with_it(cli, tmp_path):
    """Issue #30: strips delivered with a boresight error and no trajectory; `calidar trajectory` then
    `calidar boresight` with the reconstruction, its zero-mounting sensor.toml and the navigation grade,
    against the same calibration with the true SBET: the overlaps (|median dz|, RMSDz) within 1.5×
    (benchmarks/trajectory_boresight.py: within 0.1 % on 5 surveys) and the boresight within 0.001°."""
    from calidar.sim.survey import simulate_survey, survey_config

    err = {"boresight_roll": np.radians(0.08), "boresight_pitch": np.radians(-0.05), "boresight_yaw": np.radians(0.1)}
    cfg = survey_config("uav", seed=11, density=0.2, errors=err)
    sim = simulate_survey(replace(cfg, scene=replace(cfg.scene, width_m=220.0, length_m=150.0))).write(tmp_path / "sim")
    strips = sorted((sim / "strips").glob("*.laz"))
    code, out, e = cli("trajectory", *strips, "--out", tmp_path / "rec" / "traj.csv", "--sensor-out",
                       tmp_path / "rec" / "sensor.toml")
    assert code == 0, e
    runs = {}
    for name, traj, sensor, extra in (("true", sim / "sbet.out", sim / "sensor.toml", []),
                                      ("rec", tmp_path / "rec" / "traj.csv", tmp_path / "rec" / "sensor.toml",
                                       ["--trajectory-sigma", "0.02,0.002"])):
        code, out, e = cli("boresight", *strips, "--trajectory", traj, "--sensor", sensor, "--out", tmp_path / f"cal_{name}",
                           "--truth", sim / "truth.json", *extra)
        assert code in (0, 3), e
        runs[name] = json.loads((tmp_path / f"cal_{name}" / "solution.json").read_text())
    par = {k: {n: runs[k]["parameters"][n]["value"] for n in err} for k in runs}  # deg
    assert all(abs(par["rec"][n] - par["true"][n]) < 0.001 for n in err), par
    q = {}
    for k in runs:
        code, out, e = cli("regeoref", *strips, "--trajectory", sim / "sbet.out" if k == "true" else tmp_path / "rec" / "traj.csv",
                           "--from", sim / "sensor.toml" if k == "true" else tmp_path / "rec" / "sensor.toml",
                           "--to", tmp_path / f"cal_{k}" / "sensor.toml", "--out", tmp_path / f"{k}_strips")
        assert code == 0, e
        code, out, e = cli("quality", *sorted((tmp_path / f"{k}_strips").glob("*.laz")), "--json")
        assert code == 0, e
        pairs = json.loads(out)["pairs"]
        q[k] = (np.mean([abs(p["median_dz_m"]) for p in pairs]), np.mean([p["rmsdz_m"] for p in pairs]))
    assert q["rec"][1] <= 1.5 * q["true"][1] and q["rec"][0] <= max(1.5 * q["true"][0], 0.002), q
