"""The strip-calibration pipeline (``calidar boresight``, its demo step and the benchmarks).

:func:`run_boresight` does the whole run: :func:`load_inputs` (strips, trajectory, nominal
sensor, the trajectory's accuracy — found beside an SBET, read from σ columns or a file, else
a documented default), :func:`calibrate_inputs` (one calibration per method, the trajectory
model on unless switched off), the overlap quality before and after
(:func:`calidar.pipelines.boresight_outputs.quality_stages`, the code ``calidar quality``
runs), the verdict, and the outputs: ``solution.json`` (with the run's provenance),
``sensor.toml``, ``sbet_corrected.out`` when trajectory corrections were estimated,
``report.html``, optionally the recalibrated strips.
"""

from __future__ import annotations

from dataclasses import dataclass, field, replace
from pathlib import Path

import numpy as np

from calidar.errors import InputError
from calidar.pipelines import Progress, no_progress
from calidar.pipelines.inputs import PointOptions, TrajectoryOptions
from calidar.validate import parse_floats, positive

#: knot spacing (s) and Gauss–Markov correlation times of position and attitude (s) of the
#: trajectory model, validated on the simulator (docs/validation.md)
TRAJECTORY_BLOCK_S = 1.0
TRAJECTORY_CORRELATION = "20,3.5"
MAX_TRAJECTORY_BLOCK_S = 600.0  #: s, --trajectory-block (longer: no trajectory correction at all)
MAX_CORRELATION_S = 86400.0  #: s, --trajectory-correlation (a day: constant errors)


@dataclass(frozen=True)
class BoresightOptions:
    """What ``calidar boresight`` takes besides its input files (see its --help)."""

    methods: tuple[str, ...] = ("planes",)
    estimate: str = "boresight"
    trajectory_model: bool = True  #: estimate the trajectory's errors (priors: its accuracy)
    trajectory_accuracy: Path | None = None  #: smrmsg file (default: found beside an sbet*.out)
    trajectory_sigma: str | None = None  #: 'POSITION_M,ATTITUDE_DEG': one σ for all epochs and axes
    trajectory_block_s: float = TRAJECTORY_BLOCK_S
    trajectory_correlation: str = TRAJECTORY_CORRELATION
    truth: Path | None = None  #: truth.json of a simulation
    scheduler: str | None = None
    workers: int | None = None
    write_strips: bool = False
    settings: object | None = None  #: calidar.strips.calibrate.StripSettings (benchmarks, tests)
    points: PointOptions = PointOptions()  #: --crs, --time-system, --geoid-undulation of the strips
    trajectory_input: TrajectoryOptions = TrajectoryOptions()  #: --trajectory-crs and the text-trajectory options
    #: how the strips are read (calidar.pipelines.strip_source.IngestOptions; None: its defaults,
    #: the overlap grid of ``settings``, the point options above)
    ingest: object | None = None
    control: Path | None = None  #: ground control CSV (--control; calidar.pipelines.control)
    control_crs: str | None = None  #: its CRS when it is not the strips' (--control-crs)
    checkpoints: Path | None = None  #: checkpoint CSV tested after the calibration (--checkpoints; strips/checkpoint_verdict.py)
    checkpoints_crs: str | None = None  #: its CRS when it is not the strips' (--checkpoints-crs)
    checkpoint_class_cm: float | None = None  #: the ASPRS class the checkpoints must show (--class)

    def to_dict(self) -> dict:
        def plain(v):
            return str(v) if isinstance(v, Path) else ({k: plain(x) for k, x in v.__dict__.items()}
                                                       if isinstance(v, (PointOptions, TrajectoryOptions)) else v)

        d = {k: plain(v) for k, v in self.__dict__.items() if k not in ("settings", "ingest")}
        ingest = self.ingest_options()
        d["ingest"] = {"budget_points": ingest.budget_points, "chunk_points": ingest.chunk_points}
        return d

    def ingest_options(self):
        """The strip ingest options, on the calibration's overlap grid, with the strips' point options."""
        from calidar.pipelines.strip_source import IngestOptions
        from calidar.strips.calibrate import StripSettings

        s = self.settings or StripSettings()
        return replace(self.ingest or IngestOptions(), cell_m=s.overlap_cell_m, min_cells=s.min_overlap_cells,
                       points=self.points)


