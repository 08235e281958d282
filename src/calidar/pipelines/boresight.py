"""Strip calibration from files: :func:`calibrate_strips` (``calidar.calibrate_strips``, what
``calidar boresight``, its demo step and the benchmarks run).

:func:`load_inputs` reads the strips, the trajectory, the nominal sensor and the trajectory's
accuracy (a file, σ columns, an smrmsg beside an SBET, else a documented default whose level
is estimated); :func:`calibrate_inputs` runs one calibration per matcher of the configuration;
:func:`calibrate_strips` adds the overlap quality before and after
(:func:`calidar.pipelines.boresight_outputs.quality_stages`, the code ``calidar quality`` runs)
and the verdicts; :meth:`StripCalibration.write` writes ``solution.json``, ``sensor.toml``,
``sbet_corrected.out`` (when trajectory corrections were estimated), ``config.toml`` and
``report.html`` (:func:`calidar.pipelines.boresight_outputs.write_run`).
"""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np

from calidar.errors import InputError
from calidar.pipelines import Progress, no_progress
from calidar.pipelines.strip_config import StripConfig

if TYPE_CHECKING:
    import pyproj

    from calidar.ingest.settings import IngestSettings
    from calidar.ingest.source import StripSource
    from calidar.provenance import RunRecord
    from calidar.sensor import Sensor
    from calidar.strips.calibrate import CalibrationResult
    from calidar.strips.control import ControlPoints
    from calidar.strips.report import QualityStage
    from calidar.strips.strip import Strip
    from calidar.trajectory import Trajectory
    from calidar.trajectory_accuracy import TrajectoryAccuracy
    from calidar.verdict import Verdict


@dataclass
class BoresightInputs:
    """Everything a calibration reads, loaded and checked."""

    strip_paths: list[Path]
    trajectory_path: Path
    sensor_path: Path
    nominal: Sensor
    trajectory: Trajectory
    strips: list[Strip]  #: one per overlapping flight line (its kept overlap points)
    crs: pyproj.CRS | None
    config: StripConfig
    source: StripSource | None = None  #: the whole lines, streamed again for the outputs
    accuracy: TrajectoryAccuracy | None = None  #: None: the trajectory model off
    accuracy_path: Path | None = None
    #: what the user should know (e.g. a default assumed)
    notes: list[str] = field(default_factory=list)
    #: no accuracy stated: the trajectory priors' level is estimated from the overlaps
    #: (calidar.strips.trajectory_level), ``accuracy`` (the survey-grade default) its start
    estimate_accuracy: bool = False
    truth: dict | None = None  #: truth.json parameters, SI (simulations)
    control: ControlPoints | None = None  #: ground control in the strips' frame
    control_path: Path | None = None
    #: checkpoints in the strips' frame (tested after, not in the adjustment)
    checkpoints: ControlPoints | None = None
    checkpoints_path: Path | None = None

    @property
    def spans(self) -> dict[int, tuple[float, float]]:
        return {s.id: s.time_span for s in self.strips}

    @property
    def paths(self) -> list[Path]:
        """Every input file."""
        return [*self.strip_paths, self.trajectory_path, self.sensor_path,
                *([self.accuracy_path] if self.accuracy_path else []),
                *(p for p in (self.control_path, self.checkpoints_path) if p is not None)]


def load_strips(paths, trajectory, sensor, settings: IngestSettings | None = None,
                progress: Progress = no_progress):
    """Flight lines of the LAS/LAZ files as Strips in one local frame (times in the trajectory's
    system), streamed and thinned to their overlaps: (strips, CRS)."""
    from calidar.ingest.settings import IngestSettings
    from calidar.ingest.strips import StripIngest

    ingest = StripIngest(settings or IngestSettings())
    got = ingest.read(list(paths), trajectory, sensor, progress=progress)
    return got.strips, got.crs


