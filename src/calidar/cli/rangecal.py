"""``calidar range-cal`` and ``calidar simulate total-station``.

Exit codes of ``range-cal`` (the contract of every command, :mod:`calidar.cli.common`): 0 the
verdict is PASS or WARN (with ``--tolerance``, the acceptance passed); 1 bad input; 2 usage error;
3 the verdict is FAIL — e.g. the acceptance check failed (the 95 % bound of the raw range error
over the calibrated distances exceeds the tolerance); 130/143 interrupted.
"""

from __future__ import annotations

from pathlib import Path

import typer

from calidar.cli.common import (
    CONFIG_HELP, FORCE_HELP, EXIT_FAIL, given_options, console, exit_with_verdict, print_verdict,
)

ACCEPTANCE_FAILED = EXIT_FAIL  #: exit code when --tolerance is given and the check fails


def _say(text: str) -> None:
    console.print(text, highlight=False, soft_wrap=True)


def range_cal_config(path: Path | None, given: dict):
    """The configuration: the ``--config`` file's (else the defaults), with --tolerance and
    --fix-scale when given on the command line; checked."""
    from calidar.cli.common import config_values
    from calidar.pipelines.rangecal_config import RangeCalConfig

    return RangeCalConfig.configure(path, config_values(given, {"tolerance": ("tolerance_m", None),
                                                                "fix_scale": ("fix_scale", None)}))


OBSERVATIONS = typer.Argument(..., help="Observation file (CSV, format in docs/conventions.md).")
OUT = typer.Option(..., "--out", help="Output folder: solution.json, config.toml, report.html.")
TRUTH = typer.Option(None, "--truth", help="truth.json of a simulation: adds truth and error.")
TOLERANCE = typer.Option(None, "--tolerance", help="Acceptance tolerance of the raw range error "
                         "(m, ≤ 10); exit code 3 when the 95 % bound exceeds it.")
FIX_SCALE = typer.Option(False, "--fix-scale", help="Estimate the offset only (range_scale fixed "
                         "at 0), e.g. when all targets are at one distance.")


#: the command's help (its line breaks are those --help shows)
RANGE_CAL_HELP = ("Calibrate range offset and scale of a circular-scan lidar against total-station "
                  "observations.\n\nExit codes: 0 pass or warn (acceptance passed when --tolerance "
                  "is given), 1 bad input, 2 usage error,\n3 FAIL verdict (e.g. acceptance "
                  "failed), 130/143 interrupted.")


def range_cal(
    ctx: typer.Context,
    observations: Path = OBSERVATIONS,
    out: Path = OUT,
    truth: Path | None = TRUTH,
    tolerance: float | None = TOLERANCE,
    fix_scale: bool = FIX_SCALE,
    force: bool = typer.Option(False, "--force", help=FORCE_HELP),
    config: Path | None = typer.Option(None, "--config", help=CONFIG_HELP),
) -> None:
    """``calidar range-cal`` (its help: RANGE_CAL_HELP)."""
    from calidar.outputs import output_folder
    from calidar.pipelines.rangecal import run_range_cal

    cfg = range_cal_config(config, given_options(ctx))
    with output_folder(out, force, inputs=[observations, truth, config]) as tmp:
        run = run_range_cal(observations, tmp, cfg, truth=truth)
    result = run.result
    sol = result.solution
    for name, f, unit in (("range_offset", 1e3, "mm"), ("range_scale", 1e6, "ppm")):
        if (iv := result.fit.interval(name)) is not None:
            _say(f"{name} = {sol.values[name] * f:+.3f} ± {sol.sigma[name] * f:.3f} {unit} "
                 f"(95 %: {iv[0] * f:+.3f} … {iv[1] * f:+.3f} {unit})")
    m = result.method
    delta = f", Δ = {m.delta * 1e3:+.3f} mm" if m.delta is not None else ""
    _say(f"two-step method: ΔS = {m.delta_s * 1e3:+.3f} mm" + delta)
    if result.acceptance is not None:
        a = result.acceptance
        _say(f"acceptance: {'PASS' if a['passed'] else 'FAIL'} (95 % bound "
             f"{a['max_bound95_m'] * 1e3:.2f} mm, tolerance {a['tolerance_m'] * 1e3:.2f} mm)")
    print_verdict(run.verdict)
    _say(f"wrote {out / 'solution.json'}, {out / 'config.toml'} and {out / 'report.html'}")
    if result.acceptance is not None and not result.acceptance["passed"]:
        raise typer.Exit(ACCEPTANCE_FAILED)
    exit_with_verdict(run.verdict)


OUTLIERS = typer.Option(0, "--outliers", help="Scanner ranges with a gross error (≤ the targets).")
VERTICAL = typer.Option("zd", "--vertical", help="zd (zenith distance) or va (vertical angle).")


#: the command's help (its line breaks are those --help shows)
SIMULATE_TOTAL_STATION_HELP = ("Simulate total-station observations of a circular-scan lidar with "
                               "a known range offset and scale\n(at most 2 000 targets: what "
                               "range-cal reads).")


def simulate_total_station(
    out: Path = typer.Option(..., "--out", help="Output folder: observations.csv, truth.json."),
    seed: int = typer.Option(0, "--seed", help="Random seed (≥ 0)."),
    setups: int = typer.Option(2, "--setups", help="Total-station setups (1–50)."),
    groups: int = typer.Option(3, "--groups", help="Scan-circle groups (A–D) per setup (≥ 1)."),
    e_points: int = typer.Option(5, "--e-points", help="E points per setup (≥ 0)."),
    outliers: int = OUTLIERS,
    angle_unit: str = typer.Option("deg", "--angle-unit", help="deg or gon."),
    vertical: str = VERTICAL,
    force: bool = typer.Option(False, "--force", help=FORCE_HELP),
) -> None:
    """``calidar total-station`` (its help: SIMULATE_TOTAL_STATION_HELP)."""
    from calidar.outputs import output_folder
    from calidar.pipelines.rangecal import run_simulate_total_station, simulation_config

    config = simulation_config(setups, groups, e_points, outliers)
    with output_folder(out, force) as tmp:
        obs, truth, _ = run_simulate_total_station(tmp, seed, config, angle_unit=angle_unit,
                                                   vertical=vertical)
    _say(f"wrote {out / 'observations.csv'} ({len(obs)} targets) and {out / 'truth.json'}: "
         f"range_offset {truth['range_offset_m'] * 1e3:+.2f} mm, range_scale "
         f"{truth['range_scale_ppm']:+.1f} ppm")


def register(app: typer.Typer, simulate: typer.Typer) -> None:
    app.command("range-cal", help=RANGE_CAL_HELP)(range_cal)
    simulate.command("total-station", help=SIMULATE_TOTAL_STATION_HELP)(simulate_total_station)
