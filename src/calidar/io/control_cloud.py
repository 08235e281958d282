"""A reference point cloud for ``calidar boresight --control FILE.laz --control-sigma M`` (issue
28), read and checked.

Any LAS/LAZ file (a terrestrial or mobile survey, a dense calibrated flight) of part of the area;
only x, y, z are read, in chunks. Its CRS: ``--control-crs``, else the file's own, else the
strips'. ``--control-sigma`` states its vertical accuracy (the σ of its height datum, m): the
adjustment holds the cloud's height offset to it (:mod:`calidar.strips.control_cloud`). Errors
name the file and what was expected: not LAS/LAZ, no points, more than ``MAX_POINTS``, no σ.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np

from calidar.errors import InputError

SUFFIXES = (".las", ".laz")
#: a reference cloud larger than this: crop or thin it (it is held in memory)
MAX_POINTS = 50_000_000
MAX_SIGMA_M = 1.0
CHUNK_POINTS = 2_000_000


@dataclass(frozen=True, eq=False)
class ReferenceCloud:
    """The reference cloud as read: its file, points (N, 3) in its CRS, that CRS (None: not in the
    file) and the stated σ of its height datum (m)."""

    path: Path
    xyz: np.ndarray
    crs: object
    sigma_m: float


def is_cloud_file(path: str | Path) -> bool:
    """Whether ``path`` names a LAS/LAZ file (a reference cloud, not a CSV of control)."""
    return Path(path).suffix.lower() in SUFFIXES


def check_sigma(sigma_m: float | None, path: str | Path) -> float:
    """``--control-sigma``: given, > 0 and ≤ MAX_SIGMA_M m."""
    from calidar.validate import number

    if sigma_m is None:
        raise InputError(path, "--control-sigma", "a reference cloud needs its stated vertical "
                         "accuracy; expected --control-sigma M (the σ of its heights' datum, m, "
                         "e.g. 0.02)")
    return number(sigma_m, "--control-sigma", 0.0, MAX_SIGMA_M, "m", open_lo=True)


def read_reference_cloud(path: str | Path, sigma_m: float | None) -> ReferenceCloud:
    """Read the reference cloud at ``path`` (x, y, z only, chunk by chunk: any point format, GPS
    time or not) with its stated σ."""
    import laspy

    from calidar.io.las import _check_xyz, _open, _records, _resolve_crs
    from calidar.validate import existing_file

    path = existing_file(path, "reference cloud")
    sigma = check_sigma(sigma_m, path)
    xyz_only = laspy.DecompressionSelection.base() | laspy.DecompressionSelection.Z
    with _open(path, xyz_only) as reader:
        header = reader.header
        if header.point_count > MAX_POINTS:
            raise InputError(path, "point_count", f"{header.point_count:,} points; expected ≤ "
                             f"{MAX_POINTS:,} in a reference cloud of part of the area (crop or "
                             "thin it: it is held in memory)")
        crs = _resolve_crs(header, None, path)
        parts = []
        for first, rec in _records(reader, CHUNK_POINTS, path):
            xyz = np.stack([np.asarray(rec.x, float), np.asarray(rec.y, float),
                            np.asarray(rec.z, float)], axis=1)
            _check_xyz(xyz, header, path, first)
            parts.append(xyz)
    n = sum(len(p) for p in parts)
    if n == 0:
        raise InputError(path, "point_count",
                         "no points; expected a reference cloud of part of the strips' area")
    return ReferenceCloud(path, np.vstack(parts), crs, sigma)
