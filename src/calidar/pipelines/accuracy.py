"""``calidar accuracy``: the absolute vertical accuracy of delivered points against surveyed
checkpoints, as the ASPRS Positional Accuracy Standards (Edition 2, 2023) test it.

One streamed pass over the LAS/LAZ files keeps only the ground candidates within ``radius_m``
of a checkpoint (:class:`calidar.accuracy.tin.GroundCollector`); each file's ground points are
chosen as the swath checks choose them (class 2, else last returns); the TIN around each
checkpoint gives the surface there, the whole product's and each flight line's own; the
residuals give the statistics (:mod:`calidar.accuracy.asprs`), the verdict and the report.
Outputs: accuracy.json, checkpoints.csv (each checkpoint with its residual), report.html.
"""

from __future__ import annotations

import csv
import io
import json
from dataclasses import asdict, dataclass
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np

from calidar.errors import InputError
from calidar.io.las import PointOptions
from calidar.pipelines import Progress, no_progress
from calidar.validate import number

if TYPE_CHECKING:  # the run's parts, by type (imported where used)
    from calidar.accuracy.assess import Assessment
    from calidar.provenance import RunRecord
    from calidar.verdict import Verdict

CHUNK_POINTS = 1_000_000
FIELDS = ("point_source_id", "classification", "return_number", "number_of_returns",
          "scan_angle_deg")
RADIUS_RANGE_M = (0.1, 100.0)


@dataclass(frozen=True)
class AccuracySettings:
    """Options of ``calidar accuracy`` (lengths in m)."""

    checkpoints_crs: str | None = None  #: the checkpoints' CRS when it is not the points'
    survey_sigma_m: float | None = None  #: the checkpoints' survey RMSE (else the file's σ column)
    radius_m: float = 5.0  #: ground points within this of a checkpoint form its TIN
    max_edge_m: float | None = None  #: longest edge of the containing triangle (default: radius_m)
    #: the class a contract asks for (the verdict fails below it)
    target_class_cm: float | None = None
    #: LAS classes taken as ground (default: 2, else last returns)
    classes: tuple[int, ...] | None = None
    #: also the USGS swath checks (the files read twice more, as calidar quality reads them)
    swaths: bool = False

    def checked(self) -> "AccuracySettings":
        number(self.radius_m, "--radius", *RADIUS_RANGE_M, "m")
        if self.max_edge_m is not None:
            number(self.max_edge_m, "--max-edge", *RADIUS_RANGE_M, "m")
        if self.survey_sigma_m is not None:
            number(self.survey_sigma_m, "--survey-sigma", 0.0, 10.0, "m")
        if self.target_class_cm is not None:
            number(self.target_class_cm, "--class", 0.1, 10000.0, "cm")
        return self

    @property
    def edge_m(self) -> float:
        return self.max_edge_m if self.max_edge_m is not None else self.radius_m


@dataclass
class AccuracyRun:
    assessment: Assessment
    verdict: Verdict
    record: RunRecord


def _points_crs(paths, options: PointOptions):
    """The one CRS of all files (an error naming the first file that differs) and their bounds."""
    from calidar.io.las import las_file_crs, las_header

    crs, lo, hi = None, np.full(3, np.inf), np.full(3, -np.inf)
    for k, p in enumerate(paths):
        c = las_file_crs(p, options.crs)
        if k == 0:
            crs = c
        elif (c is None) != (crs is None) or (c is not None and not c.equals(crs)):
            theirs, first = getattr(c, "name", None), getattr(crs, "name", None)
            raise InputError(p, "crs", f"{theirs} differs from {first} of {paths[0]}; expected one "
                             "CRS for all files")
        h = las_header(p)
        lo, hi = np.minimum(lo, h.mins), np.maximum(hi, h.maxs)
    return crs, lo, hi


def checkpoints_in(cp, crs, options: PointOptions, checkpoints_crs: str | None) -> np.ndarray:
    """The checkpoints' coordinates in the points' CRS (transformed when ``checkpoints_crs``
    differs)."""
    if checkpoints_crs is None:
        return cp.xyz
    import pyproj

    from calidar.crs import from_crs, to_crs

    theirs = pyproj.CRS.from_user_input(checkpoints_crs)
    if crs is None:
        raise InputError(cp.path, "--checkpoints-crs",
                         "given, but the points have no CRS; expected --crs for them")
    if theirs.equals(crs):
        return cp.xyz
    ecef = from_crs(cp.xyz, theirs, None, cp.path)
    return to_crs(ecef, crs, options.geoid_undulation_m, cp.path)


def check_inside(cp, xyz: np.ndarray, lo, hi, crs) -> None:
    """An error naming the first checkpoints outside every file's bounds."""
    x, y = xyz[:, 0], xyz[:, 1]
    out = np.flatnonzero((x < lo[0]) | (x > hi[0]) | (y < lo[1]) | (y > hi[1]))
    if out.size:
        i = out[0]
        more = f" (and {out.size - 1} more)" if out.size > 1 else ""
        crs_name = ", " + crs.name if crs is not None else ""
        bounds = f"x {lo[0]:.3f} … {hi[0]:.3f}, y {lo[1]:.3f} … {hi[1]:.3f}{crs_name}"
        raise InputError(cp.path, "x/y", f"line {cp.lines[i]}: checkpoint {str(cp.ids[i])!r} at "
                         f"({x[i]:.3f}, {y[i]:.3f}){more} lies outside the points ({bounds}); "
                         "expected checkpoints on the data (in another CRS? give "
                         "--checkpoints-crs)")


