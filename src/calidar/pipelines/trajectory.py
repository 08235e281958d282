"""``calidar trajectory``: each flight line's sensor trajectory reconstructed from delivered points
(:mod:`calidar.trajrec`), written as a text trajectory with σ columns or an SBET, and a report.

One streamed pass over each file keeps the rays of multi-return pulses and a thinned sample of the
points (:mod:`calidar.trajrec.pulses`); the lines are then split and fitted one by one.
"""

from __future__ import annotations

import time as _time
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
from pyproj import CRS

from calidar.errors import CalidarError, InputError
from calidar.io.las import (
    PointOptions, adjusted_standard_in_week, iter_las_chunks, las_header, single_gps_week,
)
from calidar.trajectory import Trajectory
from calidar.trajrec import mounting
from calidar.trajrec.fit import FitSettings, one_blas_thread
from calidar.trajrec.lines import split_lines
from calidar.trajrec.pulses import Kept, keep_chunk
from calidar.trajrec.reconstruct import (
    MIN_DURATION_S, LineTrajectory, height_unit_m, reconstruct_line,
)
from calidar.trajrec.result import to_trajectory

CHUNK_POINTS = 1_000_000
FIELDS = ("scan_angle_deg", "point_source_id", "return_number", "number_of_returns")
FORMATS = ("text", "sbet")
#: a channel whose median σ exceeds this is "not determined"
DETERMINED = {"position_m": 1.0, "roll_rad": np.radians(0.1), "pitch_rad": np.radians(0.1),
              "heading_rad": np.radians(0.1)}


#: what every reconstruction is, whatever the data (the report shows them; the CLI prints only
#: the others)
STANDING_NOTES = (
    "positions are the scanner's origin and the attitude that of its scan plane (x along the "
    "flight, y to the right): no lever arm or boresight can be known from points alone (use a "
    "sensor.toml with both zero)",
    "roll is about the scan-angle field's zero: where a file's scan angles already include the "
    "aircraft's roll, the roll found is what is left (≈ 0)",
    "the σ columns say how well the points fix the path they were georeferenced with, not that "
    "path's navigation error, which points cannot know: for calidar boresight give the system's "
    "grade (--trajectory-sigma)",
)


@dataclass(frozen=True)
class TrajectorySettings:
    """``rate_hz``: epochs written a second; ``points_per_s``: points (and as many multi-return
    pulses) each line keeps a second for the fit; ``fit``:
    :class:`calidar.trajrec.fit.FitSettings`."""

    rate_hz: float = 50.0
    points_per_s: float = 600.0
    fit: FitSettings = field(
        default_factory=lambda: FitSettings(mount_sigma=mounting.DEFAULT_SIGMA))


@dataclass
class TrajectoryRun:
    trajectory: Trajectory
    crs: CRS  #: the points' CRS
    lines: list[LineTrajectory]
    files: list[Path]
    lines_from: str
    notes: list[str]
    counts: dict
    timings: dict


def _read(paths, options: PointOptions, settings: TrajectorySettings,
          progress) -> tuple[Kept, object, str]:
    """One streamed pass over every file: the points and rays kept, the CRS, the time system."""
    kept, crs, system = Kept(), None, None
    headers = [las_header(p) for p in paths]
    for path, h in zip(paths, headers):
        if "gps_time" not in h.point_format.dimension_names:
            raise InputError(path, "gps_time",
                             f"point format {h.point_format.id} has no GPS time; trajectory "
                             "reconstruction needs each point's GPS time (LAS point formats 1, "
                             "3–10)")
    total = sum(h.point_count for h in headers)
    for path in paths:
        for chunk in iter_las_chunks(path, CHUNK_POINTS, fields=FIELDS, options=options):
            if chunk.crs is None:
                raise InputError(path, "crs",
                                 "the file has no CRS (no WKT or GeoTIFF VLR); pass --crs")
            if crs is not None and not chunk.crs.equals(crs):
                raise InputError(path, "crs", f"{chunk.crs.name}; expected the CRS of the other "
                                 f"files ({crs.name})")
            if system is not None and chunk.time_system != system:
                raise InputError(path, "gps_time",
                                 f"{chunk.time_system}; expected {system} as the other files")
            crs, system = chunk.crs, chunk.time_system
            keep_chunk(kept, chunk, settings.points_per_s)
            if progress:
                progress("reading points", kept.n_read, total)
    return kept, crs, system


