"""Tie planes: planar patches found in both strips of an overlap, matched across them.

Both strips are cut by one horizontal grid (cells of ``cell_m``). In every cell the points
of a strip are fitted with a plane by principal component analysis (PCA) of their
covariance: eigenvalues λ0 ≤ λ1 ≤ λ2, normal = eigenvector of λ0. A patch is accepted when
it is planar (√λ0 ≤ ``max_rms_m``), large enough (≥ ``min_points`` points) and fills its
cell (√λ1 ≥ ``min_spread`` · cell, a uniform square gives 0.29). A cell planar in both
strips with agreeing normals is a tie plane ("connection plane", as in strip adjustment
by Kager 2004, *Discrepancies between overlapping laser scanner strips*, and Ressl et al.
2011): strip a's fitted plane, where b's centroid lies, must meet b's centroid,

    r = n_b · (â − mean(P_b[patch])),   â = Σ h_i P_a,i   (m)

â the point of a's least-squares plane at b's centroid (h: the fit's hat weights,
:func:`plane_point_weights`), which becomes one point-to-plane row of
:class:`~calidar.strips.correspond.Correspondences` with these weights. Vegetation and edges fail
the planarity test.

Why not a's plain centroid (issue 26, sixth session): a's and b's centroids in one cell lie
apart by a few cm, and not at random (the point density falls across each swath), so
r = n_b · (c_a − c_b) held b's normal's noisy tilt times that offset. On flat ground the row's
derivative by pitch is that same tilt times the strips' relative along-track move: the row's
own noise sat in its regressor and its residual alike (errors in variables), which biased
pitch (z ±2–3 on one flat overlap, ``tests/unit/strips/test_tie_plane_pitch.py``). At b's
centroid, â − c_b lies along a's normal: b's tilt no longer enters the residual.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np
from numba import njit

from calidar.strips.correspond import Correspondences
from calidar.strips.overlap import cell_keys, footprint_area_m2
from calidar.strips.moments_kernel import stable_key_order
from calidar.strips.pca import eigh3
from calidar.strips.row_variance import posterior, satterthwaite
from calidar.strips.tilt import calibrated_normals

if TYPE_CHECKING:  # scipy.sparse imported where used: `calidar quality` needs none of it
    import scipy.sparse as sp


@dataclass(frozen=True)
class PlaneSettings:
    """Tie-plane detection settings (metres, degrees where named)."""

    #: patch size; None → chosen so that a patch holds ≈ target_points
    cell_m: float | None = None
    target_points: int = 12  #: small patches: more of them planar on roofs and between trees
    min_points: int = 6
    max_rms_m: float = 0.10  #: largest point scatter about the fitted plane
    min_spread: float = 0.2  #: √λ1 / cell_m at least (the patch covers its cell)
    max_normal_angle_deg: float = 5.0  #: normals of the two strips agree within this
    max_offset_m: float = 1.0  #: gate on |r| (tie planes further apart are not the same surface)
    max_points_per_patch: int = 64  #: centroid from at most this many points (evenly picked)
    max_planes: int = 5000  #: at most this many tie planes per pair, evenly picked (dense strips)
    #: added to each row's σ for model errors (roughness); 0: the patches' own scatter already
    #: holds the roughness both strips sample (issue 26: at the truth the 2 mm made the UAV rows
    #: 15 % conservative)
    noise_floor_m: float = 0.0


@dataclass(frozen=True)
class Patches:
    """Planar patches of one strip, one per accepted cell."""

    keys: np.ndarray  #: (P,) cell keys
    centroid: np.ndarray  #: (P, 3) m
    normal: np.ndarray  #: (P, 3) unit, pointing up
    #: (P,) RMS of the points off the plane, √(λ0 · n / (n − 3)) (the planarity test takes √λ0)
    rms_m: np.ndarray
    axes: np.ndarray  #: (P, 3, 2) unit in-plane axes (the eigenvectors of λ1, λ2)
    spread_m2: np.ndarray  #: (P, 2) the points' variance along them, λ1, λ2 (m²)
    start: np.ndarray  #: (P,) first position of the patch's points in ``order``
    count: np.ndarray  #: (P,) points in the patch
    order: np.ndarray  #: point indices sorted by cell


def patch_cell_size(points: np.ndarray, target_points: int) -> float:
    """A patch size (m) holding about ``target_points`` at the points' horizontal density."""
    density = max(points.shape[0] / max(footprint_area_m2(points), 1e-9), 1e-6)
    return float(np.clip(np.sqrt(target_points / density), 0.5, 25.0))


