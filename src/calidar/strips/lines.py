"""Flight lines from LAS/LAZ files: by point_source_id, or by gaps in GPS time when ids are missing."""

from __future__ import annotations

import hashlib
from collections.abc import Sequence
from dataclasses import replace
from pathlib import Path

import numpy as np
import pyproj

from calidar.errors import InputError
from calidar.io.las import OPTIONAL_FIELDS, LasPoints, PointOptions, read_las

GAP_S = 10.0  #: a pause in GPS time longer than this starts a new flight line (s)


def line_ids(point_source_id: np.ndarray | None, gps_time: np.ndarray, gap_s: float = GAP_S) -> tuple[np.ndarray, str]:
    """One flight-line id per point and how they were found ("point_source_id" or "gps_time_gaps").

    Ids come from point_source_id when it holds at least two distinct values; otherwise
    lines are numbered 1, 2, … in time order, split where GPS time jumps by more than gap_s.
    """
    if point_source_id is not None and np.unique(point_source_id).size >= 2:
        return np.asarray(point_source_id, np.int64), "point_source_id"
    order = np.argsort(gps_time, kind="stable")
    starts = np.r_[0, np.flatnonzero(np.diff(gps_time[order]) > gap_s) + 1]
    ids = np.empty(gps_time.size, np.int64)
    ids[order] = np.repeat(np.arange(1, starts.size + 1), np.diff(np.r_[starts, gps_time.size]))
    return ids, "gps_time_gaps"


def read_flight_lines(paths: Sequence[str | Path], crs=None, gap_s: float = GAP_S,
                      options: PointOptions | None = None) -> tuple[dict[int, LasPoints], str]:
    """Read LAS/LAZ files (``crs``, or ``options``: the shared point options) and split their points
    into flight lines {id: points}.

    All files must share one CRS and one GPS time system (clear errors otherwise).
    """
    if not paths:
        raise InputError(None, "STRIPS", "expected at least one LAS/LAZ file")
    clouds = [read_las(p, crs=crs, options=options) for p in paths]
    _check_files(clouds)
    first = clouds[0]
    for c in clouds[1:]:
        if (c.crs is None) != (first.crs is None) or (c.crs is not None and not c.crs.equals(first.crs, ignore_axis_order=True)):
            raise InputError(c.path, "crs", f"expected the CRS of {first.path.name} ({_name(first.crs)}), got {_name(c.crs)}")
        if c.time_system != first.time_system:
            raise InputError(c.path, "gps_time", f"expected {first.time_system} like {first.path.name}, got {c.time_system}")
    merged = first
    if len(clouds) > 1:
        fields = {f: None if any(getattr(c, f) is None for c in clouds) else np.concatenate([getattr(c, f) for c in clouds])
                  for f in OPTIONAL_FIELDS}
        merged = replace(first, xyz=np.concatenate([c.xyz for c in clouds]),
                         gps_time=np.concatenate([c.gps_time for c in clouds]), **fields)
    ids, how = line_ids(merged.point_source_id, merged.gps_time, gap_s)
    source = np.repeat(np.arange(len(clouds)), [len(c) for c in clouds])  # the file of each point
    return {int(i): replace(merged.select(ids == i), path=clouds[source[np.argmax(ids == i)]].path)
            for i in np.unique(ids)}, how


def _check_files(clouds: Sequence[LasPoints]) -> None:
    """Refuse a file given twice, a file without points and a file holding the same points as
    another (a copy): each would silently merge into, or vanish from, the flight lines."""
    seen: dict[str, Path] = {}
    for c in clouds:
        if len(c) == 0:
            raise InputError(c.path, "points", "no points; expected a strip (flight line) with points")
        h = hashlib.sha256(np.ascontiguousarray(c.gps_time))  # no copy of the (large) arrays
        h.update(np.ascontiguousarray(c.xyz))
        digest = h.hexdigest()
        other = seen.setdefault(digest, c.path)
        if other is not c.path:
            same = other == c.path or other.resolve() == c.path.resolve()
            raise InputError(c.path, None, "given twice; expected each strip once" if same else
                             f"holds the same points as {other.name}: a duplicate; expected each strip once")


def _name(crs: pyproj.CRS | None) -> str:
    return "none" if crs is None else (f"EPSG:{crs.to_epsg()}" if crs.to_epsg() else crs.name)
