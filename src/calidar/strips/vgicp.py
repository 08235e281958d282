"""Corresponding points between two strips from VGICP registration (small_gicp).

For one overlapping pair: register strip b to strip a with voxelized GICP (Koide et al.,
"Voxelized GICP for fast and accurate 3D point cloud registration", ICRA 2021, through
small_gicp, the author's maintained implementation), apply the transform to b, and take
nearest-neighbour pairs closer than a threshold as corresponding ("same-name") points.
The pairs index the *un-registered* strips, so the calibrator's residual
``A·P_a(θ) − B·P_b(θ)`` measures what the mounting parameters must remove.

Residual kinds (see :mod:`calidar.strips.correspond`):

- ``point_to_plane`` (default): the distance ``n_b · (c_a − c_b)`` of the centroid ``c_a`` of
  a's points in a ball from b's local plane (centroid ``c_b``, normal ``n_b``: the smallest
  eigenvector of the covariance of b's k nearest points). Both sides average the same piece of
  surface, as a tie plane does; a single point of a against b's plane would carry the plane's
  curvature error (a centroid lies inside a curved surface by ≈ κr²/4). A row is kept only
  where b's neighbourhood is a plane (``max_surface_variation``: λ_min/Σλ; ``min_spread``:
  √(λ_mid/λ_max), so that one scan line across a wall is not taken for one), a's centroid lies
  near it (``max_plane_distance_m``) and on it as closely as b's own points
  (``max_scatter_ratio``), and neither side's points stop inside the ball
  (``max_centroid_offset``, in radii: where they do, the two centroids part along the plane
  and b's normal error times that lever biases residual and Jacobian alike). Each side's
  scatter along the normal enters the row's σ (:mod:`calidar.strips.vgicp_planes`).
- ``point_to_point``: the 3-D difference of the pair, as the method describes; its noise
  includes the point spacing.

Registration runs the finest stage of ``VgicpSettings.voxel_m`` first, and coarse to fine over
them only where that stage does not lock in, so that a start far from the truth (metres of strip
offset) still does; an overlap narrower than
``min_registration_width_m`` cannot fix the rotation about its long axis and is matched as it
lies. All lengths are metres, in the local Cartesian frame of the points.

What each of these tests was measured to fix: docs/validation.md, "VGICP's rows: each test and
the measurement behind it".
"""

from __future__ import annotations

import time
from dataclasses import dataclass

import numpy as np
import scipy.sparse as sp
import small_gicp

from calidar.errors import CalibrationError
from calidar.strips.correspond import Correspondences
from calidar.strips.vgicp_kernels import (cell_keys, common_cells, first_in_cells, gather_centred,
                                          neighbourhood_centroids, rows_mean, xy_bounds,
                                          xy_scatter)
from calidar.strips.vgicp_knn import GridKnn
from calidar.strips.vgicp_planes import Grid, near, nearest, plane_rows
from calidar.strips.voxel_downsample import voxel_downsample

KINDS = ("point_to_plane", "point_to_point")


