"""The input options every georeferencing command shares, defined once: ``--crs``,
``--time-system``, ``--geoid-undulation`` for points, ``--trajectory-crs`` and the text-trajectory
column options for trajectories. A command declares them as defaults::

    def cmd(..., crs: str | None = CRS, time_system: str | None = TIME_SYSTEM,
            geoid_undulation: float | None = GEOID_UNDULATION,
            trajectory_crs: str | None = TRAJECTORY_CRS,
            trajectory_angles: str | None = TRAJECTORY_ANGLES,
            trajectory_heading: str | None = TRAJECTORY_HEADING,
            trajectory_columns: str | None = TRAJECTORY_COLUMNS):
        points = point_options(crs, time_system, geoid_undulation)
        traj = trajectory_options(trajectory_crs, trajectory_angles, trajectory_heading,
                                  trajectory_columns)

and hands them to the pipelines (:class:`calidar.pipelines.inputs.PointOptions`,
:class:`~calidar.pipelines.inputs.TrajectoryOptions`).
"""

from __future__ import annotations

import math

import typer

from calidar.errors import InputError
from calidar.pipelines.inputs import PointOptions, TrajectoryOptions

CRS = typer.Option(None, "--crs", help="CRS of the points, overriding (or supplying) the file's, "
                                       "e.g. EPSG:32611.")
TIME_SYSTEM = typer.Option(
    None, "--time-system", help="GPS time of the points: week (seconds of the GPS week) or "
    "adjusted (GPS time − 1e9 s), overriding the LAS global-encoding bit when it is wrong.")
GEOID_UNDULATION = typer.Option(
    None, "--geoid-undulation", help="Geoid undulation N (m) for a CRS with heights above a geoid "
    "when PROJ lacks the geoid grid: ellipsoidal height = height + N (one value: a small area).")
TRAJECTORY_CRS = typer.Option(None, "--trajectory-crs",
                              help="CRS of a text trajectory's x/y (or lat/lon) columns, e.g. "
                                   "EPSG:32615.")
TRAJECTORY_ANGLES = typer.Option(None, "--trajectory-angles",
                                 help="Angle unit of a text trajectory: deg (default) or rad.")
TRAJECTORY_HEADING = typer.Option(
    None, "--trajectory-heading", help="Heading of a text trajectory: true (default), or grid "
    "(then corrected by the meridian convergence of --trajectory-crs).")
TRAJECTORY_COLUMNS = typer.Option(
    None, "--trajectory-columns", help="Columns of a text trajectory, comma-separated, '-' to skip "
    "one: time, lat, lon or x, y, height, roll, pitch, heading (default: from its header line).")


def crs_option(crs: str | None, option: str = "--crs") -> str | None:
    """A CRS option when pyproj knows it (None stays None), else an error naming the option."""
    from calidar.sensor import validated_crs

    return validated_crs(crs, None, option)


def _choice(value: str | None, option: str, choices: tuple[str, ...]) -> str | None:
    if value is not None and value not in choices:
        raise InputError(None, option, f"expected {' or '.join(choices)}, got {value!r}")
    return value


def point_options(crs: str | None = None, time_system: str | None = None,
                  geoid_undulation: float | None = None) -> PointOptions:
    """PointOptions from the shared point options, each checked (before any file is read)."""
    return PointOptions(crs=crs_option(crs), time_system=time_system,
                        geoid_undulation_m=geoid_undulation)


def trajectory_options(crs: str | None = None, angles: str | None = None,
                       heading: str | None = None,
                       columns: str | None = None) -> TrajectoryOptions:
    """TrajectoryOptions from the shared trajectory options, each checked (before any file is
    read)."""
    cols = None if columns is None else tuple(c.strip() for c in columns.split(","))
    return TrajectoryOptions(crs=crs_option(crs, "--trajectory-crs"),
                             angles=_choice(angles, "--trajectory-angles", ("deg", "rad")),
                             heading=_choice(heading, "--trajectory-heading", ("true", "grid")),
                             columns=cols)


def parse_sigma(text: str, option: str = "--trajectory-sigma") -> tuple[float, float]:
    """'POSITION_M,ATTITUDE_DEG' → (position σ m, attitude σ rad), each > 0 and within the bounds of
    :class:`~calidar.trajectory_accuracy.TrajectoryAccuracy`."""
    from calidar.trajectory_accuracy import MAX_ATTITUDE_SIGMA_RAD, MAX_POSITION_SIGMA_M
    from calidar.validate import parse_floats, positive

    pos_m, att_deg = parse_floats(text, 2, f"{option} (POSITION_M,ATTITUDE_DEG)")
    positive(pos_m, option, "m", hi=MAX_POSITION_SIGMA_M)
    positive(att_deg, option, "deg", hi=math.degrees(MAX_ATTITUDE_SIGMA_RAD))
    return pos_m, math.radians(att_deg)


def parse_classes(text: str | None) -> tuple[int, ...] | None:
    """'2,6' → (2, 6): LAS classes, integers 0–255 (None: choose per source)."""
    if text is None:
        return None
    parts = [p.strip() for p in str(text).split(",")]
    try:
        classes = tuple(int(p) for p in parts)
    except ValueError:
        classes = ()
    if not classes or any(not 0 <= c <= 255 for c in classes):
        raise InputError(None, "--classes", "expected LAS classes (integers 0–255) separated by "
                         f"commas, got {text!r}")
    return tuple(sorted(set(classes)))


#: the shared point options → (PointOptions attribute under ``points``, parse) for
#: cli.common.config_values
POINT_VALUES = {"crs": ("points.crs", crs_option), "time_system": ("points.time_system", None),
                "geoid_undulation": ("points.geoid_undulation_m", None)}


def parse_beams(text: str) -> tuple[str, ...] | None:
    """--beam: 'all' → None (every beam a file has), 'gt1l, GT2L' → ('gt1l', 'gt2l'): ATL03 beam
    names, each once (the configuration checks them; io checks them against each file)."""
    names = tuple(dict.fromkeys(b.strip().lower() for b in text.split(",") if b.strip()))
    if not names:
        raise InputError(None, "--beam",
                         f"expected all or beam names separated by commas, got {text!r}")
    return None if names == ("all",) else names
