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
2015, J. Human Resources 50:317, with their G/(G − 1) factor), where it is the wider
(:mod:`calidar.trajrec.quantised`).

The scanner's own calibration (encoder offset and scale, the scan plane's yaw and pitch in the
body) are parameters with priors where ``FitSettings.mount_sigma`` gives them a σ
(:mod:`calidar.trajrec.mounting`).
"""

from __future__ import annotations

import functools
from dataclasses import dataclass, field

import numpy as np

from calidar.trajrec import mounting
from calidar.trajrec.banded import band_covariance, banded_solve, interleaved
from calidar.trajrec.kernels import (  # noqa: F401 - one_blas_thread: the pipeline's import
    accumulate, mount_partials, one_blas_thread, ray_partials, scan_partials, symmetrize,
)
from calidar.trajrec.quantised import clustered_covariance, scan_quantum, widest
from calidar.trajrec.spline import Spline

CHANNELS = ("east", "north", "up", "roll", "pitch", "heading")
COARSE_STEP = 8  #: the first iterations use every 4th observation ...
FINE_ITERATIONS = 1  #: ... the last one all of them
#: smallest scale of an angle residual, rad (0.2 mm at 1 km): simulated scan lines can be planar to
#: 1e-9 rad, whose weight would make the normal matrix too ill-conditioned to solve in float64
SCALE_FLOOR = 2e-7
CAUCHY_C = 2.385  #: Cauchy constant (95 % efficiency at the normal distribution)


@dataclass(frozen=True)
class FitSettings:
    """The fit's knobs (SI)."""

    knot_s: float = 0.25  #: spacing of the spline knots, s
    accel_sigma: float = 2.0  #: prior σ of the sensor's acceleration, m/s²
    angular_accel_sigma: float = 0.1  #: prior σ of roll/pitch/heading angular acceleration, rad/s²
    roll_prior: tuple[float, float] = (0.0, np.radians(30.0))  #: roll (mean, σ), rad
    pitch_prior: tuple[float, float] = (0.0, np.radians(10.0))  #: pitch (mean, σ), rad
    #: σ of the starting heading (the scan lines' trace) when neither scan angles nor scan planes
    #: are fitted, rad
    heading_start_sigma: float = np.radians(2.0)
    iterations: int = 12
    use_scan_angles: bool = True  #: fit the scan-angle field (when usable)
    #: the beams of a scan line lie in one plane (linear/oscillating scanners)
    planar_scanner: bool = True
    #: that plane's yaw in the body, rad (the scan-angle field: body across-track angles)
    scan_plane_yaw: float = 0.0
    segment_s: float = 20.0  #: lines are solved in segments of this length (s) ...
    overlap_s: float = 2.0  #: ... overlapping by this much
    #: prior σ of the scan-angle encoder's offset (rad) and scale (1), and of the scan plane's yaw
    #: (about ``scan_plane_yaw``) and pitch in the body (rad); 0: known (held at 0), see
    #: :mod:`calidar.trajrec.mounting`
    mount_sigma: tuple[float, ...] = (0.0,) * len(mounting.NAMES)


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
    #: spline bases of t and ray_t (one spline per segment)
    cache: dict = field(default_factory=dict, repr=False)
    #: the least scale of the rays' residuals (m × 1/separation): √2 × the returns' coordinate
    #: rounding / √12, their direction's σ from the two points alone; the rays' robust scale is at
    #: least this (a few rays' MAD is no scale)
    ray_floor: float = 0.0

    def quantum(self) -> float:
        """The scan-angle field's step where it is quantised (quantised.scan_quantum), computed
        once."""
        if "quantum" not in self.cache:
            self.cache["quantum"] = scan_quantum(self.scan) if self.use_across else 0.0
        return self.cache["quantum"]

    def median_ray_sigma(self) -> float:
        if "ray_sigma" not in self.cache:
            median = float(np.median(self.ray_sigma)) if self.ray_sigma.size else 1.0
            self.cache["ray_sigma"] = median
        return self.cache["ray_sigma"]

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
    #: estimates (mounting.NAMES)
    mount: np.ndarray = field(default_factory=lambda: np.zeros(len(mounting.NAMES)))
    #: their posterior σ (0: held)
    mount_sigma: np.ndarray = field(default_factory=lambda: np.zeros(len(mounting.NAMES)))


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