@dataclass(frozen=True)
class VgicpSettings:
    """Settings of VGICP matching (lengths in metres)."""

    kind: str = "point_to_plane"  #: "point_to_plane" | "point_to_point"
    voxel_m: tuple[float, ...] = (8.0, 2.0, 1.0)  #: VGICP voxel sizes, coarse to fine
    downsampling_ratio: float = 0.5  #: registration downsampling = ratio × voxel size ...
    max_registration_points: int = 10_000  #: ... coarsened so the overlap holds about this many
    num_neighbors: int = 12  #: neighbours of b's local planes (the rows)
    #: neighbours of the registration clouds' covariances (small_gicp's ``align`` takes 10: what
    #: 10 here would change, docs/validation.md, issue 32, twelfth session)
    registration_neighbors: int = 12
    max_iterations: int = 30  #: per registration stage
    #: a stage has converged when its last step turned less than this (rad) ...
    rotation_epsilon_rad: float = 1e-5
    translation_epsilon_m: float = 1e-4  #: ... and moved less than this (m)
    #: the finest stage alone is kept where it converged with at least this fraction of b's
    #: registration points on a's voxels; else coarse to fine over ``voxel_m`` from the start
    min_inlier_fraction: float = 0.5
    overlap_cell_m: float = 10.0  #: xy cell of the overlap test (coarse enough for sparse strips)
    min_overlap_points: int = 500  #: fewer points of either strip in the overlap → skip
    #: max pair distance after registration; None: 1.5 × b's point spacing
    pair_distance_m: float | None = None
    max_pairs: int = 2000  #: at most this many correspondences per strip pair, spread on an xy grid
    min_pairs: int = 50  #: fewer usable pairs → the pair is skipped
    max_surface_variation: float = 0.003  #: point_to_plane: λ_min / Σλ of the local covariance
    #: point_to_plane: √(λ_mid / λ_max) of b's neighbourhood at least — its points span a plane, not
    #: a line (a disc: 1; one scan line across a wall: ≈ 0, and its normal is then any direction
    #: about the line)
    min_spread: float = 0.3
    #: point_to_plane: max distance of a's mean from b's plane after registration
    max_plane_distance_m: float = 0.3
    #: point_to_plane: a's ball points scatter along b's normal at most this many times b's plane
    #: scatter (its σ, moderated over the pair, or ``min_scatter_m``): a ball reaching over a ridge,
    #: an eave or a wall's foot is not b's plane
    max_scatter_ratio: float = 3.0
    #: overlaps narrower than this (m, across their long axis) are matched as they lie, not
    #: registered: a sliver cannot fix the rotation about its long axis (a 5 m × 120 m one
    #: registered 1.1 m and 1.5° off at the truth)
    min_registration_width_m: float = 20.0
    #: point_to_plane: max in-plane distance of either strip's centroid from the neighbourhood's
    #: centre, in units of its radius (a full disc of 12 points: 0.14 per axis; one cut by an edge
    #: of the points: ≥ 0.4)
    max_centroid_offset: float = 0.35
    #: a-priori σ of one residual; None: from b's plane scatter (point_to_plane) or 5 cm
    sigma_m: float | None = None
    #: added to the rows' σ in quadrature, every row alike (UAV rows fit 0 with the roughness term;
    #: with ``unevenness_length_m`` the UAV cross-line rows at the truth read RMS z 0.92–1.02 by σ
    #: quartile with 2 mm, 0.98–1.06 with 1 mm, 1.00–1.08 with 0: docs/validation.md, issue 26,
    #: thirteenth session)
    noise_floor_m: float = 0.001
    #: point_to_plane: κ of the rough rows' model error κ·ρ² in σ², ρ² a row's scatter beyond the
    #: pair's ``roughness_quantile`` (:func:`calidar.strips.row_variance.rough_rows_variance`).
    #: UAV rows fit 0.9 with ``noise_floor_m`` 0 (variance components, 6 simulated surveys), which
    #: helps opposite lines but not cross lines' pitch, urban scenes or airborne rows (these fit
    #: 0): so 0 by default (docs/validation.md, issue 26, ninth session)
    roughness_factor: float = 0.0
    roughness_quantile: float = 0.75
    #: point_to_plane: correlation length (m) of the surface's unevenness, R(d) = exp(−d²/2ℓ²),
    #: with which a row's scatter beyond the pair's ``unevenness_quantile`` is recounted as a's
    #: ball and b's plane sample it (:mod:`calidar.strips.row_sampling`); 0: taken as white;
    #: None: estimated from b's neighbourhoods (:mod:`calidar.strips.unevenness_length`): per
    #: pair at the first matching pass, then pooled over the survey and fixed here by the run
    unevenness_length_m: float | None = None
    unevenness_quantile: float = 0.5
    #: point_to_plane: b's scatter in ``max_scatter_ratio``'s test at least this (m)
    min_scatter_m: float = 0.002
    num_threads: int = 1  #: small_gicp threads (1 is bit-reproducible; see docs)

    def __post_init__(self):
        if self.kind not in KINDS:
            raise ValueError(f"kind must be one of {KINDS}, got {self.kind!r}")
        if not self.voxel_m or any(v <= 0 for v in self.voxel_m):
            raise ValueError(f"voxel_m must be positive sizes, got {self.voxel_m}")
        if self.roughness_factor < 0.0:
            raise ValueError(f"roughness_factor must be ≥ 0, got {self.roughness_factor}")
        if not 0.0 <= self.roughness_quantile <= 1.0:
            raise ValueError(f"roughness_quantile must be 0 … 1, got {self.roughness_quantile}")
        if self.unevenness_length_m is not None and self.unevenness_length_m < 0.0:
            raise ValueError(f"unevenness_length_m must be ≥ 0, got {self.unevenness_length_m}")
        if not 0.0 <= self.unevenness_quantile <= 1.0:
            raise ValueError(f"unevenness_quantile must be 0 … 1, got {self.unevenness_quantile}")
        if not 0.0 <= self.min_inlier_fraction <= 1.0:
            raise ValueError(f"min_inlier_fraction must be 0 … 1, got {self.min_inlier_fraction}")


