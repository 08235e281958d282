"""``calidar boresight``: boresight / lever-arm / range calibration from overlapping strips."""

from __future__ import annotations

from pathlib import Path

import typer

from calidar.cli.common import (
    FORCE_HELP, console, exit_with_verdict, print_verdict, print_warning, progress_bar,
    progress_callback,
)
from calidar.cli.options import (
    CRS, GEOID_UNDULATION, TIME_SYSTEM, TRAJECTORY_ANGLES, TRAJECTORY_COLUMNS, TRAJECTORY_CRS,
    TRAJECTORY_HEADING,
)
from calidar.ingest.settings import BUDGET_POINTS
from calidar.strips.selection import excluded_words
from calidar.strips.trajectory_errors import PREFIX as TRAJECTORY_PREFIX

#: the trajectory model's defaults as the options show them (those of
#: calidar.strips.config.TrajectorySettings)
TRAJECTORY_BLOCK_S, TRAJECTORY_CORRELATION = 1.0, "20,3.5"
CONTROL = typer.Option(
    None, "--control", help="Ground control points (CSV: id, x, y, z, sigma; land cover optional, "
    "vegetated ones left out), or control surfaces (CSV: plane, x, y, z, sigma; ≥ 3 surveyed "
    "points per planar patch such as a roof facet), or a reference point cloud (LAS/LAZ, with "
    "--control-sigma), observed in the adjustment with their σ: range offset, vertical lever arm "
    "and a vertical trajectory bias, which the overlaps cannot see, become determinable.")
CONTROL_SIGMA = typer.Option(
    None, "--control-sigma", help="With a reference cloud as --control: its stated vertical "
    "accuracy (σ of its heights' datum, m, e.g. 0.02); its planar cells are control surfaces.")
CONTROL_CRS = typer.Option(None, "--control-crs", help="CRS of the control points when it is not "
                           "the strips' (e.g. EPSG:32632).")
CHECKPOINTS = typer.Option(
    None, "--checkpoints", help="Checkpoints (CSV as calidar accuracy reads it), not in the "
    "adjustment: the calibrated strips' NVA against them is a finding of the verdict.")
CHECKPOINTS_CRS = typer.Option(None, "--checkpoints-crs",
                               help="CRS of the checkpoints when it is not the strips'.")
TARGET_CLASS = typer.Option(
    None, "--class", help="With --checkpoints: the ASPRS vertical accuracy class (X cm) the "
    "calibrated strips must meet at them; not met: a FAIL verdict (exit 3).")
STRIPS = typer.Argument(
    ..., help="LAS/LAZ strips (flight lines from point_source_id or time gaps).")
SENSOR = typer.Option(
    ..., "--sensor", help="Nominal sensor.toml the strips were georeferenced with.")
METHOD = typer.Option("planes", "--method", help="Correspondences: planes | vgicp, or planes,vgicp "
                      "to run both and compare them in the report.")
ESTIMATE = typer.Option(
    "boresight", "--estimate", help="Comma-separated: boresight, lever_arm, range_offset, "
    "range_scale, scan_angle_scale, scan_angle_offset, height_bias (all strips' height: needs "
    "--control), or single parameters (lever_arm_x).")
TRAJECTORY_MODEL = typer.Option(
    "on", "--trajectory-model", help="on: estimate the trajectory's errors (priors: its accuracy, "
    "see --trajectory-accuracy), so the σ include them; off: take the trajectory as exact (σ too "
    "small with ordinary GNSS/INS noise).")
MODEL_CHECK = typer.Option(
    "on", "--model-check", help="on: after the adjustment, free each structural parameter not "
    "estimated (range offset, scan-angle scale, horizontal lever arm) in turn; one the overlaps "
    "see that moves the estimated values warns, or fails (exit 3) when it is clear; off: skip it.")
TRAJECTORY_ACCURACY = typer.Option(
    None, "--trajectory-accuracy", help="The trajectory's accuracy per epoch: a POSPac smrmsg "
    "file. Default: smrmsg*.out beside an sbet*.out, σ columns of a text trajectory, else its "
    "level is estimated from the overlaps, starting from a survey-grade GNSS/INS (5 cm, 0.003° "
    "roll/pitch, 0.008° heading) kept where the data cannot tell.")
