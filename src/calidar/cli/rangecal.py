"""``calidar range-cal`` and ``calidar simulate total-station``.

Exit codes of ``range-cal``: 0 done (and, with ``--tolerance``, the acceptance passed);
1 bad input; 3 the acceptance check failed (the 95 % bound of the raw range error over the
calibrated distances exceeds the tolerance).
"""

from __future__ import annotations

import json
from pathlib import Path

import typer

from calidar.cli.common import console, read_json
from calidar.errors import InputError

ACCEPTANCE_FAILED = 3  #: exit code when --tolerance is given and the check fails


def _read_truth(path: Path) -> dict:
    from calidar.rangecal import truth_parameters

    doc = read_json(path)
    try:
        truth_parameters(doc)
    except (KeyError, TypeError, ValueError, AttributeError):
        raise InputError(path, None, "expected a truth.json with numbers range_offset_m and range_scale_ppm") from None
    return doc


def range_cal(
    observations: Path = typer.Argument(..., help="Observation file (CSV, format in docs/architecture.md)."),
    out: Path = typer.Option(..., "--out", help="Output folder: solution.json, report.html."),
    truth: Path | None = typer.Option(None, "--truth", help="truth.json of a simulation: adds truth and error."),
    tolerance: float | None = typer.Option(None, "--tolerance", help="Acceptance tolerance of the raw range error (m); "
                                           "exit code 3 when the 95 % bound exceeds it."),
    fix_scale: bool = typer.Option(False, "--fix-scale", help="Estimate the offset only (range_scale fixed at 0), "
                                   "e.g. when all targets are at one distance."),
    force: bool = typer.Option(False, "--force", help="Write into a non-empty output folder."),
) -> None:
    """Calibrate range offset and scale of a circular-scan lidar against total-station observations.

    Exit codes: 0 done (acceptance passed when --tolerance is given), 1 bad input, 3 acceptance failed.
    """
    from calidar.io.total_station import read_observations
    from calidar.outputs import prepare_out_dir
    from calidar.rangecal import calibrate, truth_parameters
    from calidar.rangecal.report import add_section
    from calidar.report import Report

    if tolerance is not None and not tolerance > 0:
        raise InputError(None, "--tolerance", f"expected a positive distance in m, got {tolerance}")
    obs = read_observations(observations)
    truth_doc = _read_truth(truth) if truth else None
    result = calibrate(obs, tolerance, fix_scale)  # before creating the folder: a failed calibration leaves nothing
    folder = prepare_out_dir(out, force)
    sol = result.solution
    sol.write_json(folder / "solution.json", truth_parameters(truth_doc) if truth_doc else None)
    report = Report("calidar range calibration")
    add_section(report, result, truth_doc)
    report.write(folder / "report.html")
    for name, f, unit in (("range_offset", 1e3, "mm"), ("range_scale", 1e6, "ppm")):
        if result.fit.interval(name) is None:
            continue
        lo, hi = result.fit.interval(name)
        console.print(f"{name} = {sol.values[name] * f:+.3f} ± {sol.sigma[name] * f:.3f} {unit} "
                      f"(95 %: {lo * f:+.3f} … {hi * f:+.3f} {unit})", highlight=False)
    m = result.method
    console.print(f"two-step method: ΔS = {m.delta_s * 1e3:+.3f} mm"
                  + (f", Δ = {m.delta * 1e3:+.3f} mm" if m.delta is not None else ""), highlight=False)
    for r in result.fit.rejected:
        console.print(f"outlier rejected: line {r['line']} point {r['point']} (w = {r['w']:+.1f})", highlight=False)
    console.print(f"wrote {folder / 'solution.json'} and {folder / 'report.html'}", highlight=False)
    if result.acceptance is not None:
        a = result.acceptance
        console.print(f"acceptance: {'PASS' if a['passed'] else 'FAIL'} (95 % bound {a['max_bound95_m'] * 1e3:.2f} mm, "
                      f"tolerance {a['tolerance_m'] * 1e3:.2f} mm)", highlight=False)
        if not a["passed"]:
            raise typer.Exit(ACCEPTANCE_FAILED)


def simulate_total_station(
    out: Path = typer.Option(..., "--out", help="Output folder: observations.csv, truth.json."),
    seed: int = typer.Option(0, "--seed", help="Random seed."),
    setups: int = typer.Option(2, "--setups", min=1, help="Total-station setups."),
    groups: int = typer.Option(3, "--groups", min=1, help="Scan-circle groups (A–D) per setup."),
    e_points: int = typer.Option(5, "--e-points", min=0, help="E points per setup."),
    outliers: int = typer.Option(0, "--outliers", min=0, help="Scanner ranges with a gross error."),
    angle_unit: str = typer.Option("deg", "--angle-unit", help="deg or gon."),
    vertical: str = typer.Option("zd", "--vertical", help="zd (zenith distance) or va (vertical angle)."),
    force: bool = typer.Option(False, "--force", help="Write into a non-empty output folder."),
) -> None:
    """Simulate total-station observations of a circular-scan lidar with a known range offset and scale."""
    from calidar.io.total_station import ANGLE_UNITS, write_observations
    from calidar.outputs import prepare_out_dir, write_text_atomic
    from calidar.sim.total_station import TotalStationSimConfig, simulate_total_station as simulate_ts

    if angle_unit not in ANGLE_UNITS:
        raise InputError(None, "--angle-unit", f"expected deg or gon, got {angle_unit!r}")
    if vertical not in ("va", "zd"):
        raise InputError(None, "--vertical", f"expected zd or va, got {vertical!r}")
    if outliers > setups * (4 * groups + e_points):
        raise InputError(None, "--outliers", f"expected at most the {setups * (4 * groups + e_points)} targets")
    folder = prepare_out_dir(out, force)
    obs, truth = simulate_ts(seed, TotalStationSimConfig(n_setups=setups, groups_per_setup=groups,
                                                         e_per_setup=e_points, outliers=outliers))
    write_observations(folder / "observations.csv", obs, angle_unit, vertical, force=True,
                       comments=[f"simulated by calidar simulate total-station --seed {seed}"])
    write_text_atomic(folder / "truth.json", json.dumps(truth, indent=2) + "\n")
    console.print(f"wrote {folder / 'observations.csv'} ({len(obs)} targets) and {folder / 'truth.json'}: "
                  f"range_offset {truth['range_offset_m'] * 1e3:+.2f} mm, range_scale {truth['range_scale_ppm']:+.1f} ppm",
                  highlight=False)


def register(app: typer.Typer, simulate: typer.Typer) -> None:
    app.command("range-cal")(range_cal)
    simulate.command("total-station")(simulate_total_station)
