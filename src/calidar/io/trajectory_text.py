"""ASCII/CSV trajectories with named columns (exports of POSPac, Inertial Explorer, PDAL...).

Columns are found from the header line (case-, quote- and unit-suffix-insensitive, see
:data:`SYNONYMS`; e.g. ``GpsTime,Y,X,Z,Roll,Pitch,Azimuth``) or given with ``columns=`` (one
canonical name per file column, ``"-"`` to skip). Positions are either geographic
(``lat``/``lon``, in the ``angles`` unit) or projected (``x``/``y`` in ``crs``, metres), with
an ellipsoidal height. Heading is true, or grid heading when ``heading_reference="grid"``,
then corrected by the meridian convergence γ of ``crs``: true = grid + γ
(:func:`calidar.frames.grid_factors`).
"""

from __future__ import annotations

import re
from pathlib import Path

import numpy as np
import pyproj

from calidar import frames, georef
from calidar.errors import InputError
from calidar.trajectory import HEIGHT_RANGE_M, TIME_SYSTEMS, Trajectory
from calidar.validate import read_text, values

MAX_TEXT_TRAJECTORY_BYTES = 1 << 30  #: a text trajectory larger than 1 GiB: convert it to an SBET

#: canonical column → accepted header names (lower case, without spaces, quotes, "_" or units)
SYNONYMS = {
    "time": ("time", "gpstime", "gpst", "t", "timestamp", "sow", "gpsseconds", "secondsofweek"),
    "lat": ("lat", "latitude", "phi"),
    "lon": ("lon", "long", "longitude", "lambda"),
    "x": ("x", "easting", "east", "e"),
    "y": ("y", "northing", "north", "n"),
    "height": ("z", "h", "height", "alt", "altitude", "ellipsoidheight", "ellipsoidalheight",
               "elevation"),
    "roll": ("roll", "r"),
    "pitch": ("pitch", "p"),
    "heading": ("heading", "azimuth", "yaw", "trueheading", "hdg"),
    # the trajectory's stated accuracy (σ per epoch; position m, attitude in the angle unit): all
    # six or none
    "sigma_north": ("sdnorth", "sigmanorth", "northsd", "northrms", "stdnorth"),
    "sigma_east": ("sdeast", "sigmaeast", "eastsd", "eastrms", "stdeast"),
    "sigma_down": ("sdheight", "sdup", "sddown", "sigmaheight", "sigmaup", "sigmadown", "heightsd",
                   "downrms", "heightrms", "stdheight", "stdup"),
    "sigma_roll": ("sdroll", "sigmaroll", "rollsd", "rollrms", "stdroll"),
    "sigma_pitch": ("sdpitch", "sigmapitch", "pitchsd", "pitchrms", "stdpitch"),
    "sigma_heading": ("sdheading", "sdazimuth", "sdyaw", "sigmaheading", "sigmaazimuth",
                      "headingsd", "headingrms", "stdheading", "stdazimuth"),
}
SIGMA_COLUMNS = ("sigma_north", "sigma_east", "sigma_down", "sigma_roll", "sigma_pitch",
                 "sigma_heading")
_LOOKUP = {alias: canon for canon, aliases in SYNONYMS.items() for alias in aliases}


def _limits(column: str, angles: str) -> tuple[float | None, float | None, str]:
    """The physical range of a column in the file's units (angles in ``angles``: deg or rad)."""
    deg = {"lat": 90.0, "lon": 360.0, "roll": 180.0, "pitch": 90.0, "heading": 360.0}
    if column in deg:
        k = 1.0 if angles == "deg" else np.pi / 180.0
        return -deg[column] * k, deg[column] * k, angles
    if column == "height":
        return (*HEIGHT_RANGE_M, "m")
    if column in SIGMA_COLUMNS:  # σ ≥ 0: position up to 1 km, attitude up to 10°
        if column in SIGMA_COLUMNS[:3]:
            return 0.0, 1000.0, "m"
        return 0.0, 10.0 if angles == "deg" else np.radians(10.0), angles
    if column in ("x", "y"):
        return -1e8, 1e8, "m"
    return None, None, "s"


def _normalise(name: str) -> str:
    """A header name as looked up: lower case, without quotes, units ("(deg)", "[m]"), spaces,
    "_", "-" or "."."""
    name = re.sub(r"[\(\[].*?[\)\]]", "", name.strip().strip("\"'").lower())
    return re.sub(r"[\s_\-\.]", "", name)


def _split(line: str, delimiter: str | None) -> list[str]:
    """A line's fields, split at ``delimiter`` (None: whitespace)."""
    return [f.strip() for f in (line.split(delimiter) if delimiter else line.split())]


def _is_number(text: str) -> bool:
    """Whether ``text`` reads as a float."""
    try:
        float(text)
    except ValueError:
        return False
    return True


