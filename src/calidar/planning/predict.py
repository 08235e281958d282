"""Predicted σ and correlations of a planned calibration flight, from the normal matrix alone.

The strip adjustment (:mod:`calidar.strips.calibrate`) solves for the sensor's parameters and
the trajectory's corrections (:mod:`calidar.strips.trajectory_errors`, priors from the stated
trajectory accuracy, Gauss–Markov correlated knots) from tie planes. Its covariance is N⁻¹,
N = JᵀWJ + P (W the rows' weights 1/σ², P the priors' precision). Here J is built by the same
:class:`~calidar.strips.problem.StripProblem` from the tie planes :mod:`calidar.planning.geometry`
samples, P by the engine's prior groups, and the sensor block of N⁻¹ taken by the Schur
complement over the trajectory knots (a sparse LU of their block): σ = √diag, with the
correlations. The model is linear in the trajectory corrections and nearly so in the mounting,
so the covariance does not depend on the (unknown) true errors.
"""

from __future__ import annotations

from dataclasses import dataclass, field, replace

import numpy as np
import scipy.sparse as sp
import scipy.sparse.linalg as spla

from calidar.adjust import prior_groups
from calidar.errors import InputError
from calidar.io.flight_lines import PlanLine
from calidar.planning.geometry import Instrument, fly_plan, pair_planes
from calidar.planning.rows import correspondences
from calidar.strips.config import Estimate
from calidar.strips.parameters import build_parameters
from calidar.strips.planes import PlaneSettings
from calidar.strips.problem import StripProblem
from calidar.strips.trajectory_errors import TrajectoryModel
from calidar.strips.verdict import CORRELATION_LIMIT, GROUND_LIMIT_M, LENGTH_LIMIT_M

#: |ρ| above which a plan cannot separate two parameters (it is called poor)
SEPARATION_LIMIT = 0.95
#: eigenvalues of the scaled normal matrix below this fraction of the largest: directions the plan
#: cannot see
NULL_EIGENVALUE = 1e-10
#: trajectory blocks up to this size are solved dense
DENSE_MAX = 8000
#: a σ moving points by more than this (m) says the tie planes do not see the parameter at all
UNSEEN_M = 10.0


@dataclass(frozen=True)
class PlanSettings:
    """What to estimate and how the trajectory's errors enter (as ``calidar boresight`` does)."""

    #: group and single-parameter names (:meth:`Estimate.of`)
    estimate: tuple[str, ...] = ("boresight",)
    trajectory: TrajectoryModel = field(default_factory=lambda: TrajectoryModel(
        1.0, 0.02, np.radians(0.002), 20.0, 3.5))
    planes: PlaneSettings = field(default_factory=PlaneSettings)
    #: how the trajectory's errors really wander when not as the adjustment's Gauss–Markov priors
    #: assume: (position, attitude) s, the kernel σ of Gaussian-smoothed noise (the simulator's:
    #: 10, 2). None: as assumed (σ = √diag N⁻¹); else the estimator's actual error covariance
    #: (below)
    true_smoothing_s: tuple[float, float] | None = None


