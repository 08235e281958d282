"""Direct (forward) and inverse georeferencing — the lidar equation.

    p_e = r_e(t) + R_eb(t) · (R_bs · ρ · u_s(angles) + a_b)

with r_e the IMU position in ECEF, R_eb = R_en(φ, λ) · R_nb(roll, pitch, heading)
interpolated by quaternion SLERP, R_bs the boresight, a_b the lever arm, ρ the corrected
range and u_s the scanner's unit beam vector. Inverse georeferencing solves the same
equation for ρ · u_s given p_e and t. Everything is in ECEF metres; :func:`to_crs` and
:func:`from_crs` convert at the edges.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import pyproj

from calidar import frames
from calidar.sensor import Sensor
from calidar.trajectory import Trajectory


@dataclass(frozen=True)
class ScanObservations:
    """What the instrument observed for each point (result of inverse georeferencing)."""

    time: np.ndarray  #: GPS s (N,)
    range_m: np.ndarray  #: measured range, m (N,)
    angles: np.ndarray  #: scanner observations, rad (N, k)
    vector_s: np.ndarray  #: true range × unit beam in the scanner frame, m (N, 3)


def _pose(traj: Trajectory, time) -> tuple[np.ndarray, np.ndarray]:
    pos, q = traj.interpolate(time)
    return pos, frames.quat_to_matrix(q)


def forward_vectors(traj: Trajectory, sensor: Sensor, time, vector_s) -> np.ndarray:
    """Points (N, 3) ECEF from scanner-frame vectors (N, 3) m at GPS times (N,)."""
    pos, r_eb = _pose(traj, time)
    v_b = np.asarray(vector_s, float) @ sensor.r_bs.T + sensor.lever_arm
    return pos + np.einsum("nij,nj->ni", r_eb, v_b)


def forward(traj: Trajectory, sensor: Sensor, time, range_m, angles) -> np.ndarray:
    """Points (N, 3) ECEF from GPS times, measured ranges (m) and scanner angles (rad)."""
    rho = sensor.true_range(range_m)
    return forward_vectors(traj, sensor, time, rho[:, None] * sensor.scanner.directions(angles))


def inverse(traj: Trajectory, sensor: Sensor, time, points_ecef) -> ScanObservations:
    """Scanner-frame vectors, measured ranges and scanner angles of points (N, 3) ECEF."""
    time = np.asarray(time, float)
    pos, r_eb = _pose(traj, time)
    v_b = np.einsum("nji,nj->ni", r_eb, np.asarray(points_ecef, float) - pos) - sensor.lever_arm
    v_s = v_b @ sensor.r_bs
    rho = np.linalg.norm(v_s, axis=1)
    u = v_s / rho[:, None]
    return ScanObservations(time, sensor.measured_range(rho), sensor.scanner.angles(u), v_s)


def regeoreference(traj: Trajectory, old: Sensor, new: Sensor, time, points_ecef) -> np.ndarray:
    """Re-georeference delivered points: inverse with ``old``, forward with ``new`` (ECEF)."""
    obs = inverse(traj, old, time, points_ecef)
    return forward(traj, new, obs.time, obs.range_m, obs.angles)


def _transformer(src, dst) -> pyproj.Transformer:
    return pyproj.Transformer.from_crs(pyproj.CRS.from_user_input(src), pyproj.CRS.from_user_input(dst), always_xy=True)


ECEF_CRS = "EPSG:4978"


def to_crs(points_ecef, crs) -> np.ndarray:
    """ECEF (N, 3) → coordinates (N, 3) in ``crs`` (x/east/lon first, heights as the CRS has them)."""
    p = np.asarray(points_ecef, float)
    x, y, z = _transformer(ECEF_CRS, crs).transform(p[:, 0], p[:, 1], p[:, 2])
    return np.stack([x, y, z], axis=-1)


def from_crs(points, crs) -> np.ndarray:
    """Coordinates (N, 3) in ``crs`` → ECEF (N, 3)."""
    p = np.asarray(points, float)
    x, y, z = _transformer(crs, ECEF_CRS).transform(p[:, 0], p[:, 1], p[:, 2])
    return np.stack([x, y, z], axis=-1)
