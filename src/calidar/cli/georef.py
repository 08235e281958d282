"""``calidar inverse`` and ``calidar regeoref``: delivered LAS points back to scanner
observations, and re-georeferenced with a changed sensor model (streamed in chunks)."""

from __future__ import annotations

import dataclasses
from pathlib import Path

import numpy as np
import typer

from calidar import georef
from calidar.cli.common import console
from calidar.errors import InputError
from calidar.io.csv import write_csv_rows
from calidar.io.las import (
    LasPoints, adjusted_standard_in_week, adjusted_standard_to_week_seconds, iter_las_chunks, iter_las_times,
    las_file_crs, las_time_system, rewrite_las_xyz, single_gps_week,
)
from calidar.io.trajectory import is_binary, read_trajectory
from calidar.outputs import atomic_path, check_not_input, check_writable, prepare_out_dir
from calidar.sensor import Sensor
from calidar.trajectory import Trajectory

CHUNK_POINTS = 2_000_000
NO_CRS = "the file has no CRS (no WKT or GeoTIFF VLR); pass --crs (e.g. --crs EPSG:32611)"
VECTOR_COLUMNS = ("gps_time", "range_m", "x_s", "y_s", "z_s", "across_track_angle_deg", "along_track_angle_deg")

TRAJ_CRS = typer.Option(None, "--trajectory-crs", help="CRS of a text trajectory's x/y (or lat/lon) columns, e.g. EPSG:32615.")
TRAJ_ANGLES = typer.Option("deg", "--trajectory-angles", help="Angle unit of a text trajectory: deg or rad.")
TRAJ_HEADING = typer.Option("true", "--trajectory-heading", help="Heading of a text trajectory: true, or grid (then corrected by the meridian convergence).")


def load_trajectory(path: Path, crs: str | None = None, angles: str = "deg", heading: str = "true") -> Trajectory:
    """A trajectory from the CLI options (text options only apply to text files)."""
    if path.is_file() and is_binary(path):
        return read_trajectory(path)
    return read_trajectory(path, crs=crs, angles=angles, heading_reference=heading)


def matching_trajectory(traj: Trajectory, system: str) -> Trajectory:
    """The trajectory with times in GPS week seconds when the LAS (``system``) has week seconds and it has not."""
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


def check_crs(path: Path, crs: str | None) -> None:
    """Error now (before any output) when ``crs`` is unknown, or a LAS/LAZ file has no CRS and none is given."""
    if las_file_crs(path, crs) is None:
        raise InputError(path, "crs", NO_CRS)


def points_ecef(points: LasPoints) -> np.ndarray:
    """Points (N, 3) in ECEF from their CRS; clear errors for no CRS or an impossible transform."""
    if points.crs is None:
        raise InputError(points.path, "crs", NO_CRS)
    e = georef.from_crs(points.xyz, points.crs)
    if not np.all(np.isfinite(e)):
        raise InputError(points.path, "crs", f"cannot transform from {points.crs.name} to ECEF "
                         "(a PROJ grid, e.g. a geoid model, may be missing); give an ellipsoidal CRS with --crs")
    return e


class Coverage:
    """Counts points outside the trajectory's time span over many chunks (count and time range
    before and after it, and NaN/inf times), to report them all at once."""

    def __init__(self, traj: Trajectory):
        self.traj, self.total, self.not_finite = traj, 0, 0
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
        return finite & ~(lo | hi)

    def check(self, source) -> None:
        """Raise a clear error naming how many points fell outside and their time ranges."""
        n = sum(o[0] for o in self.outside.values()) + self.not_finite
        if n == 0:
            return
        parts = [f"{o[0]} {side} it ({o[1]:.3f}–{o[2]:.3f} s)" for side, o in self.outside.items() if o[0]]
        parts += [f"{self.not_finite} NaN/inf"] if self.not_finite else []
        raise InputError(
            source, "gps_time",
            f"{n} of {self.total} points have GPS times outside the trajectory "
            f"{self.traj.source} ({self.traj.time[0]:.3f}–{self.traj.time[-1]:.3f} s): " + ", ".join(parts),
        )


def check_coverage(path: Path, traj: Trajectory) -> int | None:
    """First streamed pass over a LAS/LAZ file, reading only GPS times, before any output is written.

    Raises one error for the whole file when points fall outside ``traj`` (how many, before/after
    it, their time ranges; NaN times) or, when adjusted standard times must become the
    trajectory's week seconds, when the file spans GPS weeks. Returns the GPS week of that
    conversion (for :func:`point_times`), else None.
    """
    convert = las_time_system(path) == "gps_adjusted_standard" and traj.time_system == "gps_week_seconds"
    cover, week, t_range = Coverage(traj), None, [np.inf, -np.inf]
    for t in iter_las_times(path, CHUNK_POINTS):
        if convert:
            finite = t[np.isfinite(t)]
            if finite.size:
                t_range = [min(t_range[0], float(finite.min())), max(t_range[1], float(finite.max()))]
                week = single_gps_week(t_range[0], t_range[0], path) if week is None else week
            t = adjusted_standard_in_week(t, 0 if week is None else week)
        cover.inside(t)
    if week is not None:
        single_gps_week(*t_range, path)  # the whole file, before its counts (which assume one week)
    cover.check(path)
    return week


def forward_trajectory(new: Trajectory | None, traj: Trajectory, path: Path, source) -> Trajectory | None:
    """``calidar regeoref --to-trajectory``'s trajectory for the LAS ``path`` (None: none given),
    in the time system of ``traj`` and covering the file (clear errors otherwise)."""
    if new is None:
        return None
    new = matching_trajectory(new, las_time_system(path))
    if new.time_system != traj.time_system:
        raise InputError(source, "time", f"holds {new.time_system}, --trajectory holds {traj.time_system}; "
                         "expected the same time system")
    check_coverage(path, new)
    return new