@dataclass
class Prediction:
    """The predicted σ (SI) and correlations of the estimated sensor parameters."""

    names: list[str]
    units: list[str]
    sigma: np.ndarray
    correlation: np.ndarray
    median_range_m: float
    pairs: list[dict]  #: per overlapping pair: lines a, b and tie planes
    n_rows: int
    heights: list[float]  #: distinct planned heights above ground (m)
    reported: np.ndarray | None = None  #: the σ the adjustment will report (its N⁻¹; SI)

    def ground_effect(self, k: int, reported: bool = True) -> float:
        """How far (m) a σ of parameter k moves a point at the median range (lengths: σ itself): the
        σ the calibration will report (its verdict judges by it), or (``reported`` False) the
        expected error's."""
        name = self.names[k]
        s = self.reported[k] if reported and self.reported is not None else self.sigma[k]
        if self.units[k] == "rad" or name == "range_scale":
            return float(s * self.median_range_m)
        if name == "scan_angle_scale":
            return float(s * self.median_range_m * 0.35)
        return float(s)

    def limit(self, k: int) -> float:
        """The σ's ground effect up to which parameter k counts as determined (as the verdict's)."""
        return LENGTH_LIMIT_M if self.units[k] == "m" else GROUND_LIMIT_M

    def determined(self, k: int) -> bool:
        """Whether the calibration will call parameter k determined (its reported σ within the
        limit)."""
        return bool(np.isfinite(self.sigma[k]) and self.ground_effect(k) <= self.limit(k))

    def worst(self) -> int:
        """Index of the parameter whose reported σ is furthest beyond (or closest to) its limit."""
        beyond = [self.ground_effect(k) / self.limit(k) for k in range(len(self.names))]
        return int(np.argmax(beyond))

    def correlated_pairs(self, limit: float = CORRELATION_LIMIT) -> list[tuple[str, str, float]]:
        """(name, name, ρ) of the parameter pairs correlated beyond ``limit``."""
        n = len(self.names)
        return [(self.names[i], self.names[j], float(self.correlation[i, j]))
                for i in range(n) for j in range(i + 1, n) if abs(self.correlation[i, j]) > limit]

    @property
    def poor(self) -> bool:
        """Some parameter not determined, or two that the plan cannot separate."""
        return (not all(self.determined(k) for k in range(len(self.names)))
                or bool(self.correlated_pairs(SEPARATION_LIMIT)))


def _overlapping_pairs(flown: list, terrain, inst: Instrument, settings: PlanSettings,
                       cache: dict) -> list:
    """The tie planes of every pair of flown lines that overlap, from ``cache`` when sampled
    before (keyed by the two lines)."""
    pairs = []
    for a in range(len(flown)):
        for b in range(a + 1, len(flown)):
            key = (flown[a].line.to_json(), flown[b].line.to_json())
            if key not in cache:
                cache[key] = pair_planes(flown[a], flown[b], a, b, terrain, inst, settings.planes)
            if cache[key] is not None:
                pairs.append(replace(cache[key], a=a, b=b))
    if not pairs:
        raise InputError(None, "lines", "no two planned lines overlap (with tie planes on the "
                         "terrain); expected swaths that overlap")
    return pairs


def predict(lines: list[PlanLine], terrain, inst: Instrument,
            settings: PlanSettings = PlanSettings(), cache: dict | None = None) -> Prediction:
    """The plan's predicted σ and correlations (see the module docstring); ``cache``: tie planes of
    pairs already sampled (by the two lines), kept across calls (candidate lines tried one by
    one)."""
    flown = fly_plan(lines, terrain)
    cache = {} if cache is None else cache
    pairs = _overlapping_pairs(flown, terrain, inst, settings, cache)
    poses, times, corrs, noise = correspondences(flown, pairs, inst, settings.planes, terrain,
                                                 cache)
    by_id = {f.line.number: f for f in flown}
    spans = {sid: (by_id[sid].t0, by_id[sid].t1) for sid in poses}
    headings = {sid: by_id[sid].line.azimuth for sid in poses}
    names, units, cov, formal, n_rows = sensor_covariance(inst.nominal, poses, times, corrs, spans,
                                                          headings, settings, noise)
    sigma = np.sqrt(np.where(np.isnan(np.diag(cov)), np.inf, np.clip(np.diag(cov), 0.0, None)))
    with np.errstate(invalid="ignore", divide="ignore"):
        corr = cov / np.outer(sigma, sigma)
    rng = np.concatenate([inst.nominal.true_range(p.range_m) for p in poses.values()])
    formal_var = np.diag(formal)
    reported = np.sqrt(np.where(np.isfinite(formal_var), np.clip(formal_var, 0.0, None), np.inf))
    pair_rows = [{"a": flown[p.a].line.number, "b": flown[p.b].line.number,
                  "tie_planes": p.n_planes} for p in pairs]
    pred = Prediction(names, units, sigma, corr, float(np.median(rng)), pair_rows, n_rows,
                      sorted({ln.height_agl_m for ln in lines}), reported)
    # numerically null directions
    unseen = [k for k in range(len(names)) if pred.ground_effect(k, False) > UNSEEN_M]
    pred.sigma[unseen] = np.inf
    pred.reported[unseen] = np.inf
    pred.correlation[unseen, :] = np.nan
    pred.correlation[:, unseen] = np.nan
    return pred


