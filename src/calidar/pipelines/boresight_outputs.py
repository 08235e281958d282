"""The deliverables of a strip calibration, made so that they reproduce the report.

The overlap quality is measured on the WHOLE strips (streamed again from the files,
:func:`calidar.ingest.measure.measure_lines`) re-georeferenced in the files' CRS with the
plan, point selection and swath accumulator ``calidar quality`` uses
(:mod:`calidar.ingest.stages`), three times: as delivered, with the new mounting
alone (``calidar regeoref --to sensor.toml``), and with the new mounting and the corrected
trajectory (``--to-trajectory sbet_corrected.out``). Each stage names the commands that
reproduce it from the written files.
"""

from __future__ import annotations

import json
import shlex
from pathlib import Path

import numpy as np

from calidar.outputs import shown_path
from calidar.pipelines import Progress, no_progress

def corrected_trajectory(inputs, result):
    """The trajectory with the estimated corrections applied (None when none were estimated)."""
    from calidar.strips.trajectory_errors import corrected_trajectory as apply

    if not result.corrections:
        return None
    frame = inputs.strips[0].frame
    return apply(inputs.trajectory, result.corrections, inputs.spans, frame)


def _files(paths) -> str:
    """The input strips as a shell argument list (a glob when it names exactly them)."""
    paths = [Path(p) for p in paths]
    parents, suffixes = {p.parent for p in paths}, {p.suffix for p in paths}
    if len(paths) > 3 and len(parents) == 1 and len(suffixes) == 1:
        parent, suffix = parents.pop(), suffixes.pop()
        if sorted(parent.glob(f"*{suffix}")) == sorted(paths):
            return f"{shlex.quote(str(parent))}/*{suffix}"
    return " ".join(shlex.quote(str(p)) for p in paths)


def stage_commands(inputs, shown_out: Path, tag: str,
                   with_trajectory: bool) -> tuple[str, str, str]:
    """The commands that reproduce the three quality stages from the written files."""
    from calidar.pipelines.inputs import option_args

    q = lambda p: shlex.quote(str(p))  # noqa: E731
    strips = _files(inputs.strip_paths)
    given = option_args(inputs.config.points)
    regeo_given = option_args(inputs.config.points, inputs.config.trajectory_input)
    sensor_out = q(shown_out / f"sensor{tag}.toml")
    sbet_out = q(shown_out / f"sbet_corrected{tag}.out")
    regeo = (f"calidar regeoref {strips} --trajectory {q(inputs.trajectory_path)} "
             f"--from {q(inputs.sensor_path)} --to {sensor_out}{regeo_given}")
    traj = f" --to-trajectory {sbet_out}" if with_trajectory else ""
    return (f"calidar quality {strips}{given}",
            f"{regeo} --out MOUNTING && calidar quality MOUNTING/*",
            f"{regeo}{traj} --out CORRECTED && calidar quality CORRECTED/*")


def quality_stages(inputs, result, corrected, progress: Progress = no_progress, work=None) -> list:
    """Overlap quality as delivered, with the new mounting, and (when trajectory corrections were
    estimated) with the new mounting and the corrected trajectory:
    calidar.strips.report.QualityStage s (their commands named when written:
    :func:`with_commands`)."""
    from calidar.ingest.measure import measure_lines
    from calidar.strips.quality import QualitySettings
    from calidar.strips.report import QualityStage

    labels = ["as delivered", "new mounting"]
    models = [None, (result.sensor, inputs.trajectory)]
    if corrected is not None:
        labels.append("new mounting + trajectory corrections")
        models.append((result.sensor, corrected))
    progress("overlap quality", 0, 1)
    # one read of the files, every stage; the swath difference as ``calidar quality`` measures it
    # by default
    measured = measure_lines(inputs.source, inputs.nominal, models, progress, work,
                             QualitySettings())
    progress("overlap quality", 1, 1)
    return [QualityStage(label, "", pairs) for label, pairs in zip(labels, measured)]


