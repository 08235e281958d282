"""``calidar trajectory``: the sensor's flight path reconstructed from delivered points
(:mod:`calidar.pipelines.trajectory`)."""

from __future__ import annotations

import json
import shlex
import sys
from pathlib import Path

import numpy as np
import typer
from rich.markup import escape

from calidar.cli.common import (
    CONFIG_HELP, config_values, console, given_options, print_warning, progress_bar,
    progress_callback,
)
from calidar.cli.options import CRS, GEOID_UNDULATION, POINT_VALUES, TIME_SYSTEM
from calidar.validate import number

#: the options' defaults (mounting.DEFAULT_SIGMA)
ENCODER_SIGMA, SCAN_PLANE_SIGMA = "0.1,0.3,0.2", "0.1,0.1,0.02"
#: options → (TrajectoryConfig attribute, parse); --encoder-sigma and --scan-plane-sigma set the
#: mount σ together
OPTIONS = {"rate": ("settings.rate_hz", None), "points_per_second": ("settings.points_per_s", None),
           "knot_spacing": ("settings.fit.knot_s", None),
           "no_scan_angles": ("settings.fit.use_scan_angles", lambda no: not no),
           "scan_plane_yaw": ("settings.fit.scan_plane_yaw", lambda deg: _radians_yaw(deg)),
           **POINT_VALUES}


def _radians_yaw(deg: float) -> float:
    """--scan-plane-yaw in degrees, checked, in radians."""
    return float(np.radians(number(deg, "--scan-plane-yaw", -90.0, 90.0, "deg")))


POINTS = typer.Argument(..., help="LAS/LAZ files with GPS times (one or several flight lines "
                                  "each).")
OUT = typer.Option(..., "--out", "-o",
                   help="Trajectory file to write (text with σ columns, or SBET).")
FMT = typer.Option(None, "--format", help="text (CSV with σ columns) or sbet (default: sbet for "
                   "a .out/.sbet name, else text).")
REPORT = typer.Option(None, "--report", help="Report file (default: report.html beside --out).")
COMPARE = typer.Option(None, "--compare", help="A known trajectory of the same flight (SBET or "
                       "text): the errors against it in the report and the output.")
SENSOR_OUT = typer.Option(None, "--sensor-out", help="Also write the sensor.toml the trajectory "
                          "goes with (zero lever arm and boresight), e.g. for calidar boresight.")
POINTS_PER_SECOND = typer.Option(600.0, "--points-per-second",
                                 help="Points (and multi-return pulses) each line keeps a second "
                                      "for the fit.")
KNOT_SPACING = typer.Option(0.25, "--knot-spacing", help="Spacing of the trajectory spline's "
                            "knots, s (shorter: follows faster attitude changes, needs denser "
                            "points).")
NO_SCAN_ANGLES = typer.Option(False, "--no-scan-angles", help="Ignore the scan-angle field (when "
                              "it is known to be wrong); roll is then not determined.")
SCANNER = typer.Option("planar", "--scanner", help="planar: each scan line's beams lie in one "
                       "plane (oscillating mirror, polygon); other: rely on the multi-return rays "
                       "alone.")
SCAN_PLANE_YAW = typer.Option(0.0, "--scan-plane-yaw", help="Yaw of the scan plane in the body, "
                              "deg, when the scan-angle field holds body-frame angles (leeward's "
                              "scanner: 13.96); the heading written is then the body's.")
ENCODER_SIGMA_OPTION = typer.Option(ENCODER_SIGMA, "--encoder-sigma",
                                    help="Prior σ of the scan-angle encoder's offset (deg), scale "
                                         "(%) and curvature (deg at 30°); 0,0 when known. Fitted "
                                         "where the points determine them, else passed into the σ "
                                         "columns.")
SCAN_PLANE_SIGMA_OPTION = typer.Option(SCAN_PLANE_SIGMA, "--scan-plane-sigma",
                                       help="Prior σ of the scan plane's yaw (about "
                                            "--scan-plane-yaw), pitch and cone (beams out of the "
                                            "plane), deg.")


