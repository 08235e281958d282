"""Direct (forward) and inverse georeferencing — the lidar equation.

    p_e = r_e(t) + R_eb(t) · (R_bs · ρ · u_s(angles) + a_b)

with r_e the IMU position in ECEF, R_eb = R_en(φ, λ) · R_nb(roll, pitch, heading)
interpolated by quaternion SLERP, R_bs the boresight, a_b the lever arm, ρ the corrected
range and u_s the scanner's unit beam vector. Inverse georeferencing solves the same
equation for ρ · u_s given p_e and t. Everything is in ECEF metres; :func:`to_crs` and
:func:`from_crs` convert at the edges.

Speed: one fused numba loop per call (interval search, SLERP, quaternion → matrix, the
lidar equation; the linear scanner and range model inlined), > 10 million points/s on one
core (benchmarks/georef.py). tests/test_georef_fast.py checks it against a plain numpy
evaluation of the same equations to 1e-9 m.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numba import njit

# georef's face: the CRS transforms callers reach through it
from calidar.crs import ECEF_CRS, TileLinear, from_crs, tile_linear, to_crs  # noqa: F401
from calidar.scanners.linear import LinearScanner
from calidar.sensor import Sensor
from calidar.trajectory import Trajectory


@dataclass(frozen=True)
class ScanObservations:
    """What the instrument observed for each point (result of inverse georeferencing)."""

    time: np.ndarray  #: GPS s (N,)
    range_m: np.ndarray  #: measured range, m (N,)
    angles: np.ndarray  #: scanner observations, rad (N, k)
    #: true range × unit beam in the scanner frame, m (N, 3); None when not kept (a
    #: :class:`calidar.strips.strip.Strip`'s: ranges and angles are what it re-georeferences)
    vector_s: np.ndarray | None


@njit(cache=True, nogil=True)
def _interval(tt, t, i):
    """Index i of the trajectory interval [tt[i], tt[i+1]] holding t: ``i`` itself when it still
    fits (monotone scan), else a binary search; as np.searchsorted(tt, t, "right") − 1, clipped."""
    n = tt.size
    if tt[i] <= t < tt[i + 1]:
        return i
    lo, hi = 0, n
    while lo < hi:
        mid = (lo + hi) >> 1
        if tt[mid] > t:
            hi = mid
        else:
            lo = mid + 1
    return min(max(lo - 1, 0), n - 2)


@njit(cache=True, nogil=True, inline="always")
def pose(tt, pos, q, tk, i, i_prev, theta, s, sign):
    """Position (linear) and attitude matrix (SLERP, as :func:`calidar.frames.slerp`) at time tk.

    (i_prev, theta, s = 1/sin θ, sign) cache the SLERP angle of the last interval: recomputed only
    when the interval changes (cheap for time-sorted points). Returns the updated cache, then
    px, py, pz and the nine entries of R_eb row by row.
    """
    i = _interval(tt, tk, i)
    if i != i_prev:
        a, b = q[i], q[i + 1]
        dot = a[0] * b[0] + a[1] * b[1] + a[2] * b[2] + a[3] * b[3]
        sign = -1.0 if dot < 0.0 else 1.0
        theta = np.arccos(min(abs(dot), 1.0))
        s = np.sin(theta)
        s = 1.0 / s if s >= 1e-12 else 0.0  # cached as 1/sin θ (0: linear weights)
        i_prev = i
    f = (tk - tt[i]) / (tt[i + 1] - tt[i])
    if s == 0.0:
        w0, w1 = 1.0 - f, f
    else:
        w0, w1 = np.sin((1.0 - f) * theta) * s, np.sin(f * theta) * s
    w1 *= sign
    qw = w0 * q[i, 0] + w1 * q[i + 1, 0]
    qx = w0 * q[i, 1] + w1 * q[i + 1, 1]
    qy = w0 * q[i, 2] + w1 * q[i + 1, 2]
    qz = w0 * q[i, 3] + w1 * q[i + 1, 3]
    nrm = 1.0 / np.sqrt(qw * qw + qx * qx + qy * qy + qz * qz)
    qw, qx, qy, qz = qw * nrm, qx * nrm, qy * nrm, qz * nrm
    return (
        i, i_prev, theta, s, sign,
        pos[i, 0] + f * (pos[i + 1, 0] - pos[i, 0]),
        pos[i, 1] + f * (pos[i + 1, 1] - pos[i, 1]),
        pos[i, 2] + f * (pos[i + 1, 2] - pos[i, 2]),
        1 - 2 * (qy * qy + qz * qz), 2 * (qx * qy - qw * qz), 2 * (qx * qz + qw * qy),
        2 * (qx * qy + qw * qz), 1 - 2 * (qx * qx + qz * qz), 2 * (qy * qz - qw * qx),
        2 * (qx * qz - qw * qy), 2 * (qy * qz + qw * qx), 1 - 2 * (qx * qx + qy * qy),
    )


@njit(cache=True, nogil=True, inline="always")
def _lidar_equation(sx, sy, sz, r_bs, lever, px, py, pz,
                    r00, r01, r02, r10, r11, r12, r20, r21, r22, out, k):
    """out[k] = :func:`lidar_point` of the scanner-frame vector (sx, sy, sz) m."""
    out[k, 0], out[k, 1], out[k, 2] = lidar_point(sx, sy, sz, r_bs, lever, px, py, pz,
                                                  r00, r01, r02, r10, r11, r12, r20, r21, r22)


@njit(cache=True, nogil=True)
def lidar_point(sx, sy, sz, r_bs, lever, px, py, pz, r00, r01, r02, r10, r11, r12, r20, r21, r22):
    """r + R_eb·(R_bs·v_s + a): the scanner-frame vector (sx, sy, sz) m at the pose (px, py, pz
    m ECEF; R_eb row by row) of :func:`pose`, into ECEF (m) — the lidar equation."""
    bx = r_bs[0, 0] * sx + r_bs[0, 1] * sy + r_bs[0, 2] * sz + lever[0]
    by = r_bs[1, 0] * sx + r_bs[1, 1] * sy + r_bs[1, 2] * sz + lever[1]
    bz = r_bs[2, 0] * sx + r_bs[2, 1] * sy + r_bs[2, 2] * sz + lever[2]
    return px + r00 * bx + r01 * by + r02 * bz, py + r10 * bx + r11 * by + r12 * bz, \
        pz + r20 * bx + r21 * by + r22 * bz


@njit(cache=True, nogil=True)
def scanner_vector(x, y, z, px, py, pz, r00, r01, r02, r10, r11, r12, r20, r21, r22, r_bs, lever):
    """v_s = R_bsᵀ·(R_ebᵀ·(p − r) − a): the ECEF point (x, y, z) m seen from the pose (px, py,
    pz; R_eb row by row) of :func:`pose`, in the scanner frame (m) — the lidar equation
    inverted."""
    dx, dy, dz = x - px, y - py, z - pz
    bx = r00 * dx + r10 * dy + r20 * dz - lever[0]
    by = r01 * dx + r11 * dy + r21 * dz - lever[1]
    bz = r02 * dx + r12 * dy + r22 * dz - lever[2]
    return (r_bs[0, 0] * bx + r_bs[1, 0] * by + r_bs[2, 0] * bz,
            r_bs[0, 1] * bx + r_bs[1, 1] * by + r_bs[2, 1] * bz,
            r_bs[0, 2] * bx + r_bs[1, 2] * by + r_bs[2, 2] * bz)


@njit(cache=True, nogil=True)
def _forward_kernel(tt, pos, q, t, vec, r_bs, lever, out):
    """p = r(t) + R_eb(t)·(R_bs·v_s + a) for scanner-frame vectors vec (N, 3) → out (N, 3).
    Returns how many times lie outside tt."""
    n_out, i, i_prev, theta, s, sign = 0, 0, -1, 0.0, 0.0, 1.0
    for k in range(t.size):
        tk = t[k]
        n_out += not tt[0] <= tk <= tt[tt.size - 1]  # NaN counts as outside
        i, i_prev, theta, s, sign, px, py, pz, r00, r01, r02, r10, r11, r12, r20, r21, r22 = pose(
            tt, pos, q, tk, i, i_prev, theta, s, sign)
        sx, sy, sz = vec[k, 0], vec[k, 1], vec[k, 2]
        _lidar_equation(sx, sy, sz, r_bs, lever, px, py, pz,
                        r00, r01, r02, r10, r11, r12, r20, r21, r22, out, k)
    return n_out


@njit(cache=True, nogil=True)
def _forward_linear_kernel(tt, pos, q, t, range_m, theta_enc, phi, has_phi,
                           range_offset, range_scale, angle_offset, angle_scale, r_bs, lever, out):
    """:func:`_forward_kernel` fused with the range model and the linear scanner
    (:class:`calidar.scanners.linear.LinearScanner`); φ = 0 unless ``has_phi``."""
    n_out, i, i_prev, theta, s, sign = 0, 0, -1, 0.0, 0.0, 1.0
    for k in range(t.size):
        tk = t[k]
        n_out += not tt[0] <= tk <= tt[tt.size - 1]  # NaN counts as outside
        i, i_prev, theta, s, sign, px, py, pz, r00, r01, r02, r10, r11, r12, r20, r21, r22 = pose(
            tt, pos, q, tk, i, i_prev, theta, s, sign)
        rho = (range_m[k] - range_offset) / (1.0 + range_scale)
        th = (1.0 + angle_scale) * theta_enc[k] + angle_offset
        if has_phi:
            cphi = np.cos(phi[k])
            sx, sy, sz = rho * np.sin(phi[k]), rho * (cphi * np.sin(th)), rho * (cphi * np.cos(th))
        else:
            sx, sy, sz = 0.0, rho * np.sin(th), rho * np.cos(th)
        _lidar_equation(sx, sy, sz, r_bs, lever, px, py, pz,
                        r00, r01, r02, r10, r11, r12, r20, r21, r22, out, k)
    return n_out


@njit(cache=True, nogil=True)
def _inverse_kernel(tt, pos, q, t, p, r_bs, lever, out):
    """v_s = R_bsᵀ·(R_eb(t)ᵀ·(p − r(t)) − a) for ECEF points p (N, 3) → out (N, 3).
    Returns how many times lie outside tt."""
    n_out, i, i_prev, theta, s, sign = 0, 0, -1, 0.0, 0.0, 1.0
    for k in range(t.size):
        tk = t[k]
        n_out += not tt[0] <= tk <= tt[tt.size - 1]  # NaN counts as outside
        i, i_prev, theta, s, sign, px, py, pz, r00, r01, r02, r10, r11, r12, r20, r21, r22 = pose(
            tt, pos, q, tk, i, i_prev, theta, s, sign)
        out[k, 0], out[k, 1], out[k, 2] = scanner_vector(
            p[k, 0], p[k, 1], p[k, 2], px, py, pz,
            r00, r01, r02, r10, r11, r12, r20, r21, r22, r_bs, lever)
    return n_out


@njit(cache=True, nogil=True)
def _poses_kernel(tt, pos, q, t, pos_out, r_out):
    """r(t) → pos_out (N, 3) and R_eb(t) → r_out (N, 3, 3). Returns how many times lie outside
    tt."""
    n_out, i, i_prev, theta, s, sign = 0, 0, -1, 0.0, 0.0, 1.0
    for k in range(t.size):
        tk = t[k]
        n_out += not tt[0] <= tk <= tt[tt.size - 1]  # NaN counts as outside
        i, i_prev, theta, s, sign, px, py, pz, r00, r01, r02, r10, r11, r12, r20, r21, r22 = pose(
            tt, pos, q, tk, i, i_prev, theta, s, sign)
        pos_out[k, 0], pos_out[k, 1], pos_out[k, 2] = px, py, pz
        r_out[k, 0, 0], r_out[k, 0, 1], r_out[k, 0, 2] = r00, r01, r02
        r_out[k, 1, 0], r_out[k, 1, 1], r_out[k, 1, 2] = r10, r11, r12
        r_out[k, 2, 0], r_out[k, 2, 1], r_out[k, 2, 2] = r20, r21, r22
    return n_out


def poses(traj: Trajectory, time) -> tuple[np.ndarray, np.ndarray]:
    """IMU positions (N, 3) ECEF m and rotations body → ECEF (N, 3, 3) at GPS times (N,) s
    (as :meth:`Trajectory.interpolate` + :func:`calidar.frames.quat_to_matrix`, one fused loop)."""
    t = _c(time)
    pos, r_eb = np.empty((t.size, 3)), np.empty((t.size, 3, 3))
    if _poses_kernel(traj.time, _c(traj.ecef), _c(traj.q_eb), t, pos, r_eb):
        traj.check_covers(t)
    return pos, r_eb


def beams(position, rotation, sensor: Sensor, angles) -> tuple[np.ndarray, np.ndarray]:
    """Where each beam starts and where it points: origin r + R·a_b and unit direction
    R·R_bs·u_s(angles), (N, 3) each, for IMU positions (N, 3) and rotations body → frame (N, 3, 3)
    in any frame (ECEF, local ENU). The lidar equation is p = origin + ρ · direction
    (:func:`lidar_points`); the simulator casts these rays."""
    rotation = np.asarray(rotation, float)
    origin = np.asarray(position, float) + rotation @ sensor.lever_arm
    direction = np.einsum("nij,nj->ni", rotation, sensor.scanner.directions(angles) @ sensor.r_bs.T)
    return origin, direction


def lidar_points(position, rotation, sensor: Sensor, range_m, angles) -> np.ndarray:
    """The lidar equation for given poses, in numpy: p = r + R·(R_bs·ρ·u_s + a_b) with
    ρ = sensor.true_range(range_m) (docs/conventions.md; the numba kernels above fuse the same
    equation with the trajectory's interpolation). position (N, 3) and rotation body → frame
    (N, 3, 3) in any frame; returns (N, 3) in that frame."""
    vec = sensor.true_range(range_m)[:, None] * sensor.scanner.directions(angles)
    out = np.empty(vec.shape)
    _posed_kernel(_c(position), _c(rotation), _c(vec), _c(sensor.r_bs), _c(sensor.lever_arm), out)
    return out


@njit(cache=True, nogil=True)
def _posed_kernel(position, rotation, vec, r_bs, lever, out):  # pragma: no cover - numba
    """:func:`_lidar_equation` at given poses: position (N, 3), rotation (N, 3, 3), scanner-frame
    vectors (N, 3)."""
    for k in range(vec.shape[0]):
        r, p, v = rotation[k], position[k], vec[k]
        _lidar_equation(v[0], v[1], v[2], r_bs, lever, p[0], p[1], p[2],
                        r[0, 0], r[0, 1], r[0, 2],
                        r[1, 0], r[1, 1], r[1, 2],
                        r[2, 0], r[2, 1], r[2, 2], out, k)


def _c(a) -> np.ndarray:
    return np.ascontiguousarray(a, dtype=float)


def _run(kernel, traj: Trajectory, sensor: Sensor, time, *args) -> np.ndarray:
    """Call a kernel with the trajectory and mounting; a clear error for times outside the
    trajectory."""
    t = _c(time)
    out = np.empty((t.size, 3))
    for a in args:
        if isinstance(a, np.ndarray) and a.shape[0] != t.size:
            raise ValueError(f"expected {t.size} rows to match the times, "
                             f"got an array of shape {a.shape}")
    trajectory = (traj.time, _c(traj.ecef), _c(traj.q_eb))
    if kernel(*trajectory, t, *args, _c(sensor.r_bs), _c(sensor.lever_arm), out):
        traj.check_covers(t)
    return out


def forward_vectors(traj: Trajectory, sensor: Sensor, time, vector_s) -> np.ndarray:
    """Points (N, 3) ECEF from scanner-frame vectors (N, 3) m at GPS times (N,)."""
    return _run(_forward_kernel, traj, sensor, time, _c(vector_s).reshape(-1, 3))


def forward(traj: Trajectory, sensor: Sensor, time, range_m, angles) -> np.ndarray:
    """Points (N, 3) ECEF from GPS times, measured ranges (m) and scanner angles (rad) — the
    lidar equation of docs/conventions.md (``calidar.georeference``).

    >>> import numpy as np, calidar
    >>> t = np.array([0.0, 1.0])  # level flight due north at 500 m
    >>> lat, lon, level = np.radians([47.0, 47.0001]), np.radians([8.0, 8.0]), [0.0, 0.0]
    >>> traj = calidar.Trajectory(time=t, lat=lat, lon=lon, height=[500.0, 500.0],
    ...                           roll=level, pitch=level, heading=level)
    >>> sensor = calidar.Sensor()  # no mounting errors, linear scanner
    >>> p = calidar.georeference(traj, sensor, [0.5], [100.0], [0.0])  # 100 m nadir at t = 0.5 s
    >>> lat, lon, h = calidar.frames.ecef_to_geodetic(p)
    >>> round(float(h[0]), 4), round(float(np.degrees(lat[0])), 6)  # 100 m below the IMU
    (400.0, 47.00005)
    """
    sc = sensor.scanner
    if type(sc) is LinearScanner:  # exactly: a subclass may change the beam model
        a = np.asarray(angles, dtype=float)
        theta, phi = (a, a) if a.ndim == 1 else (a[:, 0], a[:, 1])
        return _run(_forward_linear_kernel, traj, sensor, time, _c(range_m), _c(theta), _c(phi),
                    a.ndim == 2, *_linear_model(sensor))
    rho = sensor.true_range(range_m)
    return forward_vectors(traj, sensor, time, rho[:, None] * sc.directions(angles))


@njit(cache=True, nogil=True)
def _linear_observations(v_s, range_offset, range_scale, angle_offset, angle_scale,
                         range_m, angles):
    """Measured ranges and linear-scanner angles [θ, φ] of scanner vectors (N, 3), as
    :meth:`calidar.scanners.linear.LinearScanner.angles` and :meth:`Sensor.measured_range`."""
    for k in range(v_s.shape[0]):
        x, y, z = v_s[k, 0], v_s[k, 1], v_s[k, 2]
        range_m[k] = (1.0 + range_scale) * np.sqrt(x * x + y * y + z * z) + range_offset
        angles[k, 0] = (np.arctan2(y, z) - angle_offset) / (1.0 + angle_scale)
        angles[k, 1] = np.arctan2(x, np.hypot(y, z))


def inverse(traj: Trajectory, sensor: Sensor, time, points_ecef) -> ScanObservations:
    """Scanner-frame vectors, measured ranges and scanner angles of points (N, 3) ECEF
    (``calidar.inverse_georeference``: the inverse of :func:`forward`).

    >>> import numpy as np, calidar
    >>> t = np.array([0.0, 1.0])
    >>> lat, lon, level = np.radians([47.0, 47.0001]), np.radians([8.0, 8.0]), [0.0, 0.0]
    >>> traj = calidar.Trajectory(time=t, lat=lat, lon=lon, height=[500.0, 500.0],
    ...                           roll=level, pitch=level, heading=level)
    >>> sensor = calidar.Sensor(boresight_roll=np.radians(0.01), lever_arm_z=0.2)
    >>> p = calidar.georeference(traj, sensor, [0.5, 0.7], [100.0, 120.0], [0.0, np.radians(10.0)])
    >>> obs = calidar.inverse_georeference(traj, sensor, [0.5, 0.7], p)
    >>> theta_deg = np.round(np.degrees(obs.angles[:, 0]), 9) + 0.0
    >>> np.round(obs.range_m, 9).tolist(), theta_deg.tolist()
    ([100.0, 120.0], [0.0, 10.0])
    """
    time = np.asarray(time, float)
    return observations(sensor, time, scanner_vectors(traj, sensor, time, points_ecef))


def scanner_vectors(traj: Trajectory, sensor: Sensor, time, points_ecef) -> np.ndarray:
    """The scanner-frame vectors (N, 3) m of points (N, 3) ECEF: :func:`inverse` without its
    ranges and angles."""
    points = _c(points_ecef).reshape(-1, 3)
    return _run(_inverse_kernel, traj, sensor, np.asarray(time, float), points)


def observations(sensor: Sensor, time, v_s: np.ndarray) -> ScanObservations:
    """What ``sensor`` measured for scanner-frame vectors v_s (N, 3) m: ranges and angles."""
    time, sc = np.asarray(time, float), sensor.scanner
    if type(sc) is LinearScanner:
        range_m, angles = np.empty(time.size), np.empty((time.size, 2))
        _linear_observations(v_s, *_linear_model(sensor), range_m, angles)
        return ScanObservations(time, range_m, angles, v_s)
    rho = np.linalg.norm(v_s, axis=1)
    return ScanObservations(time, sensor.measured_range(rho), sc.angles(v_s / rho[:, None]), v_s)


def _linear_model(sensor: Sensor) -> tuple[float, float, float, float]:
    """The range offset (m) and scale, the linear scanner's angle offset (rad) and scale, as the
    fused kernels take them."""
    sc = sensor.scanner
    return (float(sensor.range_offset), float(sensor.range_scale), float(sc.scan_angle_offset),
            float(sc.scan_angle_scale))


def regeoreference(traj: Trajectory, old: Sensor, new: Sensor, time, points_ecef,
                   new_traj: Trajectory | None = None) -> np.ndarray:
    """Re-georeference delivered points: inverse with ``traj`` and ``old``, forward with
    ``new_traj`` (default: the same trajectory, e.g. a corrected one) and ``new`` (ECEF)."""
    v_s = scanner_vectors(traj, old, time, points_ecef)
    return reforward(old, new, traj if new_traj is None else new_traj, time, v_s)


def reforward(old: Sensor, new: Sensor, traj: Trajectory, time, v_s: np.ndarray) -> np.ndarray:
    """Points (N, 3) ECEF by :func:`forward` with ``traj`` and ``new`` of what ``old`` measured as
    the scanner-frame vectors v_s (N, 3) m (:func:`scanner_vectors`): the same vectors when the
    range model and the scanner are the same (a new mounting only), else through the ranges and
    angles ``old`` measured."""
    def model(s: Sensor):
        return s.range_offset, s.range_scale, s.scanner

    if model(new) == model(old):
        return forward_vectors(traj, new, time, v_s)
    obs = observations(old, time, v_s)
    return forward(traj, new, obs.time, obs.range_m, obs.angles)
