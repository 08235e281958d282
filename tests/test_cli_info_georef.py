import json

import laspy
import numpy as np
import pytest

from calidar import frames, georef
from calidar.io import read_las, write_las, write_sbet
from calidar.io.las import week_seconds_to_adjusted_standard
from calidar.sensor import Sensor
from calidar.trajectory import Trajectory

CRS = "EPSG:32611"
T0 = 400000.0


def _trajectory(n=1001):
    """10 s at 100 Hz, 70 m/s on heading 30° at 3000 m over the Sierra Nevada, rolling ±2°."""
    t = T0 + np.arange(n) * 0.01
    lat0, lon0 = np.radians([37.7, -119.0])
    hd = np.radians(30.0)
    dist = 70.0 * (t - T0)
    lat = lat0 + dist * np.cos(hd) / 6.37e6
    lon = lon0 + dist * np.sin(hd) / (6.37e6 * np.cos(lat0))
    return Trajectory(t, lat, lon, np.full(n, 3000.0), np.radians(2 * np.sin(t)), np.full(n, 0.02), np.full(n, hd))


def _survey(tmp_path, sensor, n=5000, time_system="gps_week_seconds", t_shift=0.0, name="pts.las"):
    """A trajectory (SBET) and a LAS of points georeferenced with ``sensor``; returns their truth."""
    tr = _trajectory()
    rng = np.random.default_rng(3)
    t = np.sort(rng.uniform(T0 + 0.5, T0 + 9.5, n))
    ang = rng.uniform(-0.5, 0.5, n)
    rng_m = rng.uniform(2500, 3100, n)
    xyz = georef.to_crs(georef.forward(tr, sensor, t, rng_m, ang), CRS)
    stored_t = t + t_shift if time_system == "gps_week_seconds" else week_seconds_to_adjusted_standard(t, 2300)
    las = write_las(tmp_path / name, xyz, CRS, gps_time=stored_t, scan_angle_deg=np.degrees(ang), point_source_id=4,
                    intensity=np.arange(n) % 60000, time_system=time_system)
    sbet = write_sbet(tmp_path / "sbet.out", tr)
    return tr, las, sbet, dict(t=t, ang=ang, range=rng_m, xyz=xyz)


def _vectors(path):
    a = np.loadtxt(path, delimiter=",", skiprows=1)
    return {k: a[:, i] for i, k in enumerate(open(path).readline().strip().split(","))}


@pytest.mark.parametrize("time_system", ["gps_week_seconds", "gps_adjusted_standard"])
def test_inverse_recovers_simulated_observations(tmp_path, cli, time_system):
    s = Sensor(boresight_roll=np.radians(0.2), boresight_pitch=np.radians(-0.1), lever_arm_x=0.5, range_offset=0.1)
    sensor_file = s.write(tmp_path / "sensor.toml")
    _, las, sbet, truth = _survey(tmp_path, s, time_system=time_system)
    code, out, err = cli("inverse", las, "--trajectory", sbet, "--sensor", sensor_file, "--out", tmp_path / "v.csv")
    assert code == 0, err
    v = _vectors(tmp_path / "v.csv")
    # LAS stores 1 mm: ranges to ~1 mm, angles to ~1 mm / 2.5 km
    assert np.max(np.abs(v["range_m"] - truth["range"])) < 2e-3
    assert np.max(np.abs(np.radians(v["across_track_angle_deg"]) - truth["ang"])) < 1e-6
    assert np.max(np.abs(v["along_track_angle_deg"])) < 1e-4
    assert np.allclose(np.hypot(np.hypot(v["x_s"], v["y_s"]), v["z_s"]), v["range_m"] - 0.1, atol=1e-3)
    # refuses to overwrite, then does with --force
    code, _, err = cli("inverse", las, "--trajectory", sbet, "--out", tmp_path / "v.csv")
    assert code == 1 and "exists; pass --force" in err
    assert cli("inverse", las, "--trajectory", sbet, "--out", tmp_path / "v.csv", "--force")[0] == 0