def trajectory(
    ctx: typer.Context,
    points: list[Path] = POINTS,
    out: Path = OUT,
    fmt: str | None = FMT,
    report: Path | None = REPORT,
    compare: Path | None = COMPARE,
    sensor_out: Path | None = SENSOR_OUT,
    rate: float = typer.Option(50.0, "--rate", help="Epochs written a second, Hz."),
    points_per_second: float = POINTS_PER_SECOND,
    knot_spacing: float = KNOT_SPACING,
    no_scan_angles: bool = NO_SCAN_ANGLES,
    scanner: str = SCANNER,
    scan_plane_yaw: float = SCAN_PLANE_YAW,
    encoder_sigma: str = ENCODER_SIGMA_OPTION,
    scan_plane_sigma: str = SCAN_PLANE_SIGMA_OPTION,
    crs: str | None = CRS, time_system: str | None = TIME_SYSTEM,
    geoid_undulation: float | None = GEOID_UNDULATION,
    as_json: bool = typer.Option(False, "--json", help="Print the per-line summary as JSON."),
    force: bool = typer.Option(False, "--force", help="Overwrite the outputs."),
    config: Path | None = typer.Option(None, "--config", help=CONFIG_HELP),
) -> None:
    """Reconstruct each flight line's sensor trajectory from the points alone (multi-return rays,
    scan angles, scan-line geometry), with a σ per epoch; write it, a report and the run's settings
    (<name>.config.toml beside it, for --config)."""
    from calidar.outputs import guard_inputs
    from calidar.pipelines import trajectory as pipeline
    from calidar.pipelines.config_file import config_beside
    from calidar.trajrec.summary import line_summary

    cfg = _config(config, given_options(ctx))
    if fmt is not None and fmt not in pipeline.FORMATS:
        raise typer.BadParameter(f"expected text or sbet, got {fmt!r}", param_hint="--format")
    fmt = pipeline.output_format(out, fmt)
    rep = report if report is not None else out.parent / "report.html"
    guard_inputs([out, rep, sensor_out, config_beside(out)], [*points, compare, config])
    _check_outputs((out, rep, sensor_out, config_beside(out)), force)
    with progress_bar() as bar:
        run = pipeline.reconstruct_trajectory(points, cfg.points, cfg.settings,
                                              progress_callback(bar))
    command = "calidar " + " ".join(shlex.quote(a) for a in sys.argv[1:])
    comparison = pipeline.compare_with(run, compare) if compare is not None else None
    pipeline.write_outputs(run, out, fmt, rep, [command], force, sensor_out, comparison)
    cfg.write(config_beside(out))
    summaries = [line_summary(ln) for ln in run.lines]
    if as_json:
        print(json.dumps({"lines_from": run.lines_from, "lines": summaries, "notes": run.notes,
                          "counts": run.counts, "comparison": comparison},
                         indent=2, ensure_ascii=False))
        return
    _print(run, summaries)
    for n in run.notes[len(pipeline.STANDING_NOTES):]:
        print_warning(n)
    if comparison:
        console.print(f"against {escape(str(compare))}: 3-D position median "
                      f"{comparison['position_3d_m']['median']:.3f} m, height "
                      f"{comparison['height_m']['median']:.3f} m, heading "
                      f"{comparison['heading_deg']['median']:.4f}°, roll "
                      f"{comparison['roll_deg']['median']:.4f}°, pitch "
                      f"{comparison['pitch_deg']['median']:.4f}°",
                      highlight=False, soft_wrap=True)
    also = f", {escape(str(sensor_out))}" if sensor_out is not None else ""
    console.print(f"wrote {escape(str(out))} ({fmt}){also}, {escape(str(config_beside(out)))} "
                  f"and {escape(str(rep))}",
                  highlight=False, soft_wrap=True)


def register(app: typer.Typer, simulate: typer.Typer) -> None:
    app.command("trajectory")(trajectory)