def sensor_covariance(nominal, poses: dict, times: dict, corrs: list, spans: dict, headings: dict,
                      settings: PlanSettings, row_noise=None
                      ) -> tuple[list[str], list[str], np.ndarray, np.ndarray, int]:
    """The estimated sensor parameters' names, units, the covariance of their errors and the one
    the adjustment will report (SI), from correspondences and poses as the strip adjustment takes
    them (``poses``, ``times`` per strip id), with the trajectory model of ``settings`` over the
    strips' time ``spans`` and ``headings`` (rad).

    ``row_noise``: the variance (m²) the rows' residuals really have, when not the σ² the
    adjustment weighs them by (None: as weighed): the covariance is then the estimator's actual
    one, N⁻¹(JᵀW·Σ·WJ + P·C·P)N⁻¹ (Σ the rows' variances, C the trajectory errors'; = N⁻¹ when
    both are as assumed), not the σ the adjustment will report.

    The estimate is N⁻¹JᵀWy; with row errors ε of covariance Σ and trajectory errors e of
    covariance C (not the weights' W⁻¹ and the priors' P⁻¹) its error N⁻¹(JᵀWε − P·e) has
    covariance N⁻¹(JᵀW·Σ·WJ + P·C·P)N⁻¹."""
    estimate = Estimate.of(*settings.estimate)
    params = build_parameters(nominal, estimate, spans, settings.trajectory, headings)
    free = params.free
    problem = StripProblem(nominal, poses, corrs, [p.name for p in free], times,
                           settings.trajectory, spans)
    J = sp.csr_matrix(problem.jacobian(params.values(), free))
    w = 1.0 / problem.sigma**2
    Jw = sp.csr_matrix(J.multiply(np.sqrt(w)[:, None]))
    JWJ = (Jw.T @ Jw).tocsc()
    groups = settings.trajectory.prior_correlation(spans)
    P = _prior_precision(free, groups)
    N = JWJ + P
    layout = settings.trajectory.layout(spans)
    sensor = np.array([k for k, p in enumerate(free) if p.name not in layout])
    cov, X = _sensor_covariance(N, sensor)
    names, units = [free[k].name for k in sensor], [free[k].unit for k in sensor]
    not_as_assumed = settings.true_smoothing_s is not None or row_noise is not None
    if not_as_assumed and np.all(np.isfinite(cov)):
        pcp = P  # P·C·P with C = P⁻¹: the priors as assumed
        if settings.true_smoothing_s is not None:
            knot_time = _knot_times(settings.trajectory, spans)
            pcp = P @ _true_covariance(free, groups, knot_time, settings.true_smoothing_s) @ P
        meat = JWJ  # JᵀW·Σ·WJ with Σ = W⁻¹: the rows as weighed
        if row_noise is not None:
            Jn = sp.csr_matrix(J.multiply((w * np.sqrt(row_noise))[:, None]))
            meat = (Jn.T @ Jn).tocsc()
        return names, units, X.T @ ((meat + pcp) @ X), cov, J.shape[0]
    return names, units, cov, cov, J.shape[0]


def _knot_times(model, spans) -> dict[str, float]:
    """Each trajectory parameter's knot time (s), by name."""
    times = model.knot_times(spans)
    return {name: float(times[k.strip][k.knot]) for name, k in model.layout(spans).items()}


def _sparse(rows: list, cols: list, vals: list, n: int) -> sp.csc_matrix:
    """An (n, n) sparse matrix from lists of row, column and value arrays."""
    return sp.csc_matrix((np.concatenate(vals), (np.concatenate(rows), np.concatenate(cols))),
                         shape=(n, n))


