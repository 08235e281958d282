"""LAS/LAZ points (laspy + lazrs): coordinates, GPS time, scan angle, flight line, CRS.

GPS time is either GPS week seconds or adjusted standard GPS time (GPS time − 1e9 s), as
bit 0 of the header's global encoding says; ``LasPoints.time_system`` carries which, and
:func:`adjusted_standard_to_week_seconds` converts. Scan angles come back in degrees as
floats whatever the point format (LAS 1.2 ``scan_angle_rank``, whole degrees; LAS 1.4
``scan_angle``, 0.006° steps). The CRS comes from the WKT VLR or the GeoTIFF keys; a file
without one gives ``crs=None`` unless the caller supplies ``crs=``.
"""

from __future__ import annotations

from collections.abc import Iterator, Sequence
from dataclasses import dataclass, replace
from pathlib import Path

import laspy
import lazrs
import numpy as np
import pyproj

from calidar.errors import InputError
# the GPS-time conversions are re-exported: this module is their historical home
from calidar.io.gps_time import (  # noqa: F401
    ADJUSTED_STANDARD_OFFSET_S, adjusted_standard_in_week, adjusted_standard_to_week_seconds,
    single_gps_week, week_seconds_to_adjusted_standard,
)
from calidar.io.las_checks import bounds_tolerance, check_bounds, check_laz_count, check_scales
from calidar.io.las_crs import las_crs
# the writer is part of the io face
from calidar.io.las_write import SCAN_ANGLE_STEP_DEG, LasChunkWriter, write_las  # noqa: F401
from calidar.trajectory import TIME_SYSTEMS
from calidar.validate import existing_file, number

OPTIONAL_FIELDS = ("scan_angle_deg", "point_source_id", "return_number", "number_of_returns",
                   "classification", "intensity")
#: |x|, |y|, |z| beyond this (CRS units) is a damaged header or file, not a place
MAX_COORDINATE = 1e9
#: --time-system values
TIME_SYSTEM_NAMES = {"week": "gps_week_seconds", "adjusted": "gps_adjusted_standard"}
GEOID_UNDULATION_MAX_M = 150.0  #: |N| of every geoid model is below 110 m


@dataclass(frozen=True)
class PointOptions:
    """How to read points whatever their header says (the shared ``--crs``, ``--time-system`` and
    ``--geoid-undulation`` options): ``crs`` overrides or supplies the file's CRS; ``time_system``
    ("week" | "adjusted", or the long names of :data:`calidar.trajectory.TIME_SYSTEMS`) overrides
    the global-encoding bit when it lies; ``geoid_undulation_m`` N (m) makes a compound CRS with
    a geoid usable without the geoid grid: ellipsoidal height = height + N (docs/conventions.md)."""

    crs: str | pyproj.CRS | None = None
    time_system: str | None = None
    geoid_undulation_m: float | None = None

    def __post_init__(self):
        if self.time_system is not None:
            ts = TIME_SYSTEM_NAMES.get(self.time_system, self.time_system)
            if ts not in TIME_SYSTEMS:
                raise InputError(None, "--time-system", "expected one of "
                                 f"{', '.join(TIME_SYSTEM_NAMES)}, got {self.time_system!r}")
            object.__setattr__(self, "time_system", ts)
        if self.geoid_undulation_m is not None:
            n = number(self.geoid_undulation_m, "--geoid-undulation", -GEOID_UNDULATION_MAX_M,
                       GEOID_UNDULATION_MAX_M, "m")
            object.__setattr__(self, "geoid_undulation_m", n)


def _options(crs, options: PointOptions | None) -> PointOptions:
    """``options``, or PointOptions(crs) for the callers that only give a CRS."""
    if options is None:
        return PointOptions(crs=crs)
    if crs is not None:
        raise ValueError("give the CRS in PointOptions or as crs=, not both")
    return options


