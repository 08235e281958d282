"""sensor.toml: every key checked (docs/sensor.md): missing keys without a documented default,
wrong types, NaN/inf and values beyond physical ranges are one clear error naming the key."""

from __future__ import annotations

import numpy as np
import pytest

from calidar.errors import InputError
from calidar.sensor import Sensor

MOUNTING = ("[mounting]\nboresight_roll_deg = 0.1\nboresight_pitch_deg = -0.2\nboresight_yaw_deg = 0.3\n"
            "lever_arm_m = [0.5, -0.1, 0.2]\n")


def _roll(value: str) -> str:
    return MOUNTING.replace("boresight_roll_deg = 0.1", f"boresight_roll_deg = {value}")


def _read(tmp_path, text: str, encoding="utf-8"):
    path = tmp_path / "sensor.toml"
    path.write_bytes(text.encode(encoding))
    return path, Sensor.read


@pytest.mark.parametrize("text, field, message", [
    ("", "mounting", "missing table; expected [mounting]"),
    ("crs = 'EPSG:32611'\n", "mounting", "missing table"),
    ("[mounting]\nboresight_roll_deg = 0.0\n", "mounting.boresight_pitch_deg", "missing; expected a number in [-180, 180] deg"),
    (MOUNTING.replace("lever_arm_m = [0.5, -0.1, 0.2]\n", ""), "mounting.lever_arm_m", "missing; expected [x, y, z]"),
    (_roll("nan"), "mounting.boresight_roll_deg", "expected a finite number in [-180, 180] deg, got nan"),
    (_roll("inf"), "mounting.boresight_roll_deg", "got inf"),
    (_roll("1e6"), "mounting.boresight_roll_deg", "expected a finite number in [-180, 180] deg, got 1000000.0"),
    (_roll("true"), "mounting.boresight_roll_deg", "expected a number in [-180, 180] deg, got True"),
    (_roll('"0.1"'), "mounting.boresight_roll_deg", "got '0.1'"),
    (MOUNTING.replace("[0.5, -0.1, 0.2]", "[0.5, -0.1]"), "mounting.lever_arm_m", "expected 3 numbers [x, y, z]"),
    (MOUNTING.replace("[0.5, -0.1, 0.2]", "[0.5, -0.1, 1e9]"), "mounting.lever_arm_m.z", "in [-50, 50] m, got 1000000000.0"),
    (MOUNTING + "[range]\nscale_ppm = -2e6\n", "range.scale_ppm", "expected a finite number in [-100000, 100000] ppm, got -2000000.0"),
    (MOUNTING + "[range]\noffset_m = nan\n", "range.offset_m", "expected a finite number in [-100, 100] m, got nan"),
    (MOUNTING + "[range]\nscale = 2\n", "range.scale", "unknown key; expected one of ['offset_m', 'scale_ppm']"),
    (MOUNTING + "crs = 42\n", "mounting.crs", "unknown key"),
    ("crs = 'EPSG:99999'\n" + MOUNTING, "crs", "expected a CRS pyproj knows"),
    ("[mounting]\nboresight_roll_deg = \n", None, "not valid TOML"),
])
def test_bad_sensor_toml(tmp_path, text, field, message):
    path, read = _read(tmp_path, text)
    with pytest.raises(InputError) as e:
        read(path)
    assert str(e.value).startswith(f"{path}: {field + ': ' if field else ''}"), str(e.value)
    assert message in str(e.value)


def test_documented_defaults_and_round_trip(tmp_path):
    """[range] may be left out (offset 0 m, scale 0 ppm, docs/sensor.md); [scanner] defaults to linear."""
    path, read = _read(tmp_path, MOUNTING)
    s = read(path)
    assert np.degrees([s.boresight_roll, s.boresight_pitch, s.boresight_yaw]) == pytest.approx([0.1, -0.2, 0.3])
    assert s.lever_arm.tolist() == [0.5, -0.1, 0.2] and s.range_offset == 0 and s.range_scale == 0
    assert Sensor.read(s.write(tmp_path / "again.toml")) == s


def test_not_utf8_and_missing(tmp_path):
    path, read = _read(tmp_path, "# capteur étalonné\n" + MOUNTING, encoding="latin-1")
    with pytest.raises(InputError, match=r"sensor.toml: encoding: expected UTF-8 text, got byte 0xe9 at offset 10"):
        read(path)
    with pytest.raises(InputError, match="missing.toml: sensor.toml not found"):
        Sensor.read(tmp_path / "missing.toml")


def test_calibration_record_round_trip_and_checks(tmp_path):
    """A calibrated sensor.toml carries [calibration]: date, version, solution, σ per value; it
    still loads everywhere, georeferences exactly as without it, and its fields are checked."""
    from dataclasses import replace

    from calidar.sensor import CalibrationRecord

    record = CalibrationRecord("2026-11-26T21:00:00+00:00", "0.1.0", "solution_planes.json", "planes",
                               {"boresight_roll_deg": 0.0004, "lever_arm_z_m": 0.012})
    sensor = Sensor(boresight_roll=np.radians(0.05), lever_arm_z=0.12)
    path = replace(sensor, calibration=record).write(tmp_path / "sensor.toml")
    back = Sensor.read(path)
    assert back.calibration == record
    assert back == sensor  # the record is information, never part of the model
    assert "[calibration.sigma]" in path.read_text()
    bad = path.read_text().replace("lever_arm_z_m = 0.012", "lever_arm_z_m = -0.012")
    path.write_text(bad)
    with pytest.raises(InputError, match="calibration.sigma.lever_arm_z_m"):
        Sensor.read(path)
    path.write_text(MOUNTING + "[calibration]\ndate = 2026\n")
    with pytest.raises(InputError, match="calibration.date: expected a string"):
        Sensor.read(path)
    path.write_text(MOUNTING + "[calibration]\nwho = 'me'\n")
    with pytest.raises(InputError, match="calibration.who: unknown key"):
        Sensor.read(path)