TRAJECTORY_SIGMA = typer.Option(
    None, "--trajectory-sigma", help="Instead of an accuracy file: one σ 'POSITION_M,ATTITUDE_DEG' "
    "(e.g. 0.03,0.002) for every epoch and axis.")
TRAJECTORY_CORRELATION_OPTION = typer.Option(
    TRAJECTORY_CORRELATION, "--trajectory-correlation", help="Correlation times of the "
    "trajectory's position and attitude errors (Gauss–Markov, integral time; first order unless "
    "[trajectory_model] shape in --config says so), 'POS_S,ATT_S' s.")
SCHEDULER = typer.Option(
    None, "--scheduler", help="Dask scheduler address: the files are read, the pairs matched and "
    "the overlap quality measured as tasks on its workers (which must see the files at the same "
    "paths).")
WORKERS = typer.Option(None, "--workers", help="The same tasks on a local Dask cluster of N "
                       "processes (default: two threads in this process).")
WRITE_STRIPS = typer.Option(False, "--write-strips",
                            help="Also write the recalibrated strips (LAZ).")
STRIP_POINTS = typer.Option(
    BUDGET_POINTS, "--strip-points", help="Points of each strip's overlaps the calibration keeps "
    "(whole blocks spread evenly over them; the strips are streamed, memory and time grow with "
    "this, not with the files); 0: every overlapping point.")
ALL_CLASSES = typer.Option(
    False, "--all-classes/--no-all-classes", help="Keep every LAS class in the calibration's "
    f"points. Default: a classified file's {excluded_words()} points are "
    "left out before the --strip-points budget is spent (as `calidar quality` leaves them out); "
    "unclassified files lose none.")
CONFIG = typer.Option(
    None, "--config", help="A configuration file (TOML, as the config.toml every run writes beside "
    "its results): its settings replace the defaults, options given on the command line replace "
    "its settings.")

#: the command's help (its line breaks are those `calidar --help` shows)
HELP = ("Calibrate the mounting (and more) from overlapping strips; writes solution.json, "
        "sensor.toml,\nsbet_corrected.out (the trajectory with its estimated corrections), "
        "config.toml (this run's settings, for\n--config) and report.html.\n\n"
        "Exit codes: 0 pass or warn, 3 a FAIL verdict (outputs written, not to be used), "
        "1 bad input, 2 usage.")