@dataclass(frozen=True)
class Registration:
    """Rigid transform of strip b onto strip a, and how well it fits."""

    T_ab: np.ndarray  #: (4, 4) maps b's points onto a (local frame, m)
    converged: bool
    iterations: int
    num_inliers: int


class _Clock:
    """Accumulates this process's CPU seconds per stage into a dict (or does nothing for None): on
    a shared machine the CPU a stage takes, not the wall clock it waited."""

    def __init__(self, timings: dict[str, float] | None):
        self.timings, self.t = timings, time.process_time()

    def lap(self, stage: str) -> None:
        if self.timings is not None:
            now = time.process_time()
            self.timings[stage] = self.timings.get(stage, 0.0) + now - self.t
            self.t = now


def overlap_masks(points_a: np.ndarray, points_b: np.ndarray,
                  cell_m: float) -> tuple[np.ndarray, np.ndarray, float]:
    """Points of a and b in xy cells (size cell_m, m) occupied by both; also the overlap (m²)."""
    if len(points_a) and len(points_b):  # one pass each (strips.vgicp_kernels), the same cells
        (lo_a, hi_a), (lo_b, hi_b) = xy_bounds(points_a), xy_bounds(points_b)
        lower = np.minimum(lo_a, lo_b)
        grid = Grid(lower, np.maximum(hi_a, hi_b), cell_m)
        if grid.size <= Grid.MAX_TABLE:
            ncol, cell = grid.shape[1], float(cell_m)
            in_a, in_b, common = common_cells(cell_keys(points_a, lower, cell, ncol),
                                              cell_keys(points_b, lower, cell, ncol), grid.size)
            return in_a, in_b, common * cell_m**2
    xy_a, xy_b = points_a[:, :2], points_b[:, :2]
    lower = np.minimum(xy_a.min(axis=0), xy_b.min(axis=0))
    grid = Grid(lower, np.maximum(xy_a.max(axis=0), xy_b.max(axis=0)), cell_m)
    ka, kb = grid.keys(grid.ij(xy_a)), grid.keys(grid.ij(xy_b))
    common = ka[grid.first(ka)]  # occupied cells of a ...
    common = common[grid.isin(common, kb)]  # ... also occupied by b
    return grid.isin(ka, common), grid.isin(kb, common), common.size * cell_m**2


def registration_stages(settings: VgicpSettings, area_m2: float) -> list[tuple[float, float]]:
    """(voxel, downsampling) m of each registration stage, coarse to fine: ``settings.voxel_m``
    with the downsampling coarsened so the overlap (area_m2) holds about
    ``max_registration_points``; sparse data merge the finest stages into one."""
    min_down = np.sqrt(area_m2 / settings.max_registration_points)
    stages = []
    for voxel in sorted(settings.voxel_m, reverse=True):  # coarse to fine, however given
        down = max(settings.downsampling_ratio * voxel, min_down)
        stage = (max(voxel, 2.0 * down), down)
        if stage not in stages:
            stages.append(stage)
    return stages