def with_commands(inputs, stages: list, folder: Path, tag: str) -> list:
    """The quality stages with the commands that reproduce them from the files written in
    ``folder``."""
    from dataclasses import replace

    commands = stage_commands(inputs, Path(shown_path(str(folder))), tag, len(stages) > 2)
    return [replace(st, command=c) for st, c in zip(stages, commands)]


def calibrated_sensor(result, solution_name: str, method: str = ""):
    """The calibrated sensor with its ``[calibration]`` record: today's date (UTC), calidar's
    version, the solution file it came from and the σ of every estimated sensor value, keyed as
    sensor.toml writes values (``boresight_roll_deg``, ``lever_arm_x_m``, ...; docs/sensor.md)."""
    from dataclasses import replace
    from datetime import datetime, timezone

    from calidar import __version__
    from calidar.sensor import CalibrationRecord

    solution = result.solution
    sigma = solution.sigma
    prefix = solution.nuisance_prefix
    values = {}
    for p in solution.parameters.free:
        nuisance = prefix and p.name.startswith(prefix)
        if nuisance or p.name not in sigma or not np.isfinite(sigma[p.name]):
            continue
        key = p.name if p.display_unit == "1" else f"{p.name}_{p.display_unit}"
        values[key] = p.to_display(sigma[p.name])
    date = datetime.now(timezone.utc).replace(microsecond=0).isoformat()
    record = CalibrationRecord(date, __version__, solution_name, method or result.method, values)
    return replace(result.sensor, calibration=record)


def write_run(run, out_dir: Path, report=None, verdict_title: str | None = None,
              section_title: str | None = None, write_strips: bool = False) -> list[Path]:
    """Write a :class:`calidar.pipelines.boresight.StripCalibration` into ``out_dir``: per matcher
    :func:`write_outputs` (a ``_<name>`` suffix with several), config.toml and report.html — or,
    given a ``report``, its verdicts and sections added there (``verdict_title``,
    ``section_title``: what to call them); ``write_strips``: the recalibrated strips too (in
    out_dir/<name>/ with several)."""
    from calidar.report import Report
    from calidar.strips.report import add_comparison_section, add_report_section

    inputs, results, several = run.inputs, run.results, len(run.results) > 1
    out_dir, own = Path(out_dir), report is None
    report = Report("calidar boresight") if own else report
    stages = {m: with_commands(inputs, run.quality[m], out_dir, f"_{m}" if several else "")
              for m in results}
    for m, result in results.items():
        label = m if several else None
        verdict_label = " ".join(x for x in (verdict_title, label) if x) or None
        report.add_verdict(run.verdicts[m], verdict_label)
        title = section_title and (f"{section_title} ({m})" if label else section_title)
        add_report_section(report, result, inputs.truth, stages[m],
                           accuracy=accuracy_used(inputs, result),
                           map_pair=map_pair(inputs, stages[m]), title=title,
                           classes=inputs.config.ingest.classes_text())
    if several:
        add_comparison_section(report, results, inputs.truth)
    written = []
    for m, result in results.items():
        tag = f"_{m}" if several else ""
        strips_dir = (out_dir / m if tag else out_dir) if write_strips else None
        written += write_outputs(inputs, result, run.corrected[m], run.verdicts[m], run.record,
                                 stages[m], out_dir, tag, strips_dir)
    written.append(inputs.config.write(out_dir / "config.toml"))
    if own:
        report.record = run.record
        written.append(report.write(out_dir / "report.html"))
    return written


