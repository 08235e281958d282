"""Least-squares fit of scanner range = (1 + scale)·true + offset, with outlier tests.

Observation equation per target X (feature point or E point):
r_X = (1 + k)·S_PX(P, X) + c + e, with S_PX from the two polar observations
(:mod:`calidar.rangecal.geometry`). The polar observation of P is shared by every target of
its setup, so its errors are correlated across them: P's slope distance, vertical angle and
direction enter as nuisance parameters with the observed values as priors (σ from the
instrument's stated precision), which keeps the model a plain Gauss–Markov model with
uncorrelated observations. σ of each equation propagates the scanner noise and the
target's polar observation by the analytic Jacobian of S_PX:
σ_X² = σ_scanner² + ∂S_PX/∂S_X²·σ_S² + (∂S_PX/∂β_X² + ∂S_PX/∂Hz_X²)·σ_angle², with
σ_S = a mm + b ppm · S_OX (the factor (1 + k)² ≈ 1 + 2k on the last two terms is dropped).

Outliers: Baarda's data snooping (Baarda 1968, "A testing procedure for use in geodetic
networks"): standardized residuals w_i = v_i / σ_v_i with σ_v_i² = σ_i² − J_i Q_xx J_iᵀ
(a-priori variance factor 1); the largest |w_i| above the critical value (3.29, α = 0.001
two-sided) is removed and the fit repeated. The 95 % intervals use Student's t with the
redundancy as degrees of freedom, since σ0 is estimated from the data.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
from scipy import stats

from calidar.adjust import (Block, Parameter, ParameterSet, ResidualProblem, Solution,
                            SolverOptions, solve)
from calidar.errors import CalibrationError
from calidar.io.total_station import TotalStationObservations
from calidar.rangecal.geometry import distance_partials

SNOOPING_CRITICAL = 3.29  #: |w| critical value of data snooping (normal, α = 0.001 two-sided)
P_PARTS = ("slope", "va", "hz")
MAX_REJECTED_FRACTION = 0.2  #: data snooping rejects at most this fraction of the targets
SEPARABLE_CORRELATION = 0.999  #: |ρ(offset, scale)| above which the distances cannot separate them


def p_parameter(setup_id: str, part: str) -> str:
    """Name of the nuisance parameter of P's observation ``part`` from setup ``setup_id``."""
    return f"P_{part}_{setup_id}"


def target_distances(obs: TotalStationObservations,
                     p_values: np.ndarray | None = None) -> tuple[np.ndarray, np.ndarray]:
    """S_PX (m) of every target and its partials (n, 6) (see geometry.distance_partials).
    ``p_values`` (n_setups, 3): P's (slope m, va rad, hz rad); default the observed ones."""
    if p_values is None:
        p_values = np.array([[s.p_slope, s.p_va, s.p_hz] for s in obs.setups])
    p = p_values[obs.setup]
    return distance_partials(p[:, 0], p[:, 1], p[:, 2], obs.slope, obs.va, obs.hz)


def observation_sigma(obs: TotalStationObservations) -> np.ndarray:
    """σ (m) of each observation equation: scanner noise + the target's polar observation."""
    _, part = target_distances(obs)
    ang = np.array([s.angle_sigma for s in obs.setups])[obs.setup]
    sig_s = np.empty(len(obs))
    for i, s in enumerate(obs.setups):
        sig_s[obs.setup == i] = s.distance_sigma(obs.slope[obs.setup == i])
    # ∂S_PX/∂S_X · σ_S, and the two angles of X with one σ each
    angles = (part[:, 4] ** 2 + part[:, 5] ** 2) * ang**2
    var = obs.scanner_sigma**2 + (part[:, 3] * sig_s) ** 2 + angles
    return np.sqrt(var)


def parameter_set(obs: TotalStationObservations, fix_scale: bool = False) -> ParameterSet:
    """range_offset (m), range_scale (ppm; fixed at 0 with ``fix_scale``) and each setup's P
    nuisance parameters with priors."""
    params = [Parameter("range_offset", 0.0, "m"),
              Parameter("range_scale", 0.0, "ppm", free=not fix_scale)]
    for s in obs.setups:
        slope_sigma = float(s.distance_sigma(s.p_slope))
        params += [
            Parameter(p_parameter(s.id, "slope"), s.p_slope, "m", prior_sigma=slope_sigma),
            Parameter(p_parameter(s.id, "va"), s.p_va, "rad", prior_sigma=s.angle_sigma),
            Parameter(p_parameter(s.id, "hz"), s.p_hz, "rad", prior_sigma=s.angle_sigma),
        ]
    return ParameterSet(params)


