"""The rows a plan's tie planes give: each kept cell (:mod:`calidar.planning.geometry`) becomes
one point-to-plane row of :class:`~calidar.strips.correspond.Correspondences`.

Each side is one synthetic point at the patch's centroid with the pose the line has when it
scans it (level flight along the line at the planned height and speed, the scanner's angles
and range to the centroid; a rotating scanner — Palmer oval, wedge cone — sees the patch
twice, ahead and back, and the side averages the two looks). The row's σ is the calibrator's —
each side's point scatter over its point count, plus the noise floor — with the scatter from
range and angle noise along the normal and the surface's own roughness; where a line's patch
also lies in its other pairs' overlaps, its side's variance is raised as the calibrator's is
for a patch that several pairs' rows use (:func:`shared_factor`).
:class:`calidar.strips.problem.StripProblem` then builds the same Jacobian the adjustment uses.
"""

from __future__ import annotations

import numpy as np
import scipy.sparse as sp

from calidar.planning.geometry import Flown, Instrument, PairPlanes
from calidar.planning.sweep import body_at, pattern_looks, sweep_position
from calidar.strips.correspond import Correspondences
from calidar.strips.row_variance import posterior
from calidar.strips.planes import PlaneSettings
from calidar.strips.strip import Pose


def side_poses(f: Flown, points: np.ndarray,
               inst: Instrument) -> tuple[Pose, np.ndarray, np.ndarray]:
    """The poses at which line ``f`` scans ``points`` (n, 3) (level flight, the nominal sensor's
    angles and range), their times (s) and the beams' unit directions in the local frame. A
    linear scanner sees each point once (n poses); a rotating one (Palmer oval, wedge cone)
    twice, looking ahead and back (2n: the n fore looks, then the n aft ones)."""
    nominal = inst.nominal
    looks = pattern_looks(nominal)
    branches = [None] if looks is None else looks
    parts = [body_at(f, points, sweep_position(f, points, inst, branch), inst)
             for branch in branches]
    t, pos, R, d_b = (np.concatenate(v) for v in zip(*parts))
    rho = np.linalg.norm(d_b, axis=1)
    u_s = (d_b / rho[:, None]) @ nominal.r_bs  # R_bsᵀ · u_b
    angles = nominal.scanner.angles(u_s)
    pose = Pose(np.arange(len(rho)), pos, R, nominal.measured_range(rho), angles)
    return pose, t, np.einsum("nij,nj->ni", R, d_b) / rho[:, None]


def point_variance(beam: np.ndarray, normal: np.ndarray, rho: np.ndarray,
                   inst: Instrument) -> np.ndarray:
    """Scatter (m²) along the normal of one point: range noise along the beam, angle noise
    across it."""
    cos = np.abs(np.einsum("ij,ij->i", beam, normal))
    return (inst.range_noise_m * cos) ** 2 + (rho * inst.angle_noise_rad) ** 2 * (1.0 - cos**2)


def _weighed_variance(scatter_m2: np.ndarray, m: np.ndarray, count_b: np.ndarray | None):
    """The variance (m²) the calibrator gives a side's mean of ``m`` points scattering
    ``scatter_m2`` (strips/planes.py): the posterior variance of the scatter (Smyth 2004 §6.2),
    and on a's side (``count_b`` given) a's plane's prediction variance at b's centroid, whose
    in-plane offset spreads by both centroids' (1/m each)."""
    leverage = 1.0 if count_b is None else 1.0 + 2.0 * (1.0 + m / count_b) / m
    return posterior(scatter_m2, m - 3, sampled=False)[0] * leverage / m


def _side_rows(p: PairPlanes, f: Flown, m: np.ndarray, first: int, inst: Instrument, terrain,
               cache: dict | None, b_side: bool):
    """One side of pair ``p`` scanned by line ``f`` (its points numbered from ``first``): its
    poses and times, the (columns, weights) of each row's looks, the variance (m²) the
    calibrator gives the side and the variance its residual really has, for ``m`` points a
    patch (``b_side``: b's side; a's is the plane the row predicts at b's centroid)."""
    n = p.centroid.shape[0]
    pose, t, beam, seen = _side(f, p.centroid, inst, terrain, cache)
    looks = len(t) // n  # a rotating scanner's patch: half its points seen ahead, half back
    picked = (first + np.arange(n * looks).reshape(looks, n).T,
              seen / seen.sum(axis=1, keepdims=True))
    rho = inst.nominal.true_range(pose.range_m)
    per_look = point_variance(beam, np.tile(p.normal, (looks, 1)), rho, inst)
    points = np.sum(per_look.reshape(looks, n).T * picked[1], axis=1)
    var = _weighed_variance(points + p.roughness_m**2, m, None if b_side else p.count_b)
    own = (points + p.uneven_m**2) / m
    return (pose, t), picked, var, own


