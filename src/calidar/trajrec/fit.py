"""Robust least squares of one segment of a flight line: six cubic B-splines over time (sensor
east, north, up in the line's local frame; roll, pitch, heading) from scan-angle and ray
observations (:mod:`calidar.trajrec.geometry`).

Gauss–Newton with iteratively reweighted least squares (Cauchy weights on residuals standardised
by each observation type's MAD scale), smoothness priors on second differences of the coefficients
(a plausible acceleration and angular acceleration: where the points say little, the path stays
smooth instead of wandering — the failure PDAL issue 4627 reports) and weak priors keeping roll and
pitch within what an aircraft flies. The covariance of the coefficients is σ0²·N⁻¹.

A scan-angle field in whole degrees (LAS 1.0–1.3) breaks that covariance: each angle's rounding
error (uniform, variance Δ²/12) is a function of where the beam points, so points that share a
stored value share much of their error sweep after sweep, and it does not average as 1/√N. There
the scan-angle residuals' scale is at least Δ/√12 and the covariance is the cluster-robust sandwich
N⁻¹·M·N⁻¹ with the scan-angle scores summed per stored value (Liang & Zeger 1986; Cameron & Miller
2015, J. Human Resources 50:317, with their G/(G − 1) factor), where it is the wider.
"""

from __future__ import annotations

import contextlib
from dataclasses import dataclass, field

import numpy as np

from calidar.trajrec.kernels import accumulate, ray_partials, scan_partials, symmetrize
from calidar.trajrec.spline import Spline

CHANNELS = ("east", "north", "up", "roll", "pitch", "heading")
COARSE_STEP = 8  #: the first iterations use every 4th observation ...
FINE_ITERATIONS = 1  #: ... the last one all of them
#: smallest scale of an angle residual, rad (0.2 mm at 1 km): simulated scan lines can be planar to 1e-9 rad,
#: whose weight would make the normal matrix too ill-conditioned to solve in float64 (the weak
#: across-track / roll direction came out 4× its σ off)
SCALE_FLOOR = 2e-7
CAUCHY_C = 2.385  #: Cauchy constant (95 % efficiency at the normal distribution)
#: a scan-angle field stored in steps at least this coarse (rad) is quantised (LAS 1.0–1.3: whole degrees);
#: LAS 1.4's 0.006° steps are not
QUANTUM_MIN = np.radians(0.05)


def one_blas_thread():
    """BLAS on one thread while solving (these matrices are a few hundred wide: a second thread
    gains nothing and, on a busy machine, costs 10×; as ``calidar.adjust.solver``)."""
    try:
        from threadpoolctl import threadpool_limits
    except ImportError:  # pragma: no cover - a dependency of scikit-learn
        return contextlib.nullcontext()
    return threadpool_limits(1, user_api="blas")


@dataclass(frozen=True)
class FitSettings:
    """The fit's knobs (SI)."""

    knot_s: float = 0.25  #: spacing of the spline knots, s
    accel_sigma: float = 2.0  #: prior σ of the sensor's acceleration, m/s²
    angular_accel_sigma: float = 0.1  #: prior σ of roll/pitch/heading angular acceleration, rad/s²
    roll_prior: tuple[float, float] = (0.0, np.radians(30.0))  #: roll (mean, σ), rad
    pitch_prior: tuple[float, float] = (0.0, np.radians(10.0))  #: pitch (mean, σ), rad
    #: σ of the starting heading (the scan lines' trace) when neither scan angles nor scan planes are fitted, rad
    heading_start_sigma: float = np.radians(2.0)
    iterations: int = 12
    use_scan_angles: bool = True  #: fit the scan-angle field (when usable)
    planar_scanner: bool = True  #: the beams of a scan line lie in one plane (linear/oscillating scanners)
    scan_plane_yaw: float = 0.0  #: that plane's yaw in the body, rad (the scan-angle field: body across-track angles)
    segment_s: float = 20.0  #: lines are solved in segments of this length (s) ...
    overlap_s: float = 2.0  #: ... overlapping by this much


