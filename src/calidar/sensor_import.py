"""Vendor mounting conventions → a calidar :class:`~calidar.sensor.Sensor` (docs/sensor.md).

calidar: v_b = R_bs · v_s + a_b, R_bs = Rz(yaw) · Ry(pitch) · Rx(roll), body x forward, y right,
z down; the linear scanner's beam is u_s = (0, sin θ, cos θ) (nadir along z_s, θ > 0 to the right).
A vendor writes v_B = R_V · v_V + t_V in its own body frame B and scanner frame V. With the signed
axis maps v_b = A · v_B and v_s = P · v_V (:func:`axes`):

    R_bs = A · R_V · Pᵀ,   a_b = A · t_V.

Each vendor function states A, P and R_V from the vendor's published equations (cited there);
tests/unit/core/test_sensor_import.py checks each against an independent evaluation of the
vendor's own equation.
"""

from __future__ import annotations

import json
import re
import tomllib
from pathlib import Path

import numpy as np

from calidar import frames
from calidar.errors import InputError
from calidar.io.optech_csd import CsdHeader, read_csd_header
from calidar.sensor import Sensor
from calidar.validate import read_text, table_number

SOURCES = ("leeward", "optech-csd", "pdal-scan2imu")
_AXIS = re.compile(r"^\s*([+-]?)([xyz])\s*$")


def axes(spec: str, what: str = "--scanner-axes") -> np.ndarray:
    """The signed axis map M (3, 3) with v_calidar = M · v_vendor from "a,b,c": calidar's x, y and
    z axes as vendor axes, e.g. "y,x,-z" (calidar x = vendor y, y = vendor x, z = −vendor z)."""
    parts = spec.split(",")
    m = np.zeros((3, 3))
    used = set()
    for row, part in enumerate(parts if len(parts) == 3 else []):
        match = _AXIS.match(part)
        if not match or match.group(2) in used:
            break
        used.add(match.group(2))
        m[row, "xyz".index(match.group(2))] = -1.0 if match.group(1) == "-" else 1.0
    if len(used) != 3 or np.linalg.det(m) < 0:
        raise InputError(None, what, "expected calidar's x,y,z as three distinct signed vendor "
                         f"axes forming a right-handed frame (e.g. 'y,x,-z'), got {spec!r}")
    return m


def from_vendor(r_vendor, t_vendor_m, body: str = "x,y,z", scanner: str = "x,y,z", **kw) -> Sensor:
    """A Sensor from a vendor's scanner → body rotation R_V (3, 3) and lever arm t_V (3,) m, given
    the vendor's body and scanner axes (:func:`axes`); ``kw``: other Sensor fields."""
    a, p = axes(body, "body axes"), axes(scanner)
    r_bs = a @ np.asarray(r_vendor, float) @ p.T
    roll, pitch, yaw = (float(v) for v in frames.matrix_to_rpy(r_bs))
    lever = a @ np.asarray(t_vendor_m, float) + 0.0  # no −0.0 in sensor.toml
    return Sensor(roll, pitch, yaw, *(float(v) for v in lever), **kw)


# --- Applanix POS / POSPac (POS MV V4/V5 user guides: x forward, y starboard, z down) ---------
def lever_arm_from_pospac(reference_to_sensor_m, reference_to_imu_m=(0.0, 0.0, 0.0)) -> np.ndarray:
    """calidar's lever arm (m) from POS lever arms "reference to sensor" and "reference to IMU"
    (x forward, y starboard, z down: calidar's body axes), for an SBET output at the IMU whose axes
    are the reference frame's (zero IMU mounting angles): a_b = ref→sensor − ref→IMU. For an SBET
    output at the reference point give ``reference_to_imu_m`` = 0."""
    return np.asarray(reference_to_sensor_m, float) - np.asarray(reference_to_imu_m, float)


# --- Optech CSD (PDAL io/OptechCommon.hpp, pdal/util/Georeference.cpp) ---------------------------
#: Optech's frames: body and scanner x right, y forward, z up; local level east, north, up.
OPTECH_AXES = "y,x,-z"


def optech_matrix(roll, pitch, heading) -> np.ndarray:
    """Optech's attitude/boresight matrix "R3(heading) · R1(−pitch) · R2(−roll)" (rad) as an active
    rotation of its (right, forward, up) axes: Rz(−heading) · Rx(pitch) · Ry(roll)."""
    return frames.rot_z(-heading) @ frames.rot_x(pitch) @ frames.rot_y(roll)


def from_optech_header(header: CsdHeader, crs: str | None = None) -> Sensor:
    """The CSD's boresight: Optech's matrix of misalignment + IMU-offset angles (summed, as PDAL's
    reader does), no lever arm (the pulses carry the laser's position). The scan angle is the linear
    scanner's θ: Optech's beam (ρ sin α, 0, −ρ cos α) is calidar's (0, ρ sin α, ρ cos α)."""
    angles = np.add(header.misalignment_rad, header.imu_offsets_rad)
    return from_vendor(optech_matrix(*angles), np.zeros(3), OPTECH_AXES, OPTECH_AXES, crs=crs)


def from_optech_csd(path: str | Path) -> Sensor:
    """:func:`from_optech_header` of a CSD file."""
    return from_optech_header(read_csd_header(path))