def fit_patches(points: np.ndarray, cell_m: float, settings: PlaneSettings) -> Patches:
    """Fit a plane in every grid cell of ``points`` (N, 3) local m; keep the planar ones."""
    keys = cell_keys(points, cell_m)
    order = stable_key_order(keys)  # np.argsort(keys, kind="stable")'s, by a counting sort
    ks = keys[order]
    start = np.r_[0, np.flatnonzero(ks[1:] != ks[:-1]) + 1] if ks.size else np.zeros(0, np.int64)
    uk, count = ks[start], np.diff(np.r_[start, ks.size])
    ok = np.flatnonzero(count >= max(settings.min_points, 4))  # a plane and its scatter
    contiguous = np.ascontiguousarray(points, dtype=np.float64)
    mean, cov = _cell_moments(contiguous, order, start[ok], count[ok])
    planar, normal, lam0, (lam, vec) = _planarity(cov, cell_m, settings)
    sel = ok[planar]
    rms = np.sqrt(lam0 * count[sel] / (count[sel] - 3))  # 3 plane parameters fitted
    lam, vec = lam[planar], vec[planar]  # (eigh3 works matrix by matrix: its values on the subset)
    spread = np.clip(lam[:, 1:], 1e-12, None)
    return Patches(uk[sel], mean[planar], normal, rms, vec[:, :, 1:], spread, start[sel],
                   count[sel], order)


def plane_point_weights(points: np.ndarray, A: sp.csr_matrix, target: np.ndarray
                        ) -> tuple[sp.csr_matrix, np.ndarray]:
    """Weights over each row's points (those of the averaging matrix ``A``, (R, N)) whose weighted
    sum is the point of the row's least-squares plane (PCA of those points) at ``target`` (R, 3) m:
    the in-plane coordinates of ``target``, on the fitted plane. They sum to 1 (a rigid move moves
    that point alike):

        h_i = (1/m)·(1 + Σ_j (e_j·(t − x̄))(e_j·(x_i − x̄)) / λ_j),

    e_j the in-plane axes and λ_j the points' variances along them (the regression's hat-matrix
    row at t, e.g. Draper & Smith 1998 §3.2). Also Σ h_i² per row: the variance of the plane's
    height there in units of its points' σ² (1/m at the centroid, more off it)."""
    import scipy.sparse as sp

    points = np.ascontiguousarray(points, dtype=np.float64)
    mean, cov = _row_moments(A.indptr, A.indices, A.data, points)
    lam, vec = eigh3(cov)
    h, leverage = _hat_weights(A.indptr, A.indices, A.data, points,
                               np.ascontiguousarray(target, dtype=np.float64), mean, lam, vec)
    weights = sp.csr_matrix((h, A.indices.copy(), A.indptr.copy()), shape=A.shape)
    return weights, leverage


# The two kernels of plane_point_weights, numpy's order of operations kept (the same bits as
# ``A @ points``, the centred products summed per row by ``np.bincount`` and the einsums over
# three or two terms; tests/unit/strips/test_strips_planes.py), without the per-entry gathers.

@njit(cache=True, nogil=True)
def _row_moments(indptr, indices, data, points):  # pragma: no cover - numba
    """Each row's weighted mean (R, 3) and weighted scatter about it (R, 3, 3)."""
    n = indptr.size - 1
    mean, cov = np.zeros((n, 3)), np.zeros((n, 3, 3))
    for r in range(n):
        for k in range(indptr[r], indptr[r + 1]):
            for a in range(3):
                mean[r, a] += data[k] * points[indices[k], a]
        for k in range(indptr[r], indptr[r + 1]):
            p = indices[k]
            d0, d1, d2 = (points[p, 0] - mean[r, 0], points[p, 1] - mean[r, 1],
                          points[p, 2] - mean[r, 2])
            w0, w1, w2 = data[k] * d0, data[k] * d1, data[k] * d2
            cov[r, 0, 0] += w0 * d0
            cov[r, 0, 1] += w0 * d1
            cov[r, 0, 2] += w0 * d2
            cov[r, 1, 1] += w1 * d1
            cov[r, 1, 2] += w1 * d2
            cov[r, 2, 2] += w2 * d2
        cov[r, 1, 0], cov[r, 2, 0], cov[r, 2, 1] = cov[r, 0, 1], cov[r, 0, 2], cov[r, 1, 2]
    return mean, cov


