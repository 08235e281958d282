"""The overlap-quality stages' points re-georeferenced in one numba pass per chunk
(:func:`moved_versions`): per point the trajectory's pose is interpolated once, the delivered
point taken back into the scanner frame with the nominal mounting, then forward with every
stage's mounting (the same pose when a stage keeps the trajectory; a corrected trajectory's
own pose, once, for the stages flown with it), and each move applied to the point's CRS
coordinates through the chunk's per-tile Jacobians (:class:`calidar.crs.TileLinear`).

It is :func:`calidar.georef.scanner_vectors`, :func:`calidar.georef.reforward` (a new mounting
only: same range model and scanner) and :meth:`calidar.crs.TileLinear.moved` operation for
operation in one loop: the coordinates are bit for bit theirs
(``tests/unit/ingest/test_regeoref.py``), without three interpolations of the poses and the
(N, 3) arrays between the calls. Anything else (a new range model or scanner, a third
trajectory) returns None: the caller goes the long way.
"""

from __future__ import annotations

import numpy as np
from numba import njit

from calidar.crs import plus_jd
from calidar.georef import lidar_point, pose, scanner_vector


def moved_versions(traj, nominal, models, t: np.ndarray, lin, take: np.ndarray | None = None,
                   compact: bool = False) -> list[np.ndarray] | None:
    """CRS coordinates (N, 3) of the chunk's points (``lin``: their TileLinear, times ``t`` in
    ``traj``'s system) re-georeferenced with each (sensor, trajectory) of ``models`` (None
    entries: skipped, None in the list returned), or None when the models are not all new
    mountings on ``traj`` and at most one other trajectory; ``take``: only the points at these
    positions re-georeferenced (each as it is among all: the tiles are all the points'), the
    others' rows NaN (``compact``: only the taken points' rows, in the order of ``take``); every
    time still checked."""
    kept = [m for m in models if m is not None]

    def model(s):
        return s.range_offset, s.range_scale, s.scanner

    if any(model(s) != model(nominal) for s, _ in kept):
        return None
    others = list({id(tr): tr for _, tr in kept if tr is not traj}.values())
    if len(others) > 1:
        return None
    other = others[0] if others else traj
    t = np.ascontiguousarray(t, float)
    every = take is None
    take = np.arange(t.size) if every else np.ascontiguousarray(take, np.int64)
    compact = compact and not every
    out = np.empty((len(kept), take.size if compact else t.size, 3))
    c = lambda a: np.ascontiguousarray(a, float)  # noqa: E731 - as calidar.georef._c
    which = np.array([0 if tr is traj else 1 for _, tr in kept], np.int64)
    r_bs = np.stack([c(s.r_bs) for s, _ in kept]) if kept else np.zeros((0, 3, 3))
    lever = np.stack([c(s.lever_arm) for s, _ in kept]) if kept else np.zeros((0, 3))
    trajectories = (traj.time, c(traj.ecef), c(traj.q_eb), other.time, c(other.ecef),
                    c(other.q_eb))
    # the points' ECEF as TileLinear.near_ecef gives them, computed in the kernel's loop
    near = (np.linalg.inv(lin.jac), c(lin.anchor_ecef), np.ascontiguousarray(lin.anchor, np.int64))
    if not (every or compact):  # the rows not taken: NaN
        _nan_rows(take, out)
    n_out, n_out2 = _versions_kernel(*trajectories, t, *near, c(nominal.r_bs),
                                     c(nominal.lever_arm), r_bs, lever, which, c(lin.xyz), lin.jac,
                                     np.ascontiguousarray(lin.rows, np.int64), take, compact, out)
    if n_out or not (every or _within(traj, t)):
        traj.check_covers(t)
    if np.any(which == 1) and (n_out2 or not (every or _within(other, t))):
        other.check_covers(t)
    it = iter(out)
    return [None if m is None else next(it) for m in models]


def _within(traj, t: np.ndarray) -> bool:
    """Whether every time ``t`` lies within the trajectory's first and last (the kernel's test;
    NaN does not)."""
    return bool(np.all((t >= traj.time[0]) & (t <= traj.time[-1])))