@dataclass
class Observations:
    """What one segment's fit sees, in the line's local ENU frame, sorted by time."""

    points: np.ndarray  #: (N, 3) m
    t: np.ndarray  #: (N,) s
    scan: np.ndarray  #: (N,) scan angle, rad (NaN: none)
    use_across: bool  #: the scan-angle field is usable (across-track residuals)
    use_along: bool  #: the scanner is planar (along-track residuals)
    ray_last: np.ndarray  #: (M, 3) last return of each multi-return pulse
    ray_u1: np.ndarray
    ray_u2: np.ndarray
    ray_t: np.ndarray  #: (M,)
    ray_sigma: np.ndarray  #: (M,) relative σ of the ray's direction (1 / separation of its returns)
    cache: dict = field(default_factory=dict, repr=False)  #: spline bases of t and ray_t (one spline per segment)

    def basis(self, spline: Spline, which: str) -> tuple[np.ndarray, np.ndarray]:
        """``spline.basis`` of the point ("t") or ray ("ray_t") times, computed once."""
        if which not in self.cache:
            self.cache[which] = spline.basis(getattr(self, which))
        return self.cache[which]


@dataclass
class SegmentFit:
    spline: Spline
    coef: np.ndarray  #: (K, 6)
    cov: np.ndarray  #: (6, K, K) per channel
    sigma0: float
    scales: dict  #: robust scale of each residual type (rad)
    n_obs: dict
    iterations: int


def _normal_blocks(spline: Spline, basis, r, g, w_obs, n_mat, rhs):
    """Add Σ Jᵀ W J and −Jᵀ W r of residuals r (n,), partials g (n, 6) with spline ``basis`` (first
    coefficient, weights) into the normal matrix (6K, 6K) and right-hand side (each row touches 4
    coefficients of each channel)."""
    i, w = basis
    accumulate(n_mat, rhs, i, w, np.ascontiguousarray(g), r, w_obs, spline.n_coef)


def _robust(z: np.ndarray, floor: float = SCALE_FLOOR) -> tuple[np.ndarray, float]:
    """Cauchy weights of standardised residuals z and their MAD scale (at least ``floor``)."""
    scale = max(1.4826 * float(np.median(np.abs(z))), floor) if z.size else 1.0
    return 1.0 / (1.0 + (z / (CAUCHY_C * scale)) ** 2) / scale**2, scale


def _prior_blocks(spline: Spline, coef: np.ndarray, s: FitSettings, n_mat, rhs, heading0=None) -> None:
    """Smoothness (second differences) on every channel, roll/pitch plausibility priors, and the
    starting heading ``heading0`` (coefficients) as a prior when nothing else determines it."""
    k = spline.n_coef
    d2 = np.diff(np.eye(k), 2, axis=0)
    for c in range(6):
        sig = (s.accel_sigma if c < 3 else s.angular_accel_sigma) * spline.step**2
        sl = slice(c * k, (c + 1) * k)
        n_mat[sl, sl] += d2.T @ d2 / sig**2
        rhs[sl] -= d2.T @ (d2 @ coef[:, c]) / sig**2
    priors = [(3, s.roll_prior[0], s.roll_prior[1]), (4, s.pitch_prior[0], s.pitch_prior[1])]
    if heading0 is not None:
        priors.append((5, heading0, s.heading_start_sigma))
    for c, mean, sig in priors:
        sl = slice(c * k, (c + 1) * k)
        n_mat[sl, sl] += np.eye(k) / sig**2
        rhs[sl] -= (coef[:, c] - mean) / sig**2


def _state(coef: np.ndarray, basis) -> np.ndarray:
    """Channel values (n, 6) from coefficients (K, 6) and a basis (first coefficient, weights)."""
    i, w = basis
    return np.einsum("nj,njc->nc", w, coef[i[:, None] + np.arange(4)])


def _types(obs: Observations, spline: Spline, coef: np.ndarray, kappa: float = 0.0):
    """Per residual type: (name, basis, residuals (n,), partials (n, 6), relative σ (n,))."""
    out = []
    if obs.t.size and (obs.use_across or obs.use_along):
        basis = obs.basis(spline, "t")
        r, g = scan_partials(obs.points, _state(coef, basis), np.nan_to_num(obs.scan), kappa)
        if obs.use_across:
            ok = np.isfinite(obs.scan)
            out.append(("across", (basis[0][ok], basis[1][ok]), r[ok, 0], g[ok, 0], np.ones(int(ok.sum()))))
        if obs.use_along:
            out.append(("along", basis, r[:, 1], g[:, 1], np.ones(obs.t.size)))
    if obs.ray_t.size:
        basis = obs.basis(spline, "ray_t")
        state = _state(coef, basis)
        r, g = ray_partials(np.ascontiguousarray(state[:, :3]), obs.ray_last, obs.ray_u1, obs.ray_u2)
        for k in range(2):
            out.append((f"ray{k}", basis, r[:, k], g[:, k], obs.ray_sigma))
    return out