@dataclass(frozen=True, eq=False)
class LasPoints:
    """Points of a LAS/LAZ file (or of one chunk of it); optional fields are None when not read."""

    xyz: np.ndarray  #: (N, 3) float64, in ``crs`` (x/east/lon first), m or deg as the CRS says
    gps_time: np.ndarray  #: (N,) s, in ``time_system``
    time_system: str  #: "gps_week_seconds" | "gps_adjusted_standard"
    crs: pyproj.CRS | None
    path: Path
    #: (N,) float, deg, negative left of the flight direction
    scan_angle_deg: np.ndarray | None = None
    point_source_id: np.ndarray | None = None  #: (N,) flight line id
    return_number: np.ndarray | None = None
    number_of_returns: np.ndarray | None = None
    classification: np.ndarray | None = None
    intensity: np.ndarray | None = None
    #: N of PointOptions (heights in a geoid CRS + N = ellipsoidal)
    geoid_undulation_m: float | None = None

    def __len__(self) -> int:
        return self.gps_time.size

    def gps_week_seconds(self) -> np.ndarray:
        """GPS times as week seconds whatever the file holds (see
        :func:`adjusted_standard_to_week_seconds`; the week comes from these points only: for
        chunks of a file use the file's week instead)."""
        if self.time_system == "gps_week_seconds":
            return self.gps_time
        return adjusted_standard_to_week_seconds(self.gps_time, self.path)[0]

    def select(self, mask) -> "LasPoints":
        """The points where ``mask`` (boolean or index array) selects."""
        from calidar.cells import index_rows, take_rows

        rows = index_rows(mask, len(self))
        kw = {f: None if getattr(self, f) is None else take_rows(getattr(self, f), rows)
              for f in OPTIONAL_FIELDS}
        return replace(self, xyz=take_rows(self.xyz, rows), gps_time=take_rows(self.gps_time, rows),
                       **kw)


def concat_points(parts: Sequence[LasPoints]) -> LasPoints:
    """Several LasPoints (files or chunks) as one, with the first's CRS, path and time system;
    an optional field is kept only when every part has it."""
    first = parts[0]
    if len(parts) == 1:
        return first
    kw = {f: None if any(getattr(c, f) is None for c in parts)
          else np.concatenate([getattr(c, f) for c in parts]) for f in OPTIONAL_FIELDS}
    return replace(first, xyz=np.concatenate([c.xyz for c in parts]),
                   gps_time=np.concatenate([c.gps_time for c in parts]), **kw)


def gps_time_system(header: laspy.LasHeader, path: Path, override: str | None = None) -> str:
    """"gps_week_seconds" or "gps_adjusted_standard": ``override`` (PointOptions.time_system) when
    given, else the global-encoding bit 0; an error for point formats without GPS time."""
    if "gps_time" not in header.point_format.dimension_names:
        raise InputError(path, "point_format", f"point format {header.point_format.id} has no GPS "
                         "time; expected formats 1 or 3–10")
    if override is not None:
        return override
    standard = header.global_encoding.gps_time_type == laspy.header.GpsTimeType.STANDARD
    return "gps_adjusted_standard" if standard else "gps_week_seconds"


def _points(rec, header, path: Path, crs, time_system: str, fields, undulation=None,
            first: int = 0) -> LasPoints:
    """LasPoints from a laspy record (whole file or chunk whose first point is number ``first``);
    coordinates must be finite, within ±MAX_COORDINATE and near the header's bounds."""
    unknown = set(fields) - set(OPTIONAL_FIELDS)
    if unknown:
        raise ValueError(f"unknown LAS fields {sorted(unknown)}; expected some of "
                         f"{OPTIONAL_FIELDS}")
    kw = {}
    for f in fields:
        if f == "scan_angle_deg":
            if header.point_format.id >= 6:
                kw[f] = np.asarray(rec.scan_angle, float) * SCAN_ANGLE_STEP_DEG
            else:
                kw[f] = np.asarray(rec.scan_angle_rank, float)
        else:
            kw[f] = np.asarray(getattr(rec, f))
    xyz = _scaled_xyz(rec)
    _check_xyz(xyz, header, path, first)
    return LasPoints(xyz=xyz, gps_time=np.asarray(rec.gps_time, float), time_system=time_system,
                     crs=crs, path=path, geoid_undulation_m=undulation, **kw)


def _scaled_xyz(rec) -> np.ndarray:
    """The records' coordinates (N, 3): laspy's X · scale + offset per axis, written in place
    (the same two operations as ``np.asarray(rec.x, float)``, bit for bit, without three
    temporaries and a stacking copy)."""
    views = (rec.x, rec.y, rec.z)
    xyz = np.empty((len(rec), 3))
    for k, v in enumerate(views):
        if not all(hasattr(v, a) for a in ("array", "scale", "offset")):  # another laspy
            return np.stack([np.asarray(u, float) for u in views], axis=1)
        np.multiply(v.array, v.scale, out=xyz[:, k])
        np.add(xyz[:, k], v.offset, out=xyz[:, k])
    return xyz


def _check_xyz(xyz: np.ndarray, header, path: Path, first: int) -> None:
    """Coordinates (N, 3) of points numbered from ``first``: finite, within ±MAX_COORDINATE and near
    the header's bounds."""
    for k, axis in enumerate("xyz"):
        bad = ~(np.abs(xyz[:, k]) <= MAX_COORDINATE)
        if bad.any():
            i = int(np.argmax(bad))
            raise InputError(path, axis, f"expected finite coordinates within "
                             f"±{MAX_COORDINATE:g}, got {xyz[i, k]:g} at point {first + i} "
                             f"({int(bad.sum())} such points in this block): check the header's "
                             "scales and offsets")
    check_bounds(xyz, bounds_tolerance(header), header, path, first)


