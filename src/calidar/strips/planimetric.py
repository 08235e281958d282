"""Planimetric offset of one strip against another, estimated jointly with the height difference's
tilt.

On the overlap cells where both strips fit a plane, the difference of the two planes' heights at
the cell centre is, to first order in a horizontal shift d = (dx, dy) of strip a relative to b, a
vertical offset and a tilt (tx, ty) of a relative to b:

    dz_k = c_block(k) + tx·(x_k − x̄) + ty·(y_k − ȳ) − dx·∂z/∂x_k − dy·∂z/∂y_k + e_k

(a surface seen shifted by d has z_a(p) = z_b(p − d) ≈ z_b(p) − d·∇z, exact on a plane). The
vertical offset c is free per block of ``block_m`` (20 m): a trajectory's vertical error wanders
along a strip, and over a hill whose slope follows the position such a wander reads as a shift
(main's 2–3 dy −0.263 ± 0.004 m on the issue's survey); only slopes that vary within a block
separate d from it. The tilt stays global. Solved by least squares within the blocks (Frisch–Waugh)
with 3·MAD rejection, the gradients' own noise taken out of the normal equations (errors in
variables, Fuller 1987, Measurement Error Models §2.2), on cells inside planar facets (a fold in a
cell biases its slope against its height: :func:`inside_facets`). dx, dy are reported only where
the true slopes' spread within the blocks is large enough in both directions — otherwise "not
determined" with the reason (flat ground, slopes facing one way, slopes that only follow the
position) — and where enough blocks hold cells.

Uncertainty: the cells' residuals are neither independent nor of equal variance (roughness, folds,
the trajectory's slow errors make neighbouring cells err alike), so the formal σ of independent
cells is too small. Three estimates, each σ the largest: the formal one; the estimating functions
summed per block and correlated between blocks with product-Bartlett weights out to ``hac_m``
(Conley 1999, J. Econometrics 92:1–45; with L = 0 the cluster-robust CR1 of Liang & Zeger 1986,
Cameron & Miller 2015); and a delete-a-group jackknife over ``jackknife_groups`` stretches of the
overlap (Künsch 1989), which widens σ when the displacement itself varies along the strips
(:mod:`calidar.strips.planimetric_sigma`). docs/validation.md measures how honest the result is.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from calidar.cells import cell_keys_of, grid_indices
from calidar.strips.planimetric_sigma import (cluster_cov, formal_fit, groups_along, jackknife_cov,
                                              random_effects_mean)

SCALE_M = 100.0  #: positions enter the design in units of 100 m (tilts in m per 100 m internally)


@dataclass(frozen=True)
class PlanimetricSettings:
    """What makes the planimetric offsets determined (metres, degrees where named)."""

    max_slope_deg: float = 45.0  #: steeper planes (walls, their edges) are left out
    min_cells: int = 30
    #: slope (tan) σ within the blocks in the weakest direction (gradient noise ≪ this)
    min_slope_spread: float = 0.03
    min_sloped_cells: int = 10  #: information at least that of this many cells ...
    min_slope_deg: float = 15.0  #: ... sloped this much in each direction
    block_m: float = 20.0  #: blocks of the free vertical offsets and of the robust covariance
    min_blocks: int = 10
    #: blocks this close (Bartlett weights per axis) err together in the covariance
    hac_m: float = 100.0
    jackknife_groups: int = 5  #: groups of blocks along the overlap left out in turn (0: none)
    #: a vertical offset and tilt free per block (else an offset only; docs/validation.md)
    block_plane: bool = False
    #: a cell is inside a facet: its 4 neighbours' slopes (tan) within this
    max_neighbour_dslope: float = 0.1
    #: dx, dy as the mean of a displacement varying along the overlap (_random_effects)
    random_effects: bool = True
    groups_across: int = 3  #: ... its stretches each cut in this many parts across the overlap


@dataclass
class Planimetric:
    """The joint fit of one pair (a relative to b): offsets in m, tilts in m/m."""

    status: str  #: "determined" or "not determined"
    reason: str = ""
    dx_m: float | None = None
    dy_m: float | None = None
    sigma_dx_m: float | None = None
    sigma_dy_m: float | None = None
    corr_dxy: float | None = None
    dz0_m: float | None = None  #: vertical offset at the cells' centroid
    tilt_x: float | None = None  #: ∂dz/∂x (m/m)
    tilt_y: float | None = None
    sigma_tilt: float | None = None  #: the larger σ of the two tilts (m/m)
    n_cells: int = 0  #: cells fitted (after rejection)
    n_blocks: int = 0
    slope_spread: float | None = None  #: residual slope σ (tan) in the weakest direction

    def to_dict(self) -> dict:
        return dict(self.__dict__)


def gradients(normal: np.ndarray) -> np.ndarray:
    """Surface gradients (K, 2) ∂z/∂x, ∂z/∂y of planes with unit normals (K, 3), z up."""
    return -normal[:, :2] / normal[:, 2:3]


def gradient_noise(cov: np.ndarray, count: np.ndarray, normal: np.ndarray) -> np.ndarray:
    """Covariance (K, 2, 2) of the fitted planes' gradients from their cells' point covariances
    (K, 3, 3), counts and normals: σ²_z · (n · C_xy)⁻¹ for the least-squares slope, the vertical
    scatter σ²_z = λ_min / n_z² · n / (n − 3)."""
    lam = np.einsum("ki,kij,kj->k", normal, cov, normal)
    var_z = lam / normal[:, 2] ** 2 * count / np.maximum(count - 3, 1)
    from calidar.strips.inverse2 import inv2  # np.linalg.inv's bits, without its per-matrix cost

    return var_z[:, None, None] * inv2(cov[:, :2, :2]) / count[:, None, None]


def block_ids(centre: np.ndarray, block_m: float) -> tuple[np.ndarray, int]:
    """Block index (K,) of each cell on squares of ``block_m`` and the number of blocks (numbered
    as np.unique(axis=0) orders them; a dense table in numba when the blocks fit one)."""
    from calidar.strips.moments_kernel import dense_row_ids

    ij = grid_indices(centre, block_m)
    dense = dense_row_ids(ij)
    if dense is not None:
        return dense
    inv = np.unique(ij, axis=0, return_inverse=True)[1].ravel()
    return inv, int(inv.max()) + 1 if inv.size else 0


def within(values: np.ndarray, blocks: np.ndarray, n_blocks: int,
           centre: np.ndarray | None = None) -> np.ndarray:
    """``values`` (K, m) less what a vertical offset per block (with ``centre`` (K, 2) m: an offset
    and a tilt per block, a plane) explains: their least-squares residuals block by block."""
    v = values.reshape(len(values), -1)
    if centre is None:
        count = np.bincount(blocks, minlength=n_blocks)
        mean = np.stack([np.bincount(blocks, v[:, k], n_blocks) for k in range(v.shape[1])], axis=1)
        return (v - mean[blocks] / np.maximum(count, 1)[blocks, None]).reshape(values.shape)
    x = np.column_stack([np.ones(len(v)), centre - centre.mean(axis=0)])
    xx = np.zeros((n_blocks, 3, 3))
    np.add.at(xx, blocks, x[:, :, None] * x[:, None, :])
    xv = np.zeros((n_blocks, 3, v.shape[1]))
    np.add.at(xv, blocks, x[:, :, None] * v[:, None, :])
    # blocks whose cells lie on a line: their offset and the one slope
    coef = np.linalg.pinv(xx) @ xv
    return (v - np.einsum("ki,kim->km", x, coef[blocks])).reshape(values.shape)


def noise_moments(noise: np.ndarray, blocks: np.ndarray, n_blocks: int,
                  free: int = 1) -> np.ndarray:
    """Each cell's gradient-noise covariance (K, 2, 2) as it enters the within-block products: a
    block's ``free`` parameters (1: offset; 3: plane) take about free/m of it out (m cells in the
    block)."""
    m = np.bincount(blocks, minlength=n_blocks)[blocks]
    return noise * np.clip(1.0 - free / np.maximum(m, 1), 0.0, 1.0)[:, None, None]


def conditioning(grad: np.ndarray, noise: np.ndarray, blocks: np.ndarray, n_blocks: int,
                 centre: np.ndarray | None = None) -> tuple[float, np.ndarray]:
    """Smallest eigenvalue of the true slopes' covariance within the blocks (the information on dx,
    dy per cell once a vertical offset per block is free, in (m/m)², the gradients' own noise taken
    out) and the full 2 × 2 matrix."""
    r = within(grad, blocks, n_blocks, centre)
    moments = noise_moments(noise, blocks, n_blocks, 1 if centre is None else 3)
    s = (r.T @ r - moments.sum(axis=0)) / max(len(r), 1)
    return float(np.linalg.eigvalsh(s)[0]), s


def inside_facets(ij: np.ndarray, grad: np.ndarray, tolerance: float) -> np.ndarray:
    """Cells (K,) whose 4 neighbours (grid indices ij (K, 2)) are all there with gradients within
    ``tolerance``: inside a planar facet. A cell a fold crosses (a ridge, a hip, a slope's foot)
    fits a plane whose slope weights the cell's middle more than the height at its centre does (the
    least-squares slope is a parabola-weighted mean of the surface's slope, the shift's effect on
    the centre height an even mean): such cells bias dx, dy towards zero and are left out."""
    key = cell_keys_of(ij[:, 0], ij[:, 1])
    order = np.argsort(key)
    sk = key[order]
    ok = np.ones(len(key), bool)
    for di, dj in ((1, 0), (-1, 0), (0, 1), (0, -1)):
        nk = cell_keys_of(ij[:, 0] + di, ij[:, 1] + dj)
        at = np.clip(np.searchsorted(sk, nk), 0, len(sk) - 1)
        found = sk[at] == nk
        other = grad[order[at]]
        ok &= found & (np.hypot(*(other - grad).T) <= tolerance)
    return ok


def planimetric_offsets(centre: np.ndarray, dz: np.ndarray, grad: np.ndarray, cell_m: float,
                        settings: PlanimetricSettings | None = None,
                        noise: np.ndarray | None = None) -> Planimetric:
    """Joint fit of dz (K,) at the centres (K, 2) m of cells of ``cell_m`` with the planes'
    gradients (K, 2), whose noise covariances (K, 2, 2) (:func:`gradient_noise`; none: exact
    gradients) are taken out of the normal equations: a noisy regressor would shrink dx, dy towards
    zero (errors in variables; the moment correction of Fuller 1987, Measurement Error Models,
    §2.2)."""
    s = settings or PlanimetricSettings()
    noise = np.zeros((len(dz), 2, 2)) if noise is None else noise
    keep = np.hypot(grad[:, 0], grad[:, 1]) <= np.tan(np.radians(s.max_slope_deg))
    keep &= inside_facets(grid_indices(centre, cell_m), grad, s.max_neighbour_dslope)
    keep &= np.isfinite(dz) & np.all(np.isfinite(grad), axis=1)
    c, d, g, e = centre[keep], dz[keep], grad[keep], noise[keep]
    if d.size < s.min_cells:
        return Planimetric("not determined",
                           f"{d.size} planar cells inside facets shared (at least {s.min_cells} "
                           "needed)")
    blocks, n_blocks = block_ids(c, s.block_m)
    spread2, info = conditioning(g, e, blocks, n_blocks, c if s.block_plane else None)
    out = Planimetric("not determined", slope_spread=float(np.sqrt(max(spread2, 0.0))))
    needed = s.min_sloped_cells * np.tan(np.radians(s.min_slope_deg)) ** 2
    if spread2 < s.min_slope_spread**2 or spread2 * d.size < needed:
        w, v = np.linalg.eigh(info)
        weak = np.degrees(np.arctan2(v[1, 0], v[0, 0])) % 180.0
        out.reason = (f"the slopes do not constrain both directions: within {s.block_m:g} m blocks "
                      f"their spread across the {weak:.0f}° direction (x east, counter-clockwise) "
                      f"is {out.slope_spread:.3f} (tan) over {d.size} cells (needed ≥ "
                      f"{s.min_slope_spread:g} and the weight of {s.min_sloped_cells} cells of "
                      f"{s.min_slope_deg:g}°)")
        return out
    return _fit(c, d, g, e, blocks, n_blocks, s, out)


def _fit(c: np.ndarray, d: np.ndarray, g: np.ndarray, e: np.ndarray, blocks: np.ndarray,
         n_blocks: int, s: PlanimetricSettings, out: Planimetric) -> Planimetric:
    """dx, dy and the tilt with a free vertical offset per block (within-block least squares with
    the gradients' noise ``e`` taken out, 3·MAD rejection), their cluster-robust covariance over the
    blocks; then the offset and tilt over the whole overlap with dx, dy held. ``out`` filled in."""
    a = np.column_stack([(c - c.mean(axis=0)) / SCALE_M, -g])
    keep = np.ones(d.size, bool)
    for _ in range(6):
        aw, r, m, t = _within_fit(a, d, e, keep, blocks, n_blocks, c if s.block_plane else None)
        mad = 1.4826 * np.median(np.abs(r))
        bad = np.abs(r) > 3.0 * max(mad, 1e-6)
        if not bad.any():
            break
        keep[np.flatnonzero(keep)[bad]] = False
    else:  # the last rejection's fit
        aw, r, m, t = _within_fit(a, d, e, keep, blocks, n_blocks, c if s.block_plane else None)
    cov, used = cluster_cov(aw, r, blocks[keep], c[keep], s.hac_m, m, t)
    jk = jackknife_cov(aw, aw @ t + r, m, blocks[keep], c[keep], s.jackknife_groups)
    if jk is not None:  # each σ the larger of the two, the blocks' correlation (positive definite)
        scale = np.sqrt(np.maximum(np.diag(jk), np.diag(cov)) / np.diag(cov))
        cov = cov * np.outer(scale, scale)
    varying = None
    if s.random_effects:
        varying = _random_effects(aw, aw @ t + r, m, blocks[keep], c[keep], s, cov)
    cov, t = cov[-2:, -2:], t[-2:]  # dx, dy
    if varying is not None:  # the displacement varies along the overlap: its mean, σ its spread
        t, sd_re = varying
        scale = np.maximum(sd_re, np.sqrt(np.diag(cov))) / np.sqrt(np.diag(cov))
        cov = cov * np.outer(scale, scale)
    out.n_cells, out.n_blocks = int(keep.sum()), used
    if used < s.min_blocks:
        out.reason = (f"{used} blocks of {s.block_m:g} m hold the cells (at least {s.min_blocks} "
                      "to tell the σ)")
        return out
    sd = np.sqrt(np.diag(cov))
    out.status, out.reason = "determined", ""
    out.dx_m, out.dy_m = float(t[0]), float(t[1])
    out.sigma_dx_m, out.sigma_dy_m = float(sd[0]), float(sd[1])
    out.corr_dxy = float(cov[0, 1] / (sd[0] * sd[1])) if sd[0] * sd[1] > 0 else None
    x = np.column_stack([np.ones(keep.sum()), a[keep, :2]])
    level, *_ = np.linalg.lstsq(x, d[keep] - a[keep, 2:] @ t, rcond=None)
    lcov, _ = cluster_cov(x, d[keep] - a[keep, 2:] @ t - x @ level, blocks[keep], c[keep], s.hac_m)
    out.dz0_m = float(level[0])
    out.tilt_x, out.tilt_y = float(level[1] / SCALE_M), float(level[2] / SCALE_M)
    out.sigma_tilt = float(np.sqrt(max(lcov[1, 1], lcov[2, 2])) / SCALE_M)
    return out


def _within_fit(a, d, e, keep, blocks, n_blocks, centre=None):
    """The within-block design, residuals, noise moments and solution on the rows ``keep``: with
    ``centre`` (K, 2) a plane free per block (the design's global tilt columns then drop out), else
    an offset per block."""
    at = centre[keep] if centre is not None else None
    cols = a[keep, 2:] if centre is not None else a[keep]
    aw, dw = within(cols, blocks[keep], n_blocks, at), within(d[keep], blocks[keep], n_blocks, at)
    p = aw.shape[1]
    m = np.zeros((int(keep.sum()), p, p))
    m[:, -2:, -2:] = noise_moments(e[keep], blocks[keep], n_blocks, 1 if centre is None else 3)
    t = np.linalg.solve(aw.T @ aw - m.sum(axis=0), aw.T @ dw)
    return aw, dw - aw @ t, m, t


def _random_effects(a: np.ndarray, y: np.ndarray, m: np.ndarray, blocks: np.ndarray,
                    centre: np.ndarray, s: PlanimetricSettings,
                    cov: np.ndarray) -> tuple[np.ndarray, np.ndarray] | None:
    """dx, dy as the mean of a displacement that varies along the overlap, and their σ: the fit on
    each of ``s.jackknife_groups`` stretches alone (its σ cluster-robust), combined per axis as a
    random-effects meta-analysis (DerSimonian & Laird 1986, Controlled Clinical Trials 7:177–188):
    the stretches' spread beyond their noise, τ², is estimated from Cochran's Q, each stretch
    weighed by 1/(σ² + τ²), the mean's variance 1/Σ weights (times the Hartung–Knapp factor when the
    stretches scatter more than that says). A trajectory's slow errors move the strips
    apart differently along the overlap (by ≈ 1 cm RMS on the simulated UAV surveys): the one-offset
    fit then reads the stretches where the slopes are (and its σ, from residuals about that one
    offset, misses the spread); this estimate weighs the stretches more evenly as τ² grows and its
    σ holds τ². None with fewer than 4 stretches that determine both offsets."""
    if s.jackknife_groups < 3:
        return None
    group = groups_along(blocks, centre, s.jackknife_groups, s.groups_across)
    # a stretch holds a few blocks: its own cluster-robust variance is noisy, and may come out far
    # too small; never below its formal one times the whole overlap's robust-to-formal ratio
    ratio = np.maximum(1.0, np.diag(cov)[-2:] / np.diag(formal_fit(a, y, m, blocks)[1])[-2:])
    est, var = [], []
    for g in range(s.jackknife_groups * s.groups_across):
        rows = group == g
        ag = a[rows]
        if rows.sum() < s.min_cells or np.unique(blocks[rows]).size < 2:
            continue
        w = np.linalg.eigvalsh(ag.T @ ag - m[rows].sum(axis=0))
        if w[0] <= 1e-9 * max(w[-1], 1e-300):
            continue
        tg, formal = formal_fit(ag, y[rows], m[rows], blocks[rows])
        cg, _ = cluster_cov(ag, y[rows] - ag @ tg, blocks[rows], centre[rows], s.hac_m, m[rows], tg)
        est.append(tg[-2:])
        var.append(np.maximum(np.diag(cg)[-2:], np.diag(formal)[-2:] * ratio))
    if len(est) < 4:
        return None
    return random_effects_mean(np.array(est), np.array(var))