def resolve_accuracy(trajectory_path: Path, trajectory, accuracy_path: Path | None = None,
                     sigma: tuple[float, float] | None = None):
    """The trajectory's accuracy and where it came from: (TrajectoryAccuracy, file or None, note
    or None). In order: ``accuracy_path`` (an smrmsg), ``sigma`` (position m, attitude rad, for
    every epoch), σ columns of a text trajectory, an smrmsg*.out beside an sbet*.out, else the
    survey-grade default (with a note), whose level the calibration then estimates from the
    overlaps."""
    from calidar.io.smrmsg import find_beside, read_smrmsg
    from calidar.io.trajectory_text import SIGMA_COLUMNS
    from calidar.trajectory_accuracy import SURVEY_GRADE, TrajectoryAccuracy

    if accuracy_path is not None and sigma is not None:
        raise InputError(None, "--trajectory-sigma",
                         "give either --trajectory-accuracy FILE or --trajectory-sigma, not both")
    if accuracy_path is not None:
        return read_smrmsg(accuracy_path), Path(accuracy_path), None
    if sigma is not None:
        return TrajectoryAccuracy.uniform(*sigma, "--trajectory-sigma"), None, None
    if all(c in trajectory.extra for c in SIGMA_COLUMNS):
        pos, att = (np.stack([trajectory.extra[c] for c in cols], axis=1)
                    for cols in (SIGMA_COLUMNS[:3], SIGMA_COLUMNS[3:]))
        source = f"{trajectory_path} (σ columns)"
        return TrajectoryAccuracy(trajectory.time, pos, att, None, source), None, None
    beside = find_beside(trajectory_path)
    if beside is not None:
        return read_smrmsg(beside), beside, None
    looked = f"no smrmsg*.out beside {trajectory_path.name}, no σ columns"
    default = SURVEY_GRADE.describe().split(" (")[0]
    return SURVEY_GRADE, None, (
        f"no trajectory accuracy found ({looked}, no --trajectory-accuracy): its level is "
        f"estimated from the overlaps, starting from a survey-grade GNSS/INS — {default} — "
        "which stays where the data cannot tell")


#: the trajectory model off, yet its accuracy given (as a file or a σ)
OFF_WITH_ACCURACY = ("is off, so --trajectory-accuracy and --trajectory-sigma have nothing to do; "
                     "expected the trajectory model on (the default) or neither option")
#: the trajectory model off: what the σ then miss
OFF_NOTE = ("trajectory model off (--trajectory-model off): the trajectory is taken as exact, so "
            "the σ miss its errors (ordinary GNSS/INS noise made them 2× too small on simulated "
            "surveys)")


def _trajectory_accuracy(trajectory_path: Path, traj, config: StripConfig,
                         accuracy_path: Path | None):
    """(accuracy, its file, notes) as the configuration's trajectory model asks."""
    settings = config.calibration.trajectory
    if settings is None:
        if accuracy_path is not None:
            raise InputError(None, "--trajectory-model", OFF_WITH_ACCURACY)
        return None, None, [OFF_NOTE]
    accuracy, path, note = resolve_accuracy(trajectory_path, traj, accuracy_path, settings.sigma)
    return accuracy, path, [note] if note else []


def load_inputs(strip_paths, trajectory_path, sensor_path, config: StripConfig = StripConfig(), *,
                accuracy: Path | None = None, control: Path | None = None,
                checkpoints: Path | None = None, truth: Path | None = None,
                progress: Progress = no_progress, work=None) -> BoresightInputs:
    """Read and check every input (the trajectory's accuracy must cover every strip); ``work``:
    where the files are read (a :class:`calidar.strips.distribute.Workers`; None: one at a time
    here);
    ``checkpoints``: tested against the calibrated strips, not in the adjustment."""
    from calidar.ingest.strips import StripIngest
    from calidar.pipelines.control import checked_checkpoints, control_points, read_ground
    from calidar.pipelines.inputs import load_trajectory
    from calidar.sensor import Sensor
    from calidar.strips.control import check_estimate

    check_estimate(config.calibration.estimate, control)
    trajectory_path, sensor_path = Path(trajectory_path), Path(sensor_path)
    nominal = Sensor.read(sensor_path)
    traj = load_trajectory(trajectory_path, config.trajectory_input)
    acc, accuracy_path, notes = _trajectory_accuracy(trajectory_path, traj, config, accuracy)
    ground = read_ground(control, checkpoints, config, strip_paths, nominal)
    notes += [] if ground.control is None else list(ground.control.notes)
    progress("reading strips", 0, 1)
    ingest = StripIngest(config.ingest)
    strips, crs, source, unpaired = ingest.read(list(strip_paths), traj, nominal, ground.near,
                                                progress, work)
    inputs = BoresightInputs([Path(p) for p in strip_paths], trajectory_path, sensor_path, nominal,
                             traj, strips, crs, config, source, acc, accuracy_path,
                             notes + unpaired,
                             control_path=None if control is None else Path(control),
                             checkpoints_path=None if checkpoints is None else Path(checkpoints))
    frame = strips[0].frame
    if ground.control is not None:
        inputs.control = control_points(ground.control, frame)
    inputs.checkpoints, inputs.notes = checked_checkpoints(ground.checkpoints, frame, inputs.notes)
    if acc is not None:
        acc.check_covers(inputs.spans)
        inputs.estimate_accuracy = estimates_accuracy(acc)
    if truth is not None:
        inputs.truth = read_truth(truth, nominal, config)
    return inputs


