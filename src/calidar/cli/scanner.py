"""``calidar scanner analyze``: structural errors of Palmer, wedge and linear scanners."""

from __future__ import annotations

import json
import sys
from pathlib import Path

import typer

from calidar.cli.common import (
    CONFIG_HELP, FORCE_HELP, config_values, console, exit_with_verdict, given_options,
    print_verdict, progress_bar, progress_callback,
)

#: options → (ScannerConfig attribute, parse): the settings' fields and the errors' names
_SETTINGS = (("model", "model"), ("range_m", "range_m"), ("phase", "phase_deg"),
             ("axis_tilt_azimuth", "axis_tilt_azimuth_deg"), ("axis_angle", "axis_angle_deg"),
             ("mirror_tilt", "mirror_tilt_deg"), ("wedge_angle", "wedge_angle_deg"),
             ("refractive_index", "refractive_index"), ("fov", "fov_deg"),
             ("grating_radius_mm", "grating_radius_mm"), ("spec_arcsec", "spec_arcsec"),
             ("points", "points"))
_ERRORS = ("eccentricity", "delta_l", "delta_r", "wedge_angle_error", "axis_tilt",
           "scan_angle_offset", "scan_angle_scale")
OPTIONS = {**{p: (f"settings.{f}", None) for p, f in _SETTINGS},
           **{e: (f"settings.errors.{e}", None) for e in _ERRORS}}


MODEL = typer.Option(None, "--model", help="palmer | wedge | linear (required unless in --config).")
RANGE_M = typer.Option(None, "--range", help="Range to the pattern (m, > 0, ≤ 1e6; required "
                       "unless in --config).")
OUT = typer.Option(..., "--out", help="Output folder (CSV, PNG, summary.json, report.html).")
ECCENTRICITY = typer.Option(None, "--eccentricity", help="Encoder eccentricity ε/r (ratio, 0–0.1).")
DELTA_L = typer.Option(None, "--delta-l", help="Palmer laser–axis angle error δ_L (deg, |·| ≤ 10).")
DELTA_R = typer.Option(None, "--delta-r",
                       help="Palmer mirror-normal–axis angle error δ_R (deg, |·| ≤ 10).")
WEDGE_ANGLE_ERROR = typer.Option(None, "--wedge-angle-error",
                                 help="Wedge angle error (deg, |·| ≤ 10).")
AXIS_TILT = typer.Option(None, "--axis-tilt", help="Wedge rotation-axis tilt (deg, 0–10).")
AXIS_TILT_AZIMUTH = typer.Option(0.0, "--axis-tilt-azimuth",
                                 help="Direction of the tilt from x (deg).")
SCAN_ANGLE_OFFSET = typer.Option(None, "--scan-angle-offset",
                                 help="Linear scan-angle offset (deg, |·| ≤ 10).")
SCAN_ANGLE_SCALE = typer.Option(None, "--scan-angle-scale",
                                help="Linear scan-angle scale (ppm, |·| ≤ 1e5).")
AXIS_ANGLE = typer.Option(45.0, "--axis-angle",
                          help="Palmer motor-axis to laser angle A (deg, 0–90).")
MIRROR_TILT = typer.Option(7.5, "--mirror-tilt",
                           help="Palmer mirror-normal to axis angle B (deg, 0–A).")
REFRACTIVE_INDEX = typer.Option(1.5168, "--refractive-index", help="Wedge refractive index (1–4).")
GRATING_RADIUS_MM = typer.Option(75.0, "--grating-radius-mm",
                                 help="Encoder grating radius (mm, 0–1000).")
SPEC_ARCSEC = typer.Option(10.0, "--spec-arcsec",
                           help="Pointing spec for the verdict and tolerances (arcsec).")


#: the command's help (its line breaks are those --help shows)
ANALYZE_HELP = ("Scan pattern at a range, per-error point displacements, error budget, tolerances, "
                "separability\nfrom the boresight, and a verdict against the pointing spec; "
                "config.toml holds this run's settings\n(for --config).")


