"""Writing LAS 1.4 / LAZ files (laspy + lazrs): point format 6 with a WKT CRS, whole
(:func:`write_las`) or chunk by chunk (:class:`LasChunkWriter`); atomic, never over an existing
file without ``force``. Reading is :mod:`calidar.io.las`."""

from __future__ import annotations

from pathlib import Path

import laspy
import numpy as np
import pyproj

from calidar.outputs import atomic_path

SCAN_ANGLE_STEP_DEG = 0.006  #: LAS 1.4 scaled scan angle unit


def _las_header(crs: pyproj.CRS, offsets, time_system: str, creation_date=None) -> laspy.LasHeader:
    """A LAS 1.4 point format 6 header: 1 mm scales (1e-9 deg for a geographic CRS), ``crs`` as
    WKT."""
    header = laspy.LasHeader(point_format=6, version="1.4")
    scale = 1e-9 if crs.is_geographic else 1e-3
    header.scales = np.array([scale, scale, 1e-3])
    header.offsets = np.asarray(offsets, float)
    header.add_crs(crs)
    if creation_date is not None:
        header.creation_date = creation_date
    time_types = laspy.header.GpsTimeType
    adjusted = time_system == "gps_adjusted_standard"
    header.global_encoding.gps_time_type = time_types.STANDARD if adjusted else time_types.WEEK_TIME
    return header


def _las_data(header: laspy.LasHeader, xyz, *, gps_time, scan_angle_deg, point_source_id,
              return_number=None, number_of_returns=None, classification=None,
              intensity=None) -> laspy.LasData:
    """Points (as :func:`write_las` takes them) in a laspy LasData of ``header``."""
    xyz = np.asarray(xyz, float)
    n = xyz.shape[0]
    las = laspy.LasData(header)
    las.x, las.y, las.z = xyz[:, 0], xyz[:, 1], xyz[:, 2]
    las.gps_time = np.asarray(gps_time, float)
    steps = np.round(np.asarray(scan_angle_deg, float) / SCAN_ANGLE_STEP_DEG)
    las.scan_angle = steps.astype(np.int16)
    las.point_source_id = np.asarray(point_source_id, np.uint16) * np.ones(n, np.uint16)

    def count(v) -> np.ndarray:  # a return number or count; 1 of 1 when not given
        return np.ones(n, np.uint8) if v is None else np.asarray(v, np.uint8)

    las.return_number = count(return_number)
    las.number_of_returns = count(number_of_returns)
    if classification is not None:
        las.classification = np.asarray(classification, np.uint8)
    if intensity is not None:
        las.intensity = np.asarray(intensity, np.uint16)
    return las


def write_las(path: str | Path, xyz, crs, *, gps_time, scan_angle_deg, point_source_id,
              return_number=None, number_of_returns=None, classification=None, intensity=None,
              time_system="gps_week_seconds", creation_date=None, force=False) -> Path:
    """Write LAS 1.4 point format 6 (LAZ when the suffix is .laz) atomically.

    ``creation_date`` (datetime.date) goes into the header; default today (pass a fixed date
    for byte-reproducible files).

    ``xyz`` (N, 3) in ``crs`` (written as a WKT VLR), 1 mm scales (1e-9 deg for a geographic
    CRS); scan angles in degrees (stored in 0.006° steps); returns default to 1 of 1.

    >>> import tempfile, numpy as np, calidar
    >>> xyz = np.array([[500000.0, 5200000.0, 400.0], [500001.0, 5200002.0, 401.5]])  # UTM 32N
    >>> path = calidar.write_las(Path(tempfile.mkdtemp()) / "strip.las", xyz, "EPSG:32632",
    ...                          gps_time=[10.0, 10.5], scan_angle_deg=[-3.0, 4.5],
    ...                          point_source_id=7)
    >>> points = calidar.read_las(path)
    >>> points.time_system, points.scan_angle_deg.tolist(), points.return_number.tolist()
    ('gps_week_seconds', [-3.0, 4.5], [1, 1])
    """
    xyz = np.asarray(xyz, float)
    crs = pyproj.CRS.from_user_input(crs)
    offsets = np.floor(xyz.min(axis=0)) if xyz.shape[0] else np.zeros(3)
    header = _las_header(crs, offsets, time_system, creation_date)
    las = _las_data(header, xyz, gps_time=gps_time, scan_angle_deg=scan_angle_deg,
                    point_source_id=point_source_id, return_number=return_number,
                    number_of_returns=number_of_returns, classification=classification,
                    intensity=intensity)
    with atomic_path(path, force) as tmp:
        las.write(tmp)
    return Path(path)


class LasChunkWriter:
    """Write a LAS 1.4 point format 6 file (LAZ by suffix) chunk by chunk, atomically: the file
    appears under ``path`` only when the ``with`` block ends without an error. ``offsets``
    (CRS units) must lie near every point (e.g. the inputs' header minimum); ``write`` takes
    the arguments of :func:`write_las` but the CRS and time system."""

    def __init__(self, path: str | Path, crs, offsets, time_system: str = "gps_week_seconds",
                 force: bool = False):
        self.path, self.force = Path(path), force
        self.header = _las_header(pyproj.CRS.from_user_input(crs), offsets, time_system)

    def __enter__(self) -> "LasChunkWriter":
        self._atomic = atomic_path(self.path, self.force)
        tmp = self._atomic.__enter__()
        compress = self.path.suffix.lower() == ".laz"
        self._writer = laspy.open(tmp, mode="w", header=self.header, do_compress=compress)
        return self

    def write(self, xyz, **fields) -> None:
        self._writer.write_points(_las_data(self.header, xyz, **fields).points)

    def write_record(self, record: laspy.PackedPointRecord) -> None:
        """Points already packed as records of ``self.header`` (fast writers that build them)."""
        self._writer.write_points(record)

    def __exit__(self, *exc) -> bool:
        self._writer.close()
        return bool(self._atomic.__exit__(*exc))