def _preprocess(points: np.ndarray, down: float, settings: VgicpSettings):
    """The points (N, 3) m downsampled to ``down`` m voxels (small_gicp's voxels at ≈ 1/6 of its
    CPU: :mod:`~calidar.strips.voxel_downsample`) as a small_gicp cloud with its points'
    covariances (``registration_neighbors``), as small_gicp's ``preprocess_points`` sets them."""
    cloud = small_gicp.PointCloud(voxel_downsample(points, down))
    tree = small_gicp.KdTree(cloud, settings.num_threads)
    small_gicp.estimate_covariances(cloud, tree, settings.registration_neighbors,
                                    settings.num_threads)
    return cloud


def _align(voxelmap, source, voxel: float, T: np.ndarray, settings: VgicpSettings):
    """One VGICP stage: b's cloud onto a's voxel map from T, correspondences up to 2 voxels."""
    return small_gicp.align(voxelmap, source, T, max_correspondence_distance=2.0 * voxel,
                            num_threads=settings.num_threads,
                            max_iterations=settings.max_iterations,
                            rotation_epsilon=settings.rotation_epsilon_rad,
                            translation_epsilon=settings.translation_epsilon_m)


def locked_in(result, n_source: int, settings: VgicpSettings) -> bool:
    """Did a stage find the minimum its voxels reach: converged, and at least
    ``min_inlier_fraction`` of b's points with a's voxel within reach?"""
    return bool(result.converged) and result.num_inliers >= settings.min_inlier_fraction * n_source


def register(points_a: np.ndarray, points_b: np.ndarray, settings: VgicpSettings, area_m2: float,
             clock=None) -> Registration:
    """VGICP registration of b onto a: the finest of ``settings.voxel_m`` first; coarse to fine
    from the start again only where that stage did not lock in (:func:`locked_in`).

    Points are (N, 3) metres, best centred near the origin (small_gicp discretises at 21 bits);
    area_m2 is the overlap's area, which bounds the downsampled cloud sizes. The strips come
    with the current parameters, within decimetres of each other after the nominal mounting and
    within millimetres on later outer iterations; the finest stage then reaches the same minimum
    as the coarse-to-fine ladder, at the cost of one stage (docs/validation.md, issue 32, eighth
    session). Each cloud is downsampled once at the finest resolution; its covariances and a's
    voxel map serve the finest stage on either path. ``clock`` (optional) gets "preprocess" and
    "register" laps.
    """
    clock = clock or _Clock(None)
    stages = registration_stages(settings, area_m2)
    voxel, down = stages[-1]
    fine_a, fine_b = _preprocess(points_a, down, settings), _preprocess(points_b, down, settings)
    voxelmap = small_gicp.GaussianVoxelMap(voxel)
    voxelmap.insert(fine_a)
    clock.lap("preprocess")
    result = _align(voxelmap, fine_b, voxel, np.eye(4), settings)
    clock.lap("register")
    if len(stages) > 1 and not locked_in(result, fine_b.size(), settings):
        T = np.eye(4)  # the start was beyond the finest stage's reach: coarse to fine from it
        for coarse_voxel, coarse_down in stages[:-1]:
            target = _preprocess(fine_a.points()[:, :3], coarse_down, settings)
            source = _preprocess(fine_b.points()[:, :3], coarse_down, settings)
            coarse_map = small_gicp.GaussianVoxelMap(coarse_voxel)
            coarse_map.insert(target)
            clock.lap("preprocess")
            T = np.asarray(_align(coarse_map, source, coarse_voxel, T, settings).T_target_source)
            clock.lap("register")
        result = _align(voxelmap, fine_b, voxel, T, settings)
        clock.lap("register")
    T = np.asarray(result.T_target_source)
    return Registration(T, bool(result.converged), int(result.iterations), int(result.num_inliers))