@njit(cache=True, nogil=True)
def _hat_weights(indptr, indices, data, points, target, mean, lam, vec):  # pragma: no cover
    """Each entry's hat weight h and each row's Σ h² (see :func:`plane_point_weights`)."""
    n = indptr.size - 1
    h, leverage = np.empty(data.size), np.zeros(n)
    for r in range(n):
        t0, t1, t2 = target[r, 0] - mean[r, 0], target[r, 1] - mean[r, 1], target[r, 2] - mean[r, 2]
        c = np.empty(2)
        for j in range(2):
            spread = lam[r, j + 1] if not lam[r, j + 1] < 1e-12 else 1e-12  # np.clip: NaN kept
            c[j] = (0.0 + t0 * vec[r, 0, j + 1] + t1 * vec[r, 1, j + 1]
                    + t2 * vec[r, 2, j + 1]) / spread
        for k in range(indptr[r], indptr[r + 1]):
            p = indices[k]
            d0, d1, d2 = (points[p, 0] - mean[r, 0], points[p, 1] - mean[r, 1],
                          points[p, 2] - mean[r, 2])
            e0 = 0.0 + d0 * vec[r, 0, 1] + d1 * vec[r, 1, 1] + d2 * vec[r, 2, 1]
            e1 = 0.0 + d0 * vec[r, 0, 2] + d1 * vec[r, 1, 2] + d2 * vec[r, 2, 2]
            h[k] = data[k] * (1.0 + (c[0] * e0 + c[1] * e1))
            leverage[r] += h[k] * h[k]
    return h, leverage