def boresight(
    ctx: typer.Context,
    strips: list[Path] = STRIPS,
    trajectory: Path = typer.Option(..., "--trajectory", help="Trajectory: SBET or text."),
    sensor: Path = SENSOR,
    method: str = METHOD,
    estimate: str = ESTIMATE,
    trajectory_model: str = TRAJECTORY_MODEL,
    model_check: str = MODEL_CHECK,
    trajectory_accuracy: Path | None = TRAJECTORY_ACCURACY,
    trajectory_sigma: str | None = TRAJECTORY_SIGMA,
    trajectory_block: float = typer.Option(TRAJECTORY_BLOCK_S, "--trajectory-block",
                                           help="Spacing of the trajectory corrections' knots, s."),
    trajectory_correlation: str = TRAJECTORY_CORRELATION_OPTION,
    truth: Path | None = typer.Option(None, "--truth", help="truth.json of a simulation (adds "
                                      "truth and errors)."),
    scheduler: str | None = SCHEDULER,
    workers: int | None = WORKERS,
    out: Path = typer.Option(..., "--out", help="Output folder."),
    force: bool = typer.Option(False, "--force", help=FORCE_HELP),
    write_strips: bool = WRITE_STRIPS,
    crs: str | None = CRS, time_system: str | None = TIME_SYSTEM,
    geoid_undulation: float | None = GEOID_UNDULATION,
    trajectory_crs: str | None = TRAJECTORY_CRS, trajectory_angles: str | None = TRAJECTORY_ANGLES,
    trajectory_heading: str | None = TRAJECTORY_HEADING,
    trajectory_columns: str | None = TRAJECTORY_COLUMNS,
    control: Path | None = CONTROL, control_crs: str | None = CONTROL_CRS,
    control_sigma: float | None = CONTROL_SIGMA,
    checkpoints: Path | None = CHECKPOINTS, checkpoints_crs: str | None = CHECKPOINTS_CRS,
    target_class: float | None = TARGET_CLASS,
    strip_points: int = STRIP_POINTS,
    all_classes: bool = ALL_CLASSES,
    config: Path | None = CONFIG,
) -> None:
    """Calibrate the mounting (and more) from overlapping strips (the command's help: HELP)."""
    from calidar.cli.boresight_config import strip_config
    from calidar.outputs import check_out_dir, output_folder
    from calidar.pipelines.boresight import calibrate_strips
    from calidar.strips.distribute import check_cluster

    given = {k: v for k, v in ctx.params.items() if ctx.get_parameter_source(k).name != "DEFAULT"}
    cfg = strip_config(config, given)
    check_cluster(scheduler, workers)
    check_out_dir(out, force)
    inputs = [*strips, trajectory, sensor, trajectory_accuracy, truth, control, checkpoints, config]
    with output_folder(out, force, inputs=inputs) as tmp, progress_bar() as bar:
        run = calibrate_strips(strips, trajectory, sensor, cfg, accuracy=trajectory_accuracy,
                               control=control, checkpoints=checkpoints, truth=truth,
                               scheduler=scheduler, workers=workers,
                               progress=progress_callback(bar))
        written = run.write(tmp, strips=write_strips)
    _print_run(run, out, sorted({p.name for p in written if p.parent == Path(tmp)}), write_strips)
    # FAIL: exit 3; the outputs are written (to look at), not to be used
    exit_with_verdict(*run.verdicts.values())


def _print_run(run, out: Path, names: list[str], write_strips: bool) -> None:
    """Each method's verdict and parameters, the Dask tasks, the files written (``names``)."""
    from calidar.provenance import describe_tasks

    for m, result in run.results.items():
        print_verdict(run.verdicts[m], None if len(run.results) == 1 else m)
        _print(result, run.inputs.truth)
    if run.record.tasks:  # on Dask: what came back over the network
        console.print("Dask tasks — " + describe_tasks(run.record.tasks), markup=False)
    also = " and the recalibrated strips" if write_strips else ""
    console.print(f"wrote {out}/: {', '.join(names)}" + also, markup=False)


def _print(result, truth_si) -> None:
    from rich.table import Table

    doc = result.solution.to_dict(truth_si)
    n_traj = sum(name.startswith(TRAJECTORY_PREFIX) for name in doc["parameters"])
    if truth_si:
        table = Table(title=f"Against the truth ({result.method})")
        for h in ("parameter", "value ± σ", "truth", "error", "|error|/σ"):
            table.add_column(h, justify="left" if h == "parameter" else "right", no_wrap=True)
        for name, p in doc["parameters"].items():
            if p["free"] and not name.startswith(TRAJECTORY_PREFIX) and "error" in p:
                u = "°" if p["unit"] == "deg" else f" {p['unit']}"
                z = abs(p["error"]) / p["sigma"] if p["sigma"] else None
                value = f"{p['value']:.5f}{u}"
                if p["sigma"]:
                    value = f"{p['value']:.5f} ± {p['sigma']:.5f}{u}"
                table.add_row(name, value, f"{p['truth']:.5f}{u}", f"{p['error']:+.5f}{u}",
                              "—" if z is None else f"{z:.2f}")
        console.print(table)
    if n_traj:
        shift_mm = result.max_trajectory_shift_m() * 1e3
        console.print(f"{n_traj} trajectory corrections estimated (in solution.json and "
                      f"sbet_corrected.out; largest shift {shift_mm:.1f} mm)", markup=False)
    for w in result.warnings:
        print_warning(w)


def register(app: typer.Typer, simulate: typer.Typer) -> None:
    app.command("boresight", help=HELP)(boresight)