@dataclass
class BoresightInputs:
    """Everything a calibration reads, loaded and checked."""

    strip_paths: list[Path]
    trajectory_path: Path
    sensor_path: Path
    nominal: object  #: calidar.sensor.Sensor
    trajectory: object  #: calidar.trajectory.Trajectory
    strips: list  #: calidar.strips.strip.Strip, one per overlapping flight line (its kept overlap points)
    crs: object
    source: object | None = None  #: calidar.pipelines.strip_source.StripSource: the whole lines, streamed
    accuracy: object | None = None  #: calidar.trajectory_accuracy.TrajectoryAccuracy (None: model off)
    accuracy_path: Path | None = None
    notes: list[str] = field(default_factory=list)  #: what the user should know (e.g. a default assumed)
    #: no accuracy stated: the trajectory priors' level is estimated from the overlaps
    #: (calidar.strips.trajectory_level), ``accuracy`` (the survey-grade default) its start
    estimate_accuracy: bool = False
    truth: dict | None = None  #: truth.json parameters, SI (simulations)
    control: object | None = None  #: calidar.strips.control.ControlPoints in the strips' frame (--control)
    checkpoints: object | None = None  #: the same of --checkpoints (tested after, not in the adjustment)
    options: BoresightOptions = BoresightOptions()  #: as given (the input options name the reproducing commands)

    @property
    def spans(self) -> dict[int, tuple[float, float]]:
        return {s.id: s.time_span for s in self.strips}

    @property
    def paths(self) -> list[Path]:
        """Every input file."""
        return [*self.strip_paths, self.trajectory_path, self.sensor_path,
                *([self.accuracy_path] if self.accuracy_path else []),
                *([Path(self.options.control)] if self.options.control else []),
                *([Path(self.options.checkpoints)] if self.options.checkpoints else [])]


def load_strips(paths, trajectory, sensor, options=None, progress: Progress = no_progress):
    """Flight lines of the LAS/LAZ files as Strips in one local frame (times in the trajectory's
    system), streamed and thinned to their overlaps (``options``: an
    :class:`calidar.pipelines.strip_source.IngestOptions`): (strips, CRS)."""
    from calidar.pipelines.strip_ingest import ingest_strips
    from calidar.pipelines.strip_source import IngestOptions

    strips, crs, _, _ = ingest_strips(list(paths), trajectory, sensor, options or IngestOptions(), progress)
    return strips, crs


def parse_methods(text: str) -> list[str]:
    """'planes', 'vgicp' or 'planes,vgicp' → the methods to run, in order."""
    from calidar.strips.parameters import METHODS

    methods = [m.strip() for m in text.split(",") if m.strip()]
    if not methods or any(m not in METHODS for m in methods) or len(set(methods)) != len(methods):
        raise InputError(None, "--method", f"expected one or more of {', '.join(METHODS)} separated by commas, got {text!r}")
    return methods


def trajectory_model(sigma: str | None = None, block_s: float = TRAJECTORY_BLOCK_S,
                     correlation: str = TRAJECTORY_CORRELATION, accuracy=None):
    """The trajectory model: knots every ``block_s`` s, Gauss–Markov correlation 'POS_S,ATT_S'
    (--trajectory-correlation), priors from ``accuracy`` (a TrajectoryAccuracy) or one σ for all
    ('POSITION_M,ATTITUDE_DEG', --trajectory-sigma)."""
    from calidar.strips.trajectory_errors import TrajectoryModel

    corr_pos, corr_att = parse_floats(correlation, 2, "--trajectory-correlation (POS_S,ATT_S)")
    block_s = positive(block_s, "--trajectory-block", "s", hi=MAX_TRAJECTORY_BLOCK_S)
    for v in (corr_pos, corr_att):
        positive(v, "--trajectory-correlation", "s", hi=MAX_CORRELATION_S)
    pos_m = att_rad = None
    if accuracy is None:
        pos_m, att_rad = parse_sigma(sigma)
    return TrajectoryModel(block_s, pos_m, att_rad, corr_pos, corr_att, accuracy)