def _true_covariance(free, groups, knot_time: dict[str, float],
                     smoothing_s: tuple[float, float]) -> sp.csc_matrix:
    """Covariance of the trajectory knots' true errors: each prior σ, correlated within a group (a
    strip's, or the flight's, knots) as Gaussian-smoothed noise of kernel σ τ: exp(−Δt² / 4τ²) (Δt
    the knots' times apart; position knots τ = smoothing_s[0], rotations [1])."""
    index = {p.name: k for k, p in enumerate(free)}
    rows, cols, vals, done = [], [], [], set()
    for names, _ in groups:
        idx = np.array([index[n] for n in names])
        tau = smoothing_s[0] if names[0].startswith("trajectory_bias") else smoothing_s[1]
        d = np.array([free[i].prior_sigma for i in idx])
        t = np.array([knot_time[n] for n in names])
        lag = t[:, None] - t[None, :]
        block = np.outer(d, d) * np.exp(-(lag**2) / (4.0 * tau**2))
        r, c = np.meshgrid(idx, idx, indexing="ij")
        rows.append(r.ravel()), cols.append(c.ravel()), vals.append(block.ravel())
        done.update(idx.tolist())
    rest = [k for k, p in enumerate(free) if p.prior_sigma is not None and k not in done]
    rows.append(np.array(rest, int)), cols.append(np.array(rest, int))
    vals.append(np.array([free[k].prior_sigma ** 2 for k in rest]))
    return _sparse(rows, cols, vals, len(free))


def _prior_precision(free, prior_correlation) -> sp.csc_matrix:
    """The priors' precision P (n_free, n_free), as the engine adds it to N."""
    n = len(free)
    rows, cols, vals = [], [], []
    for idx, _, P in prior_groups(free, prior_correlation):
        r, c = np.meshgrid(idx, idx, indexing="ij")
        keep = P != 0
        rows.append(r[keep]), cols.append(c[keep]), vals.append(P[keep])
    if not rows:
        return sp.csc_matrix((n, n))
    return _sparse(rows, cols, vals, n)


def _solve_spd(A: sp.csc_matrix, B: np.ndarray) -> np.ndarray:
    """A⁻¹B for the symmetric positive definite trajectory block A (priors on every knot): dense
    Cholesky (a few thousand knots: the sparse LU fills in across overlapping strips and is slower),
    else sparse LU."""
    import scipy.linalg as la

    if A.shape[0] <= DENSE_MAX:
        try:
            factor = la.cho_factor(A.toarray(), check_finite=False)
            return la.cho_solve(factor, B, check_finite=False)
        except la.LinAlgError:
            pass
    return spla.splu(A.tocsc(), permc_spec="MMD_AT_PLUS_A").solve(B)


def _sensor_covariance(N: sp.csc_matrix, sensor: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The sensor block of N⁻¹ by the Schur complement over the other (trajectory) parameters, and
    N⁻¹'s sensor columns."""
    n = N.shape[0]
    other = np.setdiff1d(np.arange(n), sensor)
    Nss = N[sensor][:, sensor].toarray()
    if other.size:
        Nts = N[other][:, sensor].toarray()
        X = _solve_spd(N[other][:, other], Nts)
        S = Nss - Nts.T @ X
    else:
        X = np.zeros((0, sensor.size))
        S = Nss
    S = 0.5 * (S + S.T)
    d = 1.0 / np.sqrt(np.maximum(np.diag(S), 1e-300))
    lam, vec = np.linalg.eigh(S * np.outer(d, d))  # scaled: the rank test of the engine's Solution
    null = lam < NULL_EIGENVALUE * max(float(lam.max()), 1e-300)
    inv = (vec[:, ~null] / lam[~null]) @ vec[:, ~null].T
    cov = inv * np.outer(d, d)
    unseen = np.any(np.abs(vec[:, null]) > 0.1, axis=1) if null.any() else np.zeros(len(d), bool)
    cov[unseen, :] = np.nan
    cov[:, unseen] = np.nan
    cov[unseen, unseen] = np.inf
    full = np.zeros((n, sensor.size))  # the sensor columns of N⁻¹: [S⁻¹; −Ntt⁻¹·Nts·S⁻¹]
    full[sensor] = cov
    full[other] = -X @ cov
    return cov, full