@functools.lru_cache(maxsize=8)
def _second_differences(k: int) -> np.ndarray:
    """D₂ᵀ·D₂ of k coefficients (D₂ their second differences), made once per size."""
    d2 = np.diff(np.eye(k), 2, axis=0)
    out = d2.T @ d2
    out.flags.writeable = False
    return out


def _prior_blocks(spline: Spline, coef: np.ndarray, s: FitSettings, n_mat, rhs,
                  heading0=None) -> None:
    """Smoothness (second differences) on every channel, roll/pitch plausibility priors, and the
    starting heading ``heading0`` (coefficients) as a prior when nothing else determines it."""
    k = spline.n_coef
    dd = _second_differences(k)
    for c in range(6):
        sig = (s.accel_sigma if c < 3 else s.angular_accel_sigma) * spline.step**2
        sl = slice(c * k, (c + 1) * k)
        n_mat[sl, sl] += dd / sig**2
        rhs[sl] -= dd @ coef[:, c] / sig**2
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


def _types(obs: Observations, spline: Spline, coef: np.ndarray, settings: FitSettings,
           mount: np.ndarray, idx: np.ndarray = np.zeros(0, int)):
    """Per residual type: (name, basis, residuals (n,), partials (n, 6), relative σ (n,), partials
    (n, m) by the mounting parameters ``idx``), with the mounting ``mount`` (mounting.NAMES)
    applied."""
    out = []
    if obs.t.size and (obs.use_across or obs.use_along):
        basis = obs.basis(spline, "t")
        state = _state(coef, basis)
        scan = np.nan_to_num(obs.scan)
        kappa, eps = settings.scan_plane_yaw + mount[2], mount[3]
        r, g = scan_partials(obs.points, state, (1.0 + mount[1]) * scan + mount[0], kappa, eps)
        if obs.use_across:
            out.append(_across(obs, basis, r, g, scan, mount, idx))
        if obs.use_along:
            plane = np.any((idx == 2) | (idx == 3))
            gp = mount_partials(obs.points, state, kappa, eps) if plane else None
            out.append(("along", basis, r[:, 1] - mount[5], g[:, 1], np.ones(obs.t.size),
                        mounting.design("along", obs.t.size, along_partials=gp, idx=idx)))
    if obs.ray_t.size:
        basis = obs.basis(spline, "ray_t")
        state = _state(coef, basis)
        sensor = np.ascontiguousarray(state[:, :3])
        r, g = ray_partials(sensor, obs.ray_last, obs.ray_u1, obs.ray_u2)
        none = np.zeros((obs.ray_t.size, idx.size))
        for k in range(2):
            out.append((f"ray{k}", basis, r[:, k], g[:, k], obs.ray_sigma, none))
    return out


def _across(obs: Observations, basis, r, g, scan, mount, idx):
    """The across-track type of :func:`_types`. The stored angle is the observation, the
    geometry's angle read by the encoder its model: (angle − offset − curvature)/(1 + scale) −
    stored, whose partials hold no noise (mounting.design)."""
    ok = np.isfinite(obs.scan)
    f = 1.0 / (1.0 + mount[1])
    angle = r[ok, 0] + (1.0 + mount[1]) * scan[ok] + mount[0]  # the geometry's across-track angle
    q = mount[4] / mounting.CURVATURE_AT**2
    read = (angle - mount[0] - q * angle**2) * f  # what the encoder reads of it
    g_a = g[ok, 0] * (f * (1.0 - 2.0 * q * angle))[:, None]
    n = int(ok.sum())
    gm = mounting.design("across", n, scan=read, idx=idx, scale=mount[1], angle=angle)
    return "across", (basis[0][ok], basis[1][ok]), read - scan[ok], g_a, np.ones(n), gm