def _banded_solve(n_mat: np.ndarray, rhs: np.ndarray, k: int, interleaved_out: bool = False) -> np.ndarray:
    """N⁻¹·rhs by a banded Cholesky: with the unknowns interleaved (coefficient j, channel c → 6j + c) N
    is banded (half-bandwidth 23: a row touches 4 consecutive coefficients of each channel). ``rhs``
    (6K,) in channel-major order gives the answer in that order; ``interleaved_out`` with rhs = I
    gives N⁻¹ in interleaved order (its channel blocks are [c::6, c::6])."""
    from scipy.linalg import solveh_banded

    cm = (np.arange(6 * k) % 6) * k + np.arange(6 * k) // 6  # interleaved position → channel-major index
    ni = n_mat[np.ix_(cm, cm)]
    u = 23
    ab = np.zeros((u + 1, 6 * k))
    for d in range(u + 1):
        ab[u - d, d:] = np.diagonal(ni, d)
    if interleaved_out:
        return solveh_banded(ab, rhs, check_finite=False)
    x = np.empty_like(rhs)
    x[cm] = solveh_banded(ab, rhs[cm], check_finite=False)
    return x


def _thin(obs: Observations, step: int) -> Observations:
    """Every ``step``-th observation (the first iterations, far from the answer, need fewer)."""
    if step == 1:
        return obs
    return Observations(obs.points[::step], obs.t[::step], obs.scan[::step], obs.use_across, obs.use_along,
                        obs.ray_last[::step], obs.ray_u1[::step], obs.ray_u2[::step], obs.ray_t[::step],
                        obs.ray_sigma[::step])


def _iterate(obs: Observations, spline: Spline, coef: np.ndarray, settings: FitSettings, heading0=None):
    """One Gauss–Newton step: (step (K, 6), normal matrix, χ², observations, scales, counts)."""
    p = 6 * spline.n_coef
    n_mat, rhs = np.zeros((p, p)), np.zeros(p)
    chi2, n_tot, scales, n_obs = 0.0, 0, {}, {}
    quantum = scan_quantum(obs.scan) if obs.use_across else 0.0
    for name, basis, r, g, rel in _types(obs, spline, coef, settings.scan_plane_yaw):
        floor = max(SCALE_FLOOR, quantum / np.sqrt(12.0)) if name == "across" else SCALE_FLOOR
        w, scale = _robust(r / rel, floor / float(np.median(rel)))
        scales[name.rstrip("01")] = scale
        n_obs[name] = int(r.size)
        wr = w / rel**2
        _normal_blocks(spline, basis, r, g, wr, n_mat, rhs)
        chi2 += float(np.sum(wr * r**2))
        n_tot += r.size
    n_mat = symmetrize(n_mat)
    _prior_blocks(spline, coef, settings, n_mat, rhs, heading0)
    with one_blas_thread():
        dx = _banded_solve(n_mat, rhs, spline.n_coef).reshape(6, spline.n_coef).T
    return dx, n_mat, chi2, n_tot, scales, n_obs


def solve_segment(obs: Observations, spline: Spline, coef0: np.ndarray, settings: FitSettings) -> SegmentFit:
    """Gauss–Newton with IRLS from ``coef0`` (K, 6); see the module docstring. The iterations use a
    quarter of the observations until the steps are below 1 cm and 1e-5 rad; then one iteration
    (and the covariance) uses all of them."""
    coef = np.array(coef0, float)
    heading0 = None if (obs.use_across or obs.use_along) else coef[:, 5].copy()
    thin = _thin(obs, COARSE_STEP)
    it = 0
    for it in range(1, settings.iterations + 1):
        dx = _iterate(thin, spline, coef, settings, heading0)[0]
        coef += dx
        if np.all(np.abs(dx[:, :3]) < 1e-2) and np.all(np.abs(dx[:, 3:]) < 1e-5):
            break
    for _ in range(FINE_ITERATIONS):  # the covariance from the last one's normal matrix
        dx, n_mat, chi2, n_tot, scales, n_obs = _iterate(obs, spline, coef, settings, heading0)
        coef += dx
    sigma0 = float(np.sqrt(chi2 / max(n_tot - 6 * spline.n_coef, 1)))
    k = spline.n_coef
    with one_blas_thread():
        inv = _banded_solve(n_mat, np.eye(6 * k), k, interleaved_out=True) * max(sigma0, 1.0) ** 2
    cov = np.stack([inv[c::6, c::6] for c in range(6)])  # rows/columns interleaved: coefficient k, channel c
    quantum = scan_quantum(obs.scan) if obs.use_across else 0.0
    if quantum:
        cov = _widest(cov, _clustered_covariance(obs, spline, coef, settings, n_mat, quantum))
    return SegmentFit(spline, coef, cov, sigma0, scales, n_obs, it)