def parse_sigma(text: str) -> tuple[float, float]:
    """--trajectory-sigma 'POSITION_M,ATTITUDE_DEG' → (position σ m, attitude σ rad), each > 0 and
    within the bounds of :class:`~calidar.trajectory_accuracy.TrajectoryAccuracy`."""
    from calidar.trajectory_accuracy import MAX_ATTITUDE_SIGMA_RAD, MAX_POSITION_SIGMA_M

    pos_m, att_deg = parse_floats(text, 2, "--trajectory-sigma (POSITION_M,ATTITUDE_DEG)")
    positive(pos_m, "--trajectory-sigma", "m", hi=MAX_POSITION_SIGMA_M)
    positive(att_deg, "--trajectory-sigma", "deg", hi=float(np.degrees(MAX_ATTITUDE_SIGMA_RAD)))
    return pos_m, float(np.radians(att_deg))


def resolve_accuracy(trajectory_path: Path, trajectory, options: BoresightOptions):
    """The trajectory's accuracy and where it came from: (TrajectoryAccuracy, file or None, note
    or None). In order: --trajectory-accuracy, --trajectory-sigma, σ columns of a text
    trajectory, an smrmsg*.out beside an sbet*.out, else the survey-grade default (with a note),
    whose level the calibration then estimates from the overlaps (:func:`estimates_accuracy`)."""
    from calidar.io.smrmsg import find_beside, read_smrmsg
    from calidar.io.trajectory_text import SIGMA_COLUMNS
    from calidar.trajectory_accuracy import SURVEY_GRADE, TrajectoryAccuracy

    if options.trajectory_accuracy is not None and options.trajectory_sigma is not None:
        raise InputError(None, "--trajectory-sigma", "give either --trajectory-accuracy FILE or --trajectory-sigma, not both")
    if options.trajectory_accuracy is not None:
        return read_smrmsg(options.trajectory_accuracy), Path(options.trajectory_accuracy), None
    if options.trajectory_sigma is not None:
        pos_m, att_rad = parse_sigma(options.trajectory_sigma)
        return TrajectoryAccuracy.uniform(pos_m, att_rad, "--trajectory-sigma"), None, None
    if all(c in trajectory.extra for c in SIGMA_COLUMNS):
        pos, att = (np.stack([trajectory.extra[c] for c in cols], axis=1) for cols in (SIGMA_COLUMNS[:3], SIGMA_COLUMNS[3:]))
        return TrajectoryAccuracy(trajectory.time, pos, att, None, f"{trajectory_path} (σ columns)"), None, None
    beside = find_beside(trajectory_path)
    if beside is not None:
        return read_smrmsg(beside), beside, None
    return SURVEY_GRADE, None, (
        f"no trajectory accuracy found (no smrmsg*.out beside {trajectory_path.name}, no σ columns, no "
        "--trajectory-accuracy): its level is estimated from the overlaps, starting from a survey-grade "
        "GNSS/INS — " + SURVEY_GRADE.describe().split(" (")[0] + " — which stays where the data cannot tell")


def estimates_accuracy(accuracy) -> bool:
    """Whether the calibration estimates the trajectory's accuracy level from the overlaps: when
    no source stated it (``accuracy`` is the survey-grade default :func:`resolve_accuracy` fell back on)."""
    from calidar.trajectory_accuracy import SURVEY_GRADE

    return accuracy is SURVEY_GRADE