def correspondences(flown: list[Flown], pairs: list[PairPlanes], inst: Instrument,
                    settings: PlaneSettings = PlaneSettings(), terrain=None,
                    cache: dict | None = None):
    """Synthetic poses per strip, the pairs' Correspondences, each strip's point times, and the
    variance (m²) the rows' residuals really have (in the Correspondences' order). A rotating
    scanner's side averages the looks that see the patch (``terrain``: which do; a wall or crown
    hides one look of many patches beside buildings, and a one-look patch moves as that look's
    points do). ``cache``: each side's poses and looks kept across calls (candidate lines tried
    one by one).

    A row's σ is the calibrator's (both sides' variance, and a noise floor if set); what the
    residual really scatters by is the points' noise and the unevenness the patches do not share
    (the rest lies under both and cancels: σ0 ≈ 0.5 of the calibrator on the built-in scene). A row
    standing for ``weight`` planes weighs as much."""
    corrs = []
    parts: dict[int, list] = {k: [] for k in range(len(flown))}
    used = {k: 0 for k in range(len(flown))}
    for p in pairs:
        cols, var, own = [], [], []
        for k, m in ((p.a, p.count_a), (p.b, p.count_b)):
            scanned, picked, v, o = _side_rows(p, flown[k], m, used[k], inst, terrain, cache,
                                               b_side=k == p.b)
            parts[k].append(scanned)
            cols.append(picked)
            used[k] += picked[0].size
            var.append(v * shared_factor(p, k, pairs, flown, inst))
            own.append(o)
        agree = np.maximum(p.agree, 1e-3) * p.weight
        sigma = np.sqrt((var[0] + var[1] + settings.noise_floor_m**2) / agree)
        corrs.append((p.a, p.b, cols, p.normal, sigma, (own[0] + own[1]) / agree))
    poses, times = _strip_poses(flown, parts, used)
    out, noise = [], []
    for a, b, cols, normal, sigma, real in corrs:
        ids = flown[a].line.number, flown[b].line.number
        selectors = _selector(cols[0], used[a]), _selector(cols[1], used[b])
        out.append(Correspondences(*ids, *selectors, normal, sigma))
        noise.append(real)
    return poses, times, out, np.concatenate(noise)


def shared_factor(p: PairPlanes, line: int, pairs: list[PairPlanes], flown: list[Flown],
                  inst: Instrument) -> np.ndarray:
    """(k + 1)/2 per tie plane of pair ``p`` for its side on ``line``: k the pairs of that line
    whose other line's swath also covers the plane (the calibrator counts a patch that k pairs'
    rows use once, :mod:`calidar.strips.shared_patches`)."""
    k = np.ones(p.centroid.shape[0])
    for q in pairs:
        if q is p or line not in (q.a, q.b):
            continue
        other = flown[q.b if q.a == line else q.a]
        s, c = other.local(p.centroid[:, :2])
        half = other.line.height_agl_m * np.tan(inst.half_fov_rad)
        k += (s >= 0.0) & (s <= other.line.length_m) & (np.abs(c) <= half)
    return 0.5 * (k + 1.0)


def _strip_poses(flown: list[Flown], parts: dict[int, list], used: dict[int, int]):
    """Each scanned strip's poses and times (s), its sides' in order, by line number."""
    poses, times = {}, {}
    for k, items in parts.items():
        if not items:
            continue
        sid = flown[k].line.number
        cat = [np.concatenate([getattr(pz, f) for pz, _ in items])
               for f in ("position", "r_lb", "range_m", "angles")]
        poses[sid] = Pose(np.arange(used[k]), *cat)
        times[sid] = np.concatenate([t for _, t in items])
    return poses, times


def _side(f: Flown, centroid: np.ndarray, inst: Instrument, terrain, cache: dict | None):
    """:func:`side_poses` of one side of a pair and which looks see each patch (n, looks), from
    ``cache`` when the same line (number, window) scanned the same tie planes before."""
    key = ("side", f.line.to_json(), f.t0, id(centroid))
    if cache is not None and key in cache:
        return cache[key]
    pose, t, beam = side_poses(f, centroid, inst)
    n = centroid.shape[0]
    looks = len(t) // n
    seen = np.ones((n, looks))
    if looks > 1 and terrain is not None:
        origin = pose.position + np.einsum("nij,j->ni", pose.r_lb, inst.nominal.lever_arm)
        visible = terrain.visible(origin, np.tile(centroid, (looks, 1)))
        seen = visible.reshape(looks, n).T.astype(float)
        seen[seen.sum(axis=1) == 0] = 1.0  # seen from above the line (pair_planes), not by a look
    if cache is not None:
        cache[key] = (pose, t, beam, seen)
    return pose, t, beam, seen


def _selector(picked: tuple[np.ndarray, np.ndarray], n_points: int) -> sp.csr_matrix:
    """Rows averaging k points each with weights (the patch's centroid): ``picked`` = (columns,
    weights), (n, k)."""
    cols, weights = picked
    n, k = cols.shape
    indptr = np.arange(0, n * k + 1, k)
    return sp.csr_matrix((weights.ravel(), cols.ravel(), indptr), shape=(n, n_points))
