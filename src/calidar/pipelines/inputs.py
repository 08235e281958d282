"""Inputs every georeferencing pipeline shares: a trajectory and LAS/LAZ points read with the
same overrides (``--crs``, ``--trajectory-crs`` and the text-trajectory columns, ``--time-system``,
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

from calidar.errors import InputError
from calidar.ingest.times import NO_CRS, FileTimes, point_times, points_ecef
from calidar.io.las import (
    PointOptions, adjusted_standard_to_week_seconds, iter_las_times,
    las_file_crs, las_time_system,
)
from calidar.io.trajectory import read_trajectory
from calidar.trajectory import Trajectory

__all__ = ["PointOptions", "TrajectoryOptions", "load_trajectory", "option_args", "points_ecef",
           "check_crs", "check_coverage", "matching_trajectory", "point_times"]

CHUNK_POINTS = 2_000_000


@dataclass(frozen=True)
class TrajectoryOptions:
    """How to read a text trajectory (ignored for SBET and CSD files; giving one for them is an
    error): ``crs`` of its x/y or lat/lon columns, ``angles`` "deg" | "rad", ``heading`` "true" |
    "grid" (grid: corrected by the meridian convergence of ``crs``), ``columns`` (one name per
    column, "-" to skip; default from the header line), ``time_system`` of its times. None: the
    reader's default (WGS 84 lat/lon, degrees, true heading, GPS week seconds)."""

    crs: str | None = None
    angles: str | None = None
    heading: str | None = None
    columns: tuple[str, ...] | None = None
    time_system: str | None = None


def option_args(points: PointOptions = PointOptions(),
                trajectory: TrajectoryOptions | None = None) -> str:
    """The command-line options that give ``points`` (and ``trajectory``) options, " --crs …" or
    ""."""
    import shlex

    from calidar.io.las import TIME_SYSTEM_NAMES

    short = {v: k for k, v in TIME_SYSTEM_NAMES.items()}
    crs = points.crs
    if crs is not None and not isinstance(crs, str):
        crs = crs.to_string()
    pairs = [("--crs", crs), ("--time-system", short.get(points.time_system, points.time_system)),
             ("--geoid-undulation", points.geoid_undulation_m)]
    if trajectory is not None:
        columns = None if trajectory.columns is None else ",".join(trajectory.columns)
        pairs += [("--trajectory-crs", trajectory.crs), ("--trajectory-angles", trajectory.angles),
                  ("--trajectory-heading", trajectory.heading), ("--trajectory-columns", columns)]
    return "".join(f" {k} {shlex.quote(str(v))}" for k, v in pairs if v is not None)


def load_trajectory(path: str | Path,
                    options: TrajectoryOptions = TrajectoryOptions()) -> Trajectory:
    """A trajectory (SBET, Optech CSD or text) read with ``options``."""
    o = options
    columns = None if o.columns is None else list(o.columns)
    return read_trajectory(Path(path), crs=o.crs, angles=o.angles, heading_reference=o.heading,
                           columns=columns, time_system=o.time_system)


def check_crs(path: Path, options: PointOptions = PointOptions()) -> None:
    """Error now (before any output) when the CRS is unknown, or a LAS/LAZ file has none and none
    is given."""
    if las_file_crs(path, options.crs) is None:
        raise InputError(path, "crs", NO_CRS)


def matching_trajectory(traj: Trajectory, system: str) -> Trajectory:
    """The trajectory with times in GPS week seconds when the points (``system``) have week
    seconds and it has not."""
    if traj.time_system == system or system == "gps_adjusted_standard":
        return traj
    t, _ = adjusted_standard_to_week_seconds(traj.time, traj.source)
    return dataclasses.replace(traj, time=t, time_system="gps_week_seconds")


def check_coverage(path: Path, traj: Trajectory, options: PointOptions = PointOptions(),
                   chunk_points: int = CHUNK_POINTS) -> int | None:
    """First streamed pass over a LAS/LAZ file, reading only GPS times, before any output is
    written.

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
    """The trajectory in the time system of a LAS/LAZ file's points and the GPS week of their
    times (:func:`check_coverage`), after checking the file's CRS and coverage: every check a
    streamed georeferencing command makes before writing anything."""
    traj = matching_trajectory(traj, las_time_system(path, options.time_system))
    check_crs(path, options)
    return traj, check_coverage(path, traj, options, chunk_points)
