"""VGICP's point-to-plane rows: b's local planes and a's ball means about them.

The rows' geometry and the tests they pass are described in :mod:`calidar.strips.vgicp`. For
each candidate, b's ``num_neighbors`` nearest points (registered onto a), found again about
their centroid, give b's plane; a's points in a ball as large about that centroid give a's mean.
A row is kept when b's points span a plane (thin: ``max_surface_variation``; not a line:
``min_spread``), a's mean lies near it (``max_plane_distance_m``), neither side's points stop
inside the ball (``max_centroid_offset``) and a's points lie on b's plane as closely as b's own
do (``max_scatter_ratio``). Its σ² = s_a²/n_a + s_b²·(h − t/n_a) + κ·ρ² + ``noise_floor_m``²,
with s_a, s_b each side's own scatter along b's normal, each the posterior mean under a prior
fitted to the pair's rows (:mod:`calidar.strips.row_variance`; Smyth 2004 §6.2), n_a a's count,
h the leverage of b's fitted plane at a's mean, t the part of b's normal's error in a's scatter
(a's spread in b's plane over b's; :func:`_tilt_cofactor`) and κ·ρ² the rough rows' model error
(``roughness_factor``; :func:`calidar.strips.row_variance.rough_rows_variance`). Why a's own
scatter, measured: docs/validation.md, "VGICP's rows: each test and the measurement behind it";
why less b's tilt: "VGICP's σ0 on airborne surveys" (issue 26, twelfth session).
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import partial

import numpy as np
import scipy.sparse as sp
import small_gicp

from calidar.strips.correspond import moderated_variance
from calidar.strips.pca import eigh3
from calidar.strips.row_sampling import sampling_cofactors, unevenness_variance
from calidar.strips.row_variance import posterior, rough_rows_variance, satterthwaite
from calidar.strips.unevenness_length import estimate_length
from calidar.strips.vgicp_kernels import cell_keys, near_cells, neighbourhood_moments, xy_bounds
from calidar.strips.vgicp_knn import GridKnn


class Grid:
    """Square xy cells (m) over a bounding box, with O(n) membership tests by lookup table."""

    MAX_TABLE = 50_000_000  #: beyond this many cells, membership falls back to sorting

    def __init__(self, xy_min: np.ndarray, xy_max: np.ndarray, cell: float):
        self.lo, self.cell = xy_min, cell
        self.shape = np.floor((xy_max - xy_min) / cell).astype(np.int64) + 1

    def ij(self, xy: np.ndarray) -> np.ndarray:
        return np.floor((xy - self.lo) / self.cell).astype(np.int64)

    @property
    def size(self) -> int:
        return int(self.shape[0] * self.shape[1])

    def keys(self, ij: np.ndarray) -> np.ndarray:
        return ij[:, 0] * self.shape[1] + ij[:, 1]

    def isin(self, keys: np.ndarray, marked: np.ndarray) -> np.ndarray:
        """Which ``keys`` are among the ``marked`` cell keys."""
        if self.size > self.MAX_TABLE:
            return np.isin(keys, marked)
        table = np.zeros(self.size, bool)
        table[marked] = True
        return table[keys]

    def first(self, keys: np.ndarray) -> np.ndarray:
        """Index of the first of ``keys`` in each occupied cell, ascending."""
        if self.size > self.MAX_TABLE:
            return np.sort(np.unique(keys, return_index=True)[1])
        first = np.full(self.size, keys.size)
        np.minimum.at(first, keys, np.arange(keys.size))
        return np.sort(first[first < keys.size])

    def around(self, xy: np.ndarray) -> np.ndarray:
        """Keys of the cells holding ``xy`` and of their 8 neighbours (inside the grid)."""
        ij = self.ij(xy)
        steps = np.array([(i, j) for i in (-1, 0, 1) for j in (-1, 0, 1)])
        near = (ij[:, None, :] + steps).reshape(-1, 2)
        near = near[np.all((near >= 0) & (near < self.shape), axis=1)]
        return self.keys(near)


def near(points: np.ndarray, at: np.ndarray, radius: float) -> np.ndarray:
    """Indices of the points (m) that may lie within ``radius`` (m, in xy) of any of ``at``."""
    if len(points) and len(at):  # one pass each (strips.vgicp_kernels), the same indices
        lo, hi = xy_bounds(points)
        grid = Grid(lo, hi, radius)
        if grid.size <= Grid.MAX_TABLE:
            return near_cells(cell_keys(points, lo, float(radius), grid.shape[1]), at, lo,
                              float(radius), grid.shape)
    grid = Grid(points[:, :2].min(axis=0), points[:, :2].max(axis=0), radius)
    return np.flatnonzero(grid.isin(grid.keys(grid.ij(points[:, :2])), grid.around(at[:, :2])))


@dataclass(frozen=True)
class LocalPlanes:
    """The surface of a cloud around M query points, each from its k nearest points (m)."""

    index: np.ndarray  #: (M, k) the neighbours
    distance: np.ndarray  #: (M, k) their distances, ascending, m
    centroid: np.ndarray  #: (M, 3) m
    #: (M, 3) of the scatter matrix Σ(p − centroid)(p − centroid)ᵀ, ascending, m²
    eigval: np.ndarray
    eigvec: np.ndarray  #: (M, 3, 3) its unit eigenvectors in columns; column 0 is the normal

    @property
    def normal(self) -> np.ndarray:
        return self.eigvec[:, :, 0]

    @property
    def variation(self) -> np.ndarray:
        """Surface variation λ_min / Σλ."""
        return self.eigval[:, 0] / np.maximum(self.eigval.sum(axis=1), 1e-300)

    @property
    def spread(self) -> np.ndarray:
        """√(λ_mid / λ_max): 1 for a disc of points, ≈ 0 for points along a line."""
        return np.sqrt(np.clip(self.eigval[:, 1], 0, None) / np.maximum(self.eigval[:, 2], 1e-300))

    @property
    def scatter(self) -> np.ndarray:
        """RMS of the points off their plane (m; 3 parameters fitted)."""
        return np.sqrt(np.clip(self.eigval[:, 0], 0, None) / max(self.index.shape[1] - 3, 1))

    def leverage(self, at: np.ndarray) -> np.ndarray:
        """Variance of the fitted plane's height at ``at`` (M, 3) m, in units of the points' σ²:
        1/k + Σ_j ((at − centroid)·e_j)² / λ_j over the two in-plane axes (least-squares
        prediction)."""
        d = np.einsum("mi,mij->mj", at - self.centroid, self.eigvec[:, :, 1:])
        in_plane = np.sum(d**2 / np.maximum(self.eigval[:, 1:], 1e-300), axis=1)
        return 1.0 / self.index.shape[1] + in_plane


def nearest(points: np.ndarray, at: np.ndarray, k: int, num_threads: int,
            tree=None) -> tuple[np.ndarray, np.ndarray]:
    """The k nearest of ``points`` to each of ``at`` (both (·, 3) m): indices (M, k) int64 and
    distances (M, k) m, ascending (``tree``: their small_gicp KdTree or
    :class:`~calidar.strips.vgicp_knn.GridKnn`, a KdTree built here when None)."""
    tree = small_gicp.KdTree(points, num_threads=num_threads) if tree is None else tree
    idx, d2 = tree.batch_knn_search(at, k, num_threads=num_threads)
    return idx.astype(np.int64), np.sqrt(d2)


def local_planes(points: np.ndarray, at: np.ndarray, k: int, num_threads: int,
                 tree=None) -> LocalPlanes:
    """The surface of ``points`` around each of ``at`` (both (·, 3) m) from its k nearest points
    (:func:`nearest`)."""
    idx, distance = nearest(points, at, k, num_threads, tree)
    centroid, scatter = neighbourhood_moments(points, idx)
    eigval, eigvec = eigh3(scatter)  # ascending
    return LocalPlanes(idx, distance, centroid, eigval, eigvec)


def _balanced(planes: LocalPlanes, centre: np.ndarray, mean_a: np.ndarray,
              max_offset: float) -> np.ndarray:
    """Whether b's centroid lies within ``max_offset`` × the radius of the ``centre`` (M, 3) m about
    which its neighbours were found, and a's mean as near b's centroid, in b's plane: neither
    strip's points stop inside the ball."""
    def in_plane(d):
        along = np.einsum("ij,ij->i", d, planes.normal)[:, None] * planes.normal
        return np.linalg.norm(d - along, axis=1)

    limit = max_offset * planes.distance[:, -1]
    return ((in_plane(planes.centroid - centre) <= limit)
            & (in_plane(mean_a - planes.centroid) <= limit))


