"""Reference frames and rotations.

Conventions (docs/conventions.md):
- e: ECEF (WGS 84), metres.  n: local NED.  b: body/IMU (x forward, y right, z down).
- R_nb = Rz(heading) · Ry(pitch) · Rx(roll): rotates body vectors into NED.
- Quaternions are Hamilton, scalar first [w, x, y, z], active, unit norm.
- All angles in radians.
"""

from __future__ import annotations

import numpy as np
import pyproj

WGS84_A = 6378137.0  #: semi-major axis, m
WGS84_F = 1.0 / 298.257223563  #: flattening
WGS84_B = WGS84_A * (1.0 - WGS84_F)
WGS84_E2 = WGS84_F * (2.0 - WGS84_F)  #: first eccentricity squared
WGS84_EP2 = WGS84_E2 / (1.0 - WGS84_E2)  #: second eccentricity squared

#: Swaps NED and ENU axes (its own inverse): v_enu = R_ENU_NED @ v_ned.
R_ENU_NED = np.array([[0.0, 1.0, 0.0], [1.0, 0.0, 0.0], [0.0, 0.0, -1.0]])


def geodetic_to_ecef(lat_rad, lon_rad, h_m) -> np.ndarray:
    """Geodetic latitude, longitude (rad) and ellipsoidal height (m) → ECEF (…, 3) in m."""
    lat, lon, h = np.broadcast_arrays(*(np.asarray(v, float) for v in (lat_rad, lon_rad, h_m)))
    sl, cl = np.sin(lat), np.cos(lat)
    n = WGS84_A / np.sqrt(1.0 - WGS84_E2 * sl * sl)  # prime-vertical radius of curvature
    x = (n + h) * cl * np.cos(lon)
    y = (n + h) * cl * np.sin(lon)
    z = (n * (1.0 - WGS84_E2) + h) * sl
    return np.stack([x, y, z], axis=-1)


def ecef_to_geodetic(xyz_m) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """ECEF (…, 3) in m → (lat_rad, lon_rad, h_m); Bowring's method (< 1e-9 m near Earth)."""
    xyz = np.asarray(xyz_m, dtype=float)
    x, y, z = xyz[..., 0], xyz[..., 1], xyz[..., 2]
    lon = np.arctan2(y, x)
    p = np.hypot(x, y)
    beta = np.arctan2(z, p * (1.0 - WGS84_F))
    for _ in range(3):
        numerator = z + WGS84_EP2 * WGS84_B * np.sin(beta) ** 3
        lat = np.arctan2(numerator, p - WGS84_E2 * WGS84_A * np.cos(beta) ** 3)
        beta = np.arctan2((1.0 - WGS84_F) * np.sin(lat), np.cos(lat))
    sl = np.sin(lat)
    n = WGS84_A / np.sqrt(1.0 - WGS84_E2 * sl * sl)
    # height formula stable at all latitudes
    h = p * np.cos(lat) + z * sl - WGS84_A * WGS84_A / n
    return lat, lon, h


def rot_x(a) -> np.ndarray:
    """Rotation matrices (…, 3, 3) about x by angle a (rad), active."""
    a = np.asarray(a, dtype=float)
    c, s = np.cos(a), np.sin(a)
    o, z = np.ones_like(a), np.zeros_like(a)
    return _matrix([o, z, z], [z, c, -s], [z, s, c])


def rot_y(a) -> np.ndarray:
    """Rotation matrices (…, 3, 3) about y by angle a (rad), active."""
    a = np.asarray(a, dtype=float)
    c, s = np.cos(a), np.sin(a)
    o, z = np.ones_like(a), np.zeros_like(a)
    return _matrix([c, z, s], [z, o, z], [-s, z, c])


def rot_z(a) -> np.ndarray:
    """Rotation matrices (…, 3, 3) about z by angle a (rad), active."""
    a = np.asarray(a, dtype=float)
    c, s = np.cos(a), np.sin(a)
    o, z = np.ones_like(a), np.zeros_like(a)
    return _matrix([c, -s, z], [s, c, z], [z, z, o])


def _matrix(*rows) -> np.ndarray:
    """Matrices (…, n, m) from n rows of m arrays (…) each."""
    return np.stack([np.stack(row, -1) for row in rows], -2)


def rpy_to_matrix(roll_rad, pitch_rad, heading_rad) -> np.ndarray:
    """R = Rz(heading) · Ry(pitch) · Rx(roll), shape (…, 3, 3)."""
    return rot_z(heading_rad) @ rot_y(pitch_rad) @ rot_x(roll_rad)


