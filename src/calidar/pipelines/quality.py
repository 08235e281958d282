"""The strip-quality pipeline (``calidar quality`` and the boresight report's before/after):
flight lines of LAS/LAZ files, the points fit for a swath difference, and the swath-overlap
difference of every overlapping pair.

``calidar quality`` streams in two passes. The first reads point_source_id, classification,
GPS time and coordinates (:func:`calidar.strips.lines.index_flight_lines`: the flight lines
and the classes each file holds, hence its point selection) and counts the points of each
candidate selection on the 5 m overlap grid (:class:`CellCounts`): which lines overlap and the
cell of each pair (:func:`calidar.strips.quality.overlap_plan`). The second feeds the selected
points of each chunk to a :class:`calidar.strips.quality.SwathAccumulator` that keeps moments
on those cells only; memory holds cells, not points. The boresight pipeline feeds its
(re-georeferenced) lines to the same plan and accumulator (:mod:`calidar.pipelines.line_quality`).
"""

from __future__ import annotations

import tempfile
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from calidar.errors import InputError
from calidar.io.las import PointOptions
from calidar.strips.overlap import merge_counts
from calidar.strips.selection import FIELDS as SELECTION_FIELDS
from calidar.strips.selection import choose_selection

CHUNK_POINTS = 500_000  #: points read at once (the chunk, not the file, sets the peak memory with the cells)
FIELDS = ("point_source_id", *SELECTION_FIELDS)  #: point fields a chunk needs: flight line and the selection's


@dataclass(frozen=True)
class Metric:
    """Coordinates for the swath difference: metric with z up: the CRS's own when projected, else
    local ENU at ``frame`` (one frame for all lines)."""

    crs: object = None
    frame: object | None = None  #: calidar.strips.strip.LocalFrame for a geographic CRS
    geoid_undulation_m: float | None = None
    source: object = None

    @classmethod
    def at(cls, crs, xyz_min, xyz_max, geoid_undulation_m=None, source=None) -> "Metric":
        """For points in ``crs`` within the bounds (x/lon, y/lat, z)."""
        if crs is None or not crs.is_geographic:
            return cls(crs)
        from calidar.georef import from_crs
        from calidar.strips.strip import LocalFrame

        centre = 0.5 * (np.asarray(xyz_min, float) + np.asarray(xyz_max, float))
        frame = LocalFrame.at(from_crs(centre[None, :], crs, geoid_undulation_m, source=source))
        return cls(crs, frame, geoid_undulation_m, source)

    def of(self, xyz: np.ndarray) -> np.ndarray:
        """Metric coordinates (N, 3) of points (N, 3) in the CRS."""
        if self.frame is None:
            return xyz
        from calidar.georef import from_crs

        return self.frame.to_local(from_crs(xyz, self.crs, self.geoid_undulation_m, source=self.source))


class CellCounts:
    """The first pass of ``calidar quality``, chunk by chunk: for each file, its points of every
    candidate selection counted on the overlap grid, by (point_source_id, GPS second), so that
    they go to flight lines (and the file's selection is chosen) once the pass is over."""

    def __init__(self, candidates: dict, metric: Metric, grid_m: float):
        self.candidates, self.metric, self.grid_m = candidates, metric, grid_m  #: candidates: path → selections
        self.counts: dict[tuple, tuple[np.ndarray, np.ndarray]] = {}  #: (path, selection, token) → keys, counts
        self.time: dict[int, float] = {}  #: token → a GPS time of its points (s)

    def __call__(self, path, c: dict) -> None:
        from types import SimpleNamespace

        from calidar.strips.overlap import cell_keys

        t = c["gps_time"]
        sec = np.where(np.isfinite(t), np.floor(np.nan_to_num(t)), 2**32 - 1).astype(np.int64).clip(0, 2**32 - 1)
        token = (np.asarray(c["point_source_id"], np.int64) << 32) | sec
        keys = cell_keys(self.metric.of(np.c_[c["x"], c["y"], c["z"]]), self.grid_m)
        fields = SimpleNamespace(xyz=keys, **{f: c[f] for f in SELECTION_FIELDS})
        for selection in self.candidates[path]:
            keep = selection.mask(fields)
            for tok in np.unique(token[keep]):
                sel = keep & (token == tok)
                self.time.setdefault(int(tok), float(t[np.argmax(sel)]))
                uk, n = np.unique(keys[sel], return_counts=True)
                k = (path, selection, int(tok))
                self.counts[k] = merge_counts(self.counts[k], (uk, n)) if k in self.counts else (uk, n)

    def names(self, index) -> dict[int, str]:
        """The name of a file holding each flight line (for messages)."""
        return {int(index.of(np.array([tok >> 32]), np.array([self.time[tok]]))[0]): path.name
                for path, _, tok in self.counts}

    def by_line(self, index, selections: dict) -> dict[int, tuple[np.ndarray, np.ndarray]]:
        """(keys, counts) per flight line of the points each file's chosen selection keeps."""
        out = {}
        for (path, selection, tok), kn in self.counts.items():
            if selections[path] == selection:
                line = int(index.of(np.array([tok >> 32]), np.array([self.time[tok]]))[0])
                out[line] = merge_counts(out[line], kn) if line in out else kn
        return out