def _ball_means(points: np.ndarray, at: np.ndarray, radius: np.ndarray, k_max: int
                ) -> tuple[sp.csr_matrix, np.ndarray]:
    """Averaging weights (M, len(points)) over the points (m) within ``radius`` (M,) m of each
    of ``at`` (M, 3) m — at most the k_max nearest, and at least the nearest — and their counts
    (M,)."""
    k_max = min(k_max, points.shape[0])
    weights, columns, indptr, count = GridKnn(points).ball_rows(at, k_max, radius**2)
    return sp.csr_matrix((weights, columns, indptr), shape=(at.shape[0], points.shape[0])), count


def _along_normal_variance(A: sp.csr_matrix, points: np.ndarray, mean: np.ndarray,
                           normal: np.ndarray) -> np.ndarray:
    """Per row of the averaging matrix A (M, len(points)): the variance (m², n − 1 degrees of
    freedom; 0 for one point) along ``normal`` (M, 3) of the row's points (m) about their ``mean``
    (M, 3) m."""
    count = np.diff(A.indptr)
    row = np.repeat(np.arange(A.shape[0]), count)
    take = np.take  # (fancy indexing's rows, faster)
    d = np.einsum("ij,ij->i", take(points, A.indices, axis=0) - take(mean, row, axis=0),
                  take(normal, row, axis=0))
    return np.bincount(row, d**2, A.shape[0]) / np.maximum(count - 1, 1)


