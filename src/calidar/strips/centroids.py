"""The weighted sums of one side of a strip correspondence set and their exact derivatives.

The lidar equation (:func:`calidar.georef.lidar_points`), p = r + R_lb · (R_bs · ρ · u + a_b),
is linear in what boresight, lever arm and range model act on: per correspondence row the
weighted sums of r, R_lb, R_lb·ρ_m·u and R_lb·u are taken once (:class:`Centroids`), so that
:class:`calidar.strips.problem.StripProblem` evaluates its residuals in O(rows) and its sensor
and trajectory-correction Jacobian columns analytically.
"""

from __future__ import annotations

from collections.abc import Sequence
from functools import lru_cache

import numpy as np
import scipy.sparse as sp
from numba import njit

from calidar import frames
from calidar.sensor import Sensor
from calidar.strips.strip import Pose, position_table

BORESIGHT = ("boresight_roll", "boresight_pitch", "boresight_yaw")
LEVER_ARM = ("lever_arm_x", "lever_arm_y", "lever_arm_z")
#: sensor parameters whose Jacobian columns are analytic (the centroid form holds them exactly)
ANALYTIC = (*BORESIGHT, *LEVER_ARM, "range_offset", "range_scale")


def union(indices: list[np.ndarray]) -> np.ndarray:
    """Sorted union of point-index arrays (O(N), unlike a hash-based unique)."""
    return np.flatnonzero(np.bincount(np.concatenate(indices)))


def compact(m: sp.csr_matrix, cols: np.ndarray) -> sp.csr_matrix:
    """``m`` restricted to its columns ``cols`` (sorted, holding every column m references)."""
    local = position_table(cols)[m.indices]
    return sp.csr_matrix((m.data, local, m.indptr), shape=(m.shape[0], cols.size))


def boresight_derivatives(sensor: Sensor) -> np.ndarray:
    """∂R_bs/∂(roll, pitch, yaw) as (9, 3): column k the flattened derivative. With
    R_bs = Rz(yaw)·Ry(pitch)·Rx(roll) and ∂R_i(θ)/∂θ = R_i(θ)·[e_i]×. Read-only: kept for
    the last few angles (every side of every correspondence set asks at the same sensor)."""
    return _boresight_derivatives(float(sensor.boresight_roll), float(sensor.boresight_pitch),
                                  float(sensor.boresight_yaw))


@lru_cache(maxsize=16)
def _boresight_derivatives(roll: float, pitch: float, yaw: float) -> np.ndarray:
    rx, ry, rz = frames.rot_x(roll), frames.rot_y(pitch), frames.rot_z(yaw)
    gx, gy, gz = (np.cross(np.eye(3), e) for e in np.eye(3))  # [e]×: [e]×·v = e × v
    d = [rz @ ry @ rx @ gx, rz @ ry @ gy @ rx, rz @ gz @ ry @ rx]
    out = np.stack([m.ravel() for m in d], axis=1)
    out.setflags(write=False)
    return out


class Centroids:
    """C = A · P(θ) for one side of a correspondence set, in O(n_obs) per evaluation.

    With P = r + R_lb · (R_bs · v_s + a_b) and v_s = (ρ_m − offset) / (1 + scale) · u (the
    lidar equation with the sensor's range model), the averages of r, R_lb, R_lb·ρ_m·u and
    R_lb·u are taken once; boresight, lever arm and range offset/scale then act on them
    exactly. (Scanner-angle parameters change u: see :class:`StripProblem`.)
    """

    def __init__(self, A: sp.csr_matrix, poses: Pose, nominal: Sensor, range_free: bool,
                 lever_free: bool):
        """A: averaging weights over a strip's points (columns = strip point indices); poses:
        cached poses holding every point A references."""
        cols = union([A.indices])  # only the points this side references
        rows = poses.rows_of(cols)
        u = nominal.scanner.directions(poses.angles[rows])
        rho = poses.range_m[rows] if range_free else nominal.true_range(poses.range_m[rows])
        self.rowsum = np.asarray(A.sum(axis=1)).ravel()
        local = position_table(cols)[A.indices]
        #: weighted sums of the IMU positions, of R_lb, of R_lb·ρ·u and (range model free) of
        #: R_lb·u
        self.r, R, self.M_rho, M_u = _weighted_sums(A.indptr, local, A.data, rows, poses.position,
                                                    poses.r_lb, rho, u, range_free)
        self.M_u = M_u if range_free else None
        if lever_free:
            self.R, self.const = R, self.r
        else:  # a fixed lever arm adds a constant
            self.R, self.const = None, self.r + R @ nominal.lever_arm

    def _m(self, sensor: Sensor) -> np.ndarray:
        """A·R_lb·v_s as (n·3, 9) acting on vec(R_bs)."""
        if self.M_u is None:
            return self.M_rho.reshape(-1, 9)
        M = (self.M_rho - sensor.range_offset * self.M_u) / (1.0 + sensor.range_scale)
        return M.reshape(-1, 9)

    def __call__(self, sensor: Sensor) -> np.ndarray:
        n = self.rowsum.size
        out = self.const + (self._m(sensor) @ sensor.r_bs.ravel()).reshape(n, 3)
        return out if self.R is None else out + self.R @ sensor.lever_arm

    def derivatives(self, sensor: Sensor, names: Sequence[str]) -> np.ndarray:
        """∂C/∂(the named sensor parameters, all in :data:`ANALYTIC`), (n, 3, len(names))."""
        n = self.rowsum.size
        out = np.zeros((n, 3, len(names)))
        M = self._m(sensor)
        db = (M @ boresight_derivatives(sensor)).reshape(n, 3, 3)
        r_bs, stretch = sensor.r_bs.ravel(), 1.0 + sensor.range_scale
        for j, name in enumerate(names):
            if name in BORESIGHT:
                out[:, :, j] = db[:, :, BORESIGHT.index(name)]
            elif name in LEVER_ARM:
                out[:, :, j] = self.R[:, :, LEVER_ARM.index(name)]
            elif name == "range_offset":
                out[:, :, j] = -(self.M_u.reshape(-1, 9) @ r_bs).reshape(n, 3) / stretch
            elif name == "range_scale":
                out[:, :, j] = -(M @ r_bs).reshape(n, 3) / stretch
            else:
                raise ValueError(f"no analytic derivative for {name}")
        return out


