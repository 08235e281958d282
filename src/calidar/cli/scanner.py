"""``calidar scanner analyze``: structural errors of Palmer, wedge and linear scanners."""

from __future__ import annotations

import json
import sys
from pathlib import Path

import numpy as np
import typer

from calidar.cli.common import console
from calidar.errors import InputError

#: CLI option → (error name, models it applies to).
_ERROR_OPTIONS = {
    "--eccentricity": ("eccentricity", ("palmer", "wedge")),
    "--delta-l": ("delta_l", ("palmer",)),
    "--delta-r": ("delta_r", ("palmer",)),
    "--wedge-angle-error": ("wedge_angle_error", ("wedge",)),
    "--axis-tilt": ("axis_tilt", ("wedge",)),
    "--scan-angle-offset": ("scan_angle_offset", ("linear",)),
    "--scan-angle-scale": ("scan_angle_scale", ("linear",)),
}


def register(app: typer.Typer, simulate: typer.Typer) -> None:
    scanner = typer.Typer(help="Scanner models: structural-error analysis and tolerances.", no_args_is_help=True)
    app.add_typer(scanner, name="scanner")

    @scanner.command("analyze")
    def analyze_cmd(
        model: str = typer.Option(..., "--model", help="palmer | wedge | linear"),
        range_m: float = typer.Option(..., "--range", help="Range to the pattern (m)."),
        out: Path = typer.Option(..., "--out", help="Output folder (CSV, PNG, summary.json, report.html)."),
        eccentricity: float | None = typer.Option(None, "--eccentricity", help="Encoder eccentricity ε/r (ratio)."),
        phase: float = typer.Option(0.0, "--phase", help="Eccentricity phase C (deg)."),
        delta_l: float | None = typer.Option(None, "--delta-l", help="Palmer laser–axis angle error δ_L (deg)."),
        delta_r: float | None = typer.Option(None, "--delta-r", help="Palmer mirror-normal–axis angle error δ_R (deg)."),
        wedge_angle_error: float | None = typer.Option(None, "--wedge-angle-error", help="Wedge angle error (deg)."),
        axis_tilt: float | None = typer.Option(None, "--axis-tilt", help="Wedge rotation-axis tilt (deg)."),
        axis_tilt_azimuth: float = typer.Option(0.0, "--axis-tilt-azimuth", help="Direction of the tilt from x (deg)."),
        scan_angle_offset: float | None = typer.Option(None, "--scan-angle-offset", help="Linear scan-angle offset (deg)."),
        scan_angle_scale: float | None = typer.Option(None, "--scan-angle-scale", help="Linear scan-angle scale (ppm)."),
        axis_angle: float = typer.Option(45.0, "--axis-angle", help="Palmer motor-axis to laser angle A (deg)."),
        mirror_tilt: float = typer.Option(7.5, "--mirror-tilt", help="Palmer mirror-normal to axis angle B (deg)."),
        wedge_angle: float = typer.Option(20.0, "--wedge-angle", help="Wedge apex angle (deg)."),
        refractive_index: float = typer.Option(1.5168, "--refractive-index", help="Wedge refractive index."),
        fov: float = typer.Option(60.0, "--fov", help="Linear scanner field of view (deg)."),
        grating_radius_mm: float = typer.Option(75.0, "--grating-radius-mm", help="Encoder grating radius (mm)."),
        spec_arcsec: float = typer.Option(10.0, "--spec-arcsec", help="Pointing spec for the tolerances (arcsec)."),
        points: int = typer.Option(720, "--points", help="Points around the pattern."),
        as_json: bool = typer.Option(False, "--json", help="Print the summary as JSON on stdout."),
        force: bool = typer.Option(False, "--force", help="Write into a non-empty output folder."),
    ) -> None:
        """Scan pattern at a range, per-error point displacements, error budget and tolerances."""
        from calidar import scanner_analysis as sa
        from calidar.outputs import prepare_out_dir

        if model not in ("palmer", "wedge", "linear"):
            raise InputError(None, "--model", f"expected one of palmer, wedge, linear, got {model!r}")
        if points < 8:
            raise InputError(None, "--points", f"expected at least 8, got {points}")
        given = {"--eccentricity": eccentricity, "--delta-l": delta_l, "--delta-r": delta_r,
                 "--wedge-angle-error": wedge_angle_error, "--axis-tilt": axis_tilt,
                 "--scan-angle-offset": scan_angle_offset, "--scan-angle-scale": scan_angle_scale}
        sources = {s.name: s for s in sa.error_sources(model)}
        errors = {}
        for option, value in given.items():
            if value is None:
                continue
            name, models = _ERROR_OPTIONS[option]
            if model not in models:
                raise InputError(None, option, f"applies to --model {' or '.join(models)}, not {model}")
            if not np.isfinite(value):
                raise InputError(None, option, f"expected a finite number, got {value}")
            errors[name] = sources[name].to_si(value)
        analysis = sa.analyze(
            model, range_m, errors, spec_arcsec=spec_arcsec, eccentricity_phase_rad=np.radians(phase),
            axis_tilt_azimuth_rad=np.radians(axis_tilt_azimuth), grating_radius_m=grating_radius_mm * 1e-3,
            fov_deg=fov, n=points, axis_angle_deg=axis_angle, mirror_tilt_deg=mirror_tilt,
            wedge_angle_deg=wedge_angle, refractive_index=refractive_index)
        summary = sa.write_outputs(analysis, prepare_out_dir(out, force))
        if as_json:
            sys.stdout.write(json.dumps(summary) + "\n")
            return
        _print_summary(summary, out)


def _print_summary(s: dict, out: Path) -> None:
    from rich.table import Table

    p = s["pattern"]
    console.print(f"{s['model']} pattern at {s['range_m']:g} m: {p['extent_x_m']:.2f} m (x) × {p['extent_y_m']:.2f} m (y)")
    t = Table("error", "value", "max |dX| mm", "max |dY| mm", "max |dZ| mm", "max pointing ″")
    rows = list(s["errors"].items()) + list(s.get("comparisons", {}).items())
    if s["combined"]:
        rows.append(("all together", s["combined"]))
    for name, e in rows:
        value = f"{e['value']:g} {e['unit']}" if "value" in e else ""
        t.add_row(name, value, *(f"{e[k] * 1e3:.2f}" for k in ("max_abs_dx_m", "max_abs_dy_m", "max_abs_dz_m")),
                  f"{e['max_pointing_arcsec']:.2f}")
    console.print(t)
    t = Table("error", "unit", f"max alone (≤ {s['spec_arcsec']:g}″)", "max with equal RSS share")
    for name, v in s["tolerances"].items():
        t.add_row(name, v["unit"], f"{v['max_alone']:.4g}", f"{v['max_equal_share']:.4g}")
    console.print(t)
    for note in s["notes"]:
        console.print(f"note: {note}")
    console.print(f"wrote {out}/report.html, summary.json, pattern and displacement CSV/PNG")
