"""The GNSS/INS trajectory: time-sorted positions and attitude, with fast interpolation.

Times are GPS seconds (``time_system`` says which: ``"gps_week_seconds"`` as in SBET, or
``"gps_adjusted_standard"``, i.e. GPS time − 1e9 s as in LAS 1.2+ with the global-encoding
bit set). Positions are geodetic (rad, m ellipsoidal); attitude is roll/pitch and *true*
heading (rad) of the body frame (x forward, y right, z down) w.r.t. local NED.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from functools import cached_property

import numpy as np

from calidar import frames
from calidar.errors import InputError
from calidar.validate import values

TIME_SYSTEMS = ("gps_week_seconds", "gps_adjusted_standard")
SECONDS_PER_WEEK = 604800.0
HEIGHT_RANGE_M = (-1000.0, 100_000.0)  #: ellipsoidal heights a platform can have (m)
#: a pause between records longer than this many median intervals, and than GAP_MIN_S, is a gap: no
#: point is interpolated across it (a data outage, or two trajectories joined)
GAP_INTERVALS, GAP_MIN_S = 10.0, 1.0
#: physical range of every per-record field, SI (rad, m): checked on every trajectory
LIMITS = {"lat": (-np.pi / 2, np.pi / 2, "rad"), "lon": (-2 * np.pi, 2 * np.pi, "rad"),
          "height": (*HEIGHT_RANGE_M, "m"), "roll": (-np.pi, np.pi, "rad"),
          "pitch": (-np.pi / 2, np.pi / 2, "rad"), "heading": (-2 * np.pi, 2 * np.pi, "rad")}


def _check_times(t: np.ndarray, source: str) -> None:
    """A clear error unless the record times ``t`` (s) are finite and strictly increasing."""
    if not np.all(np.isfinite(t)):
        message = f"expected finite times, found {int(np.sum(~np.isfinite(t)))} NaN/inf"
        raise InputError(source, "time", message)
    bad = np.flatnonzero(np.diff(t) <= 0)
    if bad.size:
        i = bad[0]
        raise InputError(source, "time", f"expected strictly increasing times, record {i + 1} "
                         f"({t[i + 1]:.6f}) follows {t[i]:.6f} ({bad.size} such places)")


def _sign_continuous(q: np.ndarray) -> np.ndarray:
    """Flip quaternion signs so that consecutive ones lie in the same hemisphere."""
    flip = np.cumsum(np.r_[False, np.sum(q[1:] * q[:-1], axis=1) < 0]) % 2 == 1
    q[flip] *= -1
    return q


@dataclass(frozen=True, eq=False)
class Trajectory:
    """A trajectory; arrays of equal length N, times strictly increasing (SI: s, rad, m).

    >>> import numpy as np, calidar
    >>> t = np.array([0.0, 1.0, 2.0])
    >>> lat, lon = np.radians(47.0 + 1e-4 * t), np.full(3, np.radians(8.0))
    >>> level = np.zeros(3)
    >>> traj = calidar.Trajectory(time=t, lat=lat, lon=lon, height=np.full(3, 500.0),
    ...                           roll=level, pitch=level, heading=level)
    >>> len(traj), traj.time_system
    (3, 'gps_week_seconds')
    """

    time: np.ndarray  #: GPS seconds, (N,)
    lat: np.ndarray  #: geodetic latitude, rad
    lon: np.ndarray  #: longitude, rad
    height: np.ndarray  #: ellipsoidal height, m
    roll: np.ndarray  #: rad
    pitch: np.ndarray  #: rad
    heading: np.ndarray  #: true heading, rad
    velocity_ned: np.ndarray | None = None  #: (N, 3) m/s, optional (cubic interpolation)
    time_system: str = "gps_week_seconds"
    source: str = "<memory>"  #: file it came from, for error messages
    extra: dict = field(default_factory=dict)  #: other per-record columns (e.g. wander angle)

    def __post_init__(self):
        t = np.asarray(self.time, dtype=float)
        if t.ndim != 1 or t.size < 2:
            raise InputError(self.source, "time", f"expected at least 2 records, got {t.size}")
        for name in ("lat", "lon", "height", "roll", "pitch", "heading"):
            a = np.asarray(getattr(self, name), dtype=float)
            if a.shape != t.shape:
                raise InputError(self.source, name, f"expected {t.size} values, got {a.shape}")
            object.__setattr__(self, name, values(a, self.source, name, *LIMITS[name]))
        object.__setattr__(self, "time", t)
        _check_times(t, self.source)
        if self.time_system not in TIME_SYSTEMS:
            message = f"expected one of {TIME_SYSTEMS}, got {self.time_system!r}"
            raise InputError(self.source, "time_system", message)

    def __len__(self) -> int:
        return self.time.size

    @property
    def rate_hz(self) -> float:
        """Median record rate."""
        return float(1.0 / np.median(np.diff(self.time)))

    @cached_property
    def ecef(self) -> np.ndarray:
        """IMU positions in ECEF (N, 3), m."""
        return frames.geodetic_to_ecef(self.lat, self.lon, self.height)

    @cached_property
    def q_eb(self) -> np.ndarray:
        """Attitude body → ECEF as quaternions (N, 4), sign-continuous for SLERP."""
        r_eb = frames.r_en(self.lat, self.lon) @ self._r_nb()
        return _sign_continuous(frames.matrix_to_quat(r_eb))

    def _r_nb(self) -> np.ndarray:
        """Attitude body → NED as rotation matrices (N, 3, 3)."""
        return frames.rpy_to_matrix(self.roll, self.pitch, self.heading)

    @cached_property
    def velocity_ecef(self) -> np.ndarray | None:
        """Velocities in ECEF (N, 3), m/s, when the trajectory has them."""
        if self.velocity_ned is None:
            return None
        r_en = frames.r_en(self.lat, self.lon)
        return np.einsum("nij,nj->ni", r_en, np.asarray(self.velocity_ned, float))

    @cached_property
    def gaps(self) -> np.ndarray:
        """Indices i of the record intervals (time[i], time[i+1]) that are gaps (see
        GAP_INTERVALS)."""
        dt = np.diff(self.time)
        return np.flatnonzero(dt > max(GAP_MIN_S, GAP_INTERVALS * float(np.median(dt))))

    def covers(self, t) -> np.ndarray:
        """Boolean mask: which times lie within the trajectory's time span and outside its gaps."""
        t = np.asarray(t, float)
        inside = (t >= self.time[0]) & (t <= self.time[-1])
        if self.gaps.size:
            i = np.clip(np.searchsorted(self.time, t, side="right") - 1, 0, self.time.size - 2)
            inside &= ~np.isin(i, self.gaps) | (t == self.time[i])
        return inside

    def gap_text(self) -> str:
        """The gaps in words, for messages: "2 gap(s) without records (a–b s, c–d s)"."""
        g = self.gaps
        spans = ", ".join(f"{self.time[i]:.3f}–{self.time[i + 1]:.3f} s" for i in g[:3])
        more = " …" if g.size > 3 else ""
        return f"{g.size} gap(s) without records ({spans}{more})"

    def check_covers(self, t, what: str = "points") -> None:
        """Raise a clear error when times fall outside the trajectory or in its gaps (how many,
        which ranges)."""
        t = np.asarray(t, float)
        inside = self.covers(t)
        if not np.all(inside):
            out = t[~inside]
            gaps = " or in its " + self.gap_text() if self.gaps.size else ""
            raise InputError(
                self.source, "time",
                f"{out.size} of {t.size} {what} have GPS times outside the trajectory "
                f"({self.time[0]:.3f}–{self.time[-1]:.3f} s){gaps}: theirs span "
                f"{out.min():.3f}–{out.max():.3f} s",
            )

    def _locate(self, t: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        i = np.clip(np.searchsorted(self.time, t, side="right") - 1, 0, self.time.size - 2)
        dt = self.time[i + 1] - self.time[i]
        return i, (t - self.time[i]) / dt

    def interpolate(self, t, cubic: bool = False) -> tuple[np.ndarray, np.ndarray]:
        """Positions (M, 3) ECEF m and attitude quaternions q_eb (M, 4) at times t (GPS s).

        Positions: linear, or cubic Hermite using the velocities when ``cubic``.
        Attitude: quaternion SLERP between the bracketing records.
        """
        t = np.asarray(t, dtype=float)
        self.check_covers(t)
        i, f = self._locate(t)
        p0, p1 = self.ecef[i], self.ecef[i + 1]
        if cubic:
            v = self.velocity_ecef
            if v is None:
                raise InputError(self.source, "velocity",
                                 "cubic interpolation needs velocities; this trajectory has none")
            dt = (self.time[i + 1] - self.time[i])[:, None]
            ff = f[:, None]
            h00 = 2 * ff**3 - 3 * ff**2 + 1
            h10 = ff**3 - 2 * ff**2 + ff
            h01 = -2 * ff**3 + 3 * ff**2
            h11 = ff**3 - ff**2
            pos = h00 * p0 + h10 * dt * v[i] + h01 * p1 + h11 * dt * v[i + 1]
        else:
            pos = p0 + f[:, None] * (p1 - p0)
        return pos, frames.slerp(self.q_eb[i], self.q_eb[i + 1], f)

    def interpolate_rpy(self, t) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Roll, pitch, true heading (rad) at times t, through the same SLERP (for display)."""
        t = np.asarray(t, float)
        self.check_covers(t)
        i, f = self._locate(t)
        q_nb = frames.slerp(self._q_nb[i], self._q_nb[i + 1], f)
        return frames.matrix_to_rpy(frames.quat_to_matrix(q_nb))

    @cached_property
    def _q_nb(self) -> np.ndarray:
        return _sign_continuous(frames.matrix_to_quat(self._r_nb()))

    def subset(self, t0: float, t1: float, margin_s: float = 0.0) -> "Trajectory":
        """The records within [t0 − margin, t1 + margin] (at least the two bracketing ones)."""
        lo = max(int(np.searchsorted(self.time, t0 - margin_s, side="right")) - 1, 0)
        hi = min(int(np.searchsorted(self.time, t1 + margin_s, side="left")) + 1, self.time.size)
        hi = max(hi, lo + 2)
        sel = slice(lo, hi)
        vel = None if self.velocity_ned is None else np.asarray(self.velocity_ned)[sel]
        fields = (self.time, self.lat, self.lon, self.height, self.roll, self.pitch, self.heading)
        return Trajectory(*(a[sel] for a in fields), vel, self.time_system, self.source,
                          {k: np.asarray(v)[sel] for k, v in self.extra.items()})
