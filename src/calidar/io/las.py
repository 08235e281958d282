"""LAS/LAZ points (laspy + lazrs): coordinates, GPS time, scan angle, flight line, CRS.

GPS time is either GPS week seconds or adjusted standard GPS time (GPS time − 1e9 s), as
bit 0 of the header's global encoding says; ``LasPoints.time_system`` carries which, and
:func:`adjusted_standard_to_week_seconds` converts. Scan angles come back in degrees as
floats whatever the point format (LAS 1.2 ``scan_angle_rank``, whole degrees; LAS 1.4
``scan_angle``, 0.006° steps). The CRS comes from the WKT VLR or the GeoTIFF keys; a file
without one gives ``crs=None`` unless the caller supplies ``crs=``.
"""

from __future__ import annotations

from collections.abc import Iterator
from dataclasses import dataclass, replace
from pathlib import Path

import laspy
import numpy as np
import pyproj

from calidar.errors import InputError
from calidar.outputs import atomic_path
from calidar.trajectory import SECONDS_PER_WEEK

ADJUSTED_STANDARD_OFFSET_S = 1e9  #: adjusted standard GPS time = GPS time − 1e9 s
OPTIONAL_FIELDS = ("scan_angle_deg", "point_source_id", "return_number", "number_of_returns", "classification",
                   "intensity")
SCAN_ANGLE_STEP_DEG = 0.006  #: LAS 1.4 scaled scan angle unit


@dataclass(frozen=True, eq=False)
class LasPoints:
    """Points of a LAS/LAZ file (or of one chunk of it); optional fields are None when not read."""

    xyz: np.ndarray  #: (N, 3) float64, in ``crs`` (x/east/lon first), m or deg as the CRS says
    gps_time: np.ndarray  #: (N,) s, in ``time_system``
    time_system: str  #: "gps_week_seconds" | "gps_adjusted_standard"
    crs: pyproj.CRS | None
    path: Path
    scan_angle_deg: np.ndarray | None = None  #: (N,) float, deg, negative left of the flight direction
    point_source_id: np.ndarray | None = None  #: (N,) flight line id
    return_number: np.ndarray | None = None
    number_of_returns: np.ndarray | None = None
    classification: np.ndarray | None = None
    intensity: np.ndarray | None = None

    def __len__(self) -> int:
        return self.gps_time.size

    def gps_week_seconds(self) -> np.ndarray:
        """GPS times as week seconds whatever the file holds (see :func:`adjusted_standard_to_week_seconds`)."""
        if self.time_system == "gps_week_seconds":
            return self.gps_time
        return adjusted_standard_to_week_seconds(self.gps_time, self.path)[0]

    def select(self, mask) -> "LasPoints":
        """The points where ``mask`` (boolean or index array) selects."""
        kw = {f: None if getattr(self, f) is None else getattr(self, f)[mask] for f in OPTIONAL_FIELDS}
        return replace(self, xyz=self.xyz[mask], gps_time=self.gps_time[mask], **kw)


def adjusted_standard_to_week_seconds(t_adjusted_s, source=None) -> tuple[np.ndarray, int]:
    """Adjusted standard GPS times (s) → (GPS week seconds, GPS week number).

    The week comes from the times themselves; times spanning a week boundary are an error
    (week seconds would jump back to 0 there).
    """
    t = np.asarray(t_adjusted_s, float) + ADJUSTED_STANDARD_OFFSET_S
    if t.size == 0:
        return t, 0
    weeks = np.floor(t / SECONDS_PER_WEEK)
    w0, w1 = weeks.min(), weeks.max()
    if w0 != w1:
        raise InputError(source, "gps_time",
                         f"adjusted standard GPS times span GPS weeks {int(w0)}–{int(w1)}; expected one week")
    return t - w0 * SECONDS_PER_WEEK, int(w0)


