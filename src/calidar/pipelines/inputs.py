"""Inputs every georeferencing pipeline shares: a trajectory and LAS/LAZ points read with the same
overrides (``--crs``, ``--trajectory-crs`` and the text-trajectory columns, ``--time-system``,
``--geoid-undulation``), their times brought into one system, and whole-file checks before any
output is written.

    traj = load_trajectory(path, TrajectoryOptions(crs="EPSG:32615", heading="grid"))
    points = read_las(las_path, options=PointOptions(crs="EPSG:2154", time_system="adjusted"))
    ecef = points_ecef(points)
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from calidar import georef
from calidar.crs import TileLinear, tile_linear
from calidar.errors import InputError
from calidar.io.las import (
    LasPoints, PointOptions, adjusted_standard_in_week, adjusted_standard_to_week_seconds, iter_las_times,
    las_file_crs, las_time_system, single_gps_week,
)
from calidar.io.trajectory import read_trajectory
from calidar.trajectory import Trajectory

__all__ = ["PointOptions", "TrajectoryOptions", "load_trajectory", "option_args", "points_ecef", "check_crs", "check_coverage",
           "matching_trajectory", "point_times"]

CHUNK_POINTS = 2_000_000
NO_CRS = "the file has no CRS (no WKT or GeoTIFF VLR); pass --crs (e.g. --crs EPSG:32611)"


@dataclass(frozen=True)
class TrajectoryOptions:
    """How to read a text trajectory (ignored for SBET and CSD files; giving one for them is an error):
    ``crs`` of its x/y or lat/lon columns, ``angles`` "deg" | "rad", ``heading`` "true" | "grid"
    (grid: corrected by the meridian convergence of ``crs``), ``columns`` (one name per column,
    "-" to skip; default from the header line), ``time_system`` of its times. None: the reader's
    default (WGS 84 lat/lon, degrees, true heading, GPS week seconds)."""

    crs: str | None = None
    angles: str | None = None
    heading: str | None = None
    columns: tuple[str, ...] | None = None
    time_system: str | None = None


def option_args(points: PointOptions = PointOptions(), trajectory: TrajectoryOptions | None = None) -> str:
    """The command-line options that give ``points`` (and ``trajectory``) options, " --crs …" or ""."""
    import shlex

    from calidar.io.las import TIME_SYSTEM_NAMES

    short = {v: k for k, v in TIME_SYSTEM_NAMES.items()}
    crs = points.crs if points.crs is None or isinstance(points.crs, str) else points.crs.to_string()
    pairs = [("--crs", crs), ("--time-system", short.get(points.time_system, points.time_system)),
             ("--geoid-undulation", points.geoid_undulation_m)]
    if trajectory is not None:
        pairs += [("--trajectory-crs", trajectory.crs), ("--trajectory-angles", trajectory.angles),
                  ("--trajectory-heading", trajectory.heading),
                  ("--trajectory-columns", None if trajectory.columns is None else ",".join(trajectory.columns))]
    return "".join(f" {k} {shlex.quote(str(v))}" for k, v in pairs if v is not None)


def load_trajectory(path: str | Path, options: TrajectoryOptions = TrajectoryOptions()) -> Trajectory:
    """A trajectory (SBET, Optech CSD or text) read with ``options``."""
    o = options
    return read_trajectory(Path(path), crs=o.crs, angles=o.angles, heading_reference=o.heading,
                           columns=None if o.columns is None else list(o.columns), time_system=o.time_system)


def points_ecef(points: LasPoints) -> np.ndarray:
    """Points (N, 3) in ECEF from their CRS (and geoid undulation); clear errors for no CRS, a geoid
    without its grid, or an impossible transform."""
    if points.crs is None:
        raise InputError(points.path, "crs", NO_CRS)
    return _finite(points, georef.from_crs(points.xyz, points.crs, points.geoid_undulation_m, source=points.path))


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
        raise InputError(points.path, "crs", f"cannot transform from {points.crs.name} to ECEF (a PROJ grid may be "
                         "missing); give an ellipsoidal CRS with --crs")
    return values


def check_crs(path: Path, options: PointOptions = PointOptions()) -> None:
    """Error now (before any output) when the CRS is unknown, or a LAS/LAZ file has none and none is given."""
    if las_file_crs(path, options.crs) is None:
        raise InputError(path, "crs", NO_CRS)


def matching_trajectory(traj: Trajectory, system: str) -> Trajectory:
    """The trajectory with times in GPS week seconds when the points (``system``) have week seconds and it has not."""
    if traj.time_system == system or system == "gps_adjusted_standard":
        return traj
    t, _ = adjusted_standard_to_week_seconds(traj.time, traj.source)
    return dataclasses.replace(traj, time=t, time_system="gps_week_seconds")


def point_times(points: LasPoints, traj: Trajectory, gps_week: int | None = None) -> np.ndarray:
    """The points' GPS times in the trajectory's time system: adjusted standard → week seconds of
    ``gps_week`` (the whole file's, from :func:`check_coverage`; None: the week of these points)."""
    if points.time_system == traj.time_system:
        return points.gps_time
    if gps_week is None:
        return points.gps_week_seconds()
    return adjusted_standard_in_week(points.gps_time, gps_week)


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
                o = self.outside[side]
                o[:] = [o[0] + int(mask.sum()), min(o[1], float(t[mask].min())), max(o[2], float(t[mask].max()))]
        covered = self.traj.covers(t)
        self.in_gaps += int(np.count_nonzero(finite & ~(lo | hi) & ~covered))
        return covered

    def check(self, source) -> None:
        """Raise a clear error naming how many points fell outside and their time ranges."""
        n = sum(o[0] for o in self.outside.values()) + self.not_finite + self.in_gaps
        if n == 0:
            return
        parts = [f"{o[0]} {side} it ({o[1]:.3f}–{o[2]:.3f} s)" for side, o in self.outside.items() if o[0]]
        parts += [f"{self.not_finite} NaN/inf"] if self.not_finite else []
        parts += [f"{self.in_gaps} in its {self.traj.gap_text()}"] if self.in_gaps else []
        raise InputError(
            source, "gps_time",
            f"{n} of {self.total} points have GPS times outside the trajectory "
            f"{self.traj.source} ({self.traj.time[0]:.3f}–{self.traj.time[-1]:.3f} s): " + ", ".join(parts),
        )


class FileTimes:
    """A LAS/LAZ file's GPS times brought chunk by chunk into the trajectory's time system
    (adjusted standard → week seconds of the file's one GPS week, taken from its first finite
    time), counting the points outside the trajectory (:class:`Coverage`)."""

    def __init__(self, path: Path, traj: Trajectory, system: str):
        self.path, self.cover, self.week, self.t_range = path, Coverage(traj), None, [np.inf, -np.inf]
        self.convert = system == "gps_adjusted_standard" and traj.time_system == "gps_week_seconds"

    def feed(self, t: np.ndarray) -> np.ndarray:
        """The chunk's times (s, as stored) in the trajectory's system; counts those outside it."""
        if self.convert:
            finite = t[np.isfinite(t)]
            if finite.size:
                self.t_range = [min(self.t_range[0], float(finite.min())), max(self.t_range[1], float(finite.max()))]
                self.week = single_gps_week(self.t_range[0], self.t_range[0], self.path) if self.week is None else self.week
            t = adjusted_standard_in_week(t, 0 if self.week is None else self.week)
        self.cover.inside(t)
        return t

    def finish(self, name_trajectory: bool = False) -> int | None:
        """Raise the file's errors (several GPS weeks, points outside the trajectory: named as an
        error of the trajectory's time field when ``name_trajectory``); the GPS week of the
        conversion (None: none)."""
        if self.week is not None:
            single_gps_week(*self.t_range, self.path)  # the whole file, before its counts (which assume one week)
        try:
            self.cover.check(self.path)
        except InputError as e:
            if not name_trajectory or self.cover.not_finite:  # NaN/inf times are the file's own fault
                raise
            raise InputError(self.cover.traj.source, "time", f"the points of {self.path.name}: {e.problem}") from None
        return self.week


def check_coverage(path: Path, traj: Trajectory, options: PointOptions = PointOptions(),
                   chunk_points: int = CHUNK_POINTS) -> int | None:
    """First streamed pass over a LAS/LAZ file, reading only GPS times, before any output is written.

    Raises one error for the whole file when points fall outside ``traj`` (how many, before/after
    it, their time ranges; NaN times) or, when adjusted standard times must become the
    trajectory's week seconds, when the file spans GPS weeks. Returns the GPS week of that
    conversion (for :func:`point_times`), else None.
    """
    times = FileTimes(path, traj, las_time_system(path, options.time_system))
    for t in iter_las_times(path, chunk_points):
        times.feed(t)
    return times.finish()


def trajectory_for(path: Path, traj: Trajectory, options: PointOptions = PointOptions(),
                   chunk_points: int = CHUNK_POINTS) -> tuple[Trajectory, int | None]:
    """The trajectory in the time system of a LAS/LAZ file's points and the GPS week of their times
    (:func:`check_coverage`), after checking the file's CRS and coverage: every check a streamed
    georeferencing command makes before writing anything."""
    traj = matching_trajectory(traj, las_time_system(path, options.time_system))
    check_crs(path, options)
    return traj, check_coverage(path, traj, options, chunk_points)
