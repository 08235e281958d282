"""POSPac ``smrmsg`` files: the accuracy of the smoothed trajectory (SBET), epoch by epoch.

Each record is 10 little-endian float64 (80 bytes): GPS time (s of week), north / east /
down position RMS (m), north / east / down velocity RMS (m/s), roll / pitch / heading RMS
(arc-minutes) — usually one record a second over the whole SBET. POSPac writes the file
beside the SBET (``smrmsg_<mission>.out`` next to ``sbet_<mission>.out``);
:func:`find_beside` finds it there.
"""

from __future__ import annotations

import math
import re
from pathlib import Path

import numpy as np

from calidar.errors import InputError
from calidar.outputs import atomic_path
from calidar.trajectory_accuracy import (MAX_ATTITUDE_SIGMA_RAD, MAX_POSITION_SIGMA_M,
                                         TrajectoryAccuracy)
from calidar.validate import existing_file, values

FIELDS = ("time", "north_rms", "east_rms", "down_rms", "north_vel_rms", "east_vel_rms",
          "down_vel_rms", "roll_rms", "pitch_rms", "heading_rms")
RECORD_BYTES = 8 * len(FIELDS)
ARCMIN_RAD = math.pi / (180.0 * 60.0)
#: (unit, largest σ) of the position, velocity and attitude columns, as stored (beyond: not a
#: usable trajectory)
RAW_LIMITS = (("m", MAX_POSITION_SIGMA_M), ("m/s", 100.0),
              ("arc-min", math.degrees(MAX_ATTITUDE_SIGMA_RAD) * 60.0))


def read_smrmsg(path: str | Path) -> TrajectoryAccuracy:
    """Read an smrmsg file into a :class:`TrajectoryAccuracy` (SI: m, m/s, rad)."""
    path = existing_file(path, "trajectory accuracy file")
    size = path.stat().st_size
    if size == 0:
        raise InputError(path, "size",
                         f"expected smrmsg records ({RECORD_BYTES} bytes each), the file is empty")
    if size % RECORD_BYTES:
        raise InputError(path, "size", f"expected a multiple of {RECORD_BYTES} bytes (10 float64 "
                         f"per record), got {size} bytes ({size // RECORD_BYTES} records + "
                         f"{size % RECORD_BYTES} bytes): not an smrmsg file, or truncated")
    a = np.fromfile(path, dtype="<f8").reshape(-1, len(FIELDS))
    for j, name in enumerate(FIELDS[1:], 1):  # σ in the file's own units, before any conversion
        unit, hi = RAW_LIMITS[(j - 1) // 3]
        values(a[:, j], path, name, 0.0, hi, unit)
    return TrajectoryAccuracy(a[:, 0], a[:, 1:4], a[:, 7:10] * ARCMIN_RAD, a[:, 4:7], str(path))


def write_smrmsg(path: str | Path, accuracy: TrajectoryAccuracy, force: bool = False) -> Path:
    """Write ``accuracy`` as an smrmsg file (atomically; zero velocity RMS when it has none)."""
    n = len(accuracy)
    vel = np.zeros((n, 3)) if accuracy.velocity_mps is None else accuracy.velocity_mps
    attitude_arcmin = accuracy.attitude_rad / ARCMIN_RAD
    a = np.column_stack([accuracy.time, accuracy.position_m, vel, attitude_arcmin]).astype("<f8")
    with atomic_path(path, force) as tmp:
        a.tofile(tmp)
    return Path(path)


def smrmsg_info(path: str | Path) -> dict:
    """What ``calidar info`` prints: records, time span and the median σ in SI units."""
    acc = read_smrmsg(path)
    return {"file": str(path), "kind": "trajectory accuracy (POSPac smrmsg)", "records": len(acc),
            "time_start_s": float(acc.time[0]), "time_end_s": float(acc.time[-1]),
            "median": acc.medians()}


def is_smrmsg_name(path: str | Path) -> bool:
    """Whether the file is named as POSPac names accuracy files (``smrmsg*``)."""
    return Path(path).name.lower().startswith("smrmsg")


def find_beside(trajectory: str | Path) -> Path | None:
    """The smrmsg file beside an SBET named ``sbet*.out``: ``smrmsg<same suffix>.out`` when it
    exists, else the only ``smrmsg*.out`` there; None when there is none (or the trajectory is
    not named ``sbet*``). Several candidates and none with the SBET's suffix: a clear error."""
    trajectory = Path(trajectory)
    m = re.match(r"sbet(.*)\.out$", trajectory.name, re.IGNORECASE)
    if m is None:
        return None
    found = sorted(p for p in trajectory.parent.iterdir()
                   if p.is_file() and re.match(r"smrmsg.*\.out$", p.name, re.IGNORECASE))
    same = [p for p in found if p.name.lower() == f"smrmsg{m.group(1)}.out".lower()]
    if same:
        return same[0]
    if len(found) > 1:
        names = ", ".join(p.name for p in found)
        raise InputError(trajectory, "trajectory accuracy",
                         f"found {len(found)} smrmsg files beside it ({names}) and none named "
                         f"smrmsg{m.group(1)}.out; expected one (give it with "
                         "--trajectory-accuracy)")
    return found[0] if found else None
