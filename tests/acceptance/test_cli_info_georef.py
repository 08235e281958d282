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
    # what the data say (docs/sensor.md): the scanner vectors lie in one plane (a linear scanner)
    # yawed 13.96° and pitched 0.07° in the body frame — not the config's 1.76°
    u = np.c_[v["x_s"], v["y_s"], v["z_s"]] / v["range_m"][:, None]
    normal = np.linalg.svd(u, full_matrices=False)[2][2]
    normal *= np.sign(normal[0])
    assert np.degrees(np.sqrt(np.mean((u @ normal) ** 2))) < 0.01
    assert np.degrees(np.arctan2(normal[1], normal[0])) == pytest.approx(13.96, abs=0.05)
    assert np.degrees(-np.arcsin(normal[2])) == pytest.approx(0.07, abs=0.05)
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


def _one_line_error(code, err, *needles):
    """A user error: exit 1, one line on stderr containing every needle, no traceback."""
    assert code == 1, err
    assert err.strip().count("\n") == 0 and "Traceback" not in err, err
    for n in needles:
        assert n in err, (n, err)


def _week_crossing(tmp_path, n=5000):
    """Adjusted standard LAS times crossing GPS week 2300 → 2301 exactly at point 2000 (a chunk
    boundary with 1000-point chunks), and a trajectory (SBET) whose week seconds run past 604800 s."""
    tr, las, _, truth = _survey(tmp_path, Sensor(), n=n, name="src.las")
    t_week = 604796.0 + np.arange(n) * 0.002  # point 2000 is 604800.000: the first of week 2301
    t_adj = week_seconds_to_adjusted_standard(t_week, 2300)
    crossing = write_las(tmp_path / "crossing.las", truth["xyz"], CRS, gps_time=t_adj, scan_angle_deg=np.zeros(n),
                         point_source_id=1, time_system="gps_adjusted_standard")
    late = Trajectory(tr.time + (604795.0 - T0), tr.lat, tr.lon, tr.height, tr.roll, tr.pitch, tr.heading)
    return crossing, write_sbet(tmp_path / "late.out", late)


def test_week_boundary_between_chunks_is_caught(tmp_path, cli, monkeypatch):
    monkeypatch.setattr("calidar.pipelines.inputs.CHUNK_POINTS", 1000)
    las, sbet = _week_crossing(tmp_path)
    code, _, err = cli("inverse", las, "-t", sbet, "--out", tmp_path / "v.csv")
    _one_line_error(code, err, "crossing.las: gps_time:", "span GPS weeks 2300–2301")
    assert not (tmp_path / "v.csv").exists()
    toml = Sensor().write(tmp_path / "s.toml")
    code, _, err = cli("regeoref", las, "-t", sbet, "--from", toml, "--to", toml, "--out", tmp_path / "o")
    _one_line_error(code, err, "span GPS weeks 2300–2301")
    assert not (tmp_path / "o").exists()


def _stretched(las, path, factor):
    """A copy of a LAS with its GPS times stretched about their middle by ``factor``."""
    src = laspy.read(las)
    mid = 0.5 * (src.gps_time.min() + src.gps_time.max())
    src.gps_time = mid + factor * (np.asarray(src.gps_time) - mid)
    src.write(path)
    return path


@pytest.mark.parametrize("command", ["inverse", "regeoref"])
def test_outside_trajectory_counted_over_the_whole_file(tmp_path, cli, monkeypatch, command):
    """Points before and after the trajectory in several chunks: one error with whole-file counts
    and time ranges, and nothing written."""
    monkeypatch.setattr("calidar.pipelines.inputs.CHUNK_POINTS", 1000)
    _, las, sbet, _ = _survey(tmp_path, Sensor())  # times T0+0.5 … T0+9.5, trajectory T0 … T0+10
    wide = _stretched(las, tmp_path / "wide.las", 2.5)  # T0−6.25 … T0+16.25
    t = read_las(wide).gps_time
    before, after = t[t < T0], t[t > T0 + 10.0]
    assert before.size > 1000 and after.size > 1000  # more than one chunk each
    toml = Sensor().write(tmp_path / "s.toml")
    out = tmp_path / ("v.csv" if command == "inverse" else "o")
    args = ("--out", out) if command == "inverse" else ("--from", toml, "--to", toml, "--out", out)
    code, _, err = cli(command, wide, "-t", sbet, *args)
    _one_line_error(code, err, f"wide.las: gps_time: {before.size + after.size} of 5000 points",
                    f"{before.size} before it ({before.min():.3f}–{before.max():.3f} s)",
                    f"{after.size} after it ({after.min():.3f}–{after.max():.3f} s)")
    assert not out.exists()