def _open(path: Path, selection=laspy.DecompressionSelection.all()) -> laspy.LasReader:
    """A laspy reader; ``selection``: the LAZ (1.4 formats 6–10) layers to decompress."""
    # not a pipe or device: laspy would wait or read without end
    existing_file(path, "LAS/LAZ file")
    try:
        reader = laspy.open(path, decompression_selection=selection)
    except laspy.errors.LaspyException as e:
        raise InputError(path, None, f"not a readable LAS/LAZ file ({e})") from None
    h = reader.header
    try:
        check_scales(h, path)
        check_laz_count(h, path)
    except InputError:
        reader.close()
        raise
    if not h.are_points_compressed:  # the records a LAS file holds follow from its size
        has_evlrs = getattr(h, "number_of_evlrs", 0)
        end = h.start_of_first_evlr if has_evlrs else Path(path).stat().st_size
        held = (end - h.offset_to_point_data) // h.point_format.size
        if held != h.point_count:
            reader.close()
            raise InputError(path, "point_count", f"the header says {h.point_count} points, the "
                             f"file holds {held} point records: truncated or a damaged header")
    return reader


def _resolve_crs(header, crs, path: Path) -> pyproj.CRS | None:
    """``crs`` when given (clear error if pyproj does not know it), else the file's CRS or None."""
    if crs is None:
        return las_crs(header)
    try:
        return pyproj.CRS.from_user_input(crs)
    except pyproj.exceptions.CRSError:
        raise InputError(path, "crs",
                         f"expected a CRS pyproj knows (e.g. EPSG:32611), got {crs!r}") from None


def _records(reader: laspy.LasReader, chunk_points: int, path: Path, start: int = 0,
             stop: int | None = None):
    """(first point number, laspy point record of ``chunk_points`` at most) of the points
    [start, stop) (default: all); damaged files and fewer records than the header says become
    clear errors."""
    n = start
    try:
        if start:
            reader.seek(start)
        if stop is None:
            for rec in reader.chunk_iterator(chunk_points):
                yield n, rec
                n += len(rec)
        else:
            while n < stop and len(rec := reader.read_points(min(chunk_points, stop - n))):
                yield n, rec
                n += len(rec)
    except (laspy.errors.LaspyException, lazrs.LazrsError, ValueError) as e:
        size = getattr(reader.header, "calidar_laz_chunk_size", None)
        where = f" from point {n} on" + (f" (LAZ chunk {n // size})" if size else "")
        raise InputError(path, None, f"cannot read the points{where} ({e}): a truncated file or a "
                         "corrupted chunk") from None
    count = reader.header.point_count
    if n != (count if stop is None else min(stop, count)):
        raise InputError(path, "point_count", f"the header says {count} points, the file holds "
                         f"{n}: truncated or a damaged header")


def read_las(path: str | Path, crs=None, fields=OPTIONAL_FIELDS, *,
             options: PointOptions | None = None) -> LasPoints:
    """Read a LAS/LAZ file (all points). ``crs`` overrides the file's CRS (or give ``options``:
    CRS, time system, geoid undulation); ``fields`` picks which of :data:`OPTIONAL_FIELDS` to load
    besides xyz and gps_time.

    >>> import tempfile, numpy as np, calidar
    >>> xyz = np.array([[500000.0, 5200000.0, 400.0], [500001.0, 5200002.0, 401.5]])  # UTM 32N
    >>> path = calidar.write_las(Path(tempfile.mkdtemp()) / "strip.laz", xyz, "EPSG:32632",
    ...                          gps_time=[10.0, 10.5], scan_angle_deg=[-3.0, 4.5],
    ...                          point_source_id=7)
    >>> points = calidar.read_las(path)
    >>> len(points), points.crs.to_epsg(), points.xyz[1].tolist(), points.point_source_id.tolist()
    (2, 32632, [500001.0, 5200002.0, 401.5], [7, 7])
    """
    path, opts = Path(path), _options(crs, options)
    with _open(path) as reader:
        header = reader.header
        time_system = gps_time_system(header, path, opts.time_system)
        file_crs = _resolve_crs(header, opts.crs, path)
        undulation = opts.geoid_undulation_m
        chunks = [_points(rec, header, path, file_crs, time_system, fields, undulation, first)
                  for first, rec in _records(reader, max(header.point_count, 1), path)]
    if not chunks:
        rec = laspy.ScaleAwarePointRecord.zeros(0, header=header)
        return _points(rec, header, path, file_crs, time_system, fields, undulation)
    return chunks[0]