def _spread(points: np.ndarray, n_max: int, area_m2: float) -> np.ndarray:
    """Indices of at most ~n_max points spread evenly in xy (one per grid cell, deterministic)."""
    if points.shape[0] <= n_max:
        return np.arange(points.shape[0])
    lo, hi = xy_bounds(points)
    grid = Grid(lo, hi, np.sqrt(area_m2 / n_max))
    if grid.size <= Grid.MAX_TABLE:  # one pass (strips.vgicp_kernels), the same indices
        first = first_in_cells(cell_keys(points, lo, float(grid.cell), grid.shape[1]), grid.size)
    else:
        first = grid.first(grid.keys(grid.ij(points[:, :2])))
    if first.size > n_max:  # ragged overlap outline: thin regularly
        first = first[np.linspace(0, first.size - 1, n_max).astype(np.int64)]
    return first


def overlap_width(points: np.ndarray) -> float:
    """Width (m) of the points' xy footprint across its long axis: √12 × the smaller principal σ (a
    uniform strip)."""
    xy = points[:, :2] - points[:, :2].mean(axis=0)
    return float(np.sqrt(12.0 * max(np.linalg.eigvalsh(xy.T @ xy / max(len(xy), 1))[0], 0.0)))


def wide_enough(points: np.ndarray, width_m: float) -> bool:
    """``overlap_width(points) >= width_m`` (m), from one numba pass over the points
    (:func:`~calidar.strips.vgicp_kernels.xy_scatter`); within 1e-6 relative of ``width_m``, where
    its last bits could decide, by :func:`overlap_width` itself."""
    if len(points) == 0:
        return overlap_width(points) >= width_m
    sxx, sxy, syy = xy_scatter(points)
    half = 0.5 * (sxx - syy)
    low = 0.5 * (sxx + syy) - np.sqrt(half * half + sxy * sxy)  # the smaller eigenvalue, m²
    width = np.sqrt(12.0 * max(low, 0.0))
    if abs(width - width_m) <= 1e-6 * width_m:
        return overlap_width(points) >= width_m
    return bool(width >= width_m)


def _overlap_crop(points_a: np.ndarray, points_b: np.ndarray, settings: VgicpSettings) -> tuple:
    """The points (N, 3) m of a and of b in the overlap's cells (:func:`overlap_masks`): each
    side's indices and points, centred on a's mean there, and the overlap's area (m²). Raises
    CalibrationError where either side has fewer than ``min_overlap_points`` there."""
    in_a, in_b, area = overlap_masks(points_a, points_b, settings.overlap_cell_m)
    n_a, n_b = int(in_a.sum()), int(in_b.sum())
    if min(n_a, n_b) < settings.min_overlap_points:
        raise CalibrationError(f"too little overlap for VGICP ({n_a} and {n_b} points in "
                               f"{area:.0f} m², need {settings.min_overlap_points} of each strip)")
    idx_a, idx_b = np.flatnonzero(in_a), np.flatnonzero(in_b)
    origin = rows_mean(points_a, idx_a)  # numpy's mean of the rows, without gathering them first
    return (idx_a, gather_centred(points_a, idx_a, origin), idx_b,
            gather_centred(points_b, idx_b, origin), area)


