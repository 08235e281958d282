"""Optech CSD ("corrected sensor data") files: the raw pulses of Optech ALTM systems.

Layout (little-endian, packed), as PDAL's ``readers.optech`` documents it (PDAL
io/OptechCommon.hpp, io/OptechReader.cpp; checked on the real 1 000-pulse sample):

- a header of ``header_size`` bytes (2 048): signature "CSD\\0", vendor (64 chars), software
  (32 chars), format version (float32), header size, GPS week (uint16), first/last GPS time
  (float64, s of week), record count (uint32), strip count (uint16), 256 strip pointers (uint32),
  misalignment angles roll/pitch/heading (3 float64, rad), "IMU offsets" (3 float64, rad: PDAL
  adds them to the misalignment angles), temperature (°C) and pressure (mbar) (float64);
- then one 69-byte record per pulse: GPS time (float64, s of week), return count (uint8), four
  ranges (float32, m: returns 1, 2, 3 and the last), four intensities (uint16), scan angle, roll,
  pitch, heading (float32, rad), latitude, longitude (float64, rad), elevation (float32, m).

Longitudes are stored offset by multiples of 2π (the sample's are ≈ −442.55°): the reader wraps
them to (−π, π]. Angle conventions and their conversion into calidar's frames are in
docs/sensor.md ("Optech CSD"): the attitude and the boresight are calidar's roll/pitch/heading
and R_bs directly, the scan angle is the linear scanner's θ.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np

from calidar.errors import InputError
from calidar.trajectory import Trajectory
from calidar.validate import existing_file, values

SIGNATURE = b"CSD\x00"
HEADER = np.dtype([
    ("signature", "S4"), ("vendor", "S64"), ("software", "S32"), ("format_version", "<f4"),
    ("header_size", "<u2"), ("gps_week", "<u2"), ("min_time", "<f8"), ("max_time", "<f8"),
    ("records", "<u4"), ("strips", "<u2"), ("strip_pointers", "<u4", 256),
    ("misalignment", "<f8", 3), ("imu_offsets", "<f8", 3), ("temperature", "<f8"),
    ("pressure", "<f8"), ("free", "V830"),
])
RECORD = np.dtype([
    ("time", "<f8"), ("returns", "u1"), ("range", "<f4", 4), ("intensity", "<u2", 4),
    ("scan_angle", "<f4"), ("roll", "<f4"), ("pitch", "<f4"), ("heading", "<f4"), ("lat", "<f8"),
    ("lon", "<f8"), ("elevation", "<f4"),
])
MAX_RETURNS = 4


@dataclass(frozen=True)
class CsdHeader:
    """What the header says; angles in rad, times in GPS seconds of week ``gps_week``."""

    vendor: str
    software: str
    format_version: float
    header_size: int
    gps_week: int
    time_range: tuple[float, float]
    records: int
    strips: int
    misalignment_rad: tuple[float, float, float]  #: roll, pitch, heading
    imu_offsets_rad: tuple[float, float, float]  #: roll, pitch, heading (added to the misalignment)
    temperature_c: float
    pressure_mbar: float


@dataclass(frozen=True, eq=False)
class CsdPulses:
    """The pulses of a CSD file, one row each; SI units, angles in rad."""

    header: CsdHeader
    path: Path
    time: np.ndarray  #: GPS s of week (N,)
    returns: np.ndarray  #: returns per pulse (N,)
    range_m: np.ndarray  #: (N, 4): returns 1, 2, 3 and the last
    intensity: np.ndarray  #: (N, 4)
    scan_angle: np.ndarray  #: (N,) rad, positive to the right of the flight direction
    roll: np.ndarray
    pitch: np.ndarray
    heading: np.ndarray  #: true heading, rad
    lat: np.ndarray
    lon: np.ndarray  #: wrapped to (−π, π]
    height: np.ndarray  #: m (ellipsoidal, WGS 84)

    def __len__(self) -> int:
        return self.time.size


def is_csd(path: str | Path) -> bool:
    """Whether the file starts with the CSD signature."""
    with open(path, "rb") as f:
        return f.read(4) == SIGNATURE


def _text(raw: bytes) -> str:
    return raw.split(b"\x00", 1)[0].decode("latin-1").strip()


def read_csd_header(path: str | Path) -> CsdHeader:
    """The header of a CSD file; clear errors for another file, a short file or impossible
    values."""
    path = existing_file(path, "CSD file")
    raw = path.read_bytes()[:HEADER.itemsize]
    if raw[:4] != SIGNATURE:
        raise InputError(path, "signature",
                         f"expected an Optech CSD file (starting with 'CSD'), got {raw[:4]!r}")
    if len(raw) < HEADER.itemsize:
        raise InputError(path, "header", f"expected a {HEADER.itemsize}-byte header, the file has "
                         f"{len(raw)} bytes")
    h = np.frombuffer(raw, HEADER)[0]
    if h["header_size"] < HEADER.itemsize:
        raise InputError(path, "header_size",
                         f"expected ≥ {HEADER.itemsize} bytes, got {h['header_size']}")
    for name in ("misalignment", "imu_offsets"):
        values(h[name], path, name, -np.pi, np.pi, "rad", what="angle")
    return CsdHeader(
        vendor=_text(h["vendor"]), software=_text(h["software"]),
        format_version=round(float(h["format_version"]), 4),
        header_size=int(h["header_size"]), gps_week=int(h["gps_week"]),
        time_range=(float(h["min_time"]), float(h["max_time"])), records=int(h["records"]),
        strips=int(h["strips"]),
        misalignment_rad=tuple(float(v) for v in h["misalignment"]),
        imu_offsets_rad=tuple(float(v) for v in h["imu_offsets"]),
        temperature_c=float(h["temperature"]), pressure_mbar=float(h["pressure"]),
    )


def read_csd(path: str | Path) -> CsdPulses:
    """Every pulse of a CSD file, checked: record count against the file size, finite values in
    their physical ranges (ranges 0–10 km, angles, latitude, elevation −1 km … 100 km)."""
    header = read_csd_header(path)
    path = Path(path)
    body = path.stat().st_size - header.header_size
    if body != header.records * RECORD.itemsize:
        raise InputError(path, "records", f"header says {header.records} records of "
                         f"{RECORD.itemsize} bytes ({header.records * RECORD.itemsize} bytes), the "
                         f"file holds {body} bytes after the header: truncated or damaged")
    with open(path, "rb") as f:
        f.seek(header.header_size)
        r = np.fromfile(f, RECORD, header.records)
    time = values(r["time"], path, "gps_time", 0.0, 7 * 86400.0 + 1.0, "s of week")
    values(r["returns"], path, "return_count", 0, 255)
    ranges = values(r["range"], path, "range", 0.0, 1e4, "m").astype(float)
    scan = values(r["scan_angle"], path, "scan_angle", -np.pi / 2, np.pi / 2, "rad")
    attitude_ranges = (("roll", -np.pi, np.pi), ("pitch", -np.pi / 2, np.pi / 2),
                       ("heading", -2 * np.pi, 2 * np.pi))
    att = {k: values(r[k], path, k, lo, hi, "rad") for k, lo, hi in attitude_ranges}
    lat = values(r["lat"], path, "latitude", -np.pi / 2, np.pi / 2, "rad")
    lon = values(r["lon"], path, "longitude", -8 * np.pi, 8 * np.pi, "rad")
    height = values(r["elevation"], path, "elevation", -1000.0, 1e5, "m")
    return CsdPulses(header=header, path=path, time=time, returns=r["returns"].astype(np.int64),
                     range_m=ranges, intensity=r["intensity"].astype(np.int64), scan_angle=scan,
                     lat=lat, lon=np.angle(np.exp(1j * lon)), height=height, **att)


def returns(p: CsdPulses) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """One row per return, as PDAL's reader takes them: (pulse index, slot 0–3, return number,
    number of returns). A pulse with n returns gives slots 0 … min(n, 4) − 1; slot 3 holds the last
    return, numbered n. Pulses without a return give none."""
    n = np.minimum(p.returns, MAX_RETURNS)
    pulse = np.repeat(np.arange(len(p)), n)
    slot = np.arange(pulse.size) - np.repeat(np.cumsum(n) - n, n)
    number = np.where(slot == MAX_RETURNS - 1, p.returns[pulse], slot + 1)
    return pulse, slot, number, p.returns[pulse]


def csd_trajectory(p: CsdPulses) -> Trajectory:
    """The trajectory the pulses carry: one record per pulse (position of the laser, attitude;
    GPS week seconds), so that georeferencing at a pulse's time uses exactly its own record."""
    heading = np.angle(np.exp(1j * p.heading))  # wrapped to (−π, π]
    return Trajectory(time=p.time, lat=p.lat, lon=p.lon, height=p.height, roll=p.roll,
                      pitch=p.pitch, heading=heading, time_system="gps_week_seconds",
                      source=str(p.path))
