"""``calidar tpu``: per-point horizontal and vertical uncertainty as LAS extra bytes."""

from __future__ import annotations

from pathlib import Path

import typer
from rich.markup import escape

from calidar.cli.common import (
    CONFIG_HELP, FORCE_HELP, console, given_options, progress_bar, progress_callback,
)
from calidar.cli.options import CRS, GEOID_UNDULATION, TIME_SYSTEM

#: options → (the noise settings' field, factor to SI) (calidar.tpu.propagate.TpuSettings)
NOISE_OPTIONS = {"range_sigma": ("range_sigma_m", 1.0), "angle_sigma": ("angle_sigma_rad", None),
                 "beam_divergence": ("beam_divergence_rad", 1e-3)}


def tpu_config(path: Path | None, given: dict):
    """The configuration: the ``--config`` file's (else the defaults), with the options ``given`` on
    the command line ({parameter name: value}) replacing its settings; checked."""
    import numpy as np

    from calidar.cli.common import config_values
    from calidar.cli.options import POINT_VALUES, parse_sigma
    from calidar.pipelines.tpu_config import TpuConfig

    # degrees → radians as numpy converts them (the value calidar tpu has always used)
    def radians(v):
        return float(np.radians(v))

    options = {k: (f"noise.{f}", radians if factor is None else (lambda v, c=factor: v * c))
               for k, (f, factor) in NOISE_OPTIONS.items()}
    options.update(trajectory_sigma=("trajectory_sigma", parse_sigma), **POINT_VALUES)
    values = config_values({k: v for k, v in given.items() if v is not None}, options)
    return TpuConfig.configure(path, values)


POINTS = typer.Argument(..., help="LAS/LAZ files georeferenced with --trajectory and --sensor.")
TRAJECTORY = typer.Option(..., "--trajectory", "-t", help="The trajectory the points were made "
                          "with (SBET, text or CSD).")
OUT = typer.Option(..., "--out", help="Folder for the files with total_thu/total_tvu, tpu.json and "
                   "report.html.")
CALIBRATION = typer.Option(None, "--calibration", help="A calidar solution.json: propagate "
                           "the calibration's covariance (boresight, lever arm, range) too.")
TRAJECTORY_ACCURACY = typer.Option(None, "--trajectory-accuracy", help="The trajectory's σ per "
                                   "epoch (POSPac smrmsg); default: smrmsg*.out beside the SBET.")
TRAJECTORY_SIGMA = typer.Option(None, "--trajectory-sigma", help="One σ for every epoch: "
                                "POSITION_M,ATTITUDE_DEG, e.g. 0.05,0.005.")
ANGLE_SIGMA = typer.Option(0.002, "--angle-sigma", help="Encoder (scan-angle) noise, 1σ, degrees.")
BEAM_DIVERGENCE = typer.Option(0.25, "--beam-divergence", help="Beam divergence, full angle, mrad "
                               "(0: no footprint term).")


#: the command's help (its line breaks are those --help shows)
TPU_HELP = ("Per-point uncertainty (TPU): horizontal and vertical 1σ of every point from the "
            "trajectory's\naccuracy, range and scan-angle noise, the footprint on the local "
            "surface and the calibration's\ncovariance, written as LAS extra bytes "
            "total_thu/total_tvu (m); config.toml holds this run's settings\n(for --config).")


def tpu(
    ctx: typer.Context,
    points: list[Path] = POINTS,
    trajectory: Path = TRAJECTORY,
    sensor: Path = typer.Option(..., "--sensor", help="The sensor.toml the points were made with."),
    out: Path = OUT,
    calibration: Path | None = CALIBRATION,
    trajectory_accuracy: Path | None = TRAJECTORY_ACCURACY,
    trajectory_sigma: str | None = TRAJECTORY_SIGMA,
    range_sigma: float = typer.Option(0.01, "--range-sigma", help="Range noise, 1σ, m."),
    angle_sigma: float = ANGLE_SIGMA,
    beam_divergence: float = BEAM_DIVERGENCE,
    crs: str | None = CRS, time_system: str | None = TIME_SYSTEM,
    geoid_undulation: float | None = GEOID_UNDULATION,
    force: bool = typer.Option(False, "--force", help=FORCE_HELP),
    config: Path | None = typer.Option(None, "--config", help=CONFIG_HELP),
) -> None:
    """``calidar tpu`` (its help: TPU_HELP)."""
    from calidar.outputs import check_out_dir, claim_output, guard_inputs, output_folder
    from calidar.pipelines.tpu import run_tpu

    cfg = tpu_config(config, given_options(ctx))
    check_out_dir(out, force)
    inputs = [*points, trajectory, sensor, calibration, trajectory_accuracy, config]
    guard_inputs([out / p.name for p in points], inputs, [out])
    claim_output(out)  # --out is this run's from its start (released when the run ends)
    with progress_bar() as bar, output_folder(out, force, inputs=points) as tmp:
        results = run_tpu(points, trajectory, sensor, tmp, cfg, accuracy=trajectory_accuracy,
                          calibration=calibration, progress=progress_callback(bar))
    for r in results:
        console.print(f"{escape(r.path.name)}: {r.n_points:,} points, THU median "
                      f"{r.thu['median'] * 100:.2f} cm (95 % {r.thu['p95'] * 100:.2f}), TVU median "
                      f"{r.tvu['median'] * 100:.2f} cm (95 % {r.tvu['p95'] * 100:.2f})",
                      highlight=False, soft_wrap=True)
    console.print(f"wrote {escape(str(out))}/: {len(results)} files with total_thu/total_tvu, "
                  "tpu.json, config.toml, report.html", highlight=False, soft_wrap=True)


def register(app: typer.Typer, simulate: typer.Typer) -> None:
    app.command("tpu", help=TPU_HELP)(tpu)
