"""``calidar plan``: predicted σ of a planned calibration flight, before it is flown."""

from __future__ import annotations

from pathlib import Path

import typer
from rich.markup import escape

from calidar.cli.common import (
    CONFIG_HELP, FORCE_HELP, config_values, console, exit_with_verdict, given_options,
    print_verdict, progress_bar, progress_callback,
)
from calidar.cli.options import parse_sigma
from calidar.errors import InputError


def _estimate(text: str):
    """--estimate as ``calidar boresight`` writes it (names separated by commas); trajectory_bias is
    refused here: a plan always models the trajectory."""
    from calidar.pipelines.plan_config import estimate_of

    return estimate_of(tuple(n.strip() for n in text.split(",") if n.strip()))


def parse_terrain(text: str):
    """--terrain: flat, flat:HEIGHT_M, scene[:PRESET[:SEED]] or a DEM GeoTIFF's path → a
    TerrainChoice."""
    from calidar.pipelines.plan import TerrainChoice

    kind, _, rest = text.partition(":")
    if kind == "flat":
        try:
            return TerrainChoice("flat", float(rest) if rest else 0.0)
        except ValueError:
            expected = f"expected flat or flat:HEIGHT_M, got {text!r}"
            raise InputError(None, "--terrain", expected) from None
    if kind == "scene":
        preset, _, seed = rest.partition(":")
        if seed and not seed.isdigit():
            raise InputError(None, "--terrain", "expected scene[:PRESET[:SEED]] with SEED an "
                             f"integer ≥ 0, got {text!r}")
        return TerrainChoice("scene", preset=preset or "uav", seed=int(seed or 0))
    return TerrainChoice("dem", path=Path(text))


def parse_platform_motion(text: str) -> tuple[float, float]:
    """--platform-motion 'ROLL_PITCH_DEG,HEADING_DEG' → (σ roll/pitch, σ heading) rad (the pipeline
    checks the range)."""
    import math

    from calidar.validate import parse_floats

    roll_pitch, heading = parse_floats(text, 2, "--platform-motion (ROLL_PITCH_DEG,HEADING_DEG)")
    return math.radians(roll_pitch), math.radians(heading)


LINES = typer.Argument(..., help="Flight lines, CSV (line, start_x, start_y, end_x, end_y, "
                       "height_agl_m, speed_mps; projected metres) or GeoJSON LineStrings with "
                       "those properties.")
SENSOR = typer.Option(..., "--sensor",
                      help="The nominal sensor.toml (lever arm, boresight, scanner).")
TERRAIN = typer.Option("flat", "--terrain", help="flat, flat:HEIGHT_M, scene[:uav|airborne[:SEED]] "
                       "(the simulator's built-in scene with roofs), or a DEM GeoTIFF in the "
                       "lines' metres.")
FOV = typer.Option(70.0, "--fov", help="Full field of view across track, degrees (a linear "
                   "scanner; a rotating one's pattern in sensor.toml sets its own swath).")
ESTIMATE = typer.Option("boresight", "--estimate", help="What to estimate, as calidar boresight "
                        "--estimate: boresight, lever_arm, range_offset, range_scale or single "
                        "names.")
TRAJECTORY_SIGMA = typer.Option("0.02,0.002", "--trajectory-sigma",
                                help="Expected trajectory accuracy: POSITION_M,ATTITUDE_DEG (1σ).")
ANGLE_SIGMA = typer.Option(0.002, "--angle-sigma", help="Encoder (scan-angle) noise, 1σ, degrees.")
PLATFORM_MOTION = typer.Option("1.5,1.0", "--platform-motion", help="σ of the platform's attitude "
                               "wobble along a line, ROLL_PITCH_DEG,HEADING_DEG (UAV ≈ 1.5,1; "
                               "aircraft ≈ 0.8,1.5): a tilted body lets heading errors show.")
SUGGEST = typer.Option(True, "--suggest/--no-suggest", help="Try candidate lines and name the one "
                       "that most improves the worst-determined parameter.")
SIMULATE = typer.Option(0, "--simulate", help="Confirm the plan: simulate and calibrate it end to "
                        "end N times (flat or scene terrain; each takes seconds to minutes).")


#: the command's help (its line breaks are those --help shows)
PLAN_HELP = ("Predict the σ and correlations a planned calibration flight will give, before flying "
             "it: which\nparameters it will not determine and why, and the line that helps most; "
             "config.toml holds this run's\nsettings (for --config).\n\nExit codes: 0 every "
             "estimated parameter determined, 3 a poor plan (FAIL verdict), 1 bad input,\n2 usage "
             "error, 130/143 interrupted.")


def plan(
    ctx: typer.Context,
    lines: Path = LINES,
    sensor: Path = SENSOR,
    out: Path = typer.Option(..., "--out", help="Output folder: plan.json and report.html."),
    terrain: str = TERRAIN,
    pulse_rate: float = typer.Option(20_000.0, "--pulse-rate", help="Pulses per second."),
    fov: float = FOV,
    estimate: str = ESTIMATE,
    trajectory_sigma: str = TRAJECTORY_SIGMA,
    range_sigma: float = typer.Option(0.01, "--range-sigma", help="Range noise, 1σ, m."),
    angle_sigma: float = ANGLE_SIGMA,
    platform_motion: str = PLATFORM_MOTION,
    suggest: bool = SUGGEST,
    simulate: int = SIMULATE,
    force: bool = typer.Option(False, "--force", help=FORCE_HELP),
    config: Path | None = typer.Option(None, "--config", help=CONFIG_HELP),
) -> None:
    """``calidar plan`` (its help: PLAN_HELP)."""
    from calidar.outputs import output_folder
    from calidar.pipelines.plan import run_plan
    from calidar.pipelines.plan_config import PlanConfig

    options = {"terrain": ("options.terrain", parse_terrain),
               "pulse_rate": ("options.pulse_rate_hz", None),
               "fov": ("options.fov_deg", None), "range_sigma": ("options.range_sigma_m", None),
               "angle_sigma": ("options.angle_sigma_deg", None),
               "estimate": ("options.estimate", _estimate),
               "trajectory_sigma": ("options.trajectory_sigma", parse_sigma),
               "suggest": ("options.suggest", None), "simulate": ("options.simulate", None),
               "platform_motion": ("options.platform_motion", parse_platform_motion)}
    cfg = PlanConfig.configure(config, config_values(given_options(ctx), options))
    dem = cfg.options.terrain.path
    inputs = [lines, sensor, config] + ([dem] if dem else [])
    with progress_bar() as bar, output_folder(out, force, inputs=inputs) as tmp:
        run = run_plan(lines, sensor, tmp, cfg.options, progress_callback(bar))
        cfg.write(tmp / "config.toml")
    print_verdict(run.verdict)
    for s in run.suggestions[:1]:
        (x0, y0), (x1, y1) = s.line.start[:2], s.line.end[:2]
        console.print(f"suggested line: {escape(s.kind)}, from ({x0:.0f}, {y0:.0f}) to "
                      f"({x1:.0f}, {y1:.0f}) at {s.line.height_agl_m:g} m", highlight=False,
                      soft_wrap=True)
    console.print(f"wrote {escape(str(out))}/plan.json and report.html", highlight=False,
                  soft_wrap=True)
    exit_with_verdict(run.verdict)


def register(app: typer.Typer, simulate: typer.Typer) -> None:
    app.command("plan", help=PLAN_HELP)(plan)