class RangeProblem(ResidualProblem):
    """The observation equations of :mod:`calidar.rangecal.fit` as the engine's problem: residual
    model − scanner range (m) per target, σ per equation (:func:`observation_sigma`), the analytic
    Jacobian; P's polar observations addressed as one typed block (setup, part) per setup."""

    def __init__(self, obs: TotalStationObservations, fix_scale: bool = False,
                 sigma: np.ndarray | None = None):
        self.obs, self.fix_scale = obs, fix_scale
        self.parameters = parameter_set(obs, fix_scale)
        self.sigma = observation_sigma(obs) if sigma is None else sigma
        keys = {p_parameter(s.id, part): (i, part)
                for i, s in enumerate(obs.setups) for part in P_PARTS}
        self.p_block = Block.of(self.parameters, keys)

    def p_values(self, values) -> np.ndarray:
        """P's (slope m, va rad, hz rad) per setup, (n_setups, 3)."""
        return self.p_block.take(values).reshape(len(self.obs.setups), len(P_PARTS))

    def residuals(self, values) -> np.ndarray:
        d, _ = target_distances(self.obs, self.p_values(values))
        return (1.0 + values["range_scale"]) * d + values["range_offset"] - self.obs.scanner

    def jacobian(self, values) -> np.ndarray:
        obs, n_s = self.obs, len(self.obs.setups)
        d, part = target_distances(obs, self.p_values(values))
        J = np.zeros((len(obs), 2 + 3 * n_s))
        J[:, 0] = 1.0
        J[:, 1] = d
        for i in range(n_s):
            rows = obs.setup == i
            J[rows, 2 + 3 * i: 5 + 3 * i] = (1.0 + values["range_scale"]) * part[rows, :3]
        return np.delete(J, 1, axis=1) if self.fix_scale else J


def standardized_residuals(solution: Solution, jacobian: np.ndarray,
                           sigma: np.ndarray) -> np.ndarray:
    """Baarda's w_i = v_i / σ_v_i (a-priori variance factor 1) of the observation equations."""
    params = solution.parameters
    N = jacobian.T @ (jacobian / sigma[:, None] ** 2)
    for j, p in enumerate(params.free):
        if p.prior_sigma is not None:
            N[j, j] += 1.0 / p.prior_sigma**2
    q_xx = np.linalg.inv(N)
    q_vv = sigma**2 - np.einsum("ij,jk,ik->i", jacobian, q_xx, jacobian)
    return solution.residuals / np.sqrt(np.clip(q_vv, 1e-30, None))


@dataclass
class FitResult:
    """The fit on the kept observations, the outlier tests and the 95 % intervals."""

    solution: Solution
    keep: np.ndarray  #: (n,) bool over the input targets
    sigma: np.ndarray  #: (n,) a-priori σ of each equation (m)
    w: np.ndarray  #: (n,) standardized residuals of the final fit (NaN for rejected)
    residuals: np.ndarray  #: (n,) model − scanner (m) at the final estimate, rejected included
    distance: np.ndarray  #: (n,) S_PX at the final estimate of P (m)
    rejected: list[dict] = field(default_factory=list)  #: in rejection order: line, point, w
    t_factor: float = float("nan")  #: Student t quantile for the 95 % intervals
    global_test: dict = field(default_factory=dict)

    def interval(self, name: str) -> tuple[float, float] | None:
        """95 % interval (SI) of parameter ``name``; None when it is fixed."""
        if name not in self.solution.sigma:
            return None
        v, s = self.solution.values[name], self.solution.sigma[name]
        return v - self.t_factor * s, v + self.t_factor * s


