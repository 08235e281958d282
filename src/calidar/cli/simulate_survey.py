"""``calidar simulate survey``: a lidar survey with a known truth (strips, SBET, sensor, truth)."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import typer
from rich.markup import escape

from calidar.cli.common import FORCE_HELP, console, parse_floats, progress_bar, progress_callback


OUT = typer.Option(..., "--out", help="Output folder (strips/*.laz, sbet.out, sensor.toml, "
                                      "truth.json).")
PRESET = typer.Option("uav", "--preset",
                      help="uav (≈80 m above ground, 300 m × 300 m) or airborne (≈1000 m, 2.5 km × "
                           "1.6 km).")
BORESIGHT_ERROR = typer.Option("0,0,0", "--boresight-error",
                               help="True − nominal boresight ROLL,PITCH,YAW in degrees.")
LEVER_ARM_ERROR = typer.Option("0,0,0", "--lever-arm-error",
                               help="True − nominal lever arm X,Y,Z in metres (body frame).")
RANGE_NOISE = typer.Option(None, "--range-noise",
                           help="Range noise σ in metres (preset's value by default).")
BEAM_DIVERGENCE = typer.Option(0.0, "--beam-divergence", metavar="MRAD",
                               help="Beam divergence (full angle) in mrad: each return comes from "
                                    "within the footprint (0: one ray per pulse).")
VEGETATION = typer.Option(None, "--vegetation",
                          help="Fraction of the area under tree crowns, 0–0.8.")
STRIP_ERRORS = typer.Option("0,0,0,0", "--strip-errors",
                            help="σ of per-strip trajectory errors: POSITION_BIAS (m), "
                                 "POSITION_DRIFT (m/s), ATTITUDE_BIAS (deg), ATTITUDE_DRIFT "
                                 "(deg/s).")
DIRECTIONS = typer.Option("opposite", "--directions",
                          help="Line directions: same, opposite or cross.")
CHECKPOINTS = typer.Option(0, "--checkpoints", help="Surveyed checkpoints to write "
                           "(checkpoints.csv; a quarter under trees when there are trees), their "
                           "truth in truth.json.")
CHECKPOINT_SIGMA = typer.Option(0.02, "--checkpoint-sigma",
                                help="Survey σ of the checkpoints' heights, m.")
CONTROL_PLANES = typer.Option(0, "--control-planes", help="Roof facets surveyed at their corners "
                              "to write as control planes (control_planes.csv, for boresight "
                              "--control), their truth in truth.json.")
CONTROL_PLANE_SIGMA = typer.Option(0.01, "--control-plane-sigma",
                                   help="Survey σ (3-D) of the control planes' points, m.")
REFERENCE_CLOUD = typer.Option(False, "--reference-cloud", help="Also write reference.laz: a dense "
                               "(0.25 m), precise (5 mm) scan of the open ground over the central "
                               "part of the area, its datum off by N(0, --reference-cloud-sigma) "
                               "(truth.json), for boresight --control reference.laz "
                               "--control-sigma σ.")
REFERENCE_CLOUD_SIGMA = typer.Option(0.02, "--reference-cloud-sigma",
                                     help="The reference cloud's stated vertical accuracy (σ of "
                                          "its datum), m.")


def survey(
    out: Path = OUT,
    preset: str = PRESET,
    seed: int = typer.Option(0, "--seed", help="Random seed: same seed, same bytes."),
    boresight_error: str = BORESIGHT_ERROR,
    lever_arm_error: str = LEVER_ARM_ERROR,
    range_offset: float = typer.Option(0.0, "--range-offset", help="True range offset in metres."),
    range_noise: float = RANGE_NOISE,
    beam_divergence: float = BEAM_DIVERGENCE,
    vegetation: float = VEGETATION,
    strip_errors: str = STRIP_ERRORS,
    directions: str = DIRECTIONS,
    density: float = typer.Option(1.0, "--density", help="Scales the pulse rate (points per m²)."),
    checkpoints: int = CHECKPOINTS,
    checkpoint_sigma: float = CHECKPOINT_SIGMA,
    control_planes: int = CONTROL_PLANES,
    control_plane_sigma: float = CONTROL_PLANE_SIGMA,
    reference_cloud: bool = REFERENCE_CLOUD,
    reference_cloud_sigma: float = REFERENCE_CLOUD_SIGMA,
    force: bool = typer.Option(False, "--force", help=FORCE_HELP),
) -> None:
    """Simulate a survey: the true sensor shoots, the strips are delivered with the nominal one."""
    from calidar.outputs import check_out_dir, output_folder
    from calidar.sim.checkpoints import simulate_checkpoints
    from calidar.sim.survey import check_config, simulate_survey, survey_config

    r, p, y = np.radians(parse_floats(boresight_error, 3, "--boresight-error"))
    lx, ly, lz = parse_floats(lever_arm_error, 3, "--lever-arm-error")
    given = dict(boresight_roll=r, boresight_pitch=p, boresight_yaw=y, lever_arm_x=lx,
                 lever_arm_y=ly, lever_arm_z=lz, range_offset=range_offset)
    errors = {k: v for k, v in given.items() if v}
    pb, pd, ab, ad = parse_floats(strip_errors, 4, "--strip-errors")
    overrides = dict(seed=seed, errors=errors, directions=directions, density=density,
                     strip_error_sigma=(pb, pd, np.radians(ab), np.radians(ad)))
    if range_noise is not None:
        overrides["range_noise_m"] = range_noise
    if beam_divergence:
        overrides["beam_divergence_rad"] = beam_divergence * 1e-3
    if vegetation is not None:
        overrides["vegetation"] = vegetation
    cfg = survey_config(preset, **overrides)
    check_config(cfg)
    _check_ground(checkpoints, checkpoint_sigma, control_planes, control_plane_sigma,
                  reference_cloud_sigma if reference_cloud else None)
    check_out_dir(out, force)  # refuse early, before minutes of work
    with progress_bar() as bar, output_folder(out, force) as tmp:
        update = progress_callback(bar)
        result = simulate_survey(cfg, progress=update)
        result.write(tmp, force=True, progress=update)
        if checkpoints:
            simulate_checkpoints(result, checkpoints, checkpoint_sigma, seed).write(tmp)
        if control_planes:
            from calidar.sim.control_planes import simulate_control_planes

            simulate_control_planes(result, control_planes, control_plane_sigma, seed).write(tmp)
        if reference_cloud:
            from calidar.sim.reference_cloud import simulate_reference_cloud

            simulate_reference_cloud(result, reference_cloud_sigma, seed).write(tmp)
    console.print(f"{result.n_points:,} points in {len(result.strips)} strips ({result.crs}) → "
                  f"{escape(str(out))}", highlight=False, soft_wrap=True)


def register(app: typer.Typer, simulate: typer.Typer) -> None:
    simulate.command("survey")(survey)


def _check_ground(checkpoints: int, checkpoint_sigma: float, control_planes: int,
                  control_plane_sigma: float, reference_sigma: float | None) -> None:
    """The surveyed ground's options (checkpoints, control planes, a reference cloud), before any
    work."""
    from calidar.sim.checkpoints import check_checkpoint_options

    check_checkpoint_options(checkpoints, checkpoint_sigma)
    if control_planes:
        from calidar.sim.control_planes import check_control_plane_options

        check_control_plane_options(control_planes, control_plane_sigma)
    if reference_sigma is not None:
        from calidar.sim.reference_cloud import check_reference_options

        check_reference_options(reference_sigma)
