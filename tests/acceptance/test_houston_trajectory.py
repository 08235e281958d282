"""A projected text trajectory in the layout of the real Houston export calibrates a survey as
its SBET does (issue 17): library level, through the shared trajectory options and the strip
pipeline (``calidar boresight --trajectory-crs`` calls the same)."""

from __future__ import annotations

import numpy as np

from calidar import frames, georef
from calidar.pipelines.boresight import load_strips
from calidar.pipelines.inputs import TrajectoryOptions, load_trajectory
from calidar.sensor import Sensor
from calidar.sim.survey import simulate_survey, survey_config
from calidar.io.smrmsg import read_smrmsg
from calidar.strips.calibrate import calibrate
from calidar.strips.config import TrajectorySettings

ERRORS = {"boresight_roll": np.radians(0.03), "boresight_pitch": np.radians(-0.04), "boresight_yaw": np.radians(0.05)}
HOUSTON_DEG = (29.7149, -95.3123, -15.0)  #: the first record of the real export (UTM 15N), ground ≈ −15 m
UTM_15N = "EPSG:32615"


def write_houston_layout(traj, path):
    """The trajectory as the real export lays it out: "GpsTime","Y","X","Z","Roll","Pitch","Azimuth",
    UTM 15N northing before easting, ellipsoidal height, degrees; here a grid azimuth."""
    xyz = georef.to_crs(traj.ecef, UTM_15N)
    grid = np.degrees(traj.heading - frames.grid_factors(UTM_15N, traj.lon, traj.lat)[0])
    rows = np.c_[traj.time, xyz[:, 1], xyz[:, 0], xyz[:, 2], np.degrees(traj.roll), np.degrees(traj.pitch), grid]
    with open(path, "w", encoding="utf-8") as f:
        f.write('"GpsTime","Y","X","Z","Roll","Pitch","Azimuth"\n')
        np.savetxt(f, rows, fmt="%.6f", delimiter=",")
    return path


def test_projected_text_trajectory_calibrates_like_the_sbet(tmp_path):
    res = simulate_survey(survey_config("uav", seed=3, density=0.2, origin_deg=HOUSTON_DEG, errors=ERRORS,
                                        range_noise_m=0.03))
    sim = res.write(tmp_path / "sim")
    assert res.crs == UTM_15N
    sbet = load_trajectory(sim / "sbet.out")
    text = load_trajectory(write_houston_layout(sbet, tmp_path / "traj.txt"), TrajectoryOptions(crs=UTM_15N,
                                                                                               heading="grid"))
    assert np.max(np.abs(text.ecef - sbet.ecef)) < 1e-5  # 1 µm text precision
    assert np.max(np.abs(np.angle(np.exp(1j * (text.heading - sbet.heading))))) < np.radians(2e-6)
    nominal = Sensor.read(sim / "sensor.toml")
    paths = sorted((sim / "strips").glob("*.laz"))
    # the trajectory's errors modelled as `calidar boresight` does by default: priors from the smrmsg
    # beside the SBET (without them roll reads 3.0σ off on this survey: the errors differ line to line)
    model = TrajectorySettings().model(read_smrmsg(sim / "smrmsg.out"))
    solutions = {}
    for name, traj in (("sbet", sbet), ("text", text)):
        strips, _ = load_strips(paths, traj, nominal)
        solutions[name] = calibrate(strips, nominal, trajectory=model).solution  # planes, the boresight
    truth = res.truth.parameters()
    for k in ERRORS:
        a, b = solutions["sbet"], solutions["text"]
        assert abs(a.values[k] - b.values[k]) < 1e-3 * a.sigma[k], k  # the same calibration
        assert abs(b.values[k] - truth[k]) < 3 * b.sigma[k], (k, np.degrees(b.values[k] - truth[k]))
