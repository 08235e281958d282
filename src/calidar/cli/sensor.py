"""``calidar sensor import``: a vendor's mounting (boresight, lever arm) as a calidar sensor.toml
(conversions in docs/sensor.md, :mod:`calidar.sensor_import`)."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import typer

from calidar.cli.common import console
from calidar.outputs import check_writable, guard_inputs

sensor_app = typer.Typer(help="Sensor models (sensor.toml): import a vendor's mounting.",
                         no_args_is_help=True)


FILE = typer.Argument(..., help="The vendor file: leeward config.toml, Optech CSD, or a PDAL "
                      "scan2imu matrix (16 numbers, or a PDAL pipeline JSON with "
                      "filters.georeference).")
SCANNER_AXES = typer.Option(
    None, "--scanner-axes", help="pdal-scan2imu only: calidar's scanner x,y,z (forward, right, "
    "nadir) as the scanner's own axes, e.g. 'y,x,-z' (default x,y,z).")
CRS = typer.Option(None, "--crs", help="Output CRS to record in sensor.toml (optional).")


#: the command's help (its line breaks are those --help shows)
HELP = ("Convert a vendor's boresight and lever arm into calidar's R_bs = Rz·Ry·Rx (scanner → "
        "body) and\nlever arm (body frame: x forward, y right, z down); docs/sensor.md shows each "
        "convention.")


def import_(
    file: Path = FILE,
    source: str = typer.Option(..., "--from", help="leeward | optech-csd | pdal-scan2imu."),
    out: Path = typer.Option(..., "--out", "-o", help="sensor.toml to write."),
    scanner_axes: str | None = SCANNER_AXES,
    crs: str | None = CRS,
    force: bool = typer.Option(False, "--force", help="Overwrite the output."),
) -> None:
    """``calidar import`` (its help: HELP)."""
    from dataclasses import replace

    from calidar.sensor import validated_crs
    from calidar.sensor_import import import_sensor

    from calidar.sensor_import import axes

    if scanner_axes is not None:
        axes(scanner_axes)  # the options first, before the file is read
    crs = validated_crs(crs, None, "--crs")
    guard_inputs([out], [file])
    check_writable(out, force)
    sensor = import_sensor(source, file, scanner_axes)
    if crs is not None:
        sensor = replace(sensor, crs=crs)
    sensor.write(out, force=force)
    angles = np.degrees([sensor.boresight_roll, sensor.boresight_pitch, sensor.boresight_yaw])
    lever_arm = ", ".join(f"{v:.4f}" for v in sensor.lever_arm)
    console.print(f"{out}: boresight roll {angles[0]:.6f}°, pitch {angles[1]:.6f}°, yaw "
                  f"{angles[2]:.6f}°; lever arm {lever_arm} m", highlight=False, soft_wrap=True,
                  markup=False)


def register(app: typer.Typer, simulate: typer.Typer) -> None:
    sensor_app.command("import", help=HELP)(import_)
    app.add_typer(sensor_app, name="sensor")