@pytest.mark.parametrize("name", ["pts.las", "pts.laz"])
def test_regeoref_matches_direct_georeferencing(tmp_path, cli, name):
    old = Sensor()
    new = Sensor(boresight_roll=np.radians(0.1), boresight_yaw=np.radians(-0.05), lever_arm_z=-1.0)
    tr, las, sbet, truth = _survey(tmp_path, old, name=name)
    code, out, err = cli("regeoref", las, "-t", sbet, "--from", old.write(tmp_path / "old.toml"),
                         "--to", new.write(tmp_path / "new.toml"), "--out", tmp_path / "out")
    assert code == 0, err
    moved = read_las(tmp_path / "out" / name)
    with laspy.open(tmp_path / "out" / name) as r:
        assert r.header.are_points_compressed == name.endswith(".laz") and r.header.point_count == 5000
    expected = georef.to_crs(georef.forward(tr, new, truth["t"], truth["range"], truth["ang"]), CRS)
    shift = np.linalg.norm(expected - truth["xyz"], axis=1)
    assert shift.min() > 1.0  # the change mattered (0.1° at ≈ 3 km ≈ 5 m)
    assert np.max(np.abs(moved.xyz - expected)) < 3e-3  # 1 mm storage, ranges ≈ 3 km
    assert np.array_equal(moved.intensity, np.arange(len(moved)) % 60000)
    assert np.array_equal(moved.gps_time, read_las(las).gps_time)
    code, _, err = cli("regeoref", las, "-t", sbet, "--from", tmp_path / "old.toml", "--to", tmp_path / "new.toml",
                       "--out", tmp_path / "out")
    assert code == 1 and "not empty" in err


def test_points_outside_trajectory(tmp_path, cli):
    _, las, sbet, _ = _survey(tmp_path, Sensor(), t_shift=5.0)  # half the points after the trajectory ends
    code, out, err = cli("inverse", las, "-t", sbet, "--out", tmp_path / "v.csv")
    assert code == 1
    assert "points have GPS times outside the trajectory" in err and "after it" in err
    assert not (tmp_path / "v.csv").exists()
    n_after = int(np.sum(read_las(las).gps_time > T0 + 10.0))
    assert f"{n_after} of 5000 points" in err.replace("\n", " ")


def test_las_without_crs_and_without_gps_time(tmp_path, cli):
    _, las, sbet, _ = _survey(tmp_path, Sensor(), n=100)
    src = laspy.read(las)
    nocrs = laspy.create(point_format=1, file_version="1.2")
    nocrs.x, nocrs.y, nocrs.z, nocrs.gps_time = src.x, src.y, src.z, src.gps_time
    nocrs.write(tmp_path / "nocrs.las")
    code, _, err = cli("inverse", tmp_path / "nocrs.las", "-t", sbet, "--out", tmp_path / "v.csv")
    assert code == 1 and "nocrs.las: crs: the file has no CRS" in err and "Traceback" not in err
    assert cli("inverse", tmp_path / "nocrs.las", "-t", sbet, "--crs", CRS, "--out", tmp_path / "v.csv")[0] == 0
    toml = Sensor().write(tmp_path / "s.toml")
    code, _, err = cli("regeoref", tmp_path / "nocrs.las", "-t", sbet, "--from", toml, "--to", toml, "--out", tmp_path / "o")
    assert code == 1 and "nocrs.las: crs: the file has no CRS" in err and not (tmp_path / "o").exists()
    fmt2 = laspy.create(point_format=2, file_version="1.2")
    fmt2.x, fmt2.y, fmt2.z = src.x, src.y, src.z
    fmt2.write(tmp_path / "fmt2.las")
    for args in (("inverse", tmp_path / "fmt2.las", "-t", sbet, "--out", tmp_path / "w.csv"), ("info", tmp_path / "fmt2.las")):
        code, _, err = cli(*args)
        assert code == 1 and "point format 2 has no GPS time" in err


def test_bad_trajectories_on_the_command_line(tmp_path, cli):
    bad = tmp_path / "bad.out"
    bad.write_bytes(b"\x01" * 1000)
    code, _, err = cli("info", bad)
    assert code == 1 and "bad.out: size: expected a multiple of 136 bytes" in err and "got 1000 bytes" in err
    code, _, err = cli("info", tmp_path / "missing.out")
    assert code == 1 and "missing.out" in err and "Traceback" not in err


def test_info_simulated_las_and_sbet_json(tmp_path, cli):
    _, las, sbet, truth = _survey(tmp_path, Sensor())
    code, out, _ = cli("info", las, "--json")
    d = json.loads(out)
    assert code == 0 and d["points"] == 5000 and d["crs_epsg"] == 32611
    assert d["flight_lines"] == [{"point_source_id": 4, "points": 5000,
                                  "gps_time": [pytest.approx(truth["t"].min(), abs=1e-9), pytest.approx(truth["t"].max(), abs=1e-9)]}]
    assert d["scan_angle_deg"][0] == pytest.approx(np.degrees(truth["ang"].min()), abs=0.003)
    code, out, _ = cli("info", sbet, "--json")
    d = json.loads(out)
    assert d["records"] == 1001 and d["rate_hz"] == pytest.approx(100.0) and d["duration_s"] == pytest.approx(10.0)
    assert d["path_length_m"] == pytest.approx(700.0, rel=1e-2)


