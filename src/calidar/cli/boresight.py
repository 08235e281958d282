"""``calidar boresight``: boresight / lever-arm / range calibration from overlapping strips."""

from __future__ import annotations

from dataclasses import replace
from pathlib import Path

import typer

from calidar.cli.common import console, err_console, print_warning, read_json
from calidar.pipelines.boresight import load_strips, parse_methods, trajectory_model, write_strips
from calidar.strips.trajectory_errors import PREFIX as TRAJECTORY_PREFIX


def register(app: typer.Typer, simulate: typer.Typer) -> None:
    @app.command("boresight")
    def boresight(
        strips: list[Path] = typer.Argument(..., help="LAS/LAZ strips (flight lines from point_source_id or time gaps)."),
        trajectory: Path = typer.Option(..., "--trajectory", help="Trajectory: SBET or text."),
        sensor: Path = typer.Option(..., "--sensor", help="Nominal sensor.toml the strips were georeferenced with."),
        method: str = typer.Option("planes", "--method", help="Correspondences: planes | vgicp, or planes,vgicp "
                                   "to run both and compare them in the report."),
        estimate: str = typer.Option("boresight", "--estimate",
                                     help="Comma-separated: boresight, lever_arm, range_offset, range_scale, "
                                          "scan_angle_scale, scan_angle_offset, trajectory_bias."),
        trajectory_sigma: str | None = typer.Option(
            None, "--trajectory-sigma", help="The trajectory's accuracy 'POSITION_M,ATTITUDE_DEG' (e.g. 0.03,0.002): "
            "estimate its errors (linear in time between knots) with these priors, so the σ of the mounting "
            "include them."),
        trajectory_block: float = typer.Option(
            1.0, "--trajectory-block", help="Spacing of the trajectory corrections' knots, s."),
        trajectory_correlation: str = typer.Option(
            "20,3.5", "--trajectory-correlation",
            help="Correlation times of the trajectory's position and attitude errors (Gauss–Markov), 'POS_S,ATT_S' s."),
        truth: Path | None = typer.Option(None, "--truth", help="truth.json of a simulation (adds truth and errors)."),
        scheduler: str | None = typer.Option(None, "--scheduler", help="Dask scheduler address for the pair matching."),
        workers: int | None = typer.Option(None, "--workers", help="Start a local Dask cluster with N workers."),
        out: Path = typer.Option(..., "--out", help="Output folder."),
        force: bool = typer.Option(False, "--force", help="Write into a non-empty output folder."),
        write_strips_: bool = typer.Option(False, "--write-strips", help="Also write the recalibrated strips (LAZ)."),
    ) -> None:
        """Calibrate the mounting (and more) from overlapping strips; writes solution.json, sensor.toml, report.html."""
        from calidar.io.trajectory import read_trajectory
        from calidar.outputs import prepare_out_dir
        from calidar.report import Report
        from calidar.sensor import Sensor
        from calidar.strips.calibrate import StripSettings, build_parameters, calibrate, parse_estimate, truth_to_si
        from calidar.strips.report import add_comparison_section, add_report_section

        groups = parse_estimate(estimate)
        methods = parse_methods(method)
        settings = StripSettings()
        if trajectory_sigma is not None:
            settings = replace(settings, trajectory=trajectory_model(trajectory_sigma, trajectory_block,
                                                                     trajectory_correlation))
            groups = groups if "trajectory_bias" in groups else [*groups, "trajectory_bias"]
        truth_si = None
        truth_doc = read_json(truth) if truth is not None else None
        out_dir = prepare_out_dir(out, force)
        nominal = Sensor.read(sensor)
        traj = read_trajectory(trajectory)
        strip_list, crs = load_strips(strips, traj, nominal)
        if truth is not None:
            truth_si = truth_to_si(truth_doc, build_parameters(nominal, groups, {}))
        results = {}
        for m in methods:
            with err_console.status(f"calibrating ({m})…") as status:
                results[m] = calibrate(strip_list, nominal, method=m, estimate=groups, settings=settings,
                                       scheduler=scheduler, workers=workers, progress=lambda msg: status.update(msg))
        report = Report("calidar boresight")
        written = []
        for m, result in results.items():
            tag = "" if len(results) == 1 else f"_{m}"  # several methods: one set of outputs each
            result.solution.write_json(out_dir / f"solution{tag}.json", truth_si)
            result.sensor.write(out_dir / f"sensor{tag}.toml", force=True)
            written += [f"solution{tag}.json", f"sensor{tag}.toml"]
            add_report_section(report, result, truth_si)
            if write_strips_:
                write_strips(result, crs, out_dir / m if tag else out_dir, force)
            _print(result, truth_si)
        if len(results) > 1:
            add_comparison_section(report, results, truth_si)
        report.write(out_dir / "report.html")
        console.print(f"wrote {out_dir}/{', '.join(written)}, report.html"
                      + (" and recalibrated strips" if write_strips_ else ""))


def _print(result, truth_si) -> None:
    from rich.table import Table

    doc = result.solution.to_dict(truth_si)
    table = Table(title=f"Strip calibration ({result.method}), {len(result.pairs)} pairs")
    for h in ("parameter", "value", "σ", "unit", "truth", "error"):
        table.add_column(h, justify="right")
    g = lambda v: "—" if v is None else f"{v:.6g}"  # noqa: E731
    for name, p in doc["parameters"].items():
        if p["free"] and not name.startswith(TRAJECTORY_PREFIX):
            table.add_row(name, g(p["value"]), g(p["sigma"]), p["unit"], g(p.get("truth")), g(p.get("error")))
    console.print(table)
    n_traj = sum(name.startswith(TRAJECTORY_PREFIX) for name in doc["parameters"])
    if n_traj:
        console.print(f"{n_traj} trajectory corrections estimated (in solution.json; largest shift "
                      f"{result.max_trajectory_shift_m() * 1e3:.1f} mm)")
    for w in result.warnings:
        print_warning(w)