def _config(path: Path | None, given: dict):
    """The run's TrajectoryConfig: the ``--config`` file's (else the defaults) with the options
    ``given``."""
    from calidar.pipelines.trajectory_config import TrajectoryConfig

    values = config_values(given, OPTIONS)
    if "scanner" in given:
        if given["scanner"] not in ("planar", "other"):
            raise typer.BadParameter(f"expected planar or other, got {given['scanner']!r}",
                                     param_hint="--scanner")
        values["settings.fit.planar_scanner"] = given["scanner"] == "planar"
    # each of the two options replaces its own three priors (their defaults: mounting.DEFAULT_SIGMA)
    mount = _mount_sigma(given.get("encoder_sigma", ENCODER_SIGMA),
                         given.get("scan_plane_sigma", SCAN_PLANE_SIGMA))
    for option, items in (("encoder_sigma", (0, 1, 4)), ("scan_plane_sigma", (2, 3, 5))):
        if option in given:
            values.update({f"settings.fit.mount_sigma.{k}": float(mount[k]) for k in items})
    return TrajectoryConfig.configure(path, values)


def _check_outputs(paths, force: bool) -> None:
    """Checked before the run; folders are made only when writing (a failed run leaves none)."""
    from calidar.errors import OutputExistsError

    for path in paths:
        if path is not None and path.is_dir():
            raise OutputExistsError(f"{path}: is a folder; expected a file name")
        if path is not None and path.exists() and not force:
            raise OutputExistsError(f"{path}: exists; pass --force to overwrite it")


def _mount_sigma(encoder_sigma: str, scan_plane_sigma: str) -> tuple[float, ...]:
    """The prior σ of calidar.trajrec.mounting.NAMES (SI) from --encoder-sigma and
    --scan-plane-sigma."""
    from calidar.trajrec.mounting import DEFAULT_SIGMA

    encoder_units = (np.radians(1.0), 0.01, np.radians(1.0))
    enc = _pair(encoder_sigma, "--encoder-sigma", encoder_units, DEFAULT_SIGMA[4])
    plane = _pair(scan_plane_sigma, "--scan-plane-sigma", (np.radians(1.0),) * 3, DEFAULT_SIGMA[5])
    return enc[0], enc[1], plane[0], plane[1], enc[2], plane[2]


def _pair(text: str, option: str, units: tuple[float, float, float],
          third: float) -> tuple[float, float, float]:
    """Two or three numbers "a,b[,c]" from 0 to 10 (of the option's units), in SI (times
    ``units``); without c, ``third`` (already SI), or 0 when a and b are both 0 (a scanner whose
    calibration is known)."""
    from calidar.errors import InputError

    parts = text.split(",")
    if len(parts) not in (2, 3):
        raise InputError(option, None, f"expected two or three numbers a,b[,c], got {text!r}")
    v = [number(p.strip(), option, 0.0, 10.0) * u for p, u in zip(parts, units)]
    if len(v) == 2:
        v.append(third if any(v) else 0.0)
    return tuple(v)


def _print(run, summaries) -> None:
    from rich.table import Table

    import numpy as np

    d = np.degrees
    table = Table(title=f"Reconstructed lines (from {run.lines_from}; read "
                  f"{run.timings['read_s']:.2f} s, fit {run.timings['fit_s']:.2f} s)")
    heads = ("line", "s", "height m", "speed m/s", "heading °", "σ pos m", "σ roll°",
             "σ pitch°", "σ head°")
    for h in heads:
        table.add_column(h, justify="right")
    for s in summaries:
        g = s["sigma_median"]
        sigma_position = max(g["east_m"], g["north_m"], g["up_m"])
        table.add_row(s["line"], f"{s['duration_s']:.1f}", f"{s['height_m']:.1f}",
                      f"{s['speed_mps']:.1f}", f"{d(s['heading_rad']):.2f}",
                      f"{sigma_position:.2g}",
                      f"{d(g['roll_rad']):.2g}", f"{d(g['pitch_rad']):.2g}",
                      f"{d(g['heading_rad']):.2g}")
    console.print(table)