def measure_accuracy(paths, checkpoints: Path, settings: AccuracySettings = AccuracySettings(),
                     options: PointOptions = PointOptions(), progress: Progress = no_progress):
    """Read, stream, triangulate and assess: an :class:`calidar.accuracy.assess.Assessment`."""
    from calidar.accuracy.assess import assess
    from calidar.accuracy.tin import GroundCollector, heights_per_strip, tin_heights
    from calidar.io.checkpoints import check_places, read_checkpoints
    from calidar.io.las import iter_las_chunks
    from calidar.ingest.cell_counts import Metric

    settings = settings.checked()
    paths = [Path(p) for p in paths]
    cp = read_checkpoints(checkpoints)
    crs, lo, hi = _points_crs(paths, options)
    xyz = checkpoints_in(cp, crs, options, settings.checkpoints_crs)
    check_inside(cp, xyz, lo, hi, crs)
    metric = Metric.at(crs, lo, hi, options.geoid_undulation_m, paths[0])
    local = metric.of(xyz)
    check_places(cp, local[:, :2])
    collector = GroundCollector(local[:, :2], settings.radius_m)
    for k, p in enumerate(paths):
        for chunk in iter_las_chunks(p, CHUNK_POINTS, fields=FIELDS, options=options):
            collector.add(p, metric.of(chunk.xyz), chunk.point_source_id, chunk.classification,
                          chunk.return_number, chunk.number_of_returns, chunk.scan_angle_deg)
        progress("reading points", k + 1, len(paths))
    ground, ids, angles, selections = collector.ground(settings.classes)
    at, radius, edge = local[:, :2], settings.radius_m, settings.edge_m
    heights = tin_heights(ground, ids, at, radius, edge)
    per_strip = heights_per_strip(ground, ids, at, radius, edge, angles)
    progress("triangulating", 1, 1)
    tested = np.c_[xyz[:, :2], local[:, 2]] if metric.frame is not None else xyz
    return assess(cp, tested, heights, per_strip, settings.survey_sigma_m,
                  {p.name: s for p, s in selections.items()}, None if crs is None else crs.name)


def swath_checks(paths, classes, options: PointOptions, progress: Progress = no_progress):
    """The USGS swath checks of ``calidar quality`` on the same files
    (:func:`calidar.pipelines.quality.measure`, :func:`calidar.strips.usgs.usgs_checks`): a
    :class:`calidar.accuracy.usgs.SwathChecks`, with a note instead when they do not apply (one
    flight line, no line overlapping another)."""
    from calidar.accuracy.usgs import SwathChecks
    from calidar.pipelines.quality import QualityConfig, measure
    from calidar.strips.usgs import usgs_checks

    try:
        config = QualityConfig(classes=classes, points=options)
        _, _, results, _, _, precisions = measure(paths, config)
    except InputError as e:
        # one flight line, or none overlapping another
        if e.field in ("point_source_id", "STRIPS"):
            return SwathChecks(note=e.problem)
        raise
    progress("swath checks", 1, 1)
    return SwathChecks(usgs_checks(results, precisions), precisions)


def checkpoints_csv(a) -> str:
    """checkpoints.csv: each checkpoint as read, its surface, residual and what became of it."""
    buf = io.StringIO()
    w = csv.writer(buf, lineterminator="\n")
    w.writerow(["id", "line", "x", "y", "z", "class", "sigma_m", "surface_z", "dz_m",
                "ground_points", "triangle_edge_m", "flight_lines", "outlier", "not_used"])

    def f(v, d):
        return "" if v is None else f"{v:.{d}f}"

    for r in a.rows():
        w.writerow([r["id"], r["line"], f(r["x"], 3), f(r["y"], 3), f(r["z"], 3), r["cover"],
                    f(r["sigma_m"], 4), f(r["surface_z"], 4), f(r["dz_m"], 4), r["ground_points"],
                    f(r["triangle_edge_m"], 2), " ".join(map(str, r["strips"])),
                    "yes" if r["outlier"] else "", r["not_used"] or ""])
    return buf.getvalue()


def run_accuracy(paths, checkpoints: Path, out_dir: Path,
                 settings: AccuracySettings = AccuracySettings(),
                 options: PointOptions = PointOptions(), argv: list[str] | None = None,
                 report=None, progress: Progress = no_progress) -> AccuracyRun:
    """:func:`measure_accuracy`, then accuracy.json (with the verdict and the run record),
    checkpoints.csv and report.html in the existing folder ``out_dir`` (or, given ``report``, the
    verdict and sections added to it)."""
    from calidar.accuracy.report import add_sections
    from calidar.accuracy.verdict import accuracy_verdict
    from calidar.outputs import write_text_atomic
    from calidar.pipelines.reports import report_for
    from calidar.provenance import RunRecord

    record = RunRecord.capture(argv, inputs=[*paths, checkpoints], options=asdict(settings))
    a = measure_accuracy(paths, checkpoints, settings, options, progress)
    if settings.swaths:
        a.usgs_swaths = swath_checks(paths, settings.classes, options, progress)
    verdict = accuracy_verdict(a, settings.target_class_cm)
    record.finish()
    out_dir = Path(out_dir)
    doc = {**a.to_dict(), "verdict": verdict.to_dict(), "run": record.to_dict()}
    write_text_atomic(out_dir / "accuracy.json", json.dumps(doc, indent=2, allow_nan=False) + "\n")
    write_text_atomic(out_dir / "checkpoints.csv", checkpoints_csv(a))
    with report_for(report, "calidar absolute accuracy", record, out_dir / "report.html", verdict,
                    "Absolute accuracy") as rep:
        add_sections(rep, a)
    return AccuracyRun(a, verdict, record)