def fit_range_model(obs: TotalStationObservations, fix_scale: bool = False,
                    critical: float = SNOOPING_CRITICAL, level: float = 0.95) -> FitResult:
    """Fit offset and scale (or the offset alone, ``fix_scale``) over ``obs`` with data
    snooping; raise CalibrationError when the data cannot determine them (too few targets,
    or distances too alike to separate scale from offset)."""
    sigma_all = observation_sigma(obs)
    sol, keep, w, rejected = _snoop(obs, fix_scale, critical, sigma_all)
    if not fix_scale and not abs(sol.correlation[0, 1]) <= SEPARABLE_CORRELATION:
        d = target_distances(obs.subset(keep))[0]
        raise CalibrationError(f"{obs.source}: the targets span only {d.min():.2f}–{d.max():.2f} "
                               "m: range_scale cannot be separated from range_offset; add groups "
                               "or E points at other distances, or fix the scale")
    # P's polar observations: in solution.json, not in the report's table
    sol.nuisance_prefix = "P_"
    v = sol.values
    p_all = np.array([[v[p_parameter(s.id, part)] for part in P_PARTS] for s in obs.setups])
    d_all, _ = target_distances(obs, p_all)
    w_all = np.full(len(obs), np.nan)
    w_all[keep] = w
    dof = sol.dof
    return FitResult(
        solution=sol, keep=keep, sigma=sigma_all, w=w_all,
        residuals=(1.0 + v["range_scale"]) * d_all + v["range_offset"] - obs.scanner,
        distance=d_all, rejected=rejected, t_factor=float(stats.t.ppf(0.5 + level / 2, dof)),
        global_test=global_test(sol.sigma0, dof),
    )


def _snoop(obs: TotalStationObservations, fix_scale: bool, critical: float, sigma_all: np.ndarray):
    """Baarda's data snooping: fit, reject the target of the largest |w| above ``critical``, fit
    again, until none is (or too few targets, or :data:`MAX_REJECTED_FRACTION` rejected).
    Returns the last fit's solution, the targets kept (n,) bool, their w and the rejections."""
    keep = np.ones(len(obs), bool)
    rejected = []
    while True:
        sub = obs.subset(keep)
        if len(sub) < 3:
            raise CalibrationError(f"{obs.source}: {len(sub)} usable targets; at least 3 are "
                                   "needed to fit offset and scale")
        problem = RangeProblem(sub, fix_scale, sigma_all[keep])
        sol = solve(problem, SolverOptions(robust=None))
        J = problem.jacobian(sol.values)
        w = standardized_residuals(sol, J, sigma_all[keep])
        worst = int(np.argmax(np.abs(w)))
        if abs(w[worst]) <= critical or len(sub) - 1 < 4:
            return sol, keep, w, rejected
        if len(rejected) >= MAX_REJECTED_FRACTION * len(obs):
            sol.warnings.append(f"data snooping stopped after {len(rejected)} rejections with "
                                f"|w| = {abs(w[worst]):.1f} still above the critical value: the "
                                "stated precisions look too optimistic (see the global test)")
            return sol, keep, w, rejected
        idx = np.flatnonzero(keep)[worst]
        rejected.append({"line": int(obs.line[idx]), "point": str(obs.point[idx]),
                         "group": str(obs.group[idx]), "w": float(w[worst]),
                         "residual_m": float(sol.residuals[worst])})
        keep[idx] = False


def global_test(sigma0: float, dof: float, level: float = 0.95) -> dict:
    """χ² test of σ0² · dof on ``dof`` degrees of freedom (two-sided at ``level``): σ0, χ², p and
    the σ0 range that passes."""
    chi2 = sigma0**2 * dof
    lo, hi = stats.chi2.ppf((1 - level) / 2, dof), stats.chi2.ppf((1 + level) / 2, dof)
    return {"sigma0": float(sigma0), "dof": float(dof), "chi2": float(chi2),
            "p_value": float(2 * min(stats.chi2.cdf(chi2, dof), stats.chi2.sf(chi2, dof))),
            "sigma0_range95": [float(np.sqrt(lo / dof)), float(np.sqrt(hi / dof))],
            "passed": bool(lo <= chi2 <= hi)}


def acceptance(fit: FitResult, tolerance_m: float) -> dict:
    """Acceptance of the raw ranging: passes when the 95 % interval of the range error
    e(d) = offset + scale·d lies inside ±tolerance_m (m) over the calibrated distances."""
    sol = fit.solution
    names = sol.parameters.free_names
    i = [names.index(n) for n in ("range_offset", "range_scale") if n in names]
    cov = np.zeros((2, 2))
    cov[: len(i), : len(i)] = sol.covariance[np.ix_(i, i)]
    d = fit.distance[fit.keep]
    ends = np.array([d.min(), d.max()])
    e = sol.values["range_offset"] + sol.values["range_scale"] * ends
    sig = np.sqrt(cov[0, 0] + 2 * ends * cov[0, 1] + ends**2 * cov[1, 1])
    bound = np.abs(e) + fit.t_factor * sig
    return {"tolerance_m": float(tolerance_m), "distance_range_m": ends.tolist(),
            "range_error_m": e.tolist(), "bound95_m": bound.tolist(),
            "max_bound95_m": float(bound.max()), "passed": bool(bound.max() <= tolerance_m)}