def _start_pair_workers(paths, config: StripConfig, work) -> None:
    """A matcher that holds the GIL (VGICP) matches its pairs in worker processes: their forkserver
    is started now, to import what they need while the strips are read
    (:func:`calidar.strips.processes.start_server`, by the files' point counts)."""
    from calidar.errors import CalidarError
    from calidar.io.las import las_header
    from calidar.strips.processes import start_server

    if work.client is not None or not any(m.holds_gil for m in config.calibration.matchers):
        return
    try:
        points = sum(int(las_header(p).point_count) for p in paths)
    except (CalidarError, OSError):  # the ingest reports it, naming the file
        return
    start_server(points)


def estimates_accuracy(accuracy) -> bool:
    """Whether the calibration estimates the trajectory's accuracy level from the overlaps: when
    no source stated it (``accuracy`` is the survey-grade default :func:`resolve_accuracy` fell
    back on)."""
    from calidar.trajectory_accuracy import SURVEY_GRADE

    return accuracy is SURVEY_GRADE


def read_truth(path: Path, nominal: Sensor, config: StripConfig) -> dict[str, float]:
    """A simulation's truth.json: the estimated parameters' true values, SI."""
    from calidar.strips.parameters import build_parameters, truth_to_si
    from calidar.validate import read_json

    estimated = build_parameters(nominal, config.calibration.estimate, {})
    truth = truth_to_si(read_json(path), estimated)
    if not truth:
        raise InputError(path, "parameters", "none of the estimated parameters found; expected the "
                         "truth.json of `calidar simulate survey`")
    return truth


def calibrate_inputs(inputs: BoresightInputs, progress: Progress = no_progress, work=None) -> dict:
    """One :class:`calidar.strips.calibrate.CalibrationResult` per matcher of the configuration, by
    name; the pairs matched by ``work`` (a :class:`calidar.strips.distribute.Workers`; None: this
    process)."""
    from calidar.strips.calibrate import calibrate_with_client
    from calidar.strips.distribute import Workers

    config = inputs.config.calibration
    settings = config.trajectory
    model = None if settings is None else settings.model(inputs.accuracy, inputs.estimate_accuracy)
    work = work or Workers()
    results = {}
    for matcher in config.matchers:
        m = matcher.name
        results[m] = calibrate_with_client(
            inputs.strips, inputs.nominal, config, matcher=matcher, trajectory=model,
            client=work.client, log=work.log, control=inputs.control,
            progress=lambda text, done, total, m=m: progress(f"calibrating ({m})", done, total))
        results[m].solution.warnings[:0] = inputs.notes
    return results


@dataclass
class StripCalibration:
    """A strip calibration: per matcher its result, overlap quality and verdict
    (:func:`calibrate_strips`)."""

    inputs: BoresightInputs
    results: dict[str, CalibrationResult]  #: matcher name → the calibration
    #: matcher name → the overlap quality as delivered and after
    quality: dict[str, list[QualityStage]]
    verdicts: dict[str, Verdict]
    #: matcher name → the corrected trajectory (None: no corrections)
    corrected: dict[str, Trajectory | None]
    record: RunRecord
    written: list[Path] = field(default_factory=list)  #: the files :meth:`write` wrote

    @property
    def sensor(self) -> Sensor:
        """The calibrated sensor (of the first matcher) with its calibration record: date, calidar's
        version, the solution file and the σ of every estimated value."""
        from calidar.pipelines.boresight_outputs import calibrated_sensor

        m, result = next(iter(self.results.items()))
        name = "solution.json" if len(self.results) == 1 else f"solution_{m}.json"
        return calibrated_sensor(result, name)

    def write(self, folder: Path, strips: bool = False) -> list[Path]:
        """Write the results into ``folder`` (solution.json, sensor.toml, sbet_corrected.out,
        config.toml, report.html; with several matchers, each file once per matcher:
        solution_planes.json, ...); ``strips``: the recalibrated strips too. Returns the files
        written."""
        from calidar.pipelines.boresight_outputs import write_run

        self.written = write_run(self, Path(folder), write_strips=strips)
        return self.written

    def __repr__(self) -> str:
        from calidar.strips.trajectory_errors import PREFIX as TRAJECTORY_PREFIX

        lines = []
        for m, result in self.results.items():
            sol = result.solution
            n_traj = sum(1 for p in sol.parameters.free if p.name.startswith(TRAJECTORY_PREFIX))
            counts = f"{len(result.strips)} strips, {len(result.pairs)} pairs"
            corrections = f", {n_traj} trajectory corrections" if n_traj else ""
            lines.append(f"{m}: {self.verdicts[m].status.upper()}, {counts} "
                         f"({result.matcher.label})" + corrections)
            for p in sol.parameters.free:
                if sol.nuisance_prefix and p.name.startswith(sol.nuisance_prefix):
                    continue
                unit = "°" if p.display_unit == "deg" else f" {p.display_unit}"
                value, sigma = p.to_display(p.value), p.to_display(sol.sigma[p.name])
                lines.append(f"  {p.name} = {value:.5f} ± {sigma:.5f}{unit}")
        return "\n".join(lines)