# --- leeward (github.com/gadomski/leeward: src/measurement.rs, RollPitchYaw::as_matrix) ----------
#: leeward's scanner beam is ρ(cos α, 0, sin α): calidar x = leeward y, y = leeward z,
#: z = leeward x.
LEEWARD_SCANNER_AXES = "y,z,x"


def from_leeward(path: str | Path) -> Sensor:
    """leeward's config.toml: boresight roll/pitch/yaw (rad) as Rz(yaw)·Ry(pitch)·Rx(roll) in
    leeward's scanner frame, body frame as calidar's; leeward subtracts its lever arm (body = R·s −
    lever_arm), so a_b = −lever_arm."""
    try:
        doc = tomllib.loads(read_text(path, "leeward config.toml"))
    except tomllib.TOMLDecodeError as e:
        raise InputError(path, None, f"not valid TOML ({e})") from None
    b = doc.get("boresight")
    if not isinstance(b, dict):
        raise InputError(path, "boresight",
                         "missing table; expected [boresight] with roll, pitch, yaw (rad)")
    rpy = [table_number(b, k, path, -2 * np.pi, 2 * np.pi, "rad", "boresight.")
           for k in ("roll", "pitch", "yaw")]
    lever = doc.get("lever_arm", [0.0, 0.0, 0.0])
    if isinstance(lever, dict):  # older leeward: { x = …, y = …, z = … }
        lever = [lever.get(k) for k in "xyz"]
    if not (isinstance(lever, list) and len(lever) == 3):
        raise InputError(path, "lever_arm", f"expected [x, y, z] in metres, got {lever!r}")
    t = [-table_number({k: v}, k, path, -50.0, 50.0, "m", "lever_arm.")
         for k, v in zip("xyz", lever)]
    return from_vendor(frames.rpy_to_matrix(*rpy), t, "x,y,z", LEEWARD_SCANNER_AXES)


# --- PDAL filters.georeference scan2imu ----------------------------------------------------------
def read_scan2imu(path: str | Path) -> np.ndarray:
    """The 4 × 4 scan2imu matrix (row-major) from a text file of 16 numbers, or from a PDAL
    pipeline (JSON) holding a filters.georeference stage."""
    text = read_text(path, "scan2imu file").strip()
    if text[:1] in "[{":
        text = _scan2imu_option(text, path)
    try:
        vals = np.array([float(v) for v in re.split(r"[\s,;]+", text.strip()) if v], float)
    except ValueError:
        vals = np.array([])
    if vals.size != 16 or not np.all(np.isfinite(vals)):
        raise InputError(path, "scan2imu", "expected 16 finite numbers (a 4 × 4 matrix, row by "
                         f"row), got {vals.size}")
    m = vals.reshape(4, 4)
    r = m[:3, :3]
    rotation = np.allclose(r @ r.T, np.eye(3), atol=1e-5) and np.linalg.det(r) > 0
    if not rotation or not np.allclose(m[3], [0, 0, 0, 1]):
        raise InputError(path, "scan2imu", "expected a rigid transformation: a rotation "
                         "(orthonormal to 1e-5, determinant +1) and a translation, last row "
                         "0 0 0 1")
    return m


def _scan2imu_option(text: str, path) -> str:
    """The scan2imu option of the first stage that has one in a PDAL pipeline (JSON text)."""
    try:
        doc = json.loads(text)
    except json.JSONDecodeError as e:
        message = f"expected a PDAL pipeline (JSON): {e.msg}"
        raise InputError(path, f"line {e.lineno}", message) from None
    stages = doc.get("pipeline", []) if isinstance(doc, dict) else doc
    found = [s["scan2imu"] for s in stages if isinstance(s, dict) and "scan2imu" in s]
    if not found:
        raise InputError(path, "scan2imu",
                         "expected a filters.georeference stage with a scan2imu option")
    return str(found[0])


def from_scan2imu(matrix, scanner: str = "x,y,z") -> Sensor:
    """PDAL's scan2imu (NED, its default): ned = R_nb(roll, pitch, heading) · (R · p + t) with p in
    the scanner's own frame, body x forward, y right, z down (calidar's). ``scanner``: calidar's
    scanner axes as the scanner's own axes (:func:`axes`)."""
    m = np.asarray(matrix, float)
    return from_vendor(m[:3, :3], m[:3, 3], "x,y,z", scanner)


def import_sensor(source: str, path: str | Path, scanner: str | None = None) -> Sensor:
    """A Sensor from a vendor file: ``source`` one of :data:`SOURCES`; ``scanner`` axes only for
    pdal-scan2imu (the others state theirs)."""
    if source not in SOURCES:
        raise InputError(None, "--from", f"expected one of {', '.join(SOURCES)}, got {source!r}")
    if scanner is not None and source != "pdal-scan2imu":
        message = f"only for --from pdal-scan2imu; {source} states its own axes"
        raise InputError(None, "--scanner-axes", message)
    if source == "leeward":
        return from_leeward(path)
    if source == "optech-csd":
        return from_optech_csd(path)
    return from_scan2imu(read_scan2imu(path), scanner or "x,y,z")