def test_nan_gps_times_are_counted(tmp_path, cli):
    _, las, sbet, _ = _survey(tmp_path, Sensor(), n=300)
    src = laspy.read(las)
    t = np.array(src.gps_time)
    t[[5, 50]] = np.nan
    src.gps_time = t
    src.write(tmp_path / "nan.las")
    code, _, err = cli("inverse", tmp_path / "nan.las", "-t", sbet, "--out", tmp_path / "v.csv")
    _one_line_error(code, err, "nan.las: gps_time: 2 of 300 points", "2 NaN/inf")


def _stamp(*paths):
    return {p: (p.read_bytes(), p.stat().st_mtime_ns) for p in paths}


def test_inputs_never_modified_and_force(tmp_path, cli):
    """Outputs are refused without --force, replaced with it, never an input even with it; a failed
    run leaves the previous output as it was; input bytes and mtimes never change."""
    s = Sensor(boresight_roll=np.radians(0.1))
    _, las, sbet, _ = _survey(tmp_path, Sensor(), n=300)
    old, new = Sensor().write(tmp_path / "old.toml"), s.write(tmp_path / "new.toml")
    inputs = _stamp(las, sbet, old, new)
    csv, out = tmp_path / "v.csv", tmp_path / "out"
    assert cli("inverse", las, "-t", sbet, "--sensor", old, "--out", csv)[0] == 0
    assert cli("regeoref", las, "-t", sbet, "--from", old, "--to", new, "--out", out)[0] == 0
    outputs = _stamp(csv, out / las.name)
    _one_line_error(*cli("inverse", las, "-t", sbet, "--out", csv)[::2], "v.csv: exists; pass --force")
    _one_line_error(*cli("regeoref", las, "-t", sbet, "--from", old, "--to", new, "--out", out)[::2], "not empty")
    assert _stamp(csv, out / las.name) == outputs
    for target in (las, sbet, old):  # --out naming an input: refused even with --force
        code, _, err = cli("inverse", las, "-t", sbet, "--sensor", old, "--out", target, "--force")
        _one_line_error(code, err, "is an input of this command")
    _one_line_error(*cli("regeoref", las, "-t", sbet, "--from", old, "--to", new, "--out", tmp_path, "--force")[::2],
                    "holds the input", "pts.las")
    # a failing run with --force keeps the previous output
    late = _stretched(las, tmp_path / "late.las", 3.0)
    _one_line_error(*cli("inverse", late, "-t", sbet, "--out", csv, "--force")[::2], "outside the trajectory")
    assert _stamp(csv) == {csv: outputs[csv]}
    # --force replaces the outputs (atomically: no temporary file left)
    assert cli("inverse", las, "-t", sbet, "--sensor", new, "--out", csv, "--force")[0] == 0
    assert cli("regeoref", las, "-t", sbet, "--from", new, "--to", old, "--out", out, "--force")[0] == 0
    assert csv.read_bytes() != outputs[csv][0] and (out / las.name).read_bytes() != outputs[out / las.name][0]
    assert sorted(p.name for p in out.iterdir()) == [las.name]
    assert not [p for p in tmp_path.iterdir() if p.name.startswith(".")]
    assert _stamp(las, sbet, old, new) == inputs


def test_bad_inputs_through_every_command(tmp_path, cli):
    """SBET size, NaN and non-increasing times, point formats 0 and 2, a truncated LAZ, an unknown
    --crs: one line, exit 1, in inverse, regeoref and info alike, and nothing written."""
    _, las, sbet, _ = _survey(tmp_path, Sensor(), n=100)
    toml = Sensor().write(tmp_path / "s.toml")
    a = np.fromfile(sbet, "<f8").reshape(-1, 17)
    (tmp_path / "short.out").write_bytes(a.tobytes()[:-8])
    nan = a.copy()
    nan[10, 0] = np.nan
    nan.tofile(tmp_path / "nan.out")
    a[np.r_[0:10, 11, 10, 12:len(a)]].tofile(tmp_path / "unsorted.out")
    src = laspy.read(las)
    for fmt in (0, 2):
        nogps = laspy.create(point_format=fmt, file_version="1.2")
        nogps.x, nogps.y, nogps.z = src.x, src.y, src.z
        nogps.write(tmp_path / f"fmt{fmt}.las")
    src.write(tmp_path / "full.laz")
    (tmp_path / "cut.laz").write_bytes((tmp_path / "full.laz").read_bytes()[:-1000])
    cases = [
        (las, tmp_path / "short.out", "short.out: size: expected a multiple of 136 bytes"),
        (las, tmp_path / "nan.out", "nan.out: time: expected finite values in [0, 1209600] s of week, got nan"),
        (las, tmp_path / "unsorted.out", "unsorted.out: time: expected strictly increasing times"),
        (tmp_path / "fmt0.las", sbet, "fmt0.las: point_format: point format 0 has no GPS time"),
        (tmp_path / "fmt2.las", sbet, "fmt2.las: point_format: point format 2 has no GPS time"),
        (tmp_path / "cut.laz", sbet, "cut.laz: cannot read the points"),
    ]
    for points, traj, message in cases:
        _one_line_error(*cli("inverse", points, "-t", traj, "--out", tmp_path / "v.csv")[::2], message)
        _one_line_error(*cli("regeoref", points, "-t", traj, "--from", toml, "--to", toml, "--out", tmp_path / "o")[::2],
                        message)
        _one_line_error(*cli("info", points if traj == sbet else traj)[::2], message)
    unknown = ("--crs", "EPSG:99999", "--out")
    _one_line_error(*cli("inverse", las, "-t", sbet, *unknown, tmp_path / "v.csv")[::2], "crs: expected a CRS pyproj knows")
    _one_line_error(*cli("regeoref", las, "-t", sbet, "--from", toml, "--to", toml, *unknown, tmp_path / "o")[::2],
                    "crs: expected a CRS pyproj knows")
    assert not (tmp_path / "v.csv").exists() and not (tmp_path / "o").exists()