def calibrate_strips(strips, trajectory, sensor, config: StripConfig = StripConfig(), *,
                     accuracy=None, control=None, checkpoints=None, truth=None,
                     scheduler: str | None = None, workers: int | None = None,
                     progress: Progress = no_progress) -> StripCalibration:
    """Calibrate a sensor from overlapping LAS/LAZ ``strips`` flown with the ``trajectory`` (SBET or
    text) and georeferenced with the nominal ``sensor`` (a sensor.toml), as ``config`` says (what
    to estimate, the matchers, the trajectory model, how the files are read). ``accuracy``: the
    trajectory's accuracy file (default: an smrmsg beside the SBET); ``control``: ground control
    points (CSV); ``checkpoints``: surveyed ground points (CSV) the calibrated strips are tested
    against, not in the adjustment; ``truth``: a simulation's truth.json;
    ``scheduler``/``workers``: match the pairs on a Dask cluster. Returns a
    :class:`StripCalibration`: ``print`` it, take its ``.sensor``, ``.write(folder)`` the
    results.

    >>> import tempfile, numpy as np, calidar
    >>> from dataclasses import replace
    >>> from pathlib import Path
    >>> cfg = calidar.survey_config("uav", seed=0, density=0.1, directions="cross",
    ...                             errors={"boresight_roll": np.radians(0.05)})
    >>> small = replace(cfg, scene=replace(cfg.scene, width_m=150.0, length_m=150.0))
    >>> # three strips, an SBET and its smrmsg, the nominal sensor.toml
    >>> sim = calidar.simulate_survey(small).write(Path(tempfile.mkdtemp()) / "sim")
    >>> strips = sorted((sim / "strips").glob("*.laz"))
    >>> run = calidar.calibrate_strips(strips, sim / "sbet.out", sim / "sensor.toml",
    ...                                truth=sim / "truth.json")
    >>> print(run)  # doctest: +ELLIPSIS
    planes: PASS, 3 strips, 3 pairs (tie planes), ... trajectory corrections
      boresight_roll = 0.0... ± 0.00...°
      boresight_pitch = ... ± 0.00...°
      boresight_yaw = ... ± 0.00...°
    >>> err = np.degrees(run.sensor.boresight_roll) - 0.05
    >>> bool(abs(err) < 3 * run.sensor.calibration.sigma["boresight_roll_deg"] < 0.01)
    True
    >>> sorted(p.name for p in run.write(sim.parent / "cal"))
    ['config.toml', 'report.html', 'sbet_corrected.out', 'sensor.toml', 'solution.json']
    """
    from calidar.pipelines import release_memory
    from calidar.pipelines.boresight_outputs import corrected_trajectory, quality_stages
    from calidar.provenance import RunRecord
    from calidar.strips.checkpoint_verdict import checkpoint_findings
    from calidar.strips.distribute import workers_for
    from calidar.strips.verdict import agreement_finding, strip_verdict

    strips = list(strips)  # (read twice: the headers' point counts, then the points)
    with workers_for(scheduler, workers) as work:  # one cluster (or thread pool) for every stage
        _start_pair_workers(strips, config, work)
        inputs = load_inputs(strips, trajectory, sensor, config, accuracy=accuracy, control=control,
                             checkpoints=checkpoints, truth=truth, progress=progress, work=work)
        files = {"trajectory_accuracy": accuracy, "control": control,
                 "checkpoints": checkpoints, "truth": truth}
        given = {k: v for k, v in files.items() if v is not None}
        record = RunRecord.capture(None, inputs=[*inputs.paths, truth],
                                   options={**config.to_dict(), **given})
        release_memory()
        results = calibrate_inputs(inputs, progress, work)
        # the solver's arrays (0.5 GiB at 8.75 M points) back to the system before the quality
        release_memory()
        corrected = {m: corrected_trajectory(inputs, r) for m, r in results.items()}
        quality = {m: quality_stages(inputs, r, corrected[m], progress, work)
                   for m, r in results.items()}
        # the last pass read: the held points' files go beside the report (then the files)
        held, inputs.source.held = inputs.source.held, None
        if held is not None:
            held.release()
    record.tasks = work.log.to_dict()
    agree = [agreement_finding(results)] if len(results) > 1 else []  # in both matchers' verdicts
    verdicts = {m: strip_verdict(r, quality[m], inputs.notes,
                                 others=agree + checkpoint_findings(inputs, r))
                for m, r in results.items()}
    record.finish()
    return StripCalibration(inputs, results, quality, verdicts, corrected, record)