def _thin(obs: Observations, step: int) -> Observations:
    """Every ``step``-th observation (the first iterations, far from the answer, need fewer)."""
    if step == 1:
        return obs
    s = slice(None, None, step)
    return Observations(obs.points[s], obs.t[s], obs.scan[s], obs.use_across, obs.use_along,
                        obs.ray_last[s], obs.ray_u1[s], obs.ray_u2[s], obs.ray_t[s],
                        obs.ray_sigma[s], ray_floor=obs.ray_floor)


@dataclass
class _Step:
    """One Gauss–Newton step: the coefficients' step (K, 6), the mounting's (estimated ones), the
    normal matrix with its border (B, C) to the active mounting parameters, and what the
    covariance needs."""

    dx: np.ndarray
    mount: mounting.MountStep | None
    n_mat: np.ndarray
    border: np.ndarray
    c_mat: np.ndarray
    chi2: float
    n_tot: int
    scales: dict
    n_obs: dict


def _iterate(obs: Observations, spline: Spline, coef: np.ndarray, settings: FitSettings,
             mount: np.ndarray, idx: np.ndarray, est: np.ndarray | None, heading0=None) -> _Step:
    """One Gauss–Newton step (see :class:`_Step`) with the mounting parameters ``idx`` in its
    border; ``est``: which of them are estimated (the others considered; None: decide from this
    step's information, see mounting.determined)."""
    k = spline.n_coef
    n_mat, rhs = np.zeros((6 * k, 6 * k)), np.zeros(6 * k)
    b_mat, c_mat = np.zeros((6 * k, idx.size)), np.zeros((idx.size, idx.size))
    r_g = np.zeros(idx.size)
    chi2, n_tot, scales, n_obs = 0.0, 0, {}, {}
    quantum = obs.quantum()
    for name, basis, r, g, rel, gm in _types(obs, spline, coef, settings, mount, idx):
        floor = max(SCALE_FLOOR, quantum / np.sqrt(12.0)) if name == "across" else SCALE_FLOOR
        floor = floor / (obs.median_ray_sigma() if name.startswith("ray") else 1.0)
        w, scale = _robust(r / rel, max(floor, obs.ray_floor) if name.startswith("ray") else floor)
        scales[name.rstrip("01")] = scale
        n_obs[name] = int(r.size)
        wr = w / rel**2
        _normal_blocks(spline, basis, r, g, wr, n_mat, rhs)
        if idx.size and name in ("across", "along"):
            bb, cc, rr = mounting.border(basis, g, gm, wr, k, r)
            b_mat, c_mat, r_g = b_mat + bb, c_mat + cc, r_g + rr
        chi2 += float(np.sum(wr * r**2))
        n_tot += r.size
    n_mat = symmetrize(n_mat)
    _prior_blocks(spline, coef, settings, n_mat, rhs, heading0)
    rest = (n_mat, b_mat, c_mat, chi2, n_tot, scales, n_obs)
    with one_blas_thread():
        if not idx.size:
            return _Step(banded_solve(n_mat, rhs, k).reshape(6, k).T, None, *rest)
        y = banded_solve(n_mat, np.c_[rhs, b_mat], k)
        sigma = np.asarray(settings.mount_sigma, float)[idx]
        if est is None:  # a thinned step: its information × COARSE_STEP
            est = mounting.determined(b_mat, c_mat, y[:, 1:], sigma, COARSE_STEP)
        ms = mounting.mount_step(y[:, 0], y[:, 1:], b_mat, c_mat, r_g, sigma, mount[idx], est)
    return _Step(ms.dx.reshape(6, k).T, ms, *rest)


