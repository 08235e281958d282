"""Copy a LAS/LAZ file chunk by chunk with its point records rewritten (new coordinates, extra
bytes): streamed, so files larger than memory, and written atomically."""

from __future__ import annotations

from pathlib import Path

import laspy
import numpy as np

from calidar.io.las import (OPTIONAL_FIELDS, PointOptions, _open, _options, _points, _records,
                            _resolve_crs, gps_time_system)
from calidar.outputs import atomic_path


def rewrite_las_xyz(src: str | Path, dst: str | Path, new_xyz, *, crs=None,
                    chunk_points: int = 2_000_000, force: bool = False,
                    options: PointOptions | None = None) -> int:
    """Copy a LAS/LAZ file chunk by chunk, replacing coordinates by ``new_xyz(points) -> (n, 3)``
    (same CRS, scales, offsets and point format; every other attribute kept). Returns the point
    count.

    ``points`` is the chunk's :class:`LasPoints`. The output is written atomically.
    """
    def moved(rec, points):
        xyz = np.asarray(new_xyz(points), float)
        rec.x, rec.y, rec.z = xyz[:, 0], xyz[:, 1], xyz[:, 2]
        return rec

    return rewrite_las(src, dst, lambda header: header, moved, chunk_points=chunk_points,
                       force=force, options=_options(crs, options))


def rewrite_las(src: str | Path, dst: str | Path, out_header, rewrite, *, chunk_points: int,
                force: bool = False, options: PointOptions | None = None) -> int:
    """Copy a LAS/LAZ file chunk by chunk through ``rewrite(record, points) -> record``
    (``points``: the chunk's :class:`LasPoints`, read with ``options``), into a file with the
    header ``out_header(source header)``; streamed and atomic. Returns the point count."""
    src, opts = Path(src), _options(None, options)
    n = 0
    with _open(src) as reader, atomic_path(dst, force) as tmp:
        header = reader.header
        time_system = gps_time_system(header, src, opts.time_system)
        file_crs = _resolve_crs(header, opts.crs, src)
        undulation = opts.geoid_undulation_m
        compress = Path(dst).suffix.lower() == ".laz"
        with laspy.open(tmp, mode="w", header=out_header(header), do_compress=compress) as w:
            for first, rec in _records(reader, chunk_points, src):
                points = _points(rec, header, src, file_crs, time_system, OPTIONAL_FIELDS,
                                 undulation, first)
                w.write_points(rewrite(rec, points))
                n += len(rec)
    return n