def week_seconds_to_adjusted_standard(t_week_s, gps_week: int) -> np.ndarray:
    """GPS week seconds of ``gps_week`` → adjusted standard GPS time (s)."""
    return np.asarray(t_week_s, float) + gps_week * SECONDS_PER_WEEK - ADJUSTED_STANDARD_OFFSET_S


def _geokey_crs(header: laspy.LasHeader) -> pyproj.CRS | None:
    """CRS of GeoTIFF keys laspy does not resolve: a user-defined projected CRS given by an EPSG
    projection (conversion) code, e.g. UTM zone 11N = 16011, on an EPSG or WGS 84-parameter datum."""
    keys = doubles = None
    for v in header.vlrs:
        if isinstance(v, laspy.vlrs.known.GeoKeyDirectoryVlr):
            keys = {k.id: k for k in v.geo_keys}
        elif isinstance(v, laspy.vlrs.known.GeoDoubleParamsVlr):
            doubles = [float(d.value) if hasattr(d, "value") else float(d) for d in v.doubles]
    if not keys or 3074 not in keys or keys[3074].tiff_tag_location != 0:
        return None

    def value(key_id):
        k = keys.get(key_id)
        if k is None:
            return None
        if k.tiff_tag_location == 0:
            return k.value_offset
        if k.tiff_tag_location == 34736 and doubles is not None and k.value_offset < len(doubles):
            return doubles[k.value_offset]
        return None

    geographic = value(2048)
    if geographic is not None and 1024 <= geographic <= 32766:
        geodetic = pyproj.CRS.from_epsg(int(geographic))
    else:
        a, rf = value(2057), value(2059)
        if a is None or rf is None:
            return None
        if abs(a - 6378137.0) < 1e-3 and abs(rf - 298.257223563) < 1e-6:
            geodetic = pyproj.CRS.from_epsg(4326)
        else:
            geodetic = pyproj.CRS.from_proj4(f"+proj=longlat +a={a} +rf={rf} +no_defs")
    try:
        conversion = pyproj.crs.CoordinateOperation.from_epsg(int(keys[3074].value_offset))
        crs = pyproj.crs.ProjectedCRS(conversion=conversion, geodetic_crs=geodetic)
    except pyproj.exceptions.CRSError:
        return None
    epsg = crs.to_epsg(min_confidence=70)
    return pyproj.CRS.from_epsg(epsg) if epsg else crs


def las_crs(header: laspy.LasHeader) -> pyproj.CRS | None:
    """The CRS of a LAS header (WKT VLR preferred, then GeoTIFF keys), or None."""
    try:
        crs = header.parse_crs()
    except pyproj.exceptions.CRSError:
        crs = None
    return crs if crs is not None else _geokey_crs(header)


def _check_gps_time(header: laspy.LasHeader, path: Path) -> str:
    if "gps_time" not in header.point_format.dimension_names:
        raise InputError(path, "point_format",
                         f"point format {header.point_format.id} has no GPS time; expected formats 1 or 3–10")
    standard = header.global_encoding.gps_time_type == laspy.header.GpsTimeType.STANDARD
    return "gps_adjusted_standard" if standard else "gps_week_seconds"


def _points(rec, header, path: Path, crs, time_system: str, fields) -> LasPoints:
    """LasPoints from a laspy record (whole file or chunk)."""
    unknown = set(fields) - set(OPTIONAL_FIELDS)
    if unknown:
        raise ValueError(f"unknown LAS fields {sorted(unknown)}; expected some of {OPTIONAL_FIELDS}")
    kw = {}
    for f in fields:
        if f == "scan_angle_deg":
            if header.point_format.id >= 6:
                kw[f] = np.asarray(rec.scan_angle, float) * SCAN_ANGLE_STEP_DEG
            else:
                kw[f] = np.asarray(rec.scan_angle_rank, float)
        else:
            kw[f] = np.asarray(getattr(rec, f))
    xyz = np.stack([np.asarray(rec.x, float), np.asarray(rec.y, float), np.asarray(rec.z, float)], axis=1)
    return LasPoints(xyz=xyz, gps_time=np.asarray(rec.gps_time, float), time_system=time_system, crs=crs,
                     path=path, **kw)