def matrix_to_rpy(r) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Inverse of :func:`rpy_to_matrix`: (roll, pitch, heading) in rad, heading in (−π, π]."""
    r = np.asarray(r, dtype=float)
    roll = np.arctan2(r[..., 2, 1], r[..., 2, 2])
    pitch = -np.arcsin(np.clip(r[..., 2, 0], -1.0, 1.0))
    heading = np.arctan2(r[..., 1, 0], r[..., 0, 0])
    return roll, pitch, heading


def small_angle_matrix(roll_rad, pitch_rad, yaw_rad) -> np.ndarray:
    """First-order rotation I + [ω]× for small angles (boresight linearisation), (3, 3)."""
    return np.array([[1.0, -yaw_rad, pitch_rad],
                     [yaw_rad, 1.0, -roll_rad],
                     [-pitch_rad, roll_rad, 1.0]])


def r_en(lat_rad, lon_rad) -> np.ndarray:
    """Rotation NED → ECEF at the given geodetic latitude/longitude, shape (…, 3, 3)."""
    lat, lon = np.broadcast_arrays(np.asarray(lat_rad, float), np.asarray(lon_rad, float))
    sl, cl, so, co = np.sin(lat), np.cos(lat), np.sin(lon), np.cos(lon)
    north = np.stack([-sl * co, -sl * so, cl], -1)
    east = np.stack([-so, co, np.zeros_like(lat)], -1)
    down = np.stack([-cl * co, -cl * so, -sl], -1)
    return np.stack([north, east, down], -1)


def matrix_to_quat(r) -> np.ndarray:
    """Rotation matrices (…, 3, 3) → unit quaternions (…, 4) [w, x, y, z], w ≥ 0."""
    r = np.asarray(r, dtype=float)
    m00, m11, m22 = r[..., 0, 0], r[..., 1, 1], r[..., 2, 2]
    # Shepperd's method: d = 4w², 4x², 4y², 4z²; row k is 4·q_k·(w, x, y, z), the row of the
    # largest q_k the best conditioned
    d = [1 + m00 + m11 + m22, 1 + m00 - m11 - m22, 1 - m00 + m11 - m22, 1 - m00 - m11 + m22]
    x = r[..., 2, 1] - r[..., 1, 2]  # the antisymmetric part: 4w·(x, y, z)
    y = r[..., 0, 2] - r[..., 2, 0]
    z = r[..., 1, 0] - r[..., 0, 1]
    xy = r[..., 0, 1] + r[..., 1, 0]  # the symmetric part: 4xy, 4xz, 4yz
    xz = r[..., 0, 2] + r[..., 2, 0]
    yz = r[..., 1, 2] + r[..., 2, 1]
    cand = _matrix([d[0], x, y, z], [x, d[1], xy, xz], [y, xy, d[2], yz], [z, xz, yz, d[3]])
    diag = np.stack(d, -1)
    best = np.argmax(diag, axis=-1)
    q = np.take_along_axis(cand, best[..., None, None], axis=-2)[..., 0, :]
    q /= np.linalg.norm(q, axis=-1, keepdims=True)
    return np.where(q[..., :1] < 0, -q, q)


def quat_to_matrix(q) -> np.ndarray:
    """Unit quaternions (…, 4) [w, x, y, z] → rotation matrices (…, 3, 3)."""
    q = np.asarray(q, dtype=float)
    w, x, y, z = q[..., 0], q[..., 1], q[..., 2], q[..., 3]
    return np.stack(
        [
            np.stack([1 - 2 * (y * y + z * z), 2 * (x * y - w * z), 2 * (x * z + w * y)], -1),
            np.stack([2 * (x * y + w * z), 1 - 2 * (x * x + z * z), 2 * (y * z - w * x)], -1),
            np.stack([2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y)], -1),
        ],
        -2,
    )


def quat_multiply(a, b) -> np.ndarray:
    """Hamilton product a ⊗ b of quaternions (…, 4)."""
    a, b = np.asarray(a, float), np.asarray(b, float)
    aw, ax, ay, az = np.moveaxis(a, -1, 0)
    bw, bx, by, bz = np.moveaxis(b, -1, 0)
    return np.stack(
        [
            aw * bw - ax * bx - ay * by - az * bz,
            aw * bx + ax * bw + ay * bz - az * by,
            aw * by - ax * bz + ay * bw + az * bx,
            aw * bz + ax * by - ay * bx + az * bw,
        ],
        -1,
    )


def slerp(q0, q1, f) -> np.ndarray:
    """Spherical linear interpolation between unit quaternions q0, q1 (…, 4) at fraction f (…)."""
    q0, q1 = np.asarray(q0, float), np.asarray(q1, float)
    f = np.asarray(f, float)[..., None]
    dot = np.sum(q0 * q1, axis=-1, keepdims=True)
    q1 = np.where(dot < 0, -q1, q1)
    dot = np.abs(dot)
    theta = np.arccos(np.clip(dot, -1.0, 1.0))
    s = np.sin(theta)
    small = s < 1e-12
    w0 = np.where(small, 1.0 - f, np.sin((1.0 - f) * theta) / np.where(small, 1.0, s))
    w1 = np.where(small, f, np.sin(f * theta) / np.where(small, 1.0, s))
    q = w0 * q0 + w1 * q1
    return q / np.linalg.norm(q, axis=-1, keepdims=True)


def grid_factors(crs, lon_rad, lat_rad) -> tuple[np.ndarray, np.ndarray]:
    """Meridian convergence γ (rad, PROJ's sign) and point scale factor k of a projected CRS.

    True heading = grid heading + γ (checked numerically in the tests: at 119° W in UTM 11N
    true north points 1.24° clockwise of grid north and PROJ gives γ = −1.24°).
    Ground distance = grid distance / k.
    """
    crs = pyproj.CRS.from_user_input(crs)
    if not crs.is_projected:
        raise ValueError(f"grid factors need a projected CRS, got {crs.name}")
    f = pyproj.Proj(crs).get_factors(np.degrees(lon_rad), np.degrees(lat_rad), errcheck=True)
    return np.radians(np.asarray(f.meridian_convergence)), np.asarray(f.meridional_scale)