def register(app: typer.Typer, simulate: typer.Typer) -> None:
    @app.command()
    def inverse(
        points: Path = typer.Argument(..., help="LAS/LAZ file with GPS times."),
        trajectory: Path = typer.Option(..., "--trajectory", "-t", help="SBET or text trajectory."),
        out: Path = typer.Option(..., "--out", "-o", help="CSV of scanner-frame vectors."),
        sensor: Path = typer.Option(None, "--sensor", help="sensor.toml (default: linear scanner, zero boresight and lever arm)."),
        crs: str = typer.Option(None, "--crs", help="CRS of the points, overriding (or supplying) the file's."),
        trajectory_crs: str = TRAJ_CRS, trajectory_angles: str = TRAJ_ANGLES, trajectory_heading: str = TRAJ_HEADING,
        force: bool = typer.Option(False, "--force", help="Overwrite the output."),
    ) -> None:
        """Inverse georeferencing: per point the range and the scanner-frame vector (CSV).

        Columns: gps_time (s, as in the LAS), range_m (measured), x_s, y_s, z_s (m, scanner frame:
        x forward, y right, z down), across_track_angle_deg = atan2(y_s, z_s),
        along_track_angle_deg = atan2(x_s, hypot(y_s, z_s)).
        """
        check_writable(out, force)
        check_not_input(out, [points, trajectory, sensor])
        model = Sensor.read(sensor) if sensor else Sensor()
        traj = load_trajectory(trajectory, trajectory_crs, trajectory_angles, trajectory_heading)
        traj = matching_trajectory(traj, las_time_system(points))
        check_crs(points, crs)
        week = check_coverage(points, traj)
        n = 0
        with atomic_path(out, force) as tmp, open(tmp, "w", encoding="utf-8") as f:
            f.write(",".join(VECTOR_COLUMNS) + "\n")
            for chunk in iter_las_chunks(points, CHUNK_POINTS, crs=crs, fields=()):
                obs = georef.inverse(traj, model, point_times(chunk, traj, week), points_ecef(chunk))
                v = obs.vector_s
                across = np.degrees(np.arctan2(v[:, 1], v[:, 2]))
                along = np.degrees(np.arctan2(v[:, 0], np.hypot(v[:, 1], v[:, 2])))
                write_csv_rows(f, [chunk.gps_time, obs.range_m, v[:, 0], v[:, 1], v[:, 2], across, along],
                               [6, 4, 4, 4, 4, 6, 6])
                n += len(chunk)
        console.print(f"{n} points → {out}")

    @app.command()
    def regeoref(
        strips: list[Path] = typer.Argument(..., help="LAS/LAZ strips georeferenced with the --from sensor."),
        trajectory: Path = typer.Option(..., "--trajectory", "-t", help="SBET or text trajectory."),
        old: Path = typer.Option(..., "--from", help="sensor.toml the strips were georeferenced with."),
        new: Path = typer.Option(..., "--to", help="sensor.toml to re-georeference them with."),
        out: Path = typer.Option(..., "--out", "-o", help="Output folder (same file names)."),
        crs: str = typer.Option(None, "--crs", help="CRS of the strips, overriding (or supplying) the files'."),
        trajectory_crs: str = TRAJ_CRS, trajectory_angles: str = TRAJ_ANGLES, trajectory_heading: str = TRAJ_HEADING,
        force: bool = typer.Option(False, "--force", help="Write into a non-empty output folder, overwriting."),
        to_trajectory: Path = typer.Option(None, "--to-trajectory", help="Forward with this trajectory instead "
                                           "(e.g. the sbet_corrected.out of calidar boresight)."),
    ) -> None:
        """Re-georeference delivered strips with a new sensor model (and trajectory).

        Inverse georeferencing with --trajectory and --from, forward with --to-trajectory (default
        --trajectory) and --to, streamed in chunks; every other point attribute is kept, and the
        outputs keep the inputs' names, formats and CRS.
        """
        old_s, new_s = Sensor.read(old), Sensor.read(new)
        traj0 = load_trajectory(trajectory, trajectory_crs, trajectory_angles, trajectory_heading)
        new0 = to_trajectory and load_trajectory(to_trajectory, trajectory_crs, trajectory_angles, trajectory_heading)
        names = [s.name for s in strips]
        if len(set(names)) != len(names):
            raise InputError(None, "STRIPS", f"expected distinct file names (outputs share the folder), got {names}")
        plans = []  # every strip is checked (CRS, whole-file trajectory coverage) before anything is written
        for s in strips:
            if s.resolve().parent == out.resolve():
                raise InputError(s, None, "is inside --out; choose another output folder (inputs are never modified)")
            check_not_input(out / s.name, [*strips, trajectory, old, new, to_trajectory])
            traj = matching_trajectory(traj0, las_time_system(s))
            check_crs(s, crs)
            plans.append((s, traj, forward_trajectory(new0, traj, s, to_trajectory), check_coverage(s, traj)))
        out_dir = prepare_out_dir(out, force)
        for s, traj, new_traj, week in plans:

            def moved(points: LasPoints, traj=traj, new_traj=new_traj, week=week) -> np.ndarray:
                t = point_times(points, traj, week)
                p = georef.regeoreference(traj, old_s, new_s, t, points_ecef(points), new_traj)
                return georef.to_crs(p, points.crs)

            n = rewrite_las_xyz(s, out_dir / s.name, moved, crs=crs, chunk_points=CHUNK_POINTS, force=force)
            console.print(f"{s} → {out_dir / s.name}: {n} points")

