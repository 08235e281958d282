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

import warnings
from dataclasses import dataclass
from functools import lru_cache

import numpy as np
import pyproj
from numba import njit

from calidar.errors import InputError
from calidar.scanners.linear import LinearScanner
from calidar.sensor import Sensor
from calidar.trajectory import Trajectory


@dataclass(frozen=True)
class ScanObservations:
    """What the instrument observed for each point (result of inverse georeferencing)."""

    time: np.ndarray  #: GPS s (N,)
    range_m: np.ndarray  #: measured range, m (N,)
    angles: np.ndarray  #: scanner observations, rad (N, k)
    vector_s: np.ndarray  #: true range × unit beam in the scanner frame, m (N, 3)


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
def _pose(tt, pos, q, tk, i, i_prev, theta, s, sign):
    """Position (linear) and attitude matrix (SLERP, as :func:`calidar.frames.slerp`) at time tk.

    (i_prev, theta, s = 1/sin θ, sign) cache the SLERP angle of the last interval: recomputed only when
    the interval changes (cheap for time-sorted points). Returns the updated cache, then
    px, py, pz and the nine entries of R_eb row by row.
    """
    i = _interval(tt, tk, i)
    if i != i_prev:
        dot = q[i, 0] * q[i + 1, 0] + q[i, 1] * q[i + 1, 1] + q[i, 2] * q[i + 1, 2] + q[i, 3] * q[i + 1, 3]
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


@njit(cache=True, nogil=True)
def _forward_kernel(tt, pos, q, t, vec, r_bs, lever, out):
    """p = r(t) + R_eb(t)·(R_bs·v_s + a) for scanner-frame vectors vec (N, 3) → out (N, 3).
    Returns how many times lie outside tt."""
    n_out, i, i_prev, theta, s, sign = 0, 0, -1, 0.0, 0.0, 1.0
    for k in range(t.size):
        tk = t[k]
        n_out += not tt[0] <= tk <= tt[tt.size - 1]  # NaN counts as outside
        i, i_prev, theta, s, sign, px, py, pz, r00, r01, r02, r10, r11, r12, r20, r21, r22 = _pose(
            tt, pos, q, tk, i, i_prev, theta, s, sign)
        sx, sy, sz = vec[k, 0], vec[k, 1], vec[k, 2]
        bx = r_bs[0, 0] * sx + r_bs[0, 1] * sy + r_bs[0, 2] * sz + lever[0]
        by = r_bs[1, 0] * sx + r_bs[1, 1] * sy + r_bs[1, 2] * sz + lever[1]
        bz = r_bs[2, 0] * sx + r_bs[2, 1] * sy + r_bs[2, 2] * sz + lever[2]
        out[k, 0] = px + r00 * bx + r01 * by + r02 * bz
        out[k, 1] = py + r10 * bx + r11 * by + r12 * bz
        out[k, 2] = pz + r20 * bx + r21 * by + r22 * bz
    return n_out


@njit(cache=True, nogil=True)
def _forward_linear_kernel(tt, pos, q, t, range_m, theta_enc, phi, has_phi, range_offset, range_scale, angle_offset,
                           angle_scale, r_bs, lever, out):
    """:func:`_forward_kernel` fused with the range model and the linear scanner
    (:class:`calidar.scanners.linear.LinearScanner`); φ = 0 unless ``has_phi``."""
    n_out, i, i_prev, theta, s, sign = 0, 0, -1, 0.0, 0.0, 1.0
    for k in range(t.size):
        tk = t[k]
        n_out += not tt[0] <= tk <= tt[tt.size - 1]  # NaN counts as outside
        i, i_prev, theta, s, sign, px, py, pz, r00, r01, r02, r10, r11, r12, r20, r21, r22 = _pose(
            tt, pos, q, tk, i, i_prev, theta, s, sign)
        rho = (range_m[k] - range_offset) / (1.0 + range_scale)
        th = (1.0 + angle_scale) * theta_enc[k] + angle_offset
        if has_phi:
            cphi = np.cos(phi[k])
            sx, sy, sz = rho * np.sin(phi[k]), rho * (cphi * np.sin(th)), rho * (cphi * np.cos(th))
        else:
            sx, sy, sz = 0.0, rho * np.sin(th), rho * np.cos(th)
        bx = r_bs[0, 0] * sx + r_bs[0, 1] * sy + r_bs[0, 2] * sz + lever[0]
        by = r_bs[1, 0] * sx + r_bs[1, 1] * sy + r_bs[1, 2] * sz + lever[1]
        bz = r_bs[2, 0] * sx + r_bs[2, 1] * sy + r_bs[2, 2] * sz + lever[2]
        out[k, 0] = px + r00 * bx + r01 * by + r02 * bz
        out[k, 1] = py + r10 * bx + r11 * by + r12 * bz
        out[k, 2] = pz + r20 * bx + r21 * by + r22 * bz
    return n_out


