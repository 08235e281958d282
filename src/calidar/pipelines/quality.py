"""The strip-quality pipeline (``calidar quality`` and the boresight report's before/after):
flight lines of LAS/LAZ files, the points fit for a swath difference, and the swath-overlap
difference of every overlapping pair."""

from __future__ import annotations

import numpy as np

from calidar.errors import InputError


def line_coordinates(points) -> np.ndarray:
    """Metric coordinates (N, 3) with z up: the file's projected CRS, or local ENU for geographic CRSs."""
    if points.crs is not None and points.crs.is_geographic:
        from calidar.georef import from_crs
        from calidar.strips.strip import LocalFrame

        ecef = from_crs(points.xyz, points.crs)
        return LocalFrame.at(ecef).to_local(ecef)
    return points.xyz


def usable(points) -> np.ndarray:
    """Mask of points fit for the swath difference: no vegetation/noise/water classes, last returns."""
    from calidar.strips.quality import EXCLUDED_CLASSES

    keep = np.ones(len(points), bool)
    if points.classification is not None:
        keep &= ~np.isin(points.classification, EXCLUDED_CLASSES)
    if points.return_number is not None and points.number_of_returns is not None:
        keep &= points.return_number >= points.number_of_returns
    return keep


def measure(paths, cell_m=None):
    """Flight lines of the files and the PairQuality of every overlapping pair."""
    from calidar.strips.lines import read_flight_lines

    lines, how = read_flight_lines(paths)
    if len(lines) < 2:
        names = ", ".join(sorted({str(p) for p in paths}))
        raise InputError(names, "point_source_id", f"found one flight line ({how}); expected at least two "
                         "overlapping lines")
    coords = {i: line_coordinates(p)[usable(p)] for i, p in lines.items()}
    results, notes = pairs_quality(coords, cell_m, {i: p.path.name for i, p in lines.items()})
    return lines, how, results, notes


def pairs_quality(coords: dict[int, np.ndarray], cell_m: float | None = None, names: dict[int, str] | None = None):
    """The PairQuality of every overlapping pair of flight lines given as metric coordinates with z
    up (N, 3) m of their usable points (see :func:`usable`), and the overlap notes (lines named by
    ``names`` {id: file name} when given). The one implementation behind ``calidar quality`` and
    the boresight report's before/after tables."""
    from calidar.strips.overlap import find_overlaps, strip_name
    from calidar.strips.quality import QualitySettings, swath_difference

    pairs, notes = find_overlaps(coords, names=names)
    if not pairs:
        listed = ", ".join(strip_name(i, names) for i in coords)
        raise InputError(None, "STRIPS", f"none of the {len(coords)} flight lines ({listed}) overlap another; "
                         "nothing to compare")
    settings = QualitySettings(cell_m=cell_m)
    results = [swath_difference(o.a, coords[o.a][o.index_a], o.b, coords[o.b][o.index_b], settings) for o in pairs]
    empty = [f"{q.a}–{q.b}" for q in results if q.n_cells == 0]
    if empty and cell_m is not None:
        if len(empty) == len(results):
            raise InputError(None, "--cell", f"no {cell_m:g} m cell of any overlap is smooth and holds enough points "
                             "of both lines; expected a smaller cell (or leave --cell out to have one chosen)")
        notes.append(f"pairs {', '.join(empty)}: no {cell_m:g} m cell is smooth and holds enough points of both "
                     "lines (a smaller --cell may help)")
    return results, notes