def scan_quantum(scan: np.ndarray) -> float:
    """The step (rad) of a quantised scan-angle field: every value a multiple of it, at least
    QUANTUM_MIN; 0.0 when the field is finer (or has fewer than two values)."""
    v = np.unique(scan[np.isfinite(scan)])
    if v.size < 2:
        return 0.0
    step = float(np.min(np.diff(v)))
    k = (v - v[0]) / step
    return step if step >= QUANTUM_MIN and np.all(np.abs(k - np.round(k)) < 1e-3) else 0.0


def _clustered_covariance(obs: Observations, spline: Spline, coef: np.ndarray, settings: FitSettings,
                          n_mat: np.ndarray, quantum: float) -> np.ndarray:
    """(6, K, K) channel blocks of N⁻¹ + N⁻¹·(M − N_a)·N⁻¹, the scan-angle residuals' information N_a
    replaced by that of errors with a part shared by every point of one stored value (a random effect,
    the survey statistician's design effect, Kish 1965): M = (1 − ρ)·N_a + ρ·σ²·Σ_c a_c a_cᵀ, a_c the sum
    of value c's weighted partials, ρ the share of the residuals' variance between the values' means
    (0 when each value's points scatter over its whole quantum, → 1 for a scanner firing the same
    angles every sweep)."""
    k = spline.n_coef
    _, basis, r, g, rel = next(t for t in _types(obs, spline, coef, settings.scan_plane_yaw) if t[0] == "across")
    w, _ = _robust(r / rel, max(SCALE_FLOOR, quantum / np.sqrt(12.0)))
    wr = w / rel**2
    first, bw = basis
    labels = np.unique(np.round(obs.scan[np.isfinite(obs.scan)] / quantum), return_inverse=True)[1].ravel()
    n_groups = int(labels.max()) + 1 if labels.size else 0
    if n_groups < 2:
        return np.full((6, k, k), np.inf)
    size = np.bincount(labels, minlength=n_groups)
    mean = np.bincount(labels, weights=r, minlength=n_groups) / np.maximum(size, 1)
    total = max(float(np.mean((r - r.mean()) ** 2)), quantum**2 / 12.0)  # the fit absorbs part of the shared errors
    within = float(np.mean((r - mean[labels]) ** 2))
    rho = float(np.clip(1.0 - within / total, 0.0, 1.0))
    a = np.zeros((n_groups, 6 * k))
    for c in range(6):
        for j in range(4):
            np.add.at(a, (labels, c * k + first + j), bw[:, j] * g[:, c] * wr)
    n_a, rhs = np.zeros((6 * k, 6 * k)), np.zeros(6 * k)
    accumulate(n_a, rhs, first, bw, np.ascontiguousarray(g), r, wr, k)
    n_a = symmetrize(n_a)
    meat = (1.0 - rho) * n_a + rho * total * (a.T @ a)
    with one_blas_thread():
        n_inv = np.linalg.inv(n_mat)
        cov = n_inv + n_inv @ (meat - n_a) @ n_inv
    return np.stack([cov[c * k:(c + 1) * k, c * k:(c + 1) * k] for c in range(6)])


def _widest(model: np.ndarray, robust: np.ndarray) -> np.ndarray:
    """Per channel the block of the two (6, K, K) covariances whose variances sum to more."""
    wider = np.trace(robust, axis1=1, axis2=2) > np.trace(model, axis1=1, axis2=2)
    return np.where(wider[:, None, None], robust, model)


def channel_sigma(fit: SegmentFit, t) -> np.ndarray:
    """σ (n, 6) of each channel's value at times ``t`` from the coefficients' covariance."""
    i, w = fit.spline.basis(t)
    idx = i[:, None] + np.arange(4)
    out = np.empty((len(t), 6))
    for c in range(6):
        block = fit.cov[c][idx[:, :, None], idx[:, None, :]]  # (n, 4, 4)
        out[:, c] = np.sqrt(np.maximum(np.einsum("ni,nij,nj->n", w, block, w), 0.0))
    return out