def write_outputs(inputs, result, corrected, verdict, record, stages, out_dir: Path, tag: str,
                  strips_dir: Path | None) -> list[Path]:
    """solution{tag}.json, sensor{tag}.toml, sbet_corrected{tag}.out (with corrections) and, with
    ``strips_dir``, the recalibrated strips (new mounting and corrected trajectory)."""
    from calidar.io.sbet import write_sbet
    from calidar.outputs import write_text_atomic

    out_dir = Path(out_dir)
    document = solution_document(result, inputs.truth, verdict, record,
                                 accuracy_used(inputs, result), stages)
    sensor = calibrated_sensor(result, f"solution{tag}.json")
    written = [write_text_atomic(out_dir / f"solution{tag}.json", document),
               sensor.write(out_dir / f"sensor{tag}.toml", force=True)]
    # SBETs hold week seconds
    if corrected is not None and corrected.time_system == "gps_week_seconds":
        written.append(write_sbet(out_dir / f"sbet_corrected{tag}.out", corrected, force=True))
    if strips_dir is not None:
        trajectory = corrected or inputs.trajectory
        written += write_strips(inputs, result.sensor, trajectory, Path(strips_dir))
    return written


def write_strips(inputs, sensor, trajectory, out_dir: Path) -> list[Path]:
    """Recalibrated strips as LAZ (``strip_<id>.laz``, one per flight line), attributes and GPS
    times as read; streamed chunk by chunk into one writer per line."""
    from contextlib import ExitStack

    from calidar.io.las import LasChunkWriter
    from calidar.ingest.strips import bounds
    from calidar.ingest.source import line_chunks

    out_dir.mkdir(parents=True, exist_ok=True)
    offsets = np.floor(bounds(inputs.source.files)[0])
    writers = {}
    with ExitStack() as stack:
        for sid, (las,) in line_chunks(inputs.source, inputs.nominal, [(sensor, trajectory)]):
            if sid not in writers:
                crs = las.crs if las.crs is not None else inputs.crs
                writer = LasChunkWriter(out_dir / f"strip_{sid}.laz", crs, offsets,
                                        las.time_system, force=True)
                writers[sid] = stack.enter_context(writer)
            scan = las.scan_angle_deg if las.scan_angle_deg is not None else np.zeros(len(las))
            writers[sid].write(las.xyz, gps_time=las.gps_time, point_source_id=sid,
                               return_number=las.return_number, scan_angle_deg=scan,
                               number_of_returns=las.number_of_returns,
                               classification=las.classification, intensity=las.intensity)
    return [out_dir / f"strip_{sid}.laz" for sid in sorted(writers)]


def map_pair(inputs, stages) -> tuple[int, int] | None:
    """The pair whose dz maps the report shows: of the lines flown side by side (parallel or
    opposite), the pair with the most smooth overlapping cells (any pair when none is)."""
    from calidar.strips.geometry import pair_kind

    ids = {s.id for s in inputs.strips}  # the lines calibrated (those overlapping another)
    pairs = [q for q in (stages[0].pairs if stages else []) if q.a in ids and q.b in ids]
    if not pairs:
        return None
    kind = pair_kind(inputs.strips, [(q.a, q.b) for q in pairs])
    side = [q for q in pairs if kind[q.a, q.b] != "cross"] or pairs
    best = max(side, key=lambda q: q.n_cells)
    return best.a, best.b


def accuracy_used(inputs, result):
    """The trajectory accuracy a calibration's priors came from: the inputs' (file, option, σ
    columns), or the level estimated from the overlaps; None with the trajectory model off."""
    model = result.trajectory_model
    return inputs.accuracy if model is None or model.accuracy is None else model.accuracy


def solution_document(result, truth, verdict, record, accuracy, stages=()) -> str:
    """solution.json: the solution (display units), the verdict, the overlap quality stages (each
    with the commands that reproduce it), the trajectory accuracy used and the run."""
    doc = result.solution.to_dict(truth)
    doc["verdict"] = verdict.to_dict()
    doc["overlap_quality"] = [{"stage": st.label, "reproduce": st.command,
                               "pairs": [q.to_dict() for q in st.pairs]} for st in stages]
    doc["trajectory_accuracy"] = None if accuracy is None else accuracy.to_dict()
    doc["run"] = record.to_dict()
    # destinations, not temporary folders
    return shown_path(json.dumps(doc, indent=2, allow_nan=False) + "\n")
