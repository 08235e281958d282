"""``calidar inverse``, ``calidar regeoref`` and ``calidar georef``: delivered LAS points back to
scanner observations, re-georeferenced with a changed sensor model, and raw Optech CSD pulses
georeferenced with calidar's own lidar equation (:mod:`calidar.pipelines.georef`)."""

from __future__ import annotations

from pathlib import Path

import typer

from calidar.cli.common import CONFIG_HELP, FORCE_HELP, config_values, console, given_options
from calidar.cli.options import (
    CRS, GEOID_UNDULATION, TIME_SYSTEM, TRAJECTORY_ANGLES, TRAJECTORY_COLUMNS, TRAJECTORY_CRS,
    TRAJECTORY_HEADING, crs_option, point_options, trajectory_options,
)
from calidar.outputs import check_out_dir, check_writable, guard_inputs, output_folder
from calidar.pipelines import georef as pipeline

TRAJECTORY = typer.Option(..., "--trajectory", "-t", help="SBET, text trajectory or Optech CSD.")


SENSOR = typer.Option(None, "--sensor",
                      help="sensor.toml (default: linear scanner, zero boresight and lever arm).")


def inverse(
    points: Path = typer.Argument(..., help="LAS/LAZ file with GPS times."),
    trajectory: Path = TRAJECTORY,
    out: Path = typer.Option(..., "--out", "-o", help="CSV of scanner-frame vectors."),
    sensor: Path = SENSOR,
    crs: str | None = CRS, time_system: str | None = TIME_SYSTEM,
    geoid_undulation: float | None = GEOID_UNDULATION,
    trajectory_crs: str | None = TRAJECTORY_CRS, trajectory_angles: str | None = TRAJECTORY_ANGLES,
    trajectory_heading: str | None = TRAJECTORY_HEADING,
    trajectory_columns: str | None = TRAJECTORY_COLUMNS,
    force: bool = typer.Option(False, "--force", help="Overwrite the output."),
) -> None:
    """Inverse georeferencing: per point the range and the scanner-frame vector (CSV).

    Columns: gps_time (s, as in the LAS), range_m (measured), x_s, y_s, z_s (m, scanner frame:
    x forward, y right, z down), across_track_angle_deg = atan2(y_s, z_s),
    along_track_angle_deg = atan2(x_s, hypot(y_s, z_s)).
    """
    check_writable(out, force)
    notes: list[str] = []
    points_in = point_options(crs, time_system, geoid_undulation)
    trajectory_in = trajectory_options(trajectory_crs, trajectory_angles, trajectory_heading,
                                       trajectory_columns)
    n = pipeline.inverse_points(
        points, trajectory, out, sensor=sensor, point_options=points_in,
        trajectory_options=trajectory_in, force=force, notes=notes)
    for note in notes:
        console.print(f"note: {note}", highlight=False, soft_wrap=True, markup=False)
    console.print(f"{n} points → {out}", highlight=False, soft_wrap=True, markup=False)


STRIPS = typer.Argument(..., help="LAS/LAZ strips georeferenced with the --from sensor.")
TO_TRAJECTORY = typer.Option(None, "--to-trajectory", help="Forward with this trajectory instead "
                             "(e.g. the sbet_corrected.out of calidar boresight).")