def test_info_real_files(real_data, cli):
    code, out, _ = cli("info", real_data / "leeward_sierra" / "points.las")
    assert code == 0 and "flight line    36:        1,325 points" in out and "WGS 84 / UTM zone 11N" in out
    d = json.loads(cli("info", real_data / "leeward_sierra" / "sbet.out", "--json")[1])
    assert d["records"] == 200 and d["rate_hz"] == pytest.approx(200.0, rel=1e-4)
    houston = real_data / "houston_trajectory" / "sbet_047_IGS08-UTM15N-Ellipsoid-trim.txt"
    d = json.loads(cli("info", houston, "--crs", "EPSG:32615", "--json")[1])
    assert d["records"] == 14600
    code, _, err = cli("info", houston)
    assert code == 1 and "projected x/y columns" in err
    d = json.loads(cli("info", real_data / "ign_two_strips" / "faceraster_numerical_imprecision.laz", "--json")[1])
    assert [f["points"] for f in d["flight_lines"]] == [10020, 8054] and "adjusted standard" in d["warning"]


def _leeward_boresight_in_calidar_frames(roll, pitch, yaw):
    """leeward's scanner frame has the beam ρ·(cos α, 0, sin α); ours ρ·(0, sin θ, cos θ).

    x_L → z_s, y_L → x_s, z_L → y_s, so R_bs = R_bL · Pᵀ with P the permutation below."""
    p = np.array([[0.0, 1.0, 0.0], [0.0, 0.0, 1.0], [1.0, 0.0, 0.0]])
    return frames.matrix_to_rpy(frames.rpy_to_matrix(roll, pitch, yaw) @ p.T)


def test_inverse_real_leeward(real_data, cli, tmp_path):
    d = real_data / "leeward_sierra"
    las = read_las(d / "points.las")
    code, _, err = cli("inverse", d / "points.las", "--trajectory", d / "sbet.out", "--out", tmp_path / "v.csv")
    assert code == 0, err
    v = _vectors(tmp_path / "v.csv")
    diff = v["across_track_angle_deg"] - las.scan_angle_deg
    assert np.corrcoef(v["across_track_angle_deg"], las.scan_angle_deg)[0, 1] > 0.999
    assert np.median(np.abs(diff)) < 0.5
    assert 4400 < v["range_m"].min() and v["range_m"].max() < 5400
    # config.toml's boresight roll = pitch = −1.54 (rad, leeward's frames) is −π/2 (the axis swap)
    # plus 1.76°: in calidar's frames roll 0.05°, pitch 1.76°, yaw 1.77°
    r, p, y = np.degrees(_leeward_boresight_in_calidar_frames(-1.54, -1.54, 0.0))
    assert (r, p, y) == pytest.approx((0.054, 1.764, 1.765), abs=2e-3)
    assert np.allclose(_leeward_boresight_in_calidar_frames(-np.pi / 2, -np.pi / 2, 0.0), 0.0, atol=1e-12)
    sensor = Sensor(*np.radians([r, p, y])).write(tmp_path / "leeward.toml")
    cli("inverse", d / "points.las", "-t", d / "sbet.out", "--sensor", sensor, "--out", tmp_path / "w.csv")
    w = _vectors(tmp_path / "w.csv")
    assert np.corrcoef(w["across_track_angle_deg"], las.scan_angle_deg)[0, 1] > 0.999
    assert np.median(np.abs(w["across_track_angle_deg"] - las.scan_angle_deg)) < 0.5


def test_inverse_with_a_projected_text_trajectory(tmp_path, cli):
    """The same survey with its trajectory as UTM text with grid headings gives the same vectors."""
    tr, las, sbet, truth = _survey(tmp_path, Sensor(), n=500)
    xyz = georef.to_crs(tr.ecef, CRS)
    grid = tr.heading - frames.grid_factors(CRS, tr.lon, tr.lat)[0]
    text = tmp_path / "traj.csv"
    np.savetxt(text, np.c_[tr.time, xyz, np.degrees(np.c_[tr.roll, tr.pitch, grid])], fmt="%.10f", delimiter=",",
               header="GpsTime,X,Y,Z,Roll,Pitch,Azimuth", comments="")
    code, _, err = cli("inverse", las, "-t", text, "--trajectory-crs", CRS, "--trajectory-heading", "grid",
                       "--out", tmp_path / "text.csv")
    assert code == 0, err
    assert cli("inverse", las, "-t", sbet, "--out", tmp_path / "sbet.csv")[0] == 0
    a, b = _vectors(tmp_path / "text.csv"), _vectors(tmp_path / "sbet.csv")
    assert np.max(np.abs(a["range_m"] - b["range_m"])) < 2e-4
    assert np.max(np.abs(a["across_track_angle_deg"] - b["across_track_angle_deg"])) < 2e-6
    code, _, err = cli("inverse", las, "-t", text, "--out", tmp_path / "x.csv")
    assert code == 1 and "traj.csv: crs: the file has projected x/y columns" in err