def _check(kept: Kept, paths) -> None:
    """Errors for what the method cannot work without."""
    src = paths[0] if len(paths) == 1 else None
    if kept.n_read == 0:
        raise InputError(src, "point_count",
                         "no points; the method needs the points of at least one flight line")
    if kept.n_bad_time == kept.n_read:
        raise InputError(src, "gps_time", f"all {kept.n_read} points have a GPS time ≤ 0 or none; "
                         "the method needs each point's GPS time (pulses and scan lines are found "
                         "by it)")


def _week_shift(trajectory_t: np.ndarray, system: str) -> float:
    """What turns the points' times into GPS week seconds (0 for week seconds)."""
    if system == "gps_week_seconds":
        return 0.0
    week = single_gps_week(float(trajectory_t.min()), float(trajectory_t.max()))
    return float(adjusted_standard_in_week(0.0, week))


def _fit_lines(lines, crs, options, settings, progress,
               source) -> tuple[list[LineTrajectory], list[str]]:
    done, notes, errors = [], [], []
    if not lines:
        raise InputError(source, "gps_time", "no flight line has two points with distinct GPS "
                         f"times; the method needs ≥ {MIN_DURATION_S:g} s of one line's points")
    geoid = options.geoid_undulation_m
    with one_blas_thread():
        for k, line in enumerate(lines):
            try:
                done.append(reconstruct_line(line, crs, geoid, settings.fit, settings.rate_hz,
                                             source))
            except CalidarError as e:
                errors.append(e)
                notes.append(f"line {line.label} not reconstructed: {e}")
            if progress:
                progress("fitting lines", k + 1, len(lines))
    if len(errors) == 1 and not done:
        raise errors[0]
    if not done:
        raise InputError(source, "lines", "no line could be reconstructed: "
                         + "; ".join(str(e) for e in errors))
    return done, notes


def reconstruct_trajectory(paths, options: PointOptions = PointOptions(),
                           settings: TrajectorySettings = TrajectorySettings(),
                           progress: Callable[[str, int, int], None] | None = None,
                           ) -> TrajectoryRun:
    """Every flight line's trajectory from the points of ``paths`` (LAS/LAZ), as one Trajectory in
    GPS week seconds with σ columns; see the module docstring."""
    paths = [Path(p) for p in paths]
    t0 = _time.perf_counter()
    kept, crs, system = _read(paths, options, settings, progress)
    _check(kept, paths)
    t1 = _time.perf_counter()
    lines, how = split_lines(kept.arrays())
    source = paths[0] if len(paths) == 1 else None
    done, notes = _fit_lines(lines, crs, options, settings, progress, source)
    t2 = _time.perf_counter()
    shift = _week_shift(np.concatenate([ln.time for ln in done]), system)
    traj = to_trajectory(done, shift, "gps_week_seconds", source=str(paths[0]))
    notes = _notes(kept, done, system) + notes
    if height_unit_m(crs) != 1.0:
        notes.append(f"the CRS {crs.name} is 2-D in {crs.axis_info[0].unit_name}s: the heights "
                     "were taken in that unit too")
    counts = {"points_read": kept.n_read, "bad_times": kept.n_bad_time,
              "multi_return_points": kept.n_multi,
              "pulses_repeating_return_numbers": kept.return_numbers_repeated, "lines": len(done)}
    timings = {"read_s": t1 - t0, "fit_s": t2 - t1}
    return TrajectoryRun(traj, crs, done, paths, how, notes, counts, timings)


def _notes(kept: Kept, done: list[LineTrajectory], system: str) -> list[str]:
    """What the run could and could not determine, in words."""
    notes = list(STANDING_NOTES)
    if system != "gps_week_seconds":
        notes.append("the points' adjusted standard GPS times were converted to GPS week seconds")
    if kept.n_bad_time:
        notes.append(f"{kept.n_bad_time} points with a GPS time ≤ 0 or none were left out")
    if kept.return_numbers_repeated:
        notes.append(f"{kept.return_numbers_repeated} pulses repeat a return number; their rays "
                     "were taken from the highest and lowest point instead")
    for ln in done:
        notes += _line_notes(ln)
    return notes