def _numbers(path: Path, records: list[tuple[int, str]], n_columns: int,
             delimiter: str | None) -> np.ndarray:
    """Parse numeric records (line number, text) fast; on failure name the first bad line."""
    try:
        data = np.loadtxt([ln for _, ln in records], delimiter=delimiter, ndmin=2)
        if data.shape[1] == n_columns:
            return data
    except ValueError:
        pass
    for i, ln in records:
        fields = _split(ln, delimiter)
        try:
            if len(fields) != n_columns:
                raise ValueError(f"{n_columns} values, got {len(fields)}")
            [float(f) for f in fields]
        except ValueError as e:
            raise InputError(path, f"line {i + 1}", f"expected numbers ({e})") from None
    raise InputError(path, None, f"expected {n_columns} numeric columns")


def read_trajectory_text(path, *, columns=None, crs=None, angles: str = "deg",
                         heading_reference: str = "true", delimiter: str | None = None,
                         time_system: str = "gps_week_seconds") -> Trajectory:
    r"""Read an ASCII/CSV trajectory into a :class:`Trajectory`.

    ``angles``: "deg" or "rad" for roll, pitch, heading and lat/lon. ``crs``: CRS of projected
    x/y (required for them) or of lat/lon (default WGS 84); heights are taken as ellipsoidal.
    ``delimiter``: None = comma if the first data line has one, else whitespace.

    >>> import tempfile, numpy as np, calidar; path = Path(tempfile.mkdtemp()) / "export.txt"
    >>> _ = path.write_text("GpsTime Latitude Longitude H Roll Pitch Azimuth\n"
    ...                     "100.0 47.0 8.0 500.0 0.1 -0.2 90.0\n"
    ...                     "100.5 47.0 8.0001 500.1 0.1 -0.2 90.0\n")
    >>> traj = calidar.read_trajectory_text(path)
    >>> len(traj), np.degrees(traj.heading).round(6).tolist()
    (2, [90.0, 90.0])
    """
    path = Path(path)
    if angles not in ("deg", "rad"):
        raise InputError(path, "angles", f"expected 'deg' or 'rad', got {angles!r}")
    if heading_reference not in ("true", "grid"):
        raise InputError(path, "heading_reference",
                         f"expected 'true' or 'grid', got {heading_reference!r}")
    if time_system not in TIME_SYSTEMS:
        raise InputError(path, "time_system",
                         f"expected one of {TIME_SYSTEMS}, got {time_system!r}")
    lines = read_text(path, "text trajectory", limit=MAX_TEXT_TRAJECTORY_BYTES).splitlines()
    body = [(i, ln) for i, ln in enumerate(lines) if ln.strip() and not ln.lstrip().startswith("#")]
    if not body:
        raise InputError(path, None, "expected trajectory records, the file is empty")
    first = body[0][1]
    if delimiter is None:
        delimiter = "," if "," in first else None
    head = _split(first, delimiter)
    has_header = not all(_is_number(f) for f in head)
    columns, index = _columns(path, columns, head, has_header)
    records = body[1:] if has_header else body
    data = _numbers(path, records, len(columns), delimiter)
    col = {c: data[:, k] for c, k in index.items()}
    lines = [i + 1 for i, _ in records]
    for c, a in col.items():
        values(a, path, c, *_limits(c, angles), what="line", labels=lines)
    to_rad = np.radians if angles == "deg" else np.asarray
    if crs is not None:
        try:
            crs = pyproj.CRS.from_user_input(crs)
        except pyproj.exceptions.CRSError:
            raise InputError(path, "crs", "expected a CRS pyproj knows (e.g. 'EPSG:32615'), got "
                             f"{crs!r}") from None
    lat, lon, h = _geodetic(path, col, crs, to_rad)
    extra = _sigma_columns(path, col, to_rad)
    heading = to_rad(col["heading"])
    if heading_reference == "grid":
        if crs is None or not crs.is_projected:
            raise InputError(path, "heading_reference",
                             "grid heading needs a projected crs for the meridian convergence")
        heading = heading + frames.grid_factors(crs, lon, lat)[0]
    return Trajectory(time=col["time"], lat=lat, lon=lon, height=h, roll=to_rad(col["roll"]),
                      pitch=to_rad(col["pitch"]), heading=np.angle(np.exp(1j * heading)),
                      time_system=time_system, source=str(path), extra=extra)