_S = laspy.DecompressionSelection
#: the LAZ 1.4 (formats 6–10) layer of each field (LasPoints' or laspy's names; x, y and the
#: returns are in the base layer)
_LAYERS = {"gps_time": _S.GPS_TIME, "z": _S.Z, "Z": _S.Z, "scan_angle_deg": _S.SCAN_ANGLE,
           "scan_angle": _S.SCAN_ANGLE, "point_source_id": _S.POINT_SOURCE_ID,
           "classification": _S.CLASSIFICATION, "intensity": _S.INTENSITY}


def _layers(names) -> laspy.DecompressionSelection:
    """The base layer and those holding ``names``: the others are skipped when decompressing."""
    sel = _S.base()
    for name in names:
        sel |= _LAYERS.get(name, _S.base())
    return sel


def _selection(fields) -> laspy.DecompressionSelection:
    """The LAZ 1.4 (formats 6–10) layers holding xyz, GPS time and ``fields``: the others are
    skipped."""
    return _layers(("z", "gps_time", *fields))


def iter_las_chunks(path: str | Path, chunk_points: int = 2_000_000, crs=None,
                    fields=OPTIONAL_FIELDS, *, options: PointOptions | None = None, start: int = 0,
                    stop: int | None = None) -> Iterator[LasPoints]:
    """Read a LAS/LAZ file in chunks of at most ``chunk_points`` points (files larger than memory),
    the points [start, stop) only when given (a LAZ file seeks by its chunk table); of a LAZ 1.4
    file only the layers of xyz, GPS time and ``fields`` are decompressed."""
    path, opts = Path(path), _options(crs, options)
    with _open(path, _selection(fields)) as reader:
        header = reader.header
        time_system = gps_time_system(header, path, opts.time_system)
        file_crs = _resolve_crs(header, opts.crs, path)
        undulation = opts.geoid_undulation_m
        for first, rec in _records(reader, chunk_points, path, start, stop):
            yield _points(rec, header, path, file_crs, time_system, fields, undulation, first)


def iter_las_times(path: str | Path, chunk_points: int = 2_000_000) -> Iterator[np.ndarray]:
    """GPS times (s, as stored) of a LAS/LAZ file, chunk by chunk: the cheap first pass of streamed
    commands (LAZ 1.4 decompresses only the time layer)."""
    for chunk in iter_las_fields(path, ("gps_time",), chunk_points):
        yield chunk["gps_time"]


def iter_las_fields(path: str | Path, names,
                    chunk_points: int = 2_000_000) -> Iterator[dict[str, np.ndarray]]:
    """Some raw point fields (laspy names: gps_time, classification, point_source_id, return_number,
    x, X (the stored integer), ...) of a LAS/LAZ file chunk by chunk, decompressing only their
    layers (LAZ 1.4). With x, y and z, the coordinates are checked as :func:`iter_las_chunks`
    checks them (finite, within ±MAX_COORDINATE, near the header's bounds) and also given as one
    (N, 3) array "xyz"."""
    path = Path(path)
    check = {"x", "y", "z"} <= set(names)
    scaled = ("gps_time", "x", "y", "z")  # read as floats; the others as stored
    with _open(path, _layers(names)) as reader:
        gps_time_system(reader.header, path)
        for first, rec in _records(reader, chunk_points, path):
            out = {name: np.asarray(getattr(rec, name), float if name in scaled else None)
                   for name in names if not (check and name in ("x", "y", "z"))}
            if check:  # also as one (N, 3) array "xyz"
                out["xyz"] = xyz = _scaled_xyz(rec)
                _check_xyz(xyz, reader.header, path, first)
                out.update(x=xyz[:, 0], y=xyz[:, 1], z=xyz[:, 2])
            yield out


def las_header(path: str | Path) -> laspy.LasHeader:
    """The header of a LAS/LAZ file (point count, bounds, VLRs) without reading points."""
    path = Path(path)
    with _open(path) as reader:
        return reader.header


def las_file_crs(path: str | Path, crs=None) -> pyproj.CRS | None:
    """The CRS points of a LAS/LAZ file will be read in: ``crs`` when given (clear error if pyproj
    does not know it), else the file's, else None. Reads the header only."""
    return _resolve_crs(las_header(path), crs, Path(path))


def las_time_system(path: str | Path, override: str | None = None) -> str:
    """The GPS time system of a LAS/LAZ file: ``override`` (PointOptions.time_system) or its
    header's (error for formats without GPS time)."""
    return gps_time_system(las_header(path), Path(path), override)