def analyze(
    ctx: typer.Context,
    model: str | None = MODEL,
    range_m: float | None = RANGE_M,
    out: Path = OUT,
    eccentricity: float | None = ECCENTRICITY,
    phase: float = typer.Option(0.0, "--phase", help="Eccentricity phase C (deg)."),
    delta_l: float | None = DELTA_L,
    delta_r: float | None = DELTA_R,
    wedge_angle_error: float | None = WEDGE_ANGLE_ERROR,
    axis_tilt: float | None = AXIS_TILT,
    axis_tilt_azimuth: float = AXIS_TILT_AZIMUTH,
    scan_angle_offset: float | None = SCAN_ANGLE_OFFSET,
    scan_angle_scale: float | None = SCAN_ANGLE_SCALE,
    axis_angle: float = AXIS_ANGLE,
    mirror_tilt: float = MIRROR_TILT,
    wedge_angle: float = typer.Option(20.0, "--wedge-angle", help="Wedge apex angle (deg, 0–90)."),
    refractive_index: float = REFRACTIVE_INDEX,
    fov: float = typer.Option(60.0, "--fov", help="Linear scanner field of view (deg, 0–360)."),
    grating_radius_mm: float = GRATING_RADIUS_MM,
    spec_arcsec: float = SPEC_ARCSEC,
    points: int = typer.Option(720, "--points", help="Points around the pattern (8–100000)."),
    as_json: bool = typer.Option(False, "--json", help="Print the summary as JSON on stdout."),
    force: bool = typer.Option(False, "--force", help=FORCE_HELP),
    config: Path | None = typer.Option(None, "--config", help=CONFIG_HELP),
) -> None:
    """``calidar analyze`` (its help: ANALYZE_HELP)."""
    from calidar.outputs import output_folder
    from calidar.pipelines.scanner import run_scanner_analysis
    from calidar.pipelines.scanner_config import ScannerConfig

    for name, option in (("model", "--model"), ("range_m", "--range")):
        if config is None and ctx.params[name] is None:
            raise typer.BadParameter("missing (give it, or a --config file with it)",
                                     param_hint=option)
    cfg = ScannerConfig.configure(config, config_values(given_options(ctx), OPTIONS))
    with output_folder(out, force, inputs=[config]) as tmp, progress_bar() as bar:
        run = run_scanner_analysis(cfg.settings, tmp, progress=progress_callback(bar))
        cfg.write(tmp / "config.toml")
    if as_json:
        sys.stdout.write(json.dumps(run.summary, allow_nan=False) + "\n")
        exit_with_verdict(run.verdict)
        return
    _print_summary(run.summary, out)
    print_verdict(run.verdict)
    exit_with_verdict(run.verdict)


def _print_summary(s: dict, out: Path) -> None:
    from rich.table import Table

    p = s["pattern"]
    console.print(f"{s['model']} pattern at {s['range_m']:g} m: {p['extent_x_m']:.2f} m (x) × "
                  f"{p['extent_y_m']:.2f} m (y)",
                  highlight=False, markup=False)
    t = Table("error", "value", "max |dX| [mm]", "max |dY| [mm]", "max |dZ| [mm]",
              "worst pointing [″]")
    rows = list(s["errors"].items()) + list(s.get("comparisons", {}).items())
    if s["combined"]:
        rows.append(("all together", s["combined"]))
    for name, e in rows:
        value = f"{e['value']:g} {e['unit']}" if "value" in e else ""
        mm = (f"{e[k] * 1e3:.2f}" for k in ("max_abs_dx_m", "max_abs_dy_m", "max_abs_dz_m"))
        t.add_row(name, value, *mm, f"{e['max_pointing_arcsec']:.2f}")
    console.print(t)
    t = Table("error", "unit", f"largest alone (≤ {s['spec_arcsec']:g}″)",
              "largest with an equal RSS share")
    for name, v in s["tolerances"].items():
        t.add_row(name, v["unit"], f"{v['max_alone']:.4g}", f"{v['max_equal_share']:.4g}")
    console.print(t)
    for note in s["notes"]:
        console.print(f"note: {note}", highlight=False, soft_wrap=True, markup=False)
    console.print(f"wrote {out}/report.html, summary.json, pattern and displacement CSV/PNG",
                  highlight=False, soft_wrap=True, markup=False)


def register(app: typer.Typer, simulate: typer.Typer) -> None:
    scanner = typer.Typer(help="Scanner models: structural-error analysis and tolerances.",
                          no_args_is_help=True)
    scanner.command("analyze", help=ANALYZE_HELP)(analyze)
    app.add_typer(scanner, name="scanner")