def measure(paths, cell_m=None, classes=None, options: PointOptions = PointOptions(), chunk_points: int = CHUNK_POINTS):
    """Streamed ``calidar quality``: (line index, file CRS, PairQualitys, notes, selection per file,
    each line's smooth-surface precision (:class:`calidar.strips.usgs.LinePrecision`))."""
    from calidar.io.las import iter_las_chunks, las_file_crs, las_header
    from calidar.strips.lines import index_flight_lines
    from calidar.strips.quality import QualitySettings, SwathAccumulator, overlap_cell, overlap_plan
    from calidar.strips.selection import PointSelection

    paths = [Path(p) for p in paths]
    crs, header = las_file_crs(paths[0], options.crs), las_header(paths[0])
    metric = Metric.at(crs, header.mins, header.maxs, options.geoid_undulation_m, paths[0])
    first = [PointSelection("classes", classes)] if classes else [PointSelection("ground", (2,)),
                                                                  PointSelection("last returns")]
    counts = CellCounts({p: first for p in paths}, metric, overlap_cell(cell_m))
    index = index_flight_lines(paths, options, chunk_points=chunk_points, on_chunk=counts,
                               fields=("x", "y", "z", *SELECTION_FIELDS[1:]))
    if len(index.ids) < 2:
        raise InputError(", ".join(sorted({str(p) for p in paths})), "point_source_id",
                         f"found one flight line ({index.how}); expected at least two overlapping lines")
    selections = {p: choose_selection(p, index.classes[p], classes) for p in paths}
    settings = QualitySettings(cell_m=cell_m)
    names = counts.names(index)  #: line → a file holding it (for messages)
    plan = overlap_plan(counts.by_line(index, selections), counts.grid_m, settings, names)
    with tempfile.TemporaryDirectory(prefix="calidar-moments-") as spill:  # cell moments beyond HOLD_BYTES
        acc = SwathAccumulator(cell_m, plan, Path(spill))
        for p in paths:
            for chunk in iter_las_chunks(p, chunk_points, fields=FIELDS, options=options):
                chunk = chunk.select(selections[p].mask(chunk))
                ids, xyz = index.of(chunk.point_source_id, chunk.gps_time), metric.of(chunk.xyz)
                for i in np.unique(ids):
                    acc.add(int(i), xyz[ids == i], selections[p])
        for i in index.ids:  # lines without a selected point: named in the notes
            acc.add(i, np.zeros((0, 3)))
        results, notes = checked_differences(acc, settings, names)
        precisions = line_precisions(acc, settings)
    from calidar.pipelines.plausibility import heights_notes

    notes = [*index.notes, *notes, *heights_notes(crs, options.geoid_undulation_m, relative=True)]
    return index, crs, results, notes, selections, precisions


def line_precisions(acc, settings) -> list:
    """Each line's intraswath precision from the accumulator's moments (:mod:`calidar.strips.usgs`)."""
    from calidar.strips.usgs import line_precision

    return [line_precision(i, acc.line_moments(i), settings.max_rms_m, settings.max_slope_deg, settings.min_points)
            for i in sorted(acc.selections)]


def checked_differences(acc, settings, names: dict[int, str]):
    """The accumulator's pairs and notes; an error when no line overlaps another (lines named by
    ``names`` {id: file name})."""
    from calidar.strips.overlap import strip_name

    results, notes = acc.differences(settings)
    if not results:
        listed = ", ".join(strip_name(i, names) for i in sorted(acc.selections))
        if settings.cell_m is not None:
            raise InputError(None, "--cell", f"no {settings.cell_m:g} m cell holds points of two of the "
                             f"{len(acc.selections)} flight lines ({listed}); expected a larger cell (or leave "
                             "--cell out to have one chosen), unless the lines do not overlap")
        raise InputError(None, "STRIPS", f"none of the {len(acc.selections)} flight lines ({listed}) overlap another; "
                         "nothing to compare")
    empty = [f"{q.a}–{q.b}" for q in results if q.n_cells == 0]
    if empty and settings.cell_m is not None:
        if len(empty) == len(results):
            raise InputError(None, "--cell", f"no {settings.cell_m:g} m cell of any overlap is smooth and holds enough "
                             "points of both lines; expected a larger cell, to hold more points (or leave --cell out "
                             "to have one chosen)")
        notes.append(f"pairs {', '.join(empty)}: no {settings.cell_m:g} m cell is smooth and holds enough points of "
                     "both lines (a larger --cell holds more points; a smaller one is smoother on rough ground)")
    return results, notes