def _columns(path: Path, columns, head: list[str], has_header: bool) -> tuple[list, dict]:
    """The file's columns (``columns`` given, else named by the header) and the position of each
    known one; an error for unknown names or missing columns."""
    if columns is None:
        if not has_header:
            raise InputError(path, "columns", "no header line; give columns=[...] (e.g. "
                             "time,lat,lon,height,roll,pitch,heading)")
        columns = [_LOOKUP.get(_normalise(h), "-") for h in head]
    columns = list(columns)
    index = {c: k for k, c in enumerate(columns) if c != "-"}
    unknown = set(index) - set(SYNONYMS)
    if unknown:
        raise InputError(path, "columns", f"unknown column name(s) {sorted(unknown)}; expected "
                         f"some of {sorted(SYNONYMS)}")
    geographic = "lat" in index and "lon" in index
    need = ["time", "height", "roll", "pitch", "heading"]
    need += ["lat", "lon"] if geographic else ["x", "y"]
    missing = [c for c in need if c not in index]
    if missing:
        raise InputError(path, "columns", f"missing {missing}; found columns {columns} "
                         f"(header {head if has_header else 'absent'})")
    return columns, index


def _geodetic(path: Path, col: dict, crs, to_rad) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Latitude, longitude (rad) and ellipsoidal height (m) of the records: their lat/lon
    (transformed from ``crs`` when given) or their projected x/y in ``crs``."""
    if "lat" in col and "lon" in col:
        lat, lon, h = to_rad(col["lat"]), to_rad(col["lon"]), col["height"]
        if crs is not None and crs.is_projected:
            raise InputError(path, "crs",
                             f"the file has lat/lon columns but crs {crs.name} is projected")
        if crs is not None:
            lon_lat_h = np.stack([np.degrees(lon), np.degrees(lat), h], 1)
            lat, lon, h = frames.ecef_to_geodetic(georef.from_crs(lon_lat_h, crs))
        return lat, lon, h
    if crs is None or not crs.is_projected:
        raise InputError(path, "crs", "the file has projected x/y columns; give their projected "
                         "CRS (crs, --crs or --trajectory-crs; e.g. EPSG:32615)")
    xyz = np.stack([col["x"], col["y"], col["height"]], 1)
    return frames.ecef_to_geodetic(georef.from_crs(xyz, crs))


def _sigma_columns(path: Path, col: dict, to_rad) -> dict:
    """The trajectory's stated σ (SI: m, rad) when the file has all six σ columns; an error when
    it has some only."""
    sigma = [c for c in SIGMA_COLUMNS if c in col]
    if sigma and len(sigma) < len(SIGMA_COLUMNS):
        absent = [c for c in SIGMA_COLUMNS if c not in col]
        raise InputError(path, "columns", f"has the σ columns {sigma} but not {absent}; expected "
                         "all six (north, east, down, roll, pitch, heading) or none")
    return {c: col[c] if c in SIGMA_COLUMNS[:3] else to_rad(col[c]) for c in sigma}


def write_trajectory_text(path, traj: Trajectory, force: bool = False) -> Path:
    """Write ``traj`` as a CSV trajectory that :func:`read_trajectory_text` reads back: header
    ``time,lat,lon,height,roll,pitch,heading`` (s, deg, deg, m, deg), plus the six σ columns
    (m, deg) when ``traj.extra`` holds them; atomically, refusing to overwrite unless ``force``.
    Angles keep 1e-11 deg (≈ 1 µm), heights and times 1e-6.

    >>> import tempfile, numpy as np, calidar
    >>> t = np.arange(3.0)
    >>> traj = calidar.Trajectory(time=t, lat=np.radians(47.0 + 1e-5 * t),
    ...                           lon=np.full(3, np.radians(8.0)), height=np.full(3, 500.0),
    ...                           roll=np.zeros(3), pitch=np.zeros(3), heading=np.zeros(3))
    >>> path = calidar.write_trajectory_text(Path(tempfile.mkdtemp()) / "traj.csv", traj)
    >>> path.read_text().splitlines()[0]
    'time,lat,lon,height,roll,pitch,heading'
    >>> back = calidar.read_trajectory(path)   # by content: text
    >>> bool(np.allclose(back.lat, traj.lat, rtol=0, atol=1e-12)), back.time_system
    (True, 'gps_week_seconds')
    """
    from calidar.io.csv import write_csv_rows
    from calidar.outputs import atomic_path

    sigma = [c for c in SIGMA_COLUMNS if c in traj.extra]
    sigma = sigma if len(sigma) == len(SIGMA_COLUMNS) else []
    deg = np.degrees
    columns = [traj.time, deg(traj.lat), deg(traj.lon), traj.height, deg(traj.roll),
               deg(traj.pitch), deg(traj.heading)]
    columns += [traj.extra[c] if c in SIGMA_COLUMNS[:3] else deg(traj.extra[c]) for c in sigma]
    decimals = [6, 11, 11, 6, 11, 11, 11] + [6] * len(sigma)
    with atomic_path(path, force) as tmp, open(tmp, "w", encoding="utf-8", newline="") as f:
        header = ["time", "lat", "lon", "height", "roll", "pitch", "heading", *sigma]
        f.write(",".join(header) + "\n")
        write_csv_rows(f, columns, decimals)
    return Path(path)