@njit(cache=True, nogil=True)
def _weighted_sums(indptr, local, data, rows, position, r_lb, rho, u, with_u):  # pragma: no cover
    """Per row i of a CSR averaging matrix (indptr, local column, weight): Σ w·r, Σ w·R_lb,
    Σ w·R_lb·ρ·u_k and (with_u) Σ w·R_lb·u_k as (n, 3), (n, 3, 3), (n, 3, 3, 3),
    (n, 3, 3, 3); the column's point is ``rows[local]`` of position/r_lb and ``local`` of
    rho/u."""
    n = indptr.size - 1
    r, R = np.zeros((n, 3)), np.zeros((n, 3, 3))
    M_rho, M_u = np.zeros((n, 3, 3, 3)), np.zeros((n if with_u else 0, 3, 3, 3))
    # one row's sums in these (each the same additions in the same order as into the outputs;
    # 1.3–1.4× fewer CPU seconds than adding into the outputs, which LLVM must store each step)
    sr, sR, srho, su = np.empty(3), np.empty((3, 3)), np.empty((3, 3, 3)), np.empty((3, 3, 3))
    for i in range(n):
        sr[:] = 0.0
        sR[:] = 0.0
        srho[:] = 0.0
        su[:] = 0.0
        for k in range(indptr[i], indptr[i + 1]):
            j, w = local[k], data[k]
            p, rj = rows[j], rho[j]
            u0, u1, u2 = u[j, 0], u[j, 1], u[j, 2]
            for a in range(3):
                sr[a] += w * position[p, a]
                for b in range(3):
                    wr = w * r_lb[p, a, b]
                    sR[a, b] += wr
                    wrr = wr * rj  # (w·R_lb·ρ)·u_k, as before
                    srho[a, b, 0] += wrr * u0
                    srho[a, b, 1] += wrr * u1
                    srho[a, b, 2] += wrr * u2
                    if with_u:
                        su[a, b, 0] += wr * u0
                        su[a, b, 1] += wr * u1
                        su[a, b, 2] += wr * u2
        r[i] = sr
        R[i] = sR
        M_rho[i] = srho
        if with_u:
            M_u[i] = su
    return r, R, M_rho, M_u


def correction_derivatives(side: Centroids, sensor: Sensor,
                           normal: np.ndarray | None) -> np.ndarray:
    """∂(a side's corrected weighted sums)/∂(shift x, y, z, tilt x, y, z) of one knot carrying
    all the weight, (n, per, 6): shift → row sums · e, rotation → e × (sums − IMU sums);
    along the normals (per = 1) or in 3D (per = 3)."""
    v = side(sensor) - side.r
    if normal is not None:  # (e × v) · n = e · (v × n)
        along = np.concatenate([side.rowsum[:, None] * normal, np.cross(v, normal)], axis=1)
        return along[:, None, :]
    D = np.zeros((v.shape[0], 3, 6))
    D[:, [0, 1, 2], [0, 1, 2]] = side.rowsum[:, None]
    D[:, :, 3:] = np.stack([np.cross(e, v) for e in np.eye(3)], axis=2)
    return D