def test_inverse_real_ecef_las_equals_utm(real_data, cli, tmp_path):
    """points_ecef.las declares GeoTIFF model type geocentric on WGS 84: read as EPSG:4978, its
    vectors equal those of the same points in UTM (within the LAS 1 cm storage)."""
    d = real_data / "leeward_sierra"
    assert read_las(d / "points_ecef.las").crs.to_epsg() == 4978
    assert cli("inverse", d / "points_ecef.las", "-t", d / "sbet.out", "--out", tmp_path / "e.csv")[0] == 0
    assert cli("inverse", d / "points.las", "-t", d / "sbet.out", "--out", tmp_path / "u.csv")[0] == 0
    e, u = _vectors(tmp_path / "e.csv"), _vectors(tmp_path / "u.csv")
    assert np.array_equal(e["gps_time"], u["gps_time"])
    assert np.max(np.abs(e["range_m"] - u["range_m"])) < 0.02
    assert np.max(np.abs(e["across_track_angle_deg"] - u["across_track_angle_deg"])) < 2e-4


def test_regeoref_real_ecef_las_equals_utm(real_data, cli, tmp_path):
    """Both leeward files re-georeferenced with a changed mounting land on the same ECEF points
    (within the two files' 1 cm storage), the ECEF output staying ECEF."""
    d = real_data / "leeward_sierra"
    old = Sensor().write(tmp_path / "old.toml")
    new = Sensor(boresight_roll=np.radians(0.05), lever_arm_x=2.0).write(tmp_path / "new.toml")
    code, _, err = cli("regeoref", d / "points.las", d / "points_ecef.las", "-t", d / "sbet.out", "--from", old,
                       "--to", new, "--out", tmp_path / "o")
    assert code == 0, err
    u, e = read_las(tmp_path / "o" / "points.las"), read_las(tmp_path / "o" / "points_ecef.las")
    assert e.crs.to_epsg() == 4978
    assert np.linalg.norm(e.xyz - read_las(d / "points_ecef.las").xyz, axis=1).min() > 2.0  # the change mattered
    assert np.max(np.abs(georef.from_crs(u.xyz, u.crs) - e.xyz)) < 0.03


def test_time_system_override(tmp_path, cli):
    """A LAS whose global-encoding bit says week seconds while its times are adjusted standard (as
    the real IGN file): outside the trajectory without --time-system, right with it."""
    tr, _, sbet, truth = _survey(tmp_path, Sensor(), n=300)
    lying = write_las(tmp_path / "lying.las", truth["xyz"], CRS, gps_time=week_seconds_to_adjusted_standard(truth["t"], 2300),
                      scan_angle_deg=np.degrees(truth["ang"]), point_source_id=1, time_system="gps_week_seconds")
    _one_line_error(*cli("inverse", lying, "-t", sbet, "--out", tmp_path / "v.csv")[::2], "outside the trajectory")
    code, _, err = cli("inverse", lying, "-t", sbet, "--time-system", "adjusted", "--out", tmp_path / "v.csv")
    assert code == 0, err
    assert np.max(np.abs(_vectors(tmp_path / "v.csv")["range_m"] - truth["range"])) < 2e-3
    toml = Sensor().write(tmp_path / "s.toml")
    code, _, err = cli("regeoref", lying, "-t", sbet, "--from", toml, "--to", toml, "--time-system", "adjusted",
                       "--out", tmp_path / "o")
    assert code == 0, err
    assert np.max(np.abs(read_las(tmp_path / "o" / "lying.las").xyz - read_las(lying).xyz)) < 2e-3
    d = json.loads(cli("info", lying, "--time-system", "adjusted", "--json")[1])
    assert d["time_system"] == "gps_adjusted_standard" and d["warning"] is None
    _one_line_error(*cli("inverse", lying, "-t", sbet, "--time-system", "gps", "--out", tmp_path / "w.csv")[::2],
                    "--time-system: expected one of week, adjusted, got 'gps'")