def regeoref(
    strips: list[Path] = STRIPS,
    trajectory: Path = TRAJECTORY,
    old: Path = typer.Option(..., "--from", help="sensor.toml the strips were georeferenced with."),
    new: Path = typer.Option(..., "--to", help="sensor.toml to re-georeference them with."),
    out: Path = typer.Option(..., "--out", "-o", help="Output folder (same file names)."),
    crs: str | None = CRS, time_system: str | None = TIME_SYSTEM,
    geoid_undulation: float | None = GEOID_UNDULATION,
    trajectory_crs: str | None = TRAJECTORY_CRS, trajectory_angles: str | None = TRAJECTORY_ANGLES,
    trajectory_heading: str | None = TRAJECTORY_HEADING,
    trajectory_columns: str | None = TRAJECTORY_COLUMNS,
    force: bool = typer.Option(False, "--force", help=FORCE_HELP),
    to_trajectory: Path | None = TO_TRAJECTORY,
) -> None:
    """Re-georeference delivered strips with a new sensor model (and trajectory).

    Inverse georeferencing with --trajectory and --from, forward with --to-trajectory (default
    --trajectory) and --to, streamed in chunks; every other point attribute is kept, and the
    outputs keep the inputs' names, formats and CRS.
    """
    check_out_dir(out, force)
    notes: list[str] = []
    points_in = point_options(crs, time_system, geoid_undulation)
    trajectory_in = trajectory_options(trajectory_crs, trajectory_angles, trajectory_heading,
                                       trajectory_columns)
    with output_folder(out, force, inputs=[*strips, trajectory, old, new, to_trajectory]) as tmp:
        written = pipeline.regeoreference_strips(
            strips, trajectory, old, new, tmp, point_options=points_in,
            trajectory_options=trajectory_in, to_trajectory=to_trajectory, notes=notes)
    for note in notes:
        console.print(f"note: {note}", highlight=False, soft_wrap=True, markup=False)
    for path, n in written.items():
        console.print(f"{out / path.name}: {n} points", highlight=False, soft_wrap=True,
                      markup=False)


RAW = typer.Argument(..., help="Optech CSD file (raw pulses: ranges, scan angles, positions, "
                               "attitudes).")
OUT = typer.Option(..., "--out", "-o", help="Output LAS/LAZ (the sensor model goes beside it: "
                   "<name>.sensor.toml).")
CRS_OPTION = typer.Option(None, "--crs", help="CRS of the output points (default: the WGS 84 UTM "
                          "zone of the first pulse, ellipsoidal heights).")


#: the command's help (its line breaks are those --help shows)
GEOREF_HELP = ("Georeference raw Optech CSD pulses with calidar's lidar equation; writes the "
               "points, the\nheader's boresight as a calidar sensor.toml (docs/sensor.md, \"Optech "
               "CSD\") and the run's settings\nas <name>.config.toml (for --config).")


def georef(
    ctx: typer.Context,
    raw: Path = RAW,
    out: Path = OUT,
    crs: str | None = CRS_OPTION,
    geoid_undulation: float | None = GEOID_UNDULATION,
    force: bool = typer.Option(False, "--force", help="Overwrite the outputs."),
    config: Path | None = typer.Option(None, "--config", help=CONFIG_HELP),
) -> None:
    """``calidar georef`` (its help: GEOREF_HELP)."""
    from calidar.pipelines.config_file import config_beside

    options = {"crs": ("crs", crs_option), "geoid_undulation": ("geoid_undulation_m", None)}
    cfg = pipeline.GeorefConfig.configure(config, config_values(given_options(ctx), options))
    written = (out, pipeline.sensor_path(out), config_beside(out))
    guard_inputs(written, [raw, config])
    for path in written:
        check_writable(path, force)
    r = pipeline.georeference_csd(raw, out, crs=cfg.crs, geoid_undulation_m=cfg.geoid_undulation_m,
                                  force=force)
    cfg.write(config_beside(out))
    geoid = cfg.geoid_undulation_m
    x, y, z = r.first_xyz
    from calidar.crs import vertical_reference

    console.print(f"{r.n_points} points → {r.points} ({r.crs}); sensor model → {r.sensor}; "
                  f"settings → {config_beside(out)}\n"
                  f"first point: GPS time {r.first_gps_time:.6f} s, {x:.3f}, {y:.3f}, {z:.3f}\n"
                  f"heights: {vertical_reference(r.crs, geoid)[0]}", highlight=False,
                  soft_wrap=True, markup=False)


def register(app: typer.Typer, simulate: typer.Typer) -> None:
    app.command("inverse")(inverse)
    app.command("regeoref")(regeoref)
    app.command("georef", help=GEOREF_HELP)(georef)