def planar_cells(cov: np.ndarray, cell_m: float,
                 settings: PlaneSettings) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The planarity test of cells from their point covariances (K, 3, 3) m²: mask of the planar
    cells (√λ0 ≤ max_rms_m, √λ1 ≥ min_spread · cell_m), their unit normals pointing up and λ0
    (m²)."""
    return _planarity(cov, cell_m, settings)[:3]


def _planarity(cov: np.ndarray, cell_m: float, settings: PlaneSettings) -> tuple:
    """:func:`planar_cells` and the eigen decomposition of every cell it came from (eigh3's)."""
    raw = eigh3(cov)
    lam = np.clip(raw[0], 0.0, None)
    thin = np.sqrt(lam[:, 0]) <= settings.max_rms_m
    filled = np.sqrt(lam[:, 1]) >= settings.min_spread * cell_m
    planar = thin & filled
    normal = raw[1][planar][:, :, 0]
    normal *= np.where(normal[:, 2] < 0, -1.0, 1.0)[:, None]
    return planar, normal, lam[planar, 0], raw


@njit(cache=True, nogil=True)
def _cell_moments(points, order, start, count):
    """Mean (K, 3) and covariance (K, 3, 3) of the points ``order[start[c]:start[c] + count[c]]``
    of each cell c; sums about the cell's first point keep them well conditioned."""
    k_cells = start.size
    mean = np.empty((k_cells, 3))
    cov = np.empty((k_cells, 3, 3))
    for c in range(k_cells):
        first = order[start[c]]
        r0, r1, r2 = points[first, 0], points[first, 1], points[first, 2]
        s0 = s1 = s2 = s00 = s01 = s02 = s11 = s12 = s22 = 0.0
        for k in range(start[c], start[c] + count[c]):
            i = order[k]
            d0, d1, d2 = points[i, 0] - r0, points[i, 1] - r1, points[i, 2] - r2
            s0 += d0
            s1 += d1
            s2 += d2
            s00 += d0 * d0
            s01 += d0 * d1
            s02 += d0 * d2
            s11 += d1 * d1
            s12 += d1 * d2
            s22 += d2 * d2
        n = count[c]
        m0, m1, m2 = s0 / n, s1 / n, s2 / n
        mean[c, 0], mean[c, 1], mean[c, 2] = m0 + r0, m1 + r1, m2 + r2
        cov[c, 0, 0] = s00 / n - m0 * m0
        cov[c, 1, 1] = s11 / n - m1 * m1
        cov[c, 2, 2] = s22 / n - m2 * m2
        cov[c, 0, 1] = cov[c, 1, 0] = s01 / n - m0 * m1
        cov[c, 0, 2] = cov[c, 2, 0] = s02 / n - m0 * m2
        cov[c, 1, 2] = cov[c, 2, 1] = s12 / n - m1 * m2
    return mean, cov


def _averaging(patches: Patches, rows: np.ndarray, cap: int,
               n_points: int) -> tuple[sp.csr_matrix, np.ndarray]:
    """Sparse centroid weights for the patches ``rows`` (at most ``cap`` evenly picked points
    each)."""
    import scipy.sparse as sp

    c = patches.count[rows]
    m = np.minimum(c, cap)
    indptr = np.r_[0, np.cumsum(m)]
    k = np.arange(indptr[-1]) - np.repeat(indptr[:-1], m)
    pos = np.repeat(patches.start[rows], m) + (k * np.repeat(c, m)) // np.repeat(m, m)
    data = np.repeat(1.0 / m, m)
    mat = sp.csr_matrix((data, patches.order[pos], indptr), shape=(rows.size, n_points))
    return mat, m


def match_pair_planes(strip_a_id: int, points_a: np.ndarray, strip_b_id: int, points_b: np.ndarray,
                      settings: PlaneSettings | None = None) -> Correspondences:
    """Tie planes between two strips' overlapping points (each (N, 3) local ENU m).

    Returns point-to-plane correspondences: one row per tie plane, A: a's plane at b's centroid
    (:func:`plane_point_weights`), B averaging b's patch points, normal = the plane normal in
    strip b, σ from the plane scatter.
    """
    import scipy.sparse as sp

    s = settings or PlaneSettings()
    points_a = np.asarray(points_a, float)
    points_b = np.asarray(points_b, float)
    if points_a.shape[0] == 0 or points_b.shape[0] == 0:
        empty = sp.csr_matrix((0, points_a.shape[0])), sp.csr_matrix((0, points_b.shape[0]))
        return Correspondences(strip_a_id, strip_b_id, *empty, np.zeros((0, 3)), np.zeros(0),
                               "planes")
    cell = s.cell_m or max(patch_cell_size(points_a, s.target_points),
                           patch_cell_size(points_b, s.target_points))
    pa, pb = fit_patches(points_a, cell, s), fit_patches(points_b, cell, s)
    _, ia, ib = np.intersect1d(pa.keys, pb.keys, assume_unique=True, return_indices=True)
    cos_ab = np.abs(np.einsum("ij,ij->i", pa.normal[ia], pb.normal[ib]))
    offset = np.einsum("ij,ij->i", pa.centroid[ia] - pb.centroid[ib], pb.normal[ib])
    parallel = cos_ab >= np.cos(np.radians(s.max_normal_angle_deg))
    keep = np.flatnonzero(parallel & (np.abs(offset) <= s.max_offset_m))
    if keep.size > s.max_planes:  # cells in key order: an even pick spreads over the overlap
        keep = keep[np.linspace(0, keep.size - 1, s.max_planes).astype(np.int64)]
    ia, ib = ia[keep], ib[keep]
    A, _ = _averaging(pa, ia, s.max_points_per_patch, points_a.shape[0])
    B, mb = _averaging(pb, ib, s.max_points_per_patch, points_b.shape[0])
    A, leverage_a = plane_point_weights(points_a, A, B @ points_b)  # a's plane at b's centroid
    # each side's scatter (its own from count − 3 degrees of freedom): the posterior mean under a
    # prior fitted to the pair's tie planes (issue 26: moderated toward their mean, quiet rows' σ
    # were 1.2–1.3× too wide)
    var_a, nu_a = posterior(pa.rms_m[ia] ** 2, pa.count[ia] - 3)
    var_b, nu_b = posterior(pb.rms_m[ib] ** 2, pb.count[ib] - 3)
    parts = [var_a * leverage_a, var_b / mb]
    sigma = np.sqrt(parts[0] + parts[1] + s.noise_floor_m**2)
    dof = satterthwaite(parts + [np.full(ia.size, s.noise_floor_m**2)], [nu_a, nu_b, np.inf])
    # b's normal with its tilt's expectation given the fit (regression calibration, issue 26:
    # flat rows' noisy tilts held the outer loop where the last matching left it)
    normal = calibrated_normals(pb.normal[ib], pb.axes[ib], pb.spread_m2[ib], pb.rms_m[ib],
                                pb.count[ib])
    return Correspondences(strip_a_id, strip_b_id, A, B, normal, sigma, "planes", dof,
                           np.stack(parts, axis=1), np.stack([nu_a, nu_b], axis=1))