def load_inputs(strip_paths, trajectory_path, sensor_path, options: BoresightOptions = BoresightOptions(),
                progress: Progress = no_progress, work=None) -> BoresightInputs:
    """Read and check every input (the trajectory's accuracy must cover every strip); ``work``: where
    the files are read (a :class:`calidar.strips.distribute.Workers`; None: one at a time here)."""
    from calidar.pipelines.inputs import load_trajectory
    from calidar.pipelines.strip_ingest import ingest_strips
    from calidar.sensor import Sensor
    from calidar.strips.parameters import build_parameters, parse_estimate, truth_to_si
    from calidar.validate import read_json

    from calidar.pipelines.control import checked_checkpoints, with_checkpoints
    from calidar.strips.control import check_estimate

    check_estimate(parse_estimate(options.estimate), options.control)
    trajectory_path, sensor_path = Path(trajectory_path), Path(sensor_path)
    nominal = Sensor.read(sensor_path)
    traj = load_trajectory(trajectory_path, options.trajectory_input)
    accuracy, accuracy_path, notes = None, None, []
    if options.trajectory_model:  # every option checked before the strips are read
        accuracy, accuracy_path, note = resolve_accuracy(trajectory_path, traj, options)
        trajectory_model(None, options.trajectory_block_s, options.trajectory_correlation, accuracy)
        notes += [note] if note else []
    else:
        if options.trajectory_accuracy is not None or options.trajectory_sigma is not None:
            raise InputError(None, "--trajectory-model", "is off, so --trajectory-accuracy and --trajectory-sigma have "
                             "nothing to do; expected the trajectory model on (the default) or neither option")
        notes.append("trajectory model off (--trajectory-model off): the trajectory is taken as exact, so the "
                     "σ miss its errors (ordinary GNSS/INS noise made them 2× too small on simulated surveys)")
    ingest, control = options.ingest_options(), None
    if options.control is not None:
        from calidar.pipelines.control import read_control

        if not strip_paths:
            raise InputError(None, "STRIPS", "expected at least one LAS/LAZ file")
        control = read_control(options.control, options.control_crs, strip_paths[0], options.points, nominal)
        ingest, notes = replace(ingest, control_ecef=control.ecef), notes + list(control.notes)
    elif options.control_crs is not None:
        raise InputError(None, "--control-crs", "given without --control; expected --control FILE with it")
    ingest, checkpoints = with_checkpoints(options, strip_paths, nominal, ingest)
    progress("reading strips", 0, 1)
    strips, crs, source, unpaired = ingest_strips(list(strip_paths), traj, nominal, ingest, progress, work)
    inputs = BoresightInputs([Path(p) for p in strip_paths], trajectory_path, sensor_path, nominal, traj, strips, crs,
                             source, accuracy, accuracy_path, notes + unpaired, options=options)
    if control is not None:
        from calidar.pipelines.control import control_points

        inputs.control = control_points(control, strips[0].frame)
    inputs.checkpoints, inputs.notes = checked_checkpoints(checkpoints, strips[0].frame, inputs.notes)
    if accuracy is not None:
        accuracy.check_covers(inputs.spans)
        inputs.estimate_accuracy = estimates_accuracy(accuracy)
    if options.truth is not None:
        inputs.truth = truth_to_si(read_json(options.truth), build_parameters(nominal, parse_estimate(options.estimate), {}))
        if not inputs.truth:
            raise InputError(options.truth, "parameters", "none of the estimated parameters found; expected the "
                             "truth.json of `calidar simulate survey`")
    return inputs


def calibrate_inputs(inputs: BoresightInputs, options: BoresightOptions = BoresightOptions(),
                     progress: Progress = no_progress, work=None) -> dict:
    """One :class:`calidar.strips.calibrate.CalibrationResult` per method, by method name; the
    pairs matched by ``work`` (a :class:`calidar.strips.distribute.Workers`; None: a cluster of
    ``options.scheduler``/``workers`` for this call, or this process)."""
    from calidar.strips.calibrate import StripSettings, calibrate_with_client
    from calidar.strips.distribute import workers_for
    from calidar.strips.parameters import parse_estimate

    groups = parse_estimate(options.estimate)
    settings = options.settings or StripSettings()
    if options.trajectory_model:
        model = trajectory_model(None, options.trajectory_block_s, options.trajectory_correlation, inputs.accuracy)
        model = replace(model, estimate_level=inputs.estimate_accuracy)
        settings = replace(settings, trajectory=model)
        groups = groups if "trajectory_bias" in groups else [*groups, "trajectory_bias"]
    if work is None:
        with workers_for(options.scheduler, options.workers) as work:
            return calibrate_inputs(inputs, options, progress, work)
    results = {}
    for m in options.methods:
        results[m] = calibrate_with_client(
            inputs.strips, inputs.nominal, method=m, estimate=groups, settings=settings, client=work.client, log=work.log,
            progress=lambda text, done, total, m=m: progress(f"calibrating ({m})", done, total), control=inputs.control)
        results[m].solution.warnings[:0] = inputs.notes
    return results


@dataclass
class BoresightRun:
    """What :func:`run_boresight` produced."""

    inputs: BoresightInputs
    results: dict  #: method → CalibrationResult
    quality: dict  #: method → list of calidar.strips.report.QualityStage
    verdicts: dict  #: method → calidar.verdict.Verdict
    record: object  #: calidar.provenance.RunRecord
    written: list[Path]


