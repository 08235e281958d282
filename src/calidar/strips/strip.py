"""A flight strip: its points, GPS times and scanner observations, re-georeferenced on demand.

Delivered points are inverse-georeferenced ONCE with the nominal sensor
(:func:`calidar.georef.inverse`) into :class:`~calidar.georef.ScanObservations`; any
other sensor model then re-georeferences them with the lidar equation
(p = r(t) + R_eb(t) · (R_bs · ρ · u_s + a_b), as :func:`calidar.georef.forward`).
Everything a calibration looks at is expressed in a :class:`LocalFrame`: east-north-up
metres at the survey centre, so that heights are "up" and numbers stay small.
"""

from __future__ import annotations

from dataclasses import dataclass, field, replace
from functools import cached_property

import numpy as np
from numba import njit

from calidar import frames, georef
from calidar.errors import InputError
from calidar.georef import ScanObservations
from calidar.sensor import Sensor
from calidar.trajectory import Trajectory


@dataclass(frozen=True)
class LocalFrame:
    """East-north-up Cartesian frame (m) tangent to the ellipsoid at ``origin_ecef``."""

    origin_ecef: np.ndarray  #: (3,) m
    r_le: np.ndarray  #: (3, 3) rotation ECEF → local ENU

    @classmethod
    def at(cls, points_ecef: np.ndarray) -> "LocalFrame":
        """The frame at the centre of the bounding box of the points (ECEF m, (N, 3)), at their
        median height."""
        p = np.asarray(points_ecef, float)
        lat, lon, _ = frames.ecef_to_geodetic(0.5 * (p.min(axis=0) + p.max(axis=0)))
        height = float(np.median(frames.ecef_to_geodetic(p[:: max(1, len(p) // 10000)])[2]))
        origin = frames.geodetic_to_ecef(lat, lon, height)
        r_en = frames.r_en(lat, lon)  # NED → ECEF
        return cls(origin, frames.R_ENU_NED @ r_en.T)

    def to_local(self, points_ecef) -> np.ndarray:
        """ECEF (N, 3) m → local ENU (N, 3) m."""
        return (np.asarray(points_ecef, float) - self.origin_ecef) @ self.r_le.T

    def to_ecef(self, points_local) -> np.ndarray:
        """Local ENU (N, 3) m → ECEF (N, 3) m."""
        return np.asarray(points_local, float) @ self.r_le + self.origin_ecef


@dataclass(frozen=True)
class Pose:
    """IMU positions (local ENU m) and rotations body → local ENU at a set of points' times."""

    index: np.ndarray  #: (M,) indices of the points in their strip
    position: np.ndarray  #: (M, 3) m
    r_lb: np.ndarray  #: (M, 3, 3)
    range_m: np.ndarray  #: (M,) measured range, m
    angles: np.ndarray  #: (M, k) scanner observations, rad

    def take(self, rows: np.ndarray) -> "Pose":
        """The poses at positions ``rows`` of this one."""
        return Pose(self.index[rows], self.position[rows], self.r_lb[rows], self.range_m[rows],
                    self.angles[rows])

    def rows_of(self, index: np.ndarray) -> np.ndarray:
        """Positions in this pose of the strip's points ``index`` (all must be present)."""
        index = np.asarray(index, dtype=np.int64)
        table = self._row_table
        if index.size and (index.min() < 0 or index.max() >= table.size):
            raise KeyError("points not in this pose cache")
        rows = table[index]
        if np.any(rows < 0):
            raise KeyError("points not in this pose cache")
        return rows

    @cached_property
    def _row_table(self) -> np.ndarray:
        return position_table(self.index)


def position_table(index: np.ndarray) -> np.ndarray:
    """Lookup table of the distinct point indices ``index``: table[index[k]] = k, −1 elsewhere
    (O(n), where np.searchsorted costs a binary search per query)."""
    table = np.full(int(index.max()) + 1 if index.size else 0, -1, dtype=np.int64)
    table[index] = np.arange(index.size)
    return table


@dataclass(eq=False)
class Strip:
    """One flight line. ``points`` are the delivered coordinates in the local frame (m)."""

    id: int  #: flight-line id (LAS point_source_id)
    points: np.ndarray  #: (N, 3) local ENU m, as delivered (nominal sensor)
    obs: ScanObservations  #: from one inverse georeferencing with the nominal sensor
    trajectory: Trajectory
    frame: LocalFrame
    source: str = "<memory>"
    #: per-point attributes kept for output (classification, ...)
    extra: dict = field(default_factory=dict)
    #: GPS time span (s) of the whole line when ``points`` are a subset
    span: tuple[float, float] | None = None

    @property
    def time_span(self) -> tuple[float, float]:
        """First and last GPS time (s) of the flight line (of all its points, also when thinned)."""
        if self.span is not None:
            return self.span
        return float(self.obs.time.min()), float(self.obs.time.max())

    @classmethod
    def from_ecef(cls, strip_id: int, points_ecef, time, trajectory: Trajectory, nominal: Sensor,
                  frame: LocalFrame, source: str = "<memory>",
                  span: tuple[float, float] | None = None, **extra) -> "Strip":
        """Build a strip from delivered ECEF points (N, 3) m and GPS times (N,) s (``span``: the
        whole line's time span when these are some of its points).

        The trajectory must cover every time (a clear error names the strip otherwise).
        """
        time = np.asarray(time, float)
        points_ecef = np.asarray(points_ecef, float)
        if time.size == 0:
            raise InputError(source, "points", f"strip {strip_id} has no points")
        try:
            trajectory.check_covers(time, f"points of strip {strip_id} ({source})")
        except InputError as e:
            raise InputError(trajectory.source, "time", e.problem) from None
        # the scanner-frame vectors not kept: 24 B a point the strip never reads again
        obs = replace(georef.inverse(trajectory, nominal, time, points_ecef), vector_s=None)
        return cls(int(strip_id), frame.to_local(points_ecef), obs, trajectory, frame, source,
                   dict(extra), span)

    def __len__(self) -> int:
        return self.points.shape[0]

    @property
    def time(self) -> np.ndarray:
        return self.obs.time

    def pose(self, index: np.ndarray | None = None) -> Pose:
        """Trajectory poses at the times of the points ``index`` (all when None), cached by the
        caller."""
        idx = np.arange(len(self)) if index is None else np.asarray(index, dtype=np.int64)
        pos_e, r_eb = georef.poses(self.trajectory, self.obs.time[idx])
        r_lb = _rotated(self.frame.r_le, r_eb)
        if _every_point(idx, len(self)):  # the strip's own arrays, not copies of every row
            return Pose(idx, self.frame.to_local(pos_e), r_lb, self.obs.range_m, self.obs.angles)
        return Pose(idx, self.frame.to_local(pos_e), r_lb, self.obs.range_m[idx],
                    self.obs.angles[idx])

    def georeference(self, sensor: Sensor, index: np.ndarray | None = None,
                     pose: Pose | None = None) -> np.ndarray:
        """Points (M, 3) local ENU m re-georeferenced with ``sensor`` (the lidar equation).

        ``pose`` (from :meth:`pose`) avoids re-interpolating the trajectory when the same
        points are georeferenced many times (as inside a least-squares solve).
        """
        pose = self.pose(index) if pose is None else pose
        return georeference_pose(sensor, pose)

    def heading_enu(self) -> float:
        """Mean direction of travel over the strip, rad clockwise from local north."""
        t = np.linspace(*self.time_span, 16)
        pos = self.frame.to_local(self.trajectory.interpolate(t)[0])
        d = pos[-1] - pos[0]
        return float(np.arctan2(d[0], d[1]))


def _every_point(index: np.ndarray, n: int) -> bool:
    """Whether ``index`` is 0, 1, …, n − 1 (every point of a strip of ``n``, in order)."""
    return index.size == n and (n == 0 or bool(np.all(index == np.arange(n))))


def georeference_pose(sensor: Sensor, pose: Pose) -> np.ndarray:
    """The lidar equation (:func:`calidar.georef.lidar_points`) for cached poses, local m (M, 3)."""
    return georef.lidar_points(pose.position, pose.r_lb, sensor, pose.range_m, pose.angles)


@njit(cache=True, nogil=True)
def _rotated(r: np.ndarray, m: np.ndarray) -> np.ndarray:  # pragma: no cover - numba
    """r @ m[k] for every 3 × 3 matrix of m (N, 3, 3) (numpy's broadcast matmul costs 200 ns
    each)."""
    out = np.empty_like(m)
    for k in range(m.shape[0]):
        for a in range(3):
            for b in range(3):
                out[k, a, b] = r[a, 0] * m[k, 0, b] + r[a, 1] * m[k, 1, b] + r[a, 2] * m[k, 2, b]
    return out