def _tilt_cofactor(A: sp.csr_matrix, points: np.ndarray, mean: np.ndarray, eigval: np.ndarray,
                   eigvec: np.ndarray) -> np.ndarray:
    """Per row of the averaging matrix A (M, len(points)), of b's plane with scatter ``eigval``
    (M, 3) m² along ``eigvec`` (M, 3, 3; :class:`LocalPlanes`): t =
    Σ_j Σ_i ((p_i − p̄)·e_j)² / ((n − 1)·λ_j) over b's two in-plane axes e_j (λ_j b's scatter
    along them, m²), for the row's n points p_i (m) about their ``mean`` p̄ (M, 3) m; 0 for one
    point. a's scatter along b's fitted normal about a's mean holds, besides a's own noise, b's
    normal's error (variance s_b²/λ_j about e_j) times a's spread in the plane: E[s_a²] = τ_a² +
    τ_b²·t. a's mean does not carry it (issue 26, twelfth session)."""
    count = np.diff(A.indptr)
    row = np.repeat(np.arange(A.shape[0]), count)
    p = np.take(points, A.indices, axis=0) - np.take(mean, row, axis=0)
    t = np.zeros(A.shape[0])
    for j in (1, 2):
        along = np.einsum("ij,ij->i", p, np.take(eigvec[:, :, j], row, axis=0))
        t += np.bincount(row, along**2, A.shape[0]) / np.maximum(eigval[:, j], 1e-300)
    return t / np.maximum(count - 1, 1)


