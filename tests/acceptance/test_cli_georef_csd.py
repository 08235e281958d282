"""``calidar georef`` on the real Optech CSD sample and ``calidar sensor import`` (issue 17)."""

from __future__ import annotations

import re
from pathlib import Path

import numpy as np
import pytest

from calidar.io import read_las
from calidar.io.optech_csd import read_csd
from calidar.sensor import Sensor
from calidar.sensor_import import from_optech_header

SAMPLE = "optech_csd/sample.csd"
DOCS = Path(__file__).resolve().parents[2] / "docs" / "sensor.md"


def _vectors(path):
    a = np.loadtxt(path, delimiter=",", skiprows=1)
    return {k: a[:, i] for i, k in enumerate(open(path).readline().strip().split(","))}


def test_georef_csd_round_trip(real_data, cli, tmp_path):
    """1 000 points, GPS times as in the file, the header's boresight in sensor.toml, and ranges
    equal to the file's within 1 mm after inverse georeferencing (LAS stores 1 mm)."""
    csd = real_data / SAMPLE
    out = tmp_path / "points.laz"
    code, stdout, err = cli("georef", csd, "--out", out)
    assert code == 0, err
    pulses, pts = read_csd(csd), read_las(out)
    assert len(pts) == 1000 and np.array_equal(pts.gps_time, pulses.time) and pts.time_system == "gps_week_seconds"
    assert pts.crs.to_epsg() == 32617  # UTM 17N at 82.55° W
    assert np.all(pts.return_number == 1) and np.array_equal(pts.intensity, pulses.intensity[:, 0])
    assert np.max(np.abs(pts.scan_angle_deg - np.degrees(pulses.scan_angle))) <= 0.003 + 1e-9
    sensor = Sensor.read(tmp_path / "points.sensor.toml")
    expected = from_optech_header(pulses.header)
    assert [sensor.boresight_roll, sensor.boresight_pitch, sensor.boresight_yaw] == pytest.approx(
        [expected.boresight_roll, expected.boresight_pitch, expected.boresight_yaw], abs=1e-15)
    assert sensor.crs == "EPSG:32617"
    code, _, err = cli("inverse", out, "-t", csd, "--sensor", tmp_path / "points.sensor.toml", "--out", tmp_path / "v.csv")
    assert code == 0, err
    v = _vectors(tmp_path / "v.csv")
    assert np.max(np.abs(v["range_m"] - pulses.range_m[:, 0])) < 1e-3  # measured 0.64 mm
    assert np.max(np.abs(np.radians(v["across_track_angle_deg"]) - pulses.scan_angle)) < 2e-6  # 1 mm / 800 m
    assert np.max(np.abs(v["along_track_angle_deg"])) < 1e-4
    # the first point as docs/sensor.md states it (GPS time, UTM 17N easting, northing, height)
    doc = re.search(r"first point: GPS time ([\d.]+) s, E ([\d.]+), N ([\d.]+), h ([\d.]+) m", DOCS.read_text())
    assert doc, "docs/sensor.md states the first point"
    assert [float(g) for g in doc.groups()] == pytest.approx([pts.gps_time[0], *pts.xyz[0]], abs=1e-3)
    assert f"{pts.xyz[0, 0]:.3f}" in stdout


def test_georef_csd_errors(real_data, cli, tmp_path):
    csd = real_data / SAMPLE
    out = tmp_path / "p.laz"
    assert cli("georef", csd, "--out", out)[0] == 0
    code, _, err = cli("georef", csd, "--out", out)
    assert code == 1 and "p.laz: exists; pass --force" in err
    code, _, err = cli("georef", csd, "--out", csd, "--force")
    assert code == 1 and "is an input of this command" in err
    code, _, err = cli("georef", csd, "--out", tmp_path / "q.laz", "--crs", "EPSG:99999")
    assert code == 1 and "crs: expected a CRS pyproj knows" in err and not (tmp_path / "q.laz").exists()
    code, _, err = cli("georef", csd, "--out", tmp_path / "g.laz", "--crs", "EPSG:32617+3855")
    assert code == 1 and "us_nga_egm08_25.tif" in err and err.strip().count("\n") == 0
    code, _, err = cli("georef", csd, "--out", tmp_path / "g.laz", "--crs", "EPSG:32617+3855", "--geoid-undulation", "-32")
    assert code == 0, err
    h = read_las(tmp_path / "g.laz").xyz[:, 2] - read_las(out).xyz[:, 2]
    assert np.allclose(h, 32.0, atol=1.5e-3)  # orthometric = ellipsoidal − N
    code, _, err = cli("georef", real_data / "leeward_sierra" / "sbet.out", "--out", tmp_path / "s.laz")
    assert code == 1 and "signature: expected an Optech CSD file" in err


def test_sensor_import_every_source(real_data, cli, tmp_path):
    code, out, err = cli("sensor", "import", real_data / "leeward_sierra" / "config.toml", "--from", "leeward",
                         "--out", tmp_path / "leeward.toml")
    assert code == 0, err
    s = Sensor.read(tmp_path / "leeward.toml")
    assert np.degrees([s.boresight_roll, s.boresight_pitch, s.boresight_yaw]) == pytest.approx([0.0543, 1.7637, 1.7653],
                                                                                                abs=1e-4)
    assert cli("sensor", "import", real_data / SAMPLE, "--from", "optech-csd", "--out", tmp_path / "optech.toml")[0] == 0
    s = Sensor.read(tmp_path / "optech.toml")
    assert np.degrees([s.boresight_roll, s.boresight_pitch, s.boresight_yaw]) == pytest.approx(
        [1.733232, 0.681081, 0.428872], abs=1e-6)
    (tmp_path / "m.txt").write_text("0 1 0 0.1\n1 0 0 -0.2\n0 0 -1 0.3\n0 0 0 1\n")
    code, _, err = cli("sensor", "import", tmp_path / "m.txt", "--from", "pdal-scan2imu", "--scanner-axes", "y,x,-z",
                       "--crs", "EPSG:32611", "--out", tmp_path / "m.toml")
    assert code == 0, err
    s = Sensor.read(tmp_path / "m.toml")  # the matrix is exactly the axis swap: zero boresight
    assert np.allclose([s.boresight_roll, s.boresight_pitch, s.boresight_yaw], 0, atol=1e-12)
    assert s.lever_arm.tolist() == [0.1, -0.2, 0.3] and s.crs == "EPSG:32611"
    code, _, err = cli("sensor", "import", tmp_path / "m.txt", "--from", "riegl", "--out", tmp_path / "x.toml")
    assert code == 1 and "--from: expected one of leeward, optech-csd, pdal-scan2imu" in err
    code, _, err = cli("sensor", "import", tmp_path / "m.txt", "--from", "pdal-scan2imu", "--out", tmp_path / "m.txt",
                       "--force")
    assert code == 1 and "is an input of this command" in err
