"""Applanix SBET ("smoothed best estimate of trajectory") binary files.

Each record is 17 little-endian float64 (136 bytes): time (GPS week seconds), latitude,
longitude (rad), ellipsoidal height (m), x/y/z velocity (m/s, wander frame), roll, pitch,
platform heading, wander angle (rad), x/y/z acceleration (m/s², body), x/y/z angular rate
(rad/s, body).

Wander frame (checked on the real ``leeward_sierra`` SBET, whose positions differentiate to
these velocities within 1 m/s): x points north and y west when the wander angle α is zero,
z is up; the frame is turned counter-clockwise (seen from above) by α. Hence

    true heading = platform heading − α
    v_north = vx·cos α − vy·sin α,   v_east = −vx·sin α − vy·cos α,   v_down = −vz.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from calidar.errors import InputError
from calidar.outputs import atomic_path
from calidar.trajectory import HEIGHT_RANGE_M, SECONDS_PER_WEEK, Trajectory
from calidar.validate import values

FIELDS = (
    "time", "lat", "lon", "height", "x_vel", "y_vel", "z_vel", "roll", "pitch", "platform_heading",
    "wander_angle", "x_acc", "y_acc", "z_acc", "x_ang_rate", "y_ang_rate", "z_ang_rate",
)
RECORD_BYTES = 8 * len(FIELDS)
_EXTRA = ("wander_angle", "x_acc", "y_acc", "z_acc", "x_ang_rate", "y_ang_rate", "z_ang_rate")
_ANGLE = (-2 * np.pi, 2 * np.pi, "rad")
#: what every record must hold (a file of another kind, or damaged, fails here with the field's
#: name)
RAW_LIMITS = {
    "time": (0.0, 2 * SECONDS_PER_WEEK, "s of week"),
    "lat": (-np.pi / 2, np.pi / 2, "rad"),
    "lon": _ANGLE,
    "height": (*HEIGHT_RANGE_M, "m"),
    **{k: (-1000.0, 1000.0, "m/s") for k in ("x_vel", "y_vel", "z_vel")},
    "roll": (-np.pi, np.pi, "rad"),
    "pitch": (-np.pi / 2, np.pi / 2, "rad"),
    "platform_heading": _ANGLE,
    "wander_angle": _ANGLE,
    **{k: (-1000.0, 1000.0, "m/s²") for k in ("x_acc", "y_acc", "z_acc")},
    **{k: (-100.0, 100.0, "rad/s") for k in ("x_ang_rate", "y_ang_rate", "z_ang_rate")},
}


def _wander_to_ned(vx, vy, vz, wander_rad) -> np.ndarray:
    """Wander-frame velocities (m/s) → NED (N, 3). The map is its own inverse (NED → wander)."""
    c, s = np.cos(wander_rad), np.sin(wander_rad)
    return np.stack([c * vx - s * vy, -s * vx - c * vy, -vz], axis=-1)


def _wrap(a_rad) -> np.ndarray:
    """Angles wrapped to (−π, π], rad."""
    return np.angle(np.exp(1j * np.asarray(a_rad, float)))


def read_sbet(path: str | Path) -> Trajectory:
    """Read an SBET file into a :class:`Trajectory` (true heading, NED velocities, week seconds).

    The wander angle, accelerations and angular rates are kept in ``traj.extra``.

    >>> import tempfile, numpy as np, calidar
    >>> t = np.arange(0.0, 1.0, 0.01)  # 100 Hz, one second
    >>> n = t.size
    >>> traj = calidar.Trajectory(time=t, lat=np.radians(47.0 + 1e-5 * t),
    ...                           lon=np.full(n, np.radians(8.0)), height=np.full(n, 500.0),
    ...                           roll=np.zeros(n), pitch=np.zeros(n), heading=np.full(n, 0.1))
    >>> path = calidar.write_sbet(Path(tempfile.mkdtemp()) / "sbet.out", traj)
    >>> back = calidar.read_sbet(path)
    >>> len(back), path.stat().st_size, bool(np.allclose(back.heading, 0.1))
    (100, 13600, True)
    """
    path = Path(path)
    size = path.stat().st_size
    if size == 0:
        raise InputError(path, "size", "expected SBET records (136 bytes each), the file is empty")
    if size % RECORD_BYTES:
        raise InputError(
            path, "size",
            f"expected a multiple of {RECORD_BYTES} bytes (17 float64 per record), got {size} "
            f"bytes ({size // RECORD_BYTES} records + {size % RECORD_BYTES} bytes): not an SBET, "
            "or truncated",
        )
    a = np.fromfile(path, dtype="<f8").reshape(-1, len(FIELDS))
    col = {name: a[:, i] for i, name in enumerate(FIELDS)}
    for name, (lo, hi, unit) in RAW_LIMITS.items():
        values(col[name], path, name, lo, hi, unit)
    wander = col["wander_angle"]
    return Trajectory(
        time=col["time"], lat=col["lat"], lon=col["lon"], height=col["height"],
        roll=col["roll"], pitch=col["pitch"],
        heading=_wrap(col["platform_heading"] - wander),
        velocity_ned=_wander_to_ned(col["x_vel"], col["y_vel"], col["z_vel"], wander),
        time_system="gps_week_seconds", source=str(path),
        extra={k: col[k].copy() for k in _EXTRA},
    )


def write_sbet(path: str | Path, traj: Trajectory, force: bool = False) -> Path:
    """Write ``traj`` as an SBET (atomically; refuses to overwrite unless ``force``).

    Uses ``traj.extra`` for the wander angle, accelerations and angular rates when present (zero
    otherwise) and zero velocities when the trajectory has none. Reading back: :func:`read_sbet`.

    >>> import tempfile, numpy as np, calidar
    >>> t = np.arange(3.0)
    >>> traj = calidar.Trajectory(time=t, lat=np.radians(47.0 + 1e-5 * t),
    ...                           lon=np.full(3, np.radians(8.0)), height=np.full(3, 500.0),
    ...                           roll=np.zeros(3), pitch=np.zeros(3), heading=np.zeros(3))
    >>> path = calidar.write_sbet(Path(tempfile.mkdtemp()) / "sbet.out", traj)
    >>> path.stat().st_size  # 3 records of 17 float64
    408
    >>> calidar.write_sbet(path, traj)
    Traceback (most recent call last):
    calidar.errors.OutputExistsError: ...sbet.out: exists; pass --force to overwrite it
    """
    if traj.time_system != "gps_week_seconds":
        raise InputError(traj.source, "time_system",
                         f"SBET holds GPS week seconds, got {traj.time_system}")
    n = len(traj)
    extra = {k: np.asarray(traj.extra.get(k, np.zeros(n)), float) for k in _EXTRA}
    wander = extra["wander_angle"]
    v = np.zeros((n, 3)) if traj.velocity_ned is None else np.asarray(traj.velocity_ned, float)
    v_w = _wander_to_ned(v[:, 0], v[:, 1], v[:, 2], wander)
    cols = {
        "time": traj.time, "lat": traj.lat, "lon": traj.lon, "height": traj.height,
        "x_vel": v_w[:, 0], "y_vel": v_w[:, 1], "z_vel": v_w[:, 2],
        "roll": traj.roll, "pitch": traj.pitch, "platform_heading": _wrap(traj.heading + wander),
        **extra,
    }
    a = np.stack([np.asarray(cols[k], float) for k in FIELDS], axis=1).astype("<f8")
    with atomic_path(path, force) as tmp:
        a.tofile(tmp)
    return Path(path)
