"""LAS/LAZ points streamed into the trajectory's frame and time: their coordinates in ECEF (with
clear errors for no CRS or a failed transform) and their GPS times brought chunk by chunk into the
trajectory's time system, counting the points it does not cover (:class:`FileTimes`)."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from calidar import georef
from calidar.crs import TileLinear, tile_linear
from calidar.errors import InputError
from calidar.io.las import LasPoints, adjusted_standard_in_week, single_gps_week
from calidar.trajectory import Trajectory

NO_CRS = "the file has no CRS (no WKT or GeoTIFF VLR); pass --crs (e.g. --crs EPSG:32611)"


def points_ecef(points: LasPoints) -> np.ndarray:
    """Points (N, 3) in ECEF from their CRS (and geoid undulation); clear errors for no CRS, a geoid
    without its grid, or an impossible transform."""
    if points.crs is None:
        raise InputError(points.path, "crs", NO_CRS)
    ecef = georef.from_crs(points.xyz, points.crs, points.geoid_undulation_m, source=points.path)
    return _finite(points, ecef)


def point_times(points: LasPoints, traj: Trajectory, gps_week: int | None = None) -> np.ndarray:
    """The points' GPS times in the trajectory's time system: adjusted standard → week seconds of
    ``gps_week`` (the whole file's, from :func:`calidar.pipelines.inputs.check_coverage`; None:
    the week of these points)."""
    if points.time_system == traj.time_system:
        return points.gps_time
    if gps_week is None:
        return points.gps_week_seconds()
    return adjusted_standard_in_week(points.gps_time, gps_week)


def points_tile_linear(points: LasPoints) -> TileLinear:
    """The points' transform to ECEF linearized per tile (:func:`calidar.crs.tile_linear`: moved
    points to 0.1 mm, ECEF to ~1 mm); the errors of :func:`points_ecef`."""
    if points.crs is None:
        raise InputError(points.path, "crs", NO_CRS)
    lin = tile_linear(points.xyz, points.crs, points.geoid_undulation_m, source=points.path)
    _finite(points, lin.jac)
    return lin


def _finite(points: LasPoints, values: np.ndarray) -> np.ndarray:
    """``values`` transformed from the points' CRS, or an error naming the CRS when PROJ failed."""
    if not np.all(np.isfinite(values)):
        raise InputError(points.path, "crs", f"cannot transform from {points.crs.name} to ECEF (a "
                         "PROJ grid may be missing); give an ellipsoidal CRS with --crs")
    return values


class Coverage:
    """Counts points outside the trajectory's time span over many chunks (count and time range
    before and after it, in its gaps, and NaN/inf times), to report them all at once."""

    def __init__(self, traj: Trajectory):
        self.traj, self.total, self.not_finite, self.in_gaps = traj, 0, 0, 0
        self.outside = {"before": [0, np.inf, -np.inf], "after": [0, np.inf, -np.inf]}

    def inside(self, t: np.ndarray) -> np.ndarray:
        """Mask of the times (GPS s) within the trajectory; counts the others."""
        self.total += t.size
        finite = np.isfinite(t)
        self.not_finite += int(t.size - np.count_nonzero(finite))
        lo, hi = t < self.traj.time[0], t > self.traj.time[-1]
        for side, mask in (("before", lo), ("after", hi)):
            if mask.any():
                o = self.outside[side]  # [count, first time, last time]
                o[:] = [o[0] + int(mask.sum()), min(o[1], float(t[mask].min())),
                        max(o[2], float(t[mask].max()))]
        covered = self.traj.covers(t)
        self.in_gaps += int(np.count_nonzero(finite & ~(lo | hi) & ~covered))
        return covered

    def check(self, source) -> None:
        """Raise a clear error naming how many points fell outside and their time ranges."""
        n = sum(o[0] for o in self.outside.values()) + self.not_finite + self.in_gaps
        if n == 0:
            return
        parts = [f"{o[0]} {side} it ({o[1]:.3f}–{o[2]:.3f} s)"
                 for side, o in self.outside.items() if o[0]]
        parts += [f"{self.not_finite} NaN/inf"] if self.not_finite else []
        parts += [f"{self.in_gaps} in its {self.traj.gap_text()}"] if self.in_gaps else []
        span = f"{self.traj.time[0]:.3f}–{self.traj.time[-1]:.3f} s"
        raise InputError(source, "gps_time", f"{n} of {self.total} points have GPS times outside "
                         f"the trajectory {self.traj.source} ({span}): " + ", ".join(parts))


class FileTimes:
    """A LAS/LAZ file's GPS times brought chunk by chunk into the trajectory's time system
    (adjusted standard → week seconds of the file's one GPS week, taken from its first finite
    time), counting the points outside the trajectory (:class:`Coverage`)."""

    def __init__(self, path: Path, traj: Trajectory, system: str):
        self.path, self.cover, self.week = path, Coverage(traj), None
        self.t_range = [np.inf, -np.inf]
        self.convert = system == "gps_adjusted_standard" and traj.time_system == "gps_week_seconds"

    def feed(self, t: np.ndarray) -> np.ndarray:
        """The chunk's times (s, as stored) in the trajectory's system; counts those outside it."""
        if self.convert:
            finite = t[np.isfinite(t)]
            if finite.size:
                self.t_range = [min(self.t_range[0], float(finite.min())),
                                max(self.t_range[1], float(finite.max()))]
                if self.week is None:
                    self.week = single_gps_week(self.t_range[0], self.t_range[0], self.path)
            t = adjusted_standard_in_week(t, 0 if self.week is None else self.week)
        self.cover.inside(t)
        return t

    def finish(self, name_trajectory: bool = False) -> int | None:
        """Raise the file's errors (several GPS weeks, points outside the trajectory: named as an
        error of the trajectory's time field when ``name_trajectory``); the GPS week of the
        conversion (None: none)."""
        if self.week is not None:
            # the whole file, before its counts (which assume one week)
            single_gps_week(*self.t_range, self.path)
        try:
            self.cover.check(self.path)
        except InputError as e:
            # NaN/inf times are the file's own fault
            if not name_trajectory or self.cover.not_finite:
                raise
            message = f"the points of {self.path.name}: {e.problem}"
            raise InputError(self.cover.traj.source, "time", message) from None
        return self.week