@njit(cache=True, nogil=True)
def _inverse_kernel(tt, pos, q, t, p, r_bs, lever, out):
    """v_s = R_bsᵀ·(R_eb(t)ᵀ·(p − r(t)) − a) for ECEF points p (N, 3) → out (N, 3).
    Returns how many times lie outside tt."""
    n_out, i, i_prev, theta, s, sign = 0, 0, -1, 0.0, 0.0, 1.0
    for k in range(t.size):
        tk = t[k]
        n_out += not tt[0] <= tk <= tt[tt.size - 1]  # NaN counts as outside
        i, i_prev, theta, s, sign, px, py, pz, r00, r01, r02, r10, r11, r12, r20, r21, r22 = _pose(
            tt, pos, q, tk, i, i_prev, theta, s, sign)
        dx, dy, dz = p[k, 0] - px, p[k, 1] - py, p[k, 2] - pz
        bx = r00 * dx + r10 * dy + r20 * dz - lever[0]
        by = r01 * dx + r11 * dy + r21 * dz - lever[1]
        bz = r02 * dx + r12 * dy + r22 * dz - lever[2]
        out[k, 0] = r_bs[0, 0] * bx + r_bs[1, 0] * by + r_bs[2, 0] * bz
        out[k, 1] = r_bs[0, 1] * bx + r_bs[1, 1] * by + r_bs[2, 1] * bz
        out[k, 2] = r_bs[0, 2] * bx + r_bs[1, 2] * by + r_bs[2, 2] * bz
    return n_out


