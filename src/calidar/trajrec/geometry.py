"""The observation equations of trajectory reconstruction, in a line's local east-north-up frame.

A point p seen from the sensor at S with attitude (roll φ, pitch θ, heading ψ; docs/conventions.md,
R_nb = Rz(ψ)·Ry(θ)·Rx(φ) about the local north-east-down axes) has the body vector
b = R_nbᵀ · v_ned(p − S). A planar scanner fires in the body's y-z plane, so

    across-track angle  atan2(b_y, b_z) = the scan-angle field (positive right of the flight)
    along-track angle   atan2(b_x, hypot(b_y, b_z)) = 0.

A multi-return pulse gives its ray (last return p_l, unit direction d towards the sensor): the
sensor lies on it, so the components of (S − p_l) normal to d, divided by the range, are zero
(Gatziolis & McGaughey 2019). Every function here is vectorised over observations.
"""

from __future__ import annotations

import numpy as np


def body_vectors(points_enu: np.ndarray, sensor_enu: np.ndarray,
                 attitude: np.ndarray) -> np.ndarray:
    """b = R_nbᵀ · v_ned for points (N, 3) seen from sensor positions (N, 3) with attitudes (N, 3)
    (roll, pitch, heading, rad)."""
    d = points_enu - sensor_enu
    v0, v1, v2 = d[:, 1], d[:, 0], -d[:, 2]  # ENU → NED
    c, s = np.cos(attitude[:, 2]), np.sin(attitude[:, 2])
    v0, v1 = c * v0 + s * v1, -s * v0 + c * v1
    c, s = np.cos(attitude[:, 1]), np.sin(attitude[:, 1])
    v0, v2 = c * v0 - s * v2, s * v0 + c * v2
    c, s = np.cos(attitude[:, 0]), np.sin(attitude[:, 0])
    v1, v2 = c * v1 + s * v2, -s * v1 + c * v2
    return np.stack([v0, v1, v2], axis=1)


def scan_residuals(points_enu, sensor_enu, attitude, scan_angle_rad, kappa: float = 0.0,
                   eps: float = 0.0) -> np.ndarray:
    """(N, 2): across-track angle − scan angle (NaN scan angle: 0), along-track angle (rad).

    ``kappa``, ``eps``: the scan plane's yaw and pitch in the body (rad): the beams lie in the y-z
    plane of the scanner frame s = Ry(ε)ᵀ·Rz(κ)ᵀ·b, while the scan-angle field is the body's
    across-track angle (leeward's scanner: κ = 13.96°, docs/conventions.md)."""
    b = body_vectors(points_enu, sensor_enu, attitude)
    across = np.arctan2(b[:, 1], b[:, 2])
    across = np.where(np.isfinite(scan_angle_rad), across - np.nan_to_num(scan_angle_rad), 0.0)
    c, s = np.cos(kappa), np.sin(kappa)
    s0, s1 = c * b[:, 0] + s * b[:, 1], -s * b[:, 0] + c * b[:, 1]
    s0, s2 = np.cos(eps) * s0 - np.sin(eps) * b[:, 2], np.sin(eps) * s0 + np.cos(eps) * b[:, 2]
    along = np.arctan2(s0, np.hypot(s1, s2))
    return np.stack([across, along], axis=1)


def ray_basis(direction: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Two unit vectors normal to each unit direction (N, 3) and to each other."""
    x_axis, y_axis = np.array([[1.0, 0.0, 0.0]]), np.array([[0.0, 1.0, 0.0]])
    ref = np.where(np.abs(direction[:, [0]]) < 0.9, x_axis, y_axis)  # the axis least along it
    u1 = np.cross(direction, ref)
    u1 /= np.linalg.norm(u1, axis=1)[:, None]
    return u1, np.cross(direction, u1)


def ray_residuals(sensor_enu, last_enu, u1, u2) -> np.ndarray:
    """(N, 2): the sensor's offset from each ray normal to it, divided by its distance (rad)."""
    w = sensor_enu - last_enu
    r = np.linalg.norm(w, axis=1)[:, None]
    return np.stack([np.einsum("ij,ij->i", w, u1), np.einsum("ij,ij->i", w, u2)], axis=1) / r


def channel_partials(fun, state: np.ndarray, step: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Residuals (N, k) of ``fun(state)`` for per-observation states (N, 6) = (E, N, U, roll, pitch,
    heading) and their partials (N, k, 6) by central differences of ``step`` (6,)."""
    r0 = fun(state)
    g = np.empty(r0.shape + (state.shape[1],))
    for c in range(state.shape[1]):
        if step[c] == 0:
            g[..., c] = 0.0
            continue
        hi, lo = state.copy(), state.copy()
        hi[:, c] += step[c]
        lo[:, c] -= step[c]
        g[..., c] = (fun(hi) - fun(lo)) / (2 * step[c])
    return r0, g