def plane_rows(centre: np.ndarray, b_near: np.ndarray, tree_b, ov_a: np.ndarray, keep: np.ndarray,
               density_ratio: float, settings) -> tuple:
    """The point-to-plane rows about the ``centre`` (M, 3) m of b's ``num_neighbors`` nearest points
    to each candidate (``keep``: b's nearest close enough).

    b_near: b's points near the candidates, registered onto a (m), ``tree_b`` their search; ov_a:
    a's overlap points (m); density_ratio: a's points per b's; settings:
    :class:`~calidar.strips.vgicp.VgicpSettings`. Returns b's planes found again, the averaging
    matrix of a's balls over ``ov_a[near_a]``, near_a, the rows kept, their normals, σ (m;
    ``settings.sigma_m`` when set), the degrees of freedom of σ² (inf when set) and the
    unevenness's fit (:class:`~calidar.strips.unevenness_length.UnevennessFit`; None unless ℓ is
    estimated: ``unevenness_length_m`` None).
    """
    k = settings.num_neighbors  # b's k nearest again, about their centroid (the module docstring)
    planes = local_planes(b_near, centre, k, settings.num_threads, tree_b)
    # a's points in a ball as large about b's centroid (room for a denser a)
    radius = planes.distance[:, -1]
    near_a = near(ov_a, planes.centroid, float(radius[keep].max()))
    a_near = np.take(ov_a, near_a, axis=0)  # gathered once
    k_max = int(np.ceil(2 * k * max(1.0, density_ratio)))
    A, count = _ball_means(a_near, planes.centroid, radius, k_max)
    mean_a = A @ a_near
    off_plane = np.abs(np.einsum("ij,ij->i", mean_a - planes.centroid, planes.normal))
    keep = keep & (planes.variation < settings.max_surface_variation)
    keep &= off_plane < settings.max_plane_distance_m
    keep &= planes.spread >= settings.min_spread
    keep &= _balanced(planes, centre, mean_a, settings.max_centroid_offset)
    # a's ball about b's plane: its own scatter along b's normal, at most max_scatter_ratio × b's
    var_a = _along_normal_variance(A, a_near, mean_a, planes.normal)
    var_b = np.zeros(keep.size)
    var_b[keep] = moderated_variance(planes.scatter[keep] ** 2, k - 3)
    keep &= var_a <= settings.max_scatter_ratio**2 * np.maximum(var_b, settings.min_scatter_m**2)
    sigma, dof, fit = settings.sigma_m, np.inf, None
    if sigma is None:  # a's mean with a's scatter, b's plane where a's mean lies with b's
        tilt = _tilt_cofactor(A[keep], a_near, mean_a[keep], planes.eigval[keep],
                              planes.eigvec[keep])
        uneven, b_rows, length = None, b_near[planes.index[keep]], settings.unevenness_length_m
        if length is None:  # ℓ read from b's neighbourhoods
            fit = estimate_length(b_rows, planes.centroid[keep], planes.eigvec[keep],
                                  settings.unevenness_quantile)
            length = fit.length_m
        if length > 0:  # how a's ball and b's plane sample the unevenness (its rough rows')
            uneven = partial(sampling_cofactors, A[keep], a_near, b_rows, planes.centroid[keep],
                             planes.eigval[keep], planes.eigvec[keep], length)
        sigma, dof = row_sigma(var_a[keep], count[keep], planes.scatter[keep] ** 2, k - 3,
                               planes.leverage(mean_a)[keep], settings, tilt, uneven)
    return planes, A, near_a, keep, planes.normal[keep], sigma, dof, fit


def row_sigma(var_a: np.ndarray, count_a: np.ndarray, var_b: np.ndarray, dof_b: float,
              leverage: np.ndarray, settings,
              tilt_a: np.ndarray | None = None,
              uneven: tuple | None = None) -> tuple[np.ndarray, np.ndarray]:
    """σ (m) of a pair's rows and the degrees of freedom of σ², from each side's raw scatter
    variance along b's normal (m²; a's about its mean from ``count_a`` points, b's about its plane
    with ``dof_b``), each side's posterior under a prior fitted over the pair's rows, b's
    plane's ``leverage`` h at a's mean and a's ``tilt_a`` cofactor t (:func:`_tilt_cofactor`;
    None: 0): σ² = s_a²/n_a + s_b²·max(h − t/n_a, 0) + κ·ρ² + ``noise_floor_m``² — s_a² holds
    b's normal's error, τ_b²·t, which a's mean does not (see the module docstring) — plus, with
    ``uneven`` (rows → their Q, g_a, g_b: :func:`calidar.strips.row_sampling.
    sampling_cofactors`), the unevenness's part recounted as the two sides sample it
    (:func:`calidar.strips.row_sampling.unevenness_variance`)."""
    var_a, nu_a = posterior(var_a, count_a - 1)
    var_b, nu_b = posterior(var_b, dof_b)
    rough, nu_rough = rough_rows_variance(var_a, nu_a, var_b, nu_b, settings.roughness_factor,
                                          settings.roughness_quantile)
    if tilt_a is not None:
        leverage = np.maximum(leverage - tilt_a / count_a, 0.0)
    parts = [var_a / count_a, var_b * leverage, rough,
             np.full(nu_a.size, settings.noise_floor_m**2)]
    dofs = [nu_a, nu_b, nu_rough, np.inf]
    if uneven is not None:
        extra, nu_extra = unevenness_variance(var_a, count_a - 1.0, var_b, dof_b,
                                              parts[0] + parts[1], uneven,
                                              settings.unevenness_quantile)
        parts.append(extra)
        dofs.append(nu_extra)
    return np.sqrt(np.sum(parts, axis=0)), satterthwaite(parts, dofs)