def test_real_ign_time_system(real_data, cli):
    ign = real_data / "ign_two_strips" / "faceraster_numerical_imprecision.laz"
    d = json.loads(cli("info", ign, "--time-system", "adjusted", "--json")[1])
    assert d["time_system"] == "gps_adjusted_standard" and d["warning"] is None
    assert [f["points"] for f in d["flight_lines"]] == [10020, 8054]


def test_geoid_heights(tmp_path, cli):
    """A LAS in UTM + EGM2008 heights: one clear error naming the missing PROJ grid (never heights
    taken as ellipsoidal); with --geoid-undulation N the same vectors as the ellipsoidal file."""
    _, las, sbet, truth = _survey(tmp_path, Sensor(), n=300)
    n_m = -30.0
    geoid = write_las(tmp_path / "geoid.las", truth["xyz"] - [0.0, 0.0, n_m], "EPSG:32611+3855",
                      gps_time=truth["t"], scan_angle_deg=np.degrees(truth["ang"]), point_source_id=1)
    _one_line_error(*cli("inverse", geoid, "-t", sbet, "--out", tmp_path / "v.csv")[::2],
                    "geoid.las: crs: WGS 84 / UTM zone 11N + EGM2008 height has heights above a geoid",
                    "us_nga_egm08_25.tif", "--geoid-undulation")
    assert not (tmp_path / "v.csv").exists()
    assert cli("inverse", geoid, "-t", sbet, "--geoid-undulation", n_m, "--out", tmp_path / "v.csv")[0] == 0
    assert cli("inverse", las, "-t", sbet, "--out", tmp_path / "e.csv")[0] == 0
    a, b = _vectors(tmp_path / "v.csv"), _vectors(tmp_path / "e.csv")
    assert np.max(np.abs(a["range_m"] - b["range_m"])) < 2e-3
    toml = Sensor().write(tmp_path / "s.toml")
    new = Sensor(boresight_roll=np.radians(0.05)).write(tmp_path / "n.toml")
    code, _, err = cli("regeoref", geoid, "-t", sbet, "--from", toml, "--to", new, "--geoid-undulation", n_m,
                       "--out", tmp_path / "o")
    assert code == 0, err
    code, _, err = cli("regeoref", las, "-t", sbet, "--from", toml, "--to", new, "--out", tmp_path / "oe")
    assert code == 0, err
    moved_geoid, moved = read_las(tmp_path / "o" / "geoid.las").xyz, read_las(tmp_path / "oe" / "pts.las").xyz
    assert np.max(np.abs(moved_geoid - (moved - [0.0, 0.0, n_m]))) < 3e-3  # heights stay above the geoid
    _one_line_error(*cli("inverse", las, "-t", sbet, "--geoid-undulation", 5, "--out", tmp_path / "w.csv")[::2],
                    "--geoid-undulation: given (5.0 m) but WGS 84 / UTM zone 11N has ellipsoidal heights")


def test_info_on_damaged_las(tmp_path, cli):
    """NaN times are counted, not printed as 'inf … -inf'; absurd coordinates are one clear line."""
    _, las, _, _ = _survey(tmp_path, Sensor(), n=100)
    src = laspy.read(las)
    t = np.array(src.gps_time)
    t[:] = np.nan
    src.gps_time = t
    src.write(tmp_path / "nan.las")
    code, out, err = cli("info", tmp_path / "nan.las")
    assert code == 0, err
    assert "inf …" not in out and "… -inf" not in out
    assert "100 points have NaN/inf GPS times" in out and "no finite GPS time" in out
    d = json.loads(cli("info", tmp_path / "nan.las", "--json")[1])
    assert d["gps_time_not_finite"] == 100 and d["flight_lines"][0]["gps_time"] is None
    b = bytearray((tmp_path / "nan.las").read_bytes())
    b[131:139] = np.float64(1e295).tobytes()
    (tmp_path / "huge.las").write_bytes(bytes(b))
    _one_line_error(*cli("info", tmp_path / "huge.las", "--json")[::2], "huge.las: x scale factor: expected a positive scale")