def solve_segment(obs: Observations, spline: Spline, coef0: np.ndarray,
                  settings: FitSettings) -> SegmentFit:
    """Gauss–Newton with IRLS from ``coef0`` (K, 6); see the module docstring. The iterations use a
    quarter of the observations until the steps are below 1 cm and 1e-5 rad; then one iteration
    (and the covariance) uses all of them. The mounting parameters (``settings.mount_sigma``) join
    once the trajectory has converged: one step finds which the points determine; those are
    estimated with it, the others held and their σ passed on (in the last step)."""
    coef = np.array(coef0, float)
    mount = np.zeros(len(mounting.NAMES))
    every = mounting.active(settings.mount_sigma)
    idx, est, decided = np.zeros(0, int), np.zeros(0, bool), not every.size
    heading0 = None if (obs.use_across or obs.use_along) else coef[:, 5].copy()
    thin = _thin(obs, COARSE_STEP)
    it = 0
    for it in range(1, settings.iterations + 1):
        deciding = idx is every
        step = _iterate(thin, spline, coef, settings, mount, idx, None if deciding else est,
                        heading0)
        coef += step.dx
        dg = np.zeros(0)
        if step.mount is not None:
            est, dg = step.mount.est, step.mount.dg
            mount[idx[est]] += dg
        if deciding:  # decided: go on with the estimated ones alone
            idx, est, decided = every[est], np.ones(int(est.sum()), bool), True
            continue
        small = (np.all(np.abs(step.dx[:, :3]) < 1e-2) and np.all(np.abs(step.dx[:, 3:]) < 1e-5)
                 and np.all(np.abs(dg) < 1e-6))  # 1 cm, 1e-5 rad, and the mounting's
        if small:
            if decided:
                break
            idx = every  # converged without them: the next step decides
    est = np.isin(every, idx) if decided else np.zeros(every.size, bool)
    for _ in range(FINE_ITERATIONS):  # the covariance from the last one's normal matrix
        step = _iterate(obs, spline, coef, settings, mount, every, est, heading0)
        coef += step.dx
        if step.mount is not None:
            mount[every[est]] += step.mount.dg
    sigma0 = float(np.sqrt(step.chi2 / max(step.n_tot - 6 * spline.n_coef, 1)))
    k = spline.n_coef
    f = max(sigma0, 1.0) ** 2
    # the mounting's share of the covariance (mounting.py)
    low = step.mount.low_rank[interleaved(k)] if step.mount is not None else None
    cov = band_covariance(step.n_mat, low, k, f)
    if obs.quantum():
        cov = widest(cov, _clustered(obs, spline, coef, settings, mount, every, step))
    sig_m = np.zeros(len(mounting.NAMES))
    if step.mount is not None:
        sig_m[every] = step.mount.sigma * np.sqrt(f)
    return SegmentFit(spline, coef, cov, sigma0, step.scales, step.n_obs, it, mount, sig_m)


def _clustered(obs: Observations, spline: Spline, coef: np.ndarray, settings: FitSettings,
               mount: np.ndarray, every: np.ndarray, step: _Step) -> np.ndarray:
    """The cluster-robust covariance of a quantised scan-angle field (see the module docstring)
    from the last step's normal matrix with its mounting border and priors."""
    quantum = obs.quantum()
    types = _types(obs, spline, coef, settings, mount, every)
    across = next(t for t in types if t[0] == "across")
    prior = np.diag(1.0 / np.asarray(settings.mount_sigma, float)[every] ** 2)
    full = np.block([[step.n_mat, step.border], [step.border.T, step.c_mat + prior]])
    w, _ = _robust(across[2] / across[4], max(SCALE_FLOOR, quantum / np.sqrt(12.0)))
    scan = obs.scan[np.isfinite(obs.scan)]
    return clustered_covariance(across, w / across[4] ** 2, scan, quantum, full, k=spline.n_coef)


def channel_sigma(fit: SegmentFit, t) -> np.ndarray:
    """σ (n, 6) of each channel's value at times ``t`` from the coefficients' covariance."""
    i, w = fit.spline.basis(t)
    idx = i[:, None] + np.arange(4)
    out = np.empty((len(t), 6))
    for c in range(6):
        block = fit.cov[c][idx[:, :, None], idx[:, None, :]]  # (n, 4, 4)
        out[:, c] = np.sqrt(np.maximum(np.einsum("ni,nij,nj->n", w, block, w), 0.0))
    return out