def _open(path: Path) -> laspy.LasReader:
    try:
        return laspy.open(path)
    except laspy.errors.LaspyException as e:
        raise InputError(path, None, f"not a readable LAS/LAZ file ({e})") from None


def _resolve_crs(header, crs) -> pyproj.CRS | None:
    return pyproj.CRS.from_user_input(crs) if crs is not None else las_crs(header)


def read_las(path: str | Path, crs=None, fields=OPTIONAL_FIELDS) -> LasPoints:
    """Read a LAS/LAZ file (all points). ``crs`` overrides the file's CRS; ``fields`` picks
    which of :data:`OPTIONAL_FIELDS` to load besides xyz and gps_time."""
    path = Path(path)
    with _open(path) as reader:
        header = reader.header
        time_system = _check_gps_time(header, path)
        rec = reader.read_points(header.point_count)
        return _points(rec, header, path, _resolve_crs(header, crs), time_system, fields)


def iter_las_chunks(path: str | Path, chunk_points: int = 2_000_000, crs=None,
                    fields=OPTIONAL_FIELDS) -> Iterator[LasPoints]:
    """Read a LAS/LAZ file in chunks of at most ``chunk_points`` points (files larger than memory)."""
    path = Path(path)
    with _open(path) as reader:
        header = reader.header
        time_system = _check_gps_time(header, path)
        file_crs = _resolve_crs(header, crs)
        for rec in reader.chunk_iterator(chunk_points):
            yield _points(rec, header, path, file_crs, time_system, fields)


def las_header(path: str | Path) -> laspy.LasHeader:
    """The header of a LAS/LAZ file (point count, bounds, VLRs) without reading points."""
    path = Path(path)
    with _open(path) as reader:
        return reader.header


def write_las(path: str | Path, xyz, crs, *, gps_time, scan_angle_deg, point_source_id, return_number=None,
              number_of_returns=None, classification=None, intensity=None, time_system="gps_week_seconds",
              force=False) -> Path:
    """Write LAS 1.4 point format 6 (LAZ when the suffix is .laz) atomically.

    ``xyz`` (N, 3) in ``crs`` (written as a WKT VLR), 1 mm scales (1e-9 deg for a geographic
    CRS); scan angles in degrees (stored in 0.006° steps); returns default to 1 of 1.
    """
    xyz = np.asarray(xyz, float)
    n = xyz.shape[0]
    crs = pyproj.CRS.from_user_input(crs)
    header = laspy.LasHeader(point_format=6, version="1.4")
    scale = 1e-9 if crs.is_geographic else 1e-3
    header.scales = np.array([scale, scale, 1e-3])
    header.offsets = np.floor(xyz.min(axis=0)) if n else np.zeros(3)
    header.add_crs(crs)
    header.global_encoding.gps_time_type = (
        laspy.header.GpsTimeType.STANDARD if time_system == "gps_adjusted_standard" else laspy.header.GpsTimeType.WEEK_TIME
    )
    las = laspy.LasData(header)
    las.x, las.y, las.z = xyz[:, 0], xyz[:, 1], xyz[:, 2]
    las.gps_time = np.asarray(gps_time, float)
    las.scan_angle = np.round(np.asarray(scan_angle_deg, float) / SCAN_ANGLE_STEP_DEG).astype(np.int16)
    las.point_source_id = np.asarray(point_source_id, np.uint16) * np.ones(n, np.uint16)
    las.return_number = np.ones(n, np.uint8) if return_number is None else np.asarray(return_number, np.uint8)
    las.number_of_returns = np.ones(n, np.uint8) if number_of_returns is None else np.asarray(number_of_returns, np.uint8)
    if classification is not None:
        las.classification = np.asarray(classification, np.uint8)
    if intensity is not None:
        las.intensity = np.asarray(intensity, np.uint16)
    with atomic_path(path, force) as tmp:
        las.write(tmp)
    return Path(path)
