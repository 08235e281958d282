"""The deliverables of a strip calibration, made so that they reproduce the report.

The overlap quality is measured on the WHOLE strips re-georeferenced in the files' CRS with
exactly the code ``calidar quality`` runs (:func:`calidar.pipelines.quality.lines_quality`: the
same point selection and swath accumulator), three times: as delivered, with the new mounting
alone (``calidar regeoref --to sensor.toml``), and with the new mounting and the corrected
trajectory (``--to-trajectory sbet_corrected.out``). Each stage names the commands that
reproduce it from the written files.
"""

from __future__ import annotations

import json
import shlex
from dataclasses import replace
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


def regeoreferenced_lines(inputs, sensor, trajectory):
    """Per flight line (id, LasPoints): the delivered points re-georeferenced with ``sensor`` and
    ``trajectory`` (inverse with the nominal sensor and the input trajectory, as
    :func:`calidar.georef.regeoreference`), in the files' CRS, every other attribute as read."""
    from calidar import georef

    for s in inputs.strips:
        ecef = georef.forward(trajectory, sensor, s.obs.time, s.obs.range_m, s.obs.angles)
        las = s.extra["las"]
        crs = las.crs if las.crs is not None else inputs.crs
        yield s.id, replace(las, xyz=georef.to_crs(ecef, crs, las.geoid_undulation_m, source=las.path))


def measure_lines(lines) -> list:
    """The :class:`calidar.strips.quality.PairQuality` of every overlapping pair of (id, LasPoints)."""
    from calidar.pipelines.quality import lines_quality

    return lines_quality(lines)[0]


def _files(paths) -> str:
    """The input strips as a shell argument list (a glob when it names exactly them)."""
    paths = [Path(p) for p in paths]
    parents, suffixes = {p.parent for p in paths}, {p.suffix for p in paths}
    if len(paths) > 3 and len(parents) == 1 and len(suffixes) == 1:
        parent, suffix = parents.pop(), suffixes.pop()
        if sorted(parent.glob(f"*{suffix}")) == sorted(paths):
            return f"{shlex.quote(str(parent))}/*{suffix}"
    return " ".join(shlex.quote(str(p)) for p in paths)


def stage_commands(inputs, shown_out: Path, tag: str, with_trajectory: bool) -> tuple[str, str, str]:
    """The commands that reproduce the three quality stages from the written files."""
    from calidar.pipelines.inputs import option_args

    q = lambda p: shlex.quote(str(p))  # noqa: E731
    strips = _files(inputs.strip_paths)
    given = option_args(inputs.options.points)
    regeo = (f"calidar regeoref {strips} --trajectory {q(inputs.trajectory_path)} --from {q(inputs.sensor_path)} "
             f"--to {q(shown_out / f'sensor{tag}.toml')}{option_args(inputs.options.points, inputs.options.trajectory_input)}")
    traj = f" --to-trajectory {q(shown_out / f'sbet_corrected{tag}.out')}" if with_trajectory else ""
    return (f"calidar quality {strips}{given}",
            f"{regeo} --out MOUNTING && calidar quality MOUNTING/*",
            f"{regeo}{traj} --out CORRECTED && calidar quality CORRECTED/*")


def quality_stages(inputs, result, corrected, shown_out: Path, tag: str = "", progress: Progress = no_progress) -> list:
    """Overlap quality as delivered, with the new mounting, and (when trajectory corrections were
    estimated) with the new mounting and the corrected trajectory: calidar.strips.report.QualityStage s."""
    from calidar.strips.report import QualityStage

    before, mounting, both = stage_commands(inputs, Path(shown_out), tag, corrected is not None)
    total = 3 if corrected is not None else 2
    progress("overlap quality", 0, total)
    stages = [QualityStage("as delivered", before, measure_lines((s.id, s.extra["las"]) for s in inputs.strips))]
    progress("overlap quality", 1, total)
    stages.append(QualityStage("new mounting", mounting,
                               measure_lines(regeoreferenced_lines(inputs, result.sensor, inputs.trajectory))))
    progress("overlap quality", 2, total)
    if corrected is not None:
        stages.append(QualityStage("new mounting + trajectory corrections", both,
                                   measure_lines(regeoreferenced_lines(inputs, result.sensor, corrected))))
        progress("overlap quality", 3, total)
    return stages


def write_outputs(inputs, result, corrected, verdict, record, stages, out_dir: Path, tag: str,
                  strips_dir: Path | None) -> list[Path]:
    """solution{tag}.json, sensor{tag}.toml, sbet_corrected{tag}.out (with corrections) and, with
    ``strips_dir``, the recalibrated strips (new mounting and corrected trajectory)."""
    from calidar.io.sbet import write_sbet
    from calidar.outputs import write_text_atomic

    out_dir = Path(out_dir)
    written = [write_text_atomic(out_dir / f"solution{tag}.json",
                                 solution_document(result, inputs.truth, verdict, record, inputs.accuracy, stages)),
               result.sensor.write(out_dir / f"sensor{tag}.toml", force=True)]
    if corrected is not None and corrected.time_system == "gps_week_seconds":  # SBETs hold week seconds
        written.append(write_sbet(out_dir / f"sbet_corrected{tag}.out", corrected, force=True))
    if strips_dir is not None:
        written += write_strips(inputs, result.sensor, corrected or inputs.trajectory, Path(strips_dir))
    return written


def write_strips(inputs, sensor, trajectory, out_dir: Path) -> list[Path]:
    """Recalibrated strips as LAZ (``strip_<id>.laz``, one per flight line), attributes and GPS times as read."""
    from calidar.io.las import write_las

    out_dir.mkdir(parents=True, exist_ok=True)
    paths = []
    for sid, las in regeoreferenced_lines(inputs, sensor, trajectory):
        paths.append(write_las(out_dir / f"strip_{sid}.laz", las.xyz, las.crs if las.crs is not None else inputs.crs,
                               gps_time=las.gps_time, point_source_id=sid, return_number=las.return_number,
                               scan_angle_deg=las.scan_angle_deg if las.scan_angle_deg is not None else np.zeros(len(las)),
                               number_of_returns=las.number_of_returns, classification=las.classification,
                               intensity=las.intensity, time_system=las.time_system, force=True))
    return paths


def map_pair(inputs, stages) -> tuple[int, int] | None:
    """The pair whose dz maps the report shows: of the lines flown side by side (parallel or
    opposite), the pair with the most smooth overlapping cells (any pair when none is)."""
    from calidar.strips.geometry import pair_kind

    pairs = stages[0].pairs if stages else []
    if not pairs:
        return None
    kind = pair_kind(inputs.strips, [(q.a, q.b) for q in pairs])
    side = [q for q in pairs if kind[q.a, q.b] != "cross"] or pairs
    best = max(side, key=lambda q: q.n_cells)
    return best.a, best.b


def solution_document(result, truth, verdict, record, accuracy, stages=()) -> str:
    """solution.json: the solution (display units), the verdict, the overlap quality stages (each
    with the commands that reproduce it), the trajectory accuracy used and the run."""
    doc = result.solution.to_dict(truth)
    doc["verdict"] = verdict.to_dict()
    doc["overlap_quality"] = [{"stage": st.label, "reproduce": st.command, "pairs": [q.to_dict() for q in st.pairs]}
                              for st in stages]
    doc["trajectory_accuracy"] = None if accuracy is None else accuracy.to_dict()
    doc["run"] = record.to_dict()
    return shown_path(json.dumps(doc, indent=2, allow_nan=False) + "\n")  # destinations, not temporary folders
