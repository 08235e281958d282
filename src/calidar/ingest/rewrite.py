"""Whole LAS/LAZ files streamed chunk by chunk through a per-point computation and written again:
the scanner observations of ``calidar inverse`` (CSV), the strips of ``calidar regeoref`` (new
coordinates, every other attribute kept) and the per-point uncertainty of ``calidar tpu`` (extra
bytes). Each chunk's times go into the trajectory's time system
(:func:`calidar.ingest.times.point_times`) and its geometry into a
:class:`calidar.ingest.plausibility.GeometryCheck`; memory holds one chunk."""

from __future__ import annotations

from collections.abc import Callable
from pathlib import Path
from typing import TextIO

import numpy as np

from calidar import georef
from calidar.ingest import Progress, no_progress
from calidar.ingest.plausibility import GeometryCheck
from calidar.ingest.times import point_times, points_ecef
from calidar.io.las import PointOptions
from calidar.sensor import Sensor
from calidar.trajectory import Trajectory

CHUNK_POINTS = 2_000_000  #: points read at once

#: ``calidar inverse``'s CSV columns (m, s, deg) and the decimals each is written with
VECTOR_COLUMNS = ("gps_time", "range_m", "x_s", "y_s", "z_s", "across_track_angle_deg",
                  "along_track_angle_deg")
VECTOR_DECIMALS = (6, 4, 4, 4, 4, 6, 6)


def inverse_rows(f: TextIO, path: Path, traj: Trajectory, week: int | None, sensor: Sensor,
                 options: PointOptions, check: GeometryCheck, progress: Progress = no_progress,
                 total: int = 0, chunk_points: int = CHUNK_POINTS):
    """Each point of ``path`` inverse-georeferenced with ``sensor`` as a row of
    :data:`VECTOR_COLUMNS` written to ``f``: range and the scanner-frame vector, across_track_angle
    = atan2(y_s, z_s), along_track_angle = atan2(x_s, hypot(y_s, z_s)). Returns (points, the
    points' CRS)."""
    from calidar.io.csv import write_csv_rows
    from calidar.io.las import iter_las_chunks

    n, crs = 0, None
    for chunk in iter_las_chunks(path, chunk_points, fields=("scan_angle_deg",), options=options):
        t, ecef, crs = point_times(chunk, traj, week), points_ecef(chunk), chunk.crs
        check.add(traj, t, ecef, chunk.scan_angle_deg)
        obs = georef.inverse(traj, sensor, t, ecef)
        v = obs.vector_s
        across = np.degrees(np.arctan2(v[:, 1], v[:, 2]))
        along = np.degrees(np.arctan2(v[:, 0], np.hypot(v[:, 1], v[:, 2])))
        columns = [chunk.gps_time, obs.range_m, v[:, 0], v[:, 1], v[:, 2], across, along]
        write_csv_rows(f, columns, list(VECTOR_DECIMALS))
        n += len(chunk)
        progress("inverse georeferencing", n, total)
    return n, crs


def regeoreference_file(path: Path, out: Path, traj: Trajectory, week: int | None, old: Sensor,
                        new: Sensor, new_traj: Trajectory | None, options: PointOptions,
                        check: GeometryCheck, chunk_points: int = CHUNK_POINTS) -> int:
    """``path`` re-georeferenced into ``out``: each point inverted with ``traj`` and the ``old``
    sensor, forward with ``new_traj`` (None: ``traj``) and ``new``, in the file's CRS; returns the
    points written."""
    from calidar.io.las_rewrite import rewrite_las_xyz

    def moved(points) -> np.ndarray:
        t, ecef = point_times(points, traj, week), points_ecef(points)
        check.add(traj, t, ecef, points.scan_angle_deg)
        p = georef.regeoreference(traj, old, new, t, ecef, new_traj)
        return georef.to_crs(p, points.crs, points.geoid_undulation_m, source=points.path)

    return rewrite_las_xyz(path, out, moved, chunk_points=chunk_points, force=True,
                           options=options)


#: what :func:`with_extra_bytes` computes per chunk: (t, ecef, chunk) → values by extra-bytes name
PerPoint = Callable[[np.ndarray, np.ndarray, object], dict[str, np.ndarray]]


def with_extra_bytes(path: Path, out: Path, extra: dict[str, str], traj: Trajectory,
                     week: int | None, per_point: PerPoint, options: PointOptions,
                     chunk_points: int = CHUNK_POINTS) -> int:
    """``path`` written to ``out`` with the ``extra`` bytes (name → description) that
    ``per_point(t, ecef, chunk)`` gives for each chunk (t in the trajectory's time system, ECEF m);
    returns the points written."""
    from calidar.io.las_extra import rewrite_las_with_extra

    def values(points):
        return per_point(point_times(points, traj, week), points_ecef(points), points)

    return rewrite_las_with_extra(path, out, extra, values, chunk_points=chunk_points, force=True,
                                  options=options)