@njit(cache=True, nogil=True)
def _poses_kernel(tt, pos, q, t, pos_out, r_out):
    """r(t) → pos_out (N, 3) and R_eb(t) → r_out (N, 3, 3). Returns how many times lie outside tt."""
    n_out, i, i_prev, theta, s, sign = 0, 0, -1, 0.0, 0.0, 1.0
    for k in range(t.size):
        tk = t[k]
        n_out += not tt[0] <= tk <= tt[tt.size - 1]  # NaN counts as outside
        i, i_prev, theta, s, sign, px, py, pz, r00, r01, r02, r10, r11, r12, r20, r21, r22 = _pose(
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
    origin, direction = beams(position, rotation, sensor, angles)
    return origin + sensor.true_range(range_m)[:, None] * direction


def _c(a) -> np.ndarray:
    return np.ascontiguousarray(a, dtype=float)


def _run(kernel, traj: Trajectory, sensor: Sensor, time, *args) -> np.ndarray:
    """Call a kernel with the trajectory and mounting; a clear error for times outside the trajectory."""
    t = _c(time)
    out = np.empty((t.size, 3))
    for a in args:
        if isinstance(a, np.ndarray) and a.shape[0] != t.size:
            raise ValueError(f"expected {t.size} rows to match the times, got an array of shape {a.shape}")
    if kernel(traj.time, _c(traj.ecef), _c(traj.q_eb), t, *args, _c(sensor.r_bs), _c(sensor.lever_arm), out):
        traj.check_covers(t)
    return out


def forward_vectors(traj: Trajectory, sensor: Sensor, time, vector_s) -> np.ndarray:
    """Points (N, 3) ECEF from scanner-frame vectors (N, 3) m at GPS times (N,)."""
    return _run(_forward_kernel, traj, sensor, time, _c(vector_s).reshape(-1, 3))


def forward(traj: Trajectory, sensor: Sensor, time, range_m, angles) -> np.ndarray:
    """Points (N, 3) ECEF from GPS times, measured ranges (m) and scanner angles (rad)."""
    sc = sensor.scanner
    if type(sc) is LinearScanner:  # exactly: a subclass may change the beam model
        a = np.asarray(angles, dtype=float)
        theta, phi = (a, a) if a.ndim == 1 else (a[:, 0], a[:, 1])
        return _run(_forward_linear_kernel, traj, sensor, time, _c(range_m), _c(theta), _c(phi), a.ndim == 2,
                    float(sensor.range_offset), float(sensor.range_scale), float(sc.scan_angle_offset),
                    float(sc.scan_angle_scale))
    rho = sensor.true_range(range_m)
    return forward_vectors(traj, sensor, time, rho[:, None] * sc.directions(angles))


@njit(cache=True, nogil=True)
def _linear_observations(v_s, range_offset, range_scale, angle_offset, angle_scale, range_m, angles):
    """Measured ranges and linear-scanner angles [θ, φ] of scanner vectors (N, 3), as
    :meth:`calidar.scanners.linear.LinearScanner.angles` and :meth:`Sensor.measured_range`."""
    for k in range(v_s.shape[0]):
        x, y, z = v_s[k, 0], v_s[k, 1], v_s[k, 2]
        range_m[k] = (1.0 + range_scale) * np.sqrt(x * x + y * y + z * z) + range_offset
        angles[k, 0] = (np.arctan2(y, z) - angle_offset) / (1.0 + angle_scale)
        angles[k, 1] = np.arctan2(x, np.hypot(y, z))


def inverse(traj: Trajectory, sensor: Sensor, time, points_ecef) -> ScanObservations:
    """Scanner-frame vectors, measured ranges and scanner angles of points (N, 3) ECEF."""
    time = np.asarray(time, float)
    v_s = _run(_inverse_kernel, traj, sensor, time, _c(points_ecef).reshape(-1, 3))
    sc = sensor.scanner
    if type(sc) is LinearScanner:
        range_m, angles = np.empty(time.size), np.empty((time.size, 2))
        _linear_observations(v_s, float(sensor.range_offset), float(sensor.range_scale), float(sc.scan_angle_offset),
                             float(sc.scan_angle_scale), range_m, angles)
        return ScanObservations(time, range_m, angles, v_s)
    rho = np.linalg.norm(v_s, axis=1)
    return ScanObservations(time, sensor.measured_range(rho), sc.angles(v_s / rho[:, None]), v_s)


def regeoreference(traj: Trajectory, old: Sensor, new: Sensor, time, points_ecef,
                   new_traj: Trajectory | None = None) -> np.ndarray:
    """Re-georeference delivered points: inverse with ``traj`` and ``old``, forward with
    ``new_traj`` (default: the same trajectory, e.g. a corrected one) and ``new`` (ECEF)."""
    obs = inverse(traj, old, time, points_ecef)
    return forward(traj if new_traj is None else new_traj, new, obs.time, obs.range_m, obs.angles)


ECEF_CRS = "EPSG:4978"


@lru_cache(maxsize=64)
def _cached_transformer(src: pyproj.CRS, dst: pyproj.CRS) -> pyproj.Transformer:
    with warnings.catch_warnings():  # "best transformation is not available": checked by _transformer
        warnings.simplefilter("ignore", UserWarning)
        return pyproj.Transformer.from_crs(src, dst, always_xy=True)


def _missing_grids(src: pyproj.CRS, dst: pyproj.CRS) -> list[str]:
    """Names (and download addresses) of the PROJ grids the best transformation needs and lacks."""
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", UserWarning)
        group = pyproj.transformer.TransformerGroup(src, dst, always_xy=True)
    names = []
    for op in group.unavailable_operations:
        for g in op.grids:
            if not g.available and g.short_name and g.short_name not in [n.split(" ")[0] for n in names]:
                names.append(f"{g.short_name} ({g.url})" if g.url else g.short_name)
    return names


def _transformer(src, dst, source=None) -> pyproj.Transformer:
    """A transformation between two CRSs, cached; a clear error (naming the missing grid) instead of
    PROJ's "ballpark" vertical fallback, which would take heights above a geoid as ellipsoidal."""
    try:
        src, dst = pyproj.CRS.from_user_input(src), pyproj.CRS.from_user_input(dst)
    except (pyproj.exceptions.CRSError, TypeError) as e:
        raise InputError(source, "crs", f"expected a CRS pyproj knows (e.g. EPSG:32611): {e}") from None
    t = _cached_transformer(src, dst)
    if "ballpark vertical" in t.description.lower():
        geoid = src if src.is_compound or src.is_vertical else dst
        grids = _missing_grids(src, dst)
        raise InputError(source, "crs", f"{geoid.name} has heights above a geoid and PROJ lacks its grid "
                         f"({', '.join(grids[:2]) or 'no grid known'}); install it (projsync --file NAME, or "
                         "PROJ_NETWORK=ON), give --geoid-undulation N (m, constant: a small area) or an ellipsoidal "
                         "--crs (docs/conventions.md, Heights)")
    return t


def _horizontal(crs, source, undulation_m) -> pyproj.CRS:
    """The horizontal part of a compound CRS with a geoid (heights then taken as ellipsoidal after
    adding ``undulation_m``); an error for a CRS without geoid heights."""
    crs = pyproj.CRS.from_user_input(crs)
    if not crs.is_compound:
        raise InputError(source, "--geoid-undulation", f"given ({undulation_m} m) but {crs.name} has ellipsoidal "
                         "heights; expected a compound CRS with a geoid (e.g. EPSG:32632+3855)")
    return crs.sub_crs_list[0]


def to_crs(points_ecef, crs, geoid_undulation_m: float | None = None, source=None) -> np.ndarray:
    """ECEF (N, 3) → coordinates (N, 3) in ``crs`` (x/east/lon first, heights as the CRS has them).

    ``geoid_undulation_m`` N: heights above the geoid of a compound ``crs`` as ellipsoidal − N
    (a constant for a small area, instead of the geoid grid)."""
    p = np.asarray(points_ecef, float)
    if geoid_undulation_m is None:
        x, y, z = _transformer(ECEF_CRS, crs, source).transform(p[:, 0], p[:, 1], p[:, 2])
        return np.stack([x, y, z], axis=-1)
    out = to_crs(p, _horizontal(crs, source, geoid_undulation_m), None, source)
    out[:, 2] -= geoid_undulation_m
    return out


def from_crs(points, crs, geoid_undulation_m: float | None = None, source=None) -> np.ndarray:
    """Coordinates (N, 3) in ``crs`` → ECEF (N, 3); ``geoid_undulation_m`` as in :func:`to_crs`;
    ``source`` (a file) names where the points came from in errors."""
    p = np.asarray(points, float)
    if geoid_undulation_m is not None:
        p = p.copy()
        p[:, 2] += geoid_undulation_m
        crs = _horizontal(crs, source, geoid_undulation_m)
    x, y, z = _transformer(crs, ECEF_CRS, source).transform(p[:, 0], p[:, 1], p[:, 2])
    return np.stack([x, y, z], axis=-1)


def to_crs_moved(points_ecef, base_ecef, base_xyz, crs, geoid_undulation_m: float | None = None, source=None,
                 tile_m: float = 50.0) -> np.ndarray:
    """:func:`to_crs` of points moved by metres from ``base_ecef`` (N, 3), whose coordinates in
    ``crs`` are ``base_xyz`` (N, 3): base_xyz + J · (p − base), J the transform's Jacobian at one
    base point of each ``tile_m`` tile (finite differences through :func:`to_crs`). Much faster
    than transforming every point; the error is below 0.1 mm for moves up to ~10 m (J changes by
    ~tile/R ≈ 1e-5 across a tile, a second-order term by |Δ|²/R)."""
    base_xyz = np.asarray(base_xyz, float)
    base_ecef = np.asarray(base_ecef, float)
    if base_xyz.shape[0] == 0:
        return base_xyz.copy()
    tile = tile_m / 1e5 if pyproj.CRS.from_user_input(crs).is_geographic else tile_m  # ≈ 1e5 m a degree
    ij = np.floor(base_xyz[:, :2] / tile).astype(np.int64)
    ij -= ij.min(axis=0)
    key = ij[:, 0] * (int(ij[:, 1].max()) + 1) + ij[:, 1]
    first = np.full(int(key.max()) + 1, -1, np.int64)
    first[key[::-1]] = np.arange(key.size)[::-1]  # the first point of each tile (no sort)
    tiles = np.flatnonzero(first >= 0)
    index = np.empty(first.size, np.int64)
    index[tiles] = np.arange(tiles.size)
    anchor = base_ecef[first[tiles]]
    at = to_crs(anchor, crs, geoid_undulation_m, source)
    jac = np.stack([to_crs(anchor + step, crs, geoid_undulation_m, source) - at for step in np.eye(3)], axis=2)
    d, rows, out = np.asarray(points_ecef, float) - base_ecef, index[key], base_xyz.copy()
    for k in range(3):  # column by column: gathers of (n, 3), not (n, 3, 3)
        out += jac[:, :, k][rows] * d[:, k:k + 1]
    return out