@njit(cache=True, nogil=True)
def _nan_rows(take, out):  # pragma: no cover - numba
    """NaN in every row of ``out`` (M, N, 3) but those at ``take`` (the gaps between them when
    they ascend, else every row: the kernel then writes those taken)."""
    ascending = True
    for kk in range(1, take.size):
        ascending = ascending and take[kk] > take[kk - 1]
    flat = out.reshape(out.shape[0], out.shape[1] * 3)
    for m in range(out.shape[0]):
        start = 0
        for kk in range(take.size if ascending else 0):
            flat[m, 3 * start:3 * take[kk]] = np.nan
            start = take[kk] + 1
        flat[m, 3 * start:] = np.nan


@njit(cache=True, nogil=True)
def _versions_kernel(tt, pos, q, tt2, pos2, q2, t, inv, anchor_ecef, anchor, r_bs0, lever0, r_bs,
                     lever, which, base, jac, rows, take, compact, out):  # pragma: no cover - numba
    """out[m, k] (``compact``: out[m, kk]) = base + J · (forward_m(inverse(p)) − p) of each point
    k = take[kk] (see the module), p the point's ECEF from its tile's anchor (``inv`` = J⁻¹;
    :meth:`calidar.crs.TileLinear.near_ecef` operation for operation); returns how many of their
    times lie outside each trajectory (NaN counts as outside)."""
    n_out, i, i_prev, theta, s, sign = 0, 0, -1, 0.0, 0.0, 1.0
    n_out2, i2, i2_prev, theta2, s2, sign2 = 0, 0, -1, 0.0, 0.0, 1.0
    second = False
    for m in range(which.size):
        second = second or which[m] == 1
    qx = qy = qz = r00 = r01 = r02 = r10 = r11 = r12 = r20 = r21 = r22 = 0.0
    for kk in range(take.size):
        k = take[kk]
        tk = t[k]
        j = rows[k]  # p = anchor_ecef + J⁻¹ · (xyz − the anchor's xyz), as near_ecef
        a0 = anchor[j]
        d0, d1, d2 = base[k, 0] - base[a0, 0], base[k, 1] - base[a0, 1], base[k, 2] - base[a0, 2]
        p0, p1, p2 = plus_jd(anchor_ecef[j, 0], anchor_ecef[j, 1], anchor_ecef[j, 2], inv, j,
                             d0, d1, d2)
        n_out += not tt[0] <= tk <= tt[tt.size - 1]
        i, i_prev, theta, s, sign, px, py, pz, a00, a01, a02, a10, a11, a12, a20, a21, a22 = pose(
            tt, pos, q, tk, i, i_prev, theta, s, sign)
        if second:
            n_out2 += not tt2[0] <= tk <= tt2[tt2.size - 1]
            (i2, i2_prev, theta2, s2, sign2,
             qx, qy, qz, r00, r01, r02, r10, r11, r12, r20, r21, r22) = pose(
                tt2, pos2, q2, tk, i2, i2_prev, theta2, s2, sign2)
        sx, sy, sz = scanner_vector(p0, p1, p2, px, py, pz,
                                    a00, a01, a02, a10, a11, a12, a20, a21, a22, r_bs0, lever0)
        for m in range(which.size):
            if which[m] == 0:  # the pose on the first trajectory
                ox, oy, oz = px, py, pz
                e00, e01, e02, e10, e11, e12 = a00, a01, a02, a10, a11, a12
                e20, e21, e22 = a20, a21, a22
            else:  # on the second
                ox, oy, oz = qx, qy, qz
                e00, e01, e02, e10, e11, e12 = r00, r01, r02, r10, r11, r12
                e20, e21, e22 = r20, r21, r22
            # the lidar equation, then the move (calidar.crs.tile_moved)
            x, y, z = lidar_point(sx, sy, sz, r_bs[m], lever[m], ox, oy, oz,
                                  e00, e01, e02, e10, e11, e12, e20, e21, e22)
            r = kk if compact else k
            out[m, r, 0], out[m, r, 1], out[m, r, 2] = plus_jd(
                base[k, 0], base[k, 1], base[k, 2], jac, j, x - p0, y - p1, z - p2)
    return n_out, n_out2