def _weak_channels(ln: LineTrajectory) -> list[str]:
    """The channels of a line whose median σ exceeds :data:`DETERMINED` (the attitude limits
    widened by twice its largest mounting prior σ, rad)."""
    med = np.median(ln.sigma, axis=0)
    # an attitude σ at its mounting priors' level is what the priors say, not the points' weakness
    mount_sigmas = [v[2] for k, v in ln.info.get("mount", {}).items() if k != "scan_scale"]
    prior = 2 * max(mount_sigmas, default=0.0)
    limits = (("position", med[:3].max(), DETERMINED["position_m"]),
              ("roll", med[3], np.hypot(DETERMINED["roll_rad"], prior)),
              ("pitch", med[4], np.hypot(DETERMINED["pitch_rad"], prior)),
              ("heading", med[5], np.hypot(DETERMINED["heading_rad"], prior)))
    return [name for name, s, lim in limits if s > lim]


def _line_notes(ln: LineTrajectory) -> list[str]:
    """What one line's points could and could not determine, in words."""
    notes = []
    weak = _weak_channels(ln)
    if not ln.info["scan_angles"] and not ln.info.get("planar", True):
        notes.append(f"line {ln.label}: without scan angles and scan-plane geometry the rays give "
                     "the position only: roll and pitch are their priors' (0) and heading the scan "
                     "lines' trace on the ground")
    elif not ln.info["scan_angles"]:
        notes.append(f"line {ln.label}: the scan-angle field is missing or too coarse: roll is not "
                     "determined (held near 0 by its prior) and the position rests on the "
                     "multi-return rays alone")
    if ln.info.get("mount"):
        notes.append(f"line {ln.label}: the scanner's calibration (encoder, scan plane): "
                     + "; ".join(mounting.notes(ln.info["mount"])))
    if weak:
        notes.append(f"line {ln.label}: not determined by its points: {', '.join(weak)} (median σ "
                     "above 1 m / 0.1°); see the σ columns")
    misfit = ln.info["scales"].get("along", 0.0)
    if misfit > np.radians(0.2):
        notes.append(f"line {ln.label}: the points do not lie in planar scan lines (misfit "
                     f"{np.degrees(misfit):.2f}°: a conical or other non-planar scanner?): "
                     "pitch and heading are doubtful")
    return notes


def output_format(out: Path, fmt: str | None) -> str:
    """``fmt`` when given (checked), else sbet for an ``.out``/``.sbet`` name and text otherwise."""
    if fmt is None:
        return "sbet" if out.suffix.lower() in (".out", ".sbet") else "text"
    if fmt not in FORMATS:
        raise InputError(None, "--format", f"expected {' or '.join(FORMATS)}, got {fmt!r}")
    return fmt


def sensor_for(run: TrajectoryRun):
    """The sensor a reconstructed trajectory goes with: a linear scanner at the trajectory's
    point with zero mounting (the trajectory is the scanner's origin and scan-plane attitude), the
    points' CRS."""
    from calidar.sensor import Sensor

    epsg = run.crs.to_epsg()
    return Sensor(crs=f"EPSG:{epsg}" if epsg else run.crs.to_wkt())


def compare_with(run: TrajectoryRun, known: Path) -> dict:
    """Errors of the reconstruction against a known trajectory file (SBET, text or CSD) at its
    own point (:func:`calidar.trajrec.result.error_summary`); an error when their times do not
    overlap."""
    from calidar.io.trajectory import read_trajectory
    from calidar.trajrec.result import compare, error_summary

    truth = read_trajectory(known)
    c = compare(run.trajectory, truth)
    if c["time"].size == 0:
        t = run.trajectory.time
        raise InputError(known, "time", f"{truth.time[0]:.3f}–{truth.time[-1]:.3f} s; expected to "
                         f"overlap the reconstruction's {t[0]:.3f}–{t[-1]:.3f} s "
                         "(GPS week seconds)")
    return error_summary(c)


def write_outputs(run: TrajectoryRun, out: Path, fmt: str, report: Path | None,
                  commands: list[str], force: bool = False, sensor_out: Path | None = None,
                  comparison: dict | None = None) -> tuple[Path, Path]:
    """The trajectory (text with σ columns, or SBET), the report (default: report.html beside
    it) and, when ``sensor_out`` is given, the sensor.toml that goes with the trajectory
    (:func:`sensor_for`)."""
    from calidar.io.sbet import write_sbet
    from calidar.io.trajectory_text import write_trajectory_text
    from calidar.trajrec.report import trajectory_report

    out = Path(out)
    report = Path(report) if report is not None else out.parent / "report.html"
    trajectory_report(run, commands, comparison).write(report, force)
    if sensor_out is not None:
        sensor_for(run).write(sensor_out, force=force)
    if fmt == "sbet":
        write_sbet(out, run.trajectory, force=force)
    else:
        write_trajectory_text(out, run.trajectory, force=force)
    return out, report
