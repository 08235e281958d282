"""Optech CSD reading: the real 1 000-pulse sample, returns, and damaged files."""

from __future__ import annotations

import numpy as np
import pytest

from calidar.errors import InputError
from calidar.io.optech_csd import HEADER, RECORD, csd_trajectory, is_csd, read_csd, read_csd_header, returns
from calidar.io.trajectory import read_trajectory

SAMPLE = "optech_csd/sample.csd"


def write_csd(path, n=5, **fields):
    """A small CSD file: n pulses 1 ms apart, one return each at 800 m, header as the real sample's."""
    h = np.zeros((), HEADER)
    h["signature"], h["vendor"], h["software"] = b"CSD", b"Optech Incorporated", b"DASHMap"
    h["format_version"], h["header_size"], h["gps_week"], h["records"], h["strips"] = 5.201, 2048, 1660, n, 1
    h["misalignment"], h["imu_offsets"] = [0.028, 0.014, 0.002], [0.00225, -0.00211, 0.00549]
    r = np.zeros(n, RECORD)
    r["time"] = 575644.0 + 1e-3 * np.arange(n)
    r["returns"], r["range"][:, 0], r["intensity"][:, 0] = 1, 800.0, 100
    r["scan_angle"] = np.linspace(-0.2, 0.2, n)
    r["pitch"], r["heading"] = 0.016, -0.739
    r["lat"], r["lon"], r["elevation"] = 0.6376703, -7.7239894, 1140.6
    for k, v in fields.items():
        r[k] = v
    path.write_bytes(h.tobytes() + r.tobytes())
    return path


def test_real_sample(real_data):
    """The numbers of the real-data README: 1 000 pulses over 14 ms, one return each, ranges
    794.6–829.3 m, scan angles ±15.28°, latitude 36.536°, longitude −442.55° stored (−82.55°)."""
    p = read_csd(real_data / SAMPLE)
    h = p.header
    assert (h.vendor, h.software, h.format_version, h.gps_week, h.records, h.strips) == (
        "Optech Incorporated", "DASHMap", 5.201, 1660, 1000, 1)
    assert h.misalignment_rad == pytest.approx((0.028, 0.014, 0.002))
    assert h.time_range == pytest.approx((575644.744846, 575644.758832), abs=1e-6)
    assert len(p) == 1000 and np.all(p.returns == 1) and np.all(np.diff(p.time) > 0)
    assert p.time[[0, -1]] == pytest.approx(h.time_range, abs=1e-9)
    assert p.range_m[:, 0].min() == pytest.approx(794.6, abs=0.05) and p.range_m[:, 0].max() == pytest.approx(829.3, abs=0.05)
    assert np.degrees(np.abs(p.scan_angle)).max() == pytest.approx(15.28, abs=0.01)
    assert np.degrees(p.lat).mean() == pytest.approx(36.536, abs=1e-3)
    assert np.degrees(p.lon).mean() == pytest.approx(-442.55 + 360.0, abs=0.01)
    assert p.height.mean() == pytest.approx(1140.6, abs=0.1)
    assert is_csd(real_data / SAMPLE) and not is_csd(real_data / "leeward_sierra" / "sbet.out")


def test_the_pulses_are_a_trajectory(real_data):
    """read_trajectory recognises a CSD by its signature; one record per pulse, exactly its values."""
    p = read_csd(real_data / SAMPLE)
    tr = read_trajectory(real_data / SAMPLE)
    assert len(tr) == 1000 and tr.time_system == "gps_week_seconds"
    assert np.array_equal(tr.time, p.time) and np.array_equal(tr.roll, p.roll) and np.array_equal(tr.lon, p.lon)
    assert np.allclose(np.exp(1j * tr.heading), np.exp(1j * p.heading), atol=1e-12)
    with pytest.raises(InputError, match="is an option of text trajectories; this file is an Optech CSD"):
        read_trajectory(real_data / SAMPLE, crs="EPSG:32617")
    assert csd_trajectory(p).source == str(real_data / SAMPLE)


def test_returns_as_pdal_takes_them(tmp_path):
    """Slots 0…min(n, 4) − 1 of a pulse with n returns; slot 3 is the last return, numbered n; none
    for n = 0."""
    p = read_csd(write_csd(tmp_path / "r.csd", n=4, returns=[0, 1, 2, 6]))
    pulse, slot, number, count = returns(p)
    assert pulse.tolist() == [1, 2, 2, 3, 3, 3, 3]
    assert slot.tolist() == [0, 0, 1, 0, 1, 2, 3]
    assert number.tolist() == [1, 1, 2, 1, 2, 3, 6]
    assert count.tolist() == [1, 2, 2, 6, 6, 6, 6]


@pytest.mark.parametrize("damage, message", [
    (lambda b: b[:-10], "records: header says 5 records of 69 bytes (345 bytes), the file holds 335 bytes"),
    (lambda b: b[:1000], "header: expected a 2048-byte header, the file has 1000 bytes"),
    (lambda b: b"LASF" + b[4:], "signature: expected an Optech CSD file"),
])
def test_damaged_files(tmp_path, damage, message):
    path = tmp_path / "bad.csd"
    path.write_bytes(damage(write_csd(tmp_path / "good.csd").read_bytes()))
    with pytest.raises(InputError) as e:
        read_csd(path)
    assert str(e.value).startswith(f"{path}: {message}")


@pytest.mark.parametrize("field, value, message", [
    ("range", np.nan, "range: expected finite values in [0, 10000] m, got nan"),
    ("roll", 50.0, "roll: expected finite values in [-3.14159, 3.14159] rad, got 50"),
    ("lat", 2.0, "latitude: expected finite values in [-1.5708, 1.5708] rad, got 2"),
    ("elevation", 1e9, "elevation: expected finite values in [-1000, 100000] m, got 1e+09"),
    ("time", np.inf, "gps_time: expected finite values"),
])
def test_bad_values_name_the_field(tmp_path, field, value, message):
    path = write_csd(tmp_path / "bad.csd", **{field: value})
    with pytest.raises(InputError) as e:
        read_csd(path)
    assert str(e.value).startswith(f"{path}: {message}")


def test_bad_header_angles(tmp_path):
    path = write_csd(tmp_path / "h.csd")
    b = bytearray(path.read_bytes())
    off = HEADER.fields["misalignment"][1]
    b[off:off + 8] = np.float64(np.nan).tobytes()
    path.write_bytes(bytes(b))
    with pytest.raises(InputError, match="misalignment: expected finite values in"):
        read_csd_header(path)