def match_pair_vgicp(strip_a_id: int, points_a: np.ndarray, strip_b_id: int, points_b: np.ndarray,
                     settings: VgicpSettings | None = None,
                     timings: dict[str, float] | None = None) -> Correspondences:
    """Corresponding points of strips a and b by VGICP registration + nearest neighbours.

    points_a, points_b: (N, 3) float64, the strips re-georeferenced with the current
    parameters in a local Cartesian frame (m); settings None → :class:`VgicpSettings`.
    Returns at most ``settings.max_pairs`` correspondences spread over the overlap: one point
    of a and b's nearest point (point_to_point), or the ``num_neighbors`` nearest points of b
    around a point of a (found again about their centroid) with their plane's normal and the
    points of a in a ball as large about b's centroid (point_to_plane); A and B average them. Raises
    CalibrationError (the calibrator skips the pair with a warning naming it) when either strip has
    fewer than ``min_overlap_points`` in the overlap or fewer than ``min_pairs`` pairs are found.
    ``timings``, when given, accumulates the CPU seconds spent per stage ("preprocess", "register",
    "correspond").
    """
    settings = settings or VgicpSettings()
    clock = _Clock(timings)
    points_a = np.asarray(points_a, dtype=np.float64)
    points_b = np.asarray(points_b, dtype=np.float64)
    idx_a, ov_a, idx_b, ov_b, area = _overlap_crop(points_a, points_b, settings)
    n_a, n_b = len(idx_a), len(idx_b)
    clock.lap("preprocess")
    if wide_enough(ov_a, settings.min_registration_width_m):
        reg = register(ov_a, ov_b, settings, area, clock)
    # a sliver: the strips as they lie (the outer loop has brought them close by the other pairs)
    else:
        reg = Registration(np.eye(4), True, 0, 0)
    R, t = reg.T_ab[:3, :3], reg.T_ab[:3, 3]
    b_on_a = ov_b @ R.T + t

    cand = _spread(ov_a, settings.max_pairs, area)
    # 1.5 × b's mean point spacing, m
    threshold = settings.pair_distance_m or 1.5 * np.sqrt(area / len(idx_b))
    # only points near the candidates enter the KdTree: the nearest within the threshold and
    # the k nearest of b (≈ 2 spacings, about a centroid ≲ 1 spacing off the candidate) lie
    # within it
    near_b = near(b_on_a, ov_a[cand], max(threshold, 4.0 * np.sqrt(area / len(idx_b))))
    k = settings.num_neighbors if settings.kind == "point_to_plane" else 1
    if near_b.size < k:  # (small_gicp aborts on an empty tree)
        raise CalibrationError(f"too few VGICP correspondences: registration left {near_b.size} "
                               f"points of b near a's points (need {settings.min_pairs} pairs)")
    b_near = np.take(b_on_a, near_b, axis=0)
    tree_b = GridKnn(b_near)  # small_gicp's KdTree's neighbours, without its build's cost
    index, distance = nearest(b_near, ov_a[cand], k, settings.num_threads, tree_b)
    keep = distance[:, 0] < threshold
    sigma, dof = (0.05 if settings.sigma_m is None else settings.sigma_m), np.inf
    normal = fit = None
    if settings.kind == "point_to_plane" and keep.any():  # b's planes about their centroids
        planes, A, near_a, keep, normal, sigma, dof, fit = plane_rows(
            neighbourhood_centroids(b_near, index), b_near, tree_b, ov_a, keep, n_a / n_b, settings)
        index = planes.index
    n_pairs = int(keep.sum())
    if n_pairs < settings.min_pairs:
        where = " on planar surfaces" if settings.kind == "point_to_plane" else ""
        raise CalibrationError(f"too few VGICP correspondences ({n_pairs} closer than "
                               f"{threshold:.2f} m{where} after registration, need "
                               f"{settings.min_pairs})")
    if settings.kind == "point_to_point":
        A = sp.csr_matrix((np.ones(n_pairs), (np.arange(n_pairs), idx_a[cand[keep]])),
                          shape=(n_pairs, points_a.shape[0]))
    else:  # columns: the ball's points of a among all of a's points
        A = A[keep]
        A = sp.csr_matrix((A.data, idx_a[near_a[A.indices]], A.indptr),
                          shape=(n_pairs, points_a.shape[0]))
    columns_b = idx_b[near_b[index[keep]]].ravel()  # each row's k nearest of b
    B = sp.csr_matrix((np.full(n_pairs * k, 1.0 / k), columns_b, np.arange(n_pairs + 1) * k),
                      shape=(n_pairs, points_b.shape[0]))
    clock.lap("correspond")
    return Correspondences(strip_a_id, strip_b_id, A, B, normal, sigma_m=sigma, method="vgicp",
                           dof=dof, unevenness=None if fit is None else fit.to_dict(),
                           unevenness_surface=None if fit is None else fit.surface)
