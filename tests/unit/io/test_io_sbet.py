import numpy as np
import pytest

from calidar import frames
from calidar.errors import InputError, OutputExistsError
from calidar.io import read_sbet, read_trajectory, write_sbet
from calidar.io.sbet import FIELDS
from calidar.trajectory import Trajectory


def _traj(n=50, wander=0.3):
    t = 400000.0 + np.arange(n) * 0.005
    rng = np.random.default_rng(1)
    return Trajectory(
        t, np.full(n, 0.6) + 1e-7 * np.arange(n), np.full(n, -2.0), np.full(n, 1500.0),
        rng.normal(0, 0.01, n), rng.normal(0, 0.01, n), np.linspace(-3.1, 3.1, n),
        velocity_ned=rng.normal(0, 50, (n, 3)), extra={"wander_angle": np.full(n, wander)},
    )


def test_real_sbet_reads_200_records_at_200_hz(real_data):
    tr = read_sbet(real_data / "leeward_sierra" / "sbet.out")
    assert len(tr) == 200
    assert tr.rate_hz == pytest.approx(200.0, rel=1e-4)
    assert tr.time_system == "gps_week_seconds"
    assert np.degrees(tr.lat.mean()) == pytest.approx(37.764, abs=1e-3)
    # true heading = platform heading (165.01°) − wander angle (1.02°)
    assert np.degrees(tr.heading[0]) == pytest.approx(165.0089 - 1.0217, abs=1e-3)
    assert "wander_angle" in tr.extra


def test_real_sbet_velocities_match_differentiated_positions(real_data):
    """Checks the wander-frame → NED rotation (x north, y west, z up, turned by α)."""
    tr = read_sbet(real_data / "leeward_sierra" / "sbet.out")
    v_e = np.gradient(tr.ecef, tr.time, axis=0)
    v_ned = np.einsum("nji,nj->ni", frames.r_en(tr.lat, tr.lon), v_e)
    err = np.abs(v_ned - tr.velocity_ned)[5:-5]
    assert np.max(err[:, :2]) < 0.15  # m/s (speed ≈ 110 m/s; a wrong wander sign gives ≈ 3.9 m/s)
    assert np.max(err[:, 2]) < 0.02


def test_write_read_round_trip(tmp_path):
    tr = _traj()
    p = write_sbet(tmp_path / "a.out", tr)
    assert p.stat().st_size == 136 * len(tr)
    back = read_sbet(p)
    for name in ("time", "lat", "lon", "height", "roll", "pitch"):
        assert np.allclose(getattr(back, name), getattr(tr, name), atol=1e-12, rtol=0)
    assert np.allclose(np.exp(1j * back.heading), np.exp(1j * tr.heading), atol=1e-12)
    assert np.allclose(back.velocity_ned, tr.velocity_ned, atol=1e-9)
    raw = np.fromfile(p, "<f8").reshape(-1, 17)
    ph = raw[:, FIELDS.index("platform_heading")]
    assert np.allclose(np.exp(1j * (ph - 0.3)), np.exp(1j * tr.heading), atol=1e-12)
    with pytest.raises(OutputExistsError):
        write_sbet(p, tr)
    write_sbet(p, tr, force=True)


def test_wander_absent_is_zero(tmp_path):
    tr = _traj()
    plain = Trajectory(tr.time, tr.lat, tr.lon, tr.height, tr.roll, tr.pitch, tr.heading)
    back = read_sbet(write_sbet(tmp_path / "b.out", plain))
    assert np.all(back.extra["wander_angle"] == 0)
    assert np.allclose(np.exp(1j * back.heading), np.exp(1j * tr.heading), atol=1e-12)
    assert np.all(back.velocity_ned == 0)


def _field(a, name, value):
    """The SBET records ``a`` with field ``name`` of record 2 set to ``value``, as bytes."""
    a = a.copy()
    a[2, FIELDS.index(name)] = value
    return a.tobytes()


@pytest.mark.parametrize(
    "make, message",
    [
        (lambda a: a.tobytes()[:-8], "multiple of 136 bytes"),
        (lambda a: b"", "empty"),
        (lambda a: np.where(np.arange(a.size).reshape(a.shape) == 17 * 3, np.nan, a).tobytes(),
         "time: expected finite values in [0, 1209600] s of week, got nan (1 of 4 values, first at record 3)"),
        (lambda a: a[[0, 2, 1, 3]].tobytes(), "strictly increasing"),
        (lambda a: _field(a, "height", 1e9), "height: expected finite values in [-1000, 100000] m, got 1e+09"),
        (lambda a: _field(a, "roll", 50.0), "roll: expected finite values in [-3.14159, 3.14159] rad, got 50"),
        (lambda a: _field(a, "lat", 2.0), "lat: expected finite values in [-1.5708, 1.5708] rad, got 2"),
        (lambda a: _field(a, "x_vel", np.inf), "x_vel: expected finite values in [-1000, 1000] m/s, got inf"),
    ],
)
def test_bad_sbet_is_a_clear_error(tmp_path, make, message):
    a = np.fromfile(write_sbet(tmp_path / "good.out", _traj(4)), "<f8").reshape(-1, 17)
    bad = tmp_path / "bad.out"
    bad.write_bytes(make(a))
    with pytest.raises(InputError) as e:
        read_trajectory(bad)
    assert str(bad) in str(e.value) and message in str(e.value)