def run_boresight(strip_paths, trajectory_path, sensor_path, out_dir: Path, options: BoresightOptions = BoresightOptions(),
                  progress: Progress = no_progress, argv: list[str] | None = None, report=None,
                  shown_out: Path | None = None, verdict_title: str | None = None,
                  section_title: str | None = None) -> BoresightRun:
    """The whole ``calidar boresight`` run into the folder ``out_dir`` (the CLI hands it its
    output transaction's temporary folder; ``shown_out``: the folder's final name, for the
    commands the report shows). ``report``: add the sections and verdicts to this report instead
    of writing out_dir/report.html (``verdict_title``, ``section_title``: what to call them there).
    Returns what was computed and written (``calidar.calibrate_strips``).

    >>> import tempfile, numpy as np, calidar
    >>> cfg = calidar.survey_config("uav", seed=0, density=0.1, directions="cross", errors={"boresight_roll": np.radians(0.05)})
    >>> sim = calidar.simulate_survey(replace(cfg, scene=replace(cfg.scene, width_m=150.0, length_m=150.0))).write(
    ...     Path(tempfile.mkdtemp()) / "sim")  # three strips, an SBET and its smrmsg, the nominal sensor.toml
    >>> run = calidar.calibrate_strips(sorted((sim / "strips").glob("*.laz")), sim / "sbet.out", sim / "sensor.toml",
    ...                                sim.parent / "cal", BoresightOptions(truth=sim / "truth.json"))
    >>> sol = run.results["planes"].solution
    >>> err = np.degrees(sol.values["boresight_roll"]) - 0.05
    >>> bool(abs(err) < 3 * np.degrees(sol.sigma["boresight_roll"]) < 0.01), run.verdicts["planes"].status
    (True, 'pass')
    >>> sorted(p.name for p in run.written)
    ['report.html', 'sbet_corrected.out', 'sensor.toml', 'solution.json']
    """
    from calidar.pipelines import release_memory
    from calidar.pipelines.boresight_outputs import (accuracy_used, corrected_trajectory, map_pair, quality_stages,
                                                     write_outputs)
    from calidar.provenance import RunRecord
    from calidar.report import Report
    from calidar.strips.distribute import workers_for
    from calidar.strips.report import add_comparison_section, add_report_section
    from calidar.strips.checkpoint_verdict import checkpoint_findings
    from calidar.strips.verdict import agreement_finding, strip_verdict

    with workers_for(options.scheduler, options.workers) as work:  # one cluster (or thread pool) for every stage
        inputs = load_inputs(strip_paths, trajectory_path, sensor_path, options, progress, work)
        record = RunRecord.capture(argv, inputs=[*inputs.paths, options.truth], options=options.to_dict())
        release_memory()
        results = calibrate_inputs(inputs, options, progress, work)
        release_memory()  # the solver's arrays (0.5 GiB at 8.75 M points) back to the system before the quality
        corrected = {m: corrected_trajectory(inputs, r) for m, r in results.items()}
        quality = {m: quality_stages(inputs, r, corrected[m], shown_out or out_dir, "" if len(results) == 1 else f"_{m}",
                                     progress, work) for m, r in results.items()}
    record.tasks = work.log.to_dict()
    out_dir = Path(out_dir)
    own = report is None
    report = Report("calidar boresight") if own else report
    verdicts, written = {}, []
    agree = [agreement_finding(results)] if len(results) > 1 else []  # in both methods' verdicts
    for m, result in results.items():
        verdicts[m] = strip_verdict(result, quality[m], inputs.notes, others=agree + checkpoint_findings(inputs, result))
        label = m if len(results) > 1 else None
        report.add_verdict(verdicts[m], " ".join(x for x in (verdict_title, label) if x) or None)
        add_report_section(report, result, inputs.truth, quality[m], accuracy=accuracy_used(inputs, result),
                           map_pair=map_pair(inputs, quality[m]),
                           title=section_title and (f"{section_title} ({m})" if label else section_title))
    if len(results) > 1:
        add_comparison_section(report, results, inputs.truth)
    record.finish()
    for m, result in results.items():
        tag = "" if len(results) == 1 else f"_{m}"
        strips_dir = (out_dir / m if tag else out_dir) if options.write_strips else None
        written += write_outputs(inputs, result, corrected[m], verdicts[m], record, quality[m], out_dir, tag, strips_dir)
    if own:
        report.record = record
        written.append(report.write(out_dir / "report.html"))
    return BoresightRun(inputs, results, quality, verdicts, record, written)
