"""``calidar accuracy``: absolute vertical accuracy against surveyed checkpoints
(ASPRS Edition 2)."""

from __future__ import annotations

from pathlib import Path

import typer
from rich.markup import escape

from calidar.cli.common import (
    CONFIG_HELP, EXIT_FAIL, FORCE_HELP, config_values, console, exit_with_verdict, given_options,
    print_verdict, progress_bar, progress_callback,
)
from calidar.cli.options import (
    CRS, GEOID_UNDULATION, POINT_VALUES, TIME_SYSTEM, crs_option, parse_classes,
)

CLASS_NOT_MET = EXIT_FAIL  #: exit code when --class is given and not met
#: options → (AccuracyConfig attribute, parse)
OPTIONS = {"checkpoints_crs": ("settings.checkpoints_crs",
                               lambda v: crs_option(v, "--checkpoints-crs")),
           "survey_sigma": ("settings.survey_sigma_m", None),
           "target_class": ("settings.target_class_cm", None),
           "radius": ("settings.radius_m", None), "max_edge": ("settings.max_edge_m", None),
           "classes": ("settings.classes", parse_classes), "swaths": ("settings.swaths", None),
           **POINT_VALUES}


CHECKPOINTS = typer.Option(..., "--checkpoints", help="Checkpoint CSV: id, x, y, z, class "
                           "(non-vegetated | vegetated; NVA/VVA, open/vegetated accepted), "
                           "optional sigma (m).")
OUT = typer.Option(..., "--out", help="Output folder: accuracy.json, checkpoints.csv, report.html.")
CHECKPOINTS_CRS = typer.Option(None, "--checkpoints-crs", help="CRS of the checkpoints when not "
                               "the points' (e.g. EPSG:6340); they are transformed to the points'.")
SURVEY_SIGMA = typer.Option(None, "--survey-sigma", help="The checkpoints' survey RMSE (m), "
                            "when the file has no sigma column (Edition 2 includes it).")
TARGET_CLASS = typer.Option(None, "--class", help="Vertical accuracy class the contract asks "
                            "for, X in cm (e.g. 10): exit code 3 when not met.")
RADIUS = typer.Option(5.0, "--radius", help="Ground points within this distance (m) of a "
                      "checkpoint form its TIN.")
MAX_EDGE = typer.Option(None, "--max-edge", help="Longest edge (m) of the TIN triangle holding "
                        "a checkpoint (default: --radius); longer: a gap, not tested.")
CLASSES = typer.Option(None, "--classes", help="LAS classes taken as ground, e.g. 2 or 2,8 "
                       "(default: 2 where a file has it, else last and single returns).")
SWATHS = typer.Option(False, "--swaths", help="Also the USGS Lidar Base Specification swath checks "
                      "(smooth-surface precision, interswath RMSDz and max |dz|) as calidar "
                      "quality measures them; the files are read twice more.")


#: the command's help (its line breaks are those --help shows)
ACCURACY_HELP = ("Vertical accuracy of the points at surveyed checkpoints: NVA RMSEz and class, "
                 "VVA, per ASPRS Edition 2.\n\nExit codes: 0 pass or warn (the --class met when "
                 "given), 1 bad input, 2 usage error, 3 FAIL verdict or\nthe --class not met, "
                 "130/143 interrupted.")


def accuracy(
    ctx: typer.Context,
    points: list[Path] = typer.Argument(..., help="LAS/LAZ files (the delivered points)."),
    checkpoints: Path = CHECKPOINTS,
    out: Path = OUT,
    checkpoints_crs: str | None = CHECKPOINTS_CRS,
    survey_sigma: float | None = SURVEY_SIGMA,
    target_class: float | None = TARGET_CLASS,
    radius: float = RADIUS,
    max_edge: float | None = MAX_EDGE,
    classes: str | None = CLASSES,
    swaths: bool = SWATHS,
    crs: str | None = CRS, time_system: str | None = TIME_SYSTEM,
    geoid_undulation: float | None = GEOID_UNDULATION,
    force: bool = typer.Option(False, "--force", help=FORCE_HELP),
    config: Path | None = typer.Option(None, "--config", help=CONFIG_HELP),
) -> None:
    """``calidar accuracy`` (its help: ACCURACY_HELP)."""
    from calidar.outputs import output_folder
    from calidar.pipelines.accuracy import run_accuracy
    from calidar.pipelines.accuracy_config import AccuracyConfig

    cfg = AccuracyConfig.configure(config, config_values(given_options(ctx), OPTIONS))
    inputs = [*points, checkpoints, config]
    with progress_bar() as bar, output_folder(out, force, inputs=inputs) as tmp:
        run = run_accuracy(points, checkpoints, tmp, cfg.settings, cfg.points,
                           progress=progress_callback(bar))
        cfg.write(tmp / "config.toml")
    print_verdict(run.verdict)
    console.print(f"wrote {escape(str(out))}/accuracy.json, checkpoints.csv, config.toml and "
                  "report.html", highlight=False, soft_wrap=True)
    target = cfg.settings.target_class_cm
    met = run.assessment.accuracy.meets(target) if target is not None else True
    if not met:
        raise typer.Exit(CLASS_NOT_MET)
    exit_with_verdict(run.verdict)  # the contract of every command: a FAIL verdict exits 3


def register(app: typer.Typer, simulate: typer.Typer) -> None:
    app.command("accuracy", help=ACCURACY_HELP)(accuracy)
