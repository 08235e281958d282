"""Gauss–Newton / Levenberg–Marquardt with robust (IRLS) reweighting.

Model: a problem (:class:`calidar.adjust.residuals.ResidualProblem`) gives residuals r(θ) and
their Jacobian, observations with a-priori σ, optional priors on parameters as
pseudo-observations; how to iterate is a :class:`calidar.adjust.residuals.SolverOptions`. The
covariance of the free parameters is σ0² · (JᵀWJ + P)⁻¹ with σ0² the a-posteriori variance factor
(the linear algebra in :mod:`calidar.adjust.normals`).

Robust weights (Huber, Cauchy) act on standardised residuals u = r / (σ · s), where s is
a robust scale (1.4826 · MAD of r/σ) re-estimated every iteration, so that clutter
(vegetation, moving objects) loses weight while well-modelled observations keep it.
"""

from __future__ import annotations

import contextlib
from collections.abc import Callable
from dataclasses import dataclass, replace
from functools import cached_property

import numpy as np
import scipy.sparse as sp

from calidar.adjust.m_estimator import (
    ROBUST_K, normal_psi_square, psi, robust_weights, sandwich_covariance, small_sample_factor,
    variance_factor,
)
from calidar.adjust.normals import (
    cluster_robust, damped, inverse_diagonal, normal_matrix, solve_damped,
)
from calidar.adjust.parameters import ParameterSet
from calidar.adjust.residuals import (STEP_IN_SIGMA, FunctionProblem, ResidualProblem,
                                      SolverOptions, numerical_jacobian, prior_groups, values_of)
from calidar.adjust.solution import Solution, residual_stats
from calidar.adjust.unit_weight import GROSS_Z, skipped_sigma0
from calidar.errors import CalibrationError

__all__ = ["Estimate", "ROBUST_K", "STEP_IN_SIGMA", "estimate", "numerical_jacobian",
           "prior_groups", "robust_weights", "solve"]

Progress = Callable[[int, float], None]
#: the keyword arguments of the function form (``solve(residual_fn, params, sigma=…, …)``) that
#: are solver options
_OPTION_KEYS = ("robust", "robust_k", "robust_scale", "max_iter", "tol", "step_in_sigma")
_PROBLEM_KEYS = ("sigma", "jacobian_fn", "prior_correlation", "normal_fn", "absolute_sigma")


def solve(problem: ResidualProblem, options: SolverOptions | None = None, *,
          progress: Progress | None = None,
          clusters: np.ndarray | list[np.ndarray] | None = None, **function_form) -> Solution:
    """Least-squares estimate of the free parameters of ``problem`` (a
    :class:`calidar.adjust.residuals.ResidualProblem`: its parameters, row σ, priors, residuals and
    Jacobian), iterated as ``options`` say (:class:`calidar.adjust.residuals.SolverOptions`;
    None: the defaults, Cauchy-robust).

    progress(iteration, cost) is called after every iteration. clusters: optional group id per
    observation (n,) for observations whose errors are correlated within groups (e.g. by a smooth
    trajectory error), or two ids per observation (n, 2) when each observation joins two groups
    (dyadic: correlated when sharing either): σ then come from the cluster-robust sandwich
    N⁻¹ (Σ_g J_gᵀW_g r_g r_gᵀW_g J_g) N⁻¹ · G/(G−1) (Liang & Zeger 1986; dyadic form of Cameron &
    Miller 2014) where it exceeds the usual σ0²·N⁻¹ (σ raised, correlations kept); a list of such
    groupings raises each σ to the largest of their estimates (sandwich estimates from few groups
    run low). The covariance is σ0²·N⁻¹ without priors (σ relative) and max(σ0², 1)·N⁻¹ with them
    (σ absolute: the priors are never tightened by an a-posteriori σ0 below 1) or when the problem's
    ``absolute_sigma`` says its observations' own σ are absolute. With robust weights the solution
    also records :func:`calidar.adjust.unit_weight.skipped_sigma0` (``extra["unit_weight"]``).

    The function form ``solve(residual_fn, params, sigma=…, jacobian_fn=…, robust=…, …)`` (values
    by name → residuals) is kept: it wraps the functions in a
    :class:`calidar.adjust.residuals.FunctionProblem` and the option keywords in SolverOptions.
    """
    problem, options = _problem_and_options(problem, options, function_form)
    return estimate(problem, options, progress=progress).solution(clusters)


def estimate(problem: ResidualProblem, options: SolverOptions | None = None, *,
             progress: Progress | None = None, step_scale: np.ndarray | None = None,
             **function_form) -> "Estimate":
    """The iterations of :func:`solve` without its covariance: an :class:`Estimate` whose
    ``solution()`` adds it. ``options.step_in_sigma``: stop when every step is below this fraction
    of its σ (an outer loop that re-matches its observations can stop early and ``refine`` its
    last); ``step_scale``: diag(N⁻¹) for that σ (an earlier Estimate's, whose normal matrix is
    nearly this one's; None: from the first step's N)."""
    problem, options = _problem_and_options(problem, options, function_form)
    params = problem.parameters
    if not params.free:
        raise CalibrationError("no free parameters to estimate")
    with _one_blas_thread():
        fit = _Fit(problem, options)
        history = [{"iteration": 0, "cost": fit.cost(fit.r0, fit.weights(fit.r0), fit.x0),
                    "rms": residual_stats(fit.r0)["rms"], "values": params.values()}]
        start = Estimate(fit, fit.x0, fit.r0, fit.weights(fit.r0), history, False, step_scale,
                         options, progress)
        return start.refine(options.step_in_sigma)


def _problem_and_options(problem, options,
                         function_form: dict) -> tuple[ResidualProblem, SolverOptions]:
    """(problem, options) from the protocol form, or from the function form
    ``(residual_fn, params, **keywords)`` (``options`` then holds the ParameterSet)."""
    if not isinstance(options, ParameterSet):
        if function_form:
            raise TypeError(f"solve(problem, options): unexpected keywords {sorted(function_form)}")
        return problem, options or SolverOptions()
    unknown = set(function_form) - set(_OPTION_KEYS) - set(_PROBLEM_KEYS)
    if unknown:
        raise TypeError(f"solve: unexpected keywords {sorted(unknown)}")
    kw = {k: function_form[k] for k in _PROBLEM_KEYS if k in function_form}
    opts = SolverOptions(**{k: function_form[k] for k in _OPTION_KEYS if k in function_form})
    return FunctionProblem(problem, options, **kw), opts


@dataclass
class Estimate:
    """Where the iterations stopped: free values ``x`` (SI), residuals, robust weights (× 1/σ²),
    the history, whether the stop rule fired, the σ scale of that rule (diag N⁻¹), the options."""

    fit: "_Fit"
    x: np.ndarray
    r: np.ndarray
    w: np.ndarray
    history: list[dict]
    converged: bool
    step_scale: np.ndarray | None
    options: SolverOptions = SolverOptions()
    progress: Progress | None = None

    @property
    def parameters(self) -> ParameterSet:
        return self.fit.params.updated(self.x)

    @cached_property
    def normals(self) -> tuple:
        """(J, N) at x: the Jacobian and the normal matrix with the priors, computed once for
        :meth:`solution` and whoever asks after it (the model check's freed fits); read only.
        (Not a field: an Estimate made from this one by ``replace`` computes its own.)"""
        with _one_blas_thread():
            J = self.fit.jacobian(self.x)
            return J, self.fit.normal_equations(J, self.w, x=self.x)[0]

    def refine(self, step_in_sigma: float = STEP_IN_SIGMA) -> "Estimate":
        """Iterate on from here until every step is below ``step_in_sigma`` of its σ."""
        with _one_blas_thread():
            return _levenberg_marquardt(self, step_in_sigma)

    def solution(self, clusters: np.ndarray | list[np.ndarray] | None = None) -> Solution:
        """The :class:`Solution` here: covariance = variance factor · N⁻¹ (or, with
        ``options.covariance`` "sandwich", the M-estimator sandwich, the IRLS σ of the parameters
        no prior holds recorded beside it), raised by the cluster-robust sandwich of each grouping
        in ``clusters`` (see :func:`solve`)."""
        fit, x, r, w = self.fit, self.x, self.r, self.w
        with _one_blas_thread():
            J, N = self.normals
            sol = _solution(fit, x, r, w, self.history, self.converged, J, N)
            factor = fit.variance_factor(r, w, x)
            finite = factor > 0 and np.all(np.isfinite(sol.covariance))
            irls = (sol.covariance, None)  # the IRLS model's covariance and bread N⁻¹ (lazy)
            if self.options.covariance == "sandwich":
                sandwich, sol.extra["covariance"] = _sandwich(fit, J, r, x, sol)
                models = [irls] if sandwich is None else [irls, sandwich]
            else:
                models = [irls]
        groupings = clusters if isinstance(clusters, list) else [clusters]
        groupings = [] if clusters is None else groupings
        scores = sp.diags(w * r) @ J if groupings else None  # per row ∂cost/∂θ, as J
        raised = []
        for cov, bread in models:
            model_cov = cov
            if bread is None:
                bread = cov / factor if finite else np.linalg.pinv(N)
            for grouping in groupings:
                cov = cluster_robust(cov, bread, scores, np.asarray(grouping))
            raised.append((model_cov, cov))
        sol.covariance = raised[-1][1]
        if len(raised) == 2:  # what the IRLS model would have said, and the model parts
            record = sol.extra["covariance"]
            for key, cov in (("irls_model_sigma", raised[0][0]), ("irls_sigma", raised[0][1]),
                             ("model_sigma", raised[1][0])):
                record[key] = _unheld_sigma(fit, cov)
        return sol


def _unheld_sigma(fit: "_Fit", cov: np.ndarray) -> dict[str, float]:
    """σ (SI) of the free parameters no prior holds (the calibration's, not the nuisance)."""
    sig = np.sqrt(np.clip(np.diag(cov), 0, None))
    return {p.name: float(sig[i]) for i, p in enumerate(fit.free) if p.prior_sigma is None}


def _one_blas_thread():
    """BLAS/LAPACK on one thread while solving: the normal matrices are at most a few thousand
    wide, where a second thread gains < 2× on an idle machine and, on a busy one, costs 10×
    (Cholesky of 1 300 parameters: 0.04 s on one thread, 0.38 s on two, load 5 on 2 cores)."""
    try:
        from threadpoolctl import threadpool_limits
    except ImportError:  # pragma: no cover - a dependency of scikit-learn
        return contextlib.nullcontext()
    return threadpool_limits(1, user_api="blas")


class _Fit:
    """The weighted least-squares problem the iterations work on: residuals, Jacobian, robust
    weights, cost (priors included) at free-parameter vectors x (SI)."""

    def __init__(self, problem: ResidualProblem, options: SolverOptions):
        self.problem, self.params = problem, problem.parameters
        self.robust, self.robust_k = options.robust, options.robust_k
        self.robust_scale = options.robust_scale
        self.absolute_sigma = bool(getattr(problem, "absolute_sigma", False))
        self.free = self.params.free
        self.priors = prior_groups(self.free, getattr(problem, "prior_correlation", ()))
        self.n_prior = sum(idx.size for idx, _, _ in self.priors)
        self.x0 = self.params.x()
        self.r0 = self.residuals(self.x0)
        self.n = self.r0.size
        self.sig = np.broadcast_to(np.asarray(getattr(problem, "sigma", 1.0), float), (self.n,))
        #: each residual's share of an observation (rows that share a noise term count partly)
        self.share = np.broadcast_to(np.asarray(getattr(problem, "row_share", 1.0), float),
                                     (self.n,))
        if self.n < len(self.free) - self.n_prior:
            raise CalibrationError(f"{self.n} observations cannot determine {len(self.free)} "
                                   "parameters")
        if not np.all(np.isfinite(self.r0)):
            n_bad = int(np.sum(~np.isfinite(self.r0)))
            raise CalibrationError(f"{n_bad} residuals are not finite at the start")

    def residuals(self, x: np.ndarray) -> np.ndarray:
        r = np.asarray(self.problem.residuals(values_of(self.params, x)), dtype=float)
        if r.ndim != 1:
            raise CalibrationError(f"residual function returned shape {r.shape}, expected (n,)")
        return r

    def jacobian(self, x: np.ndarray):
        return self.problem.jacobian(values_of(self.params, x))

    def scale(self, z: np.ndarray) -> float:
        """The robust weights' scale s of the standardised residuals z = r/σ: 1.4826 · MAD when
        re-estimated (robust_scale), else 1."""
        if self.robust and self.robust_scale:
            mad = 1.4826 * np.median(np.abs(z - np.median(z)))
            return float(mad) if mad > 0 else 1.0
        return 1.0

    def weights(self, r: np.ndarray) -> np.ndarray:
        """Relative robust weights (0..1) times 1/σ²."""
        z = r / self.sig
        return robust_weights(z / self.scale(z), self.robust, self.robust_k) / self.sig**2

    def cost(self, r: np.ndarray, w: np.ndarray, x: np.ndarray) -> float:
        with np.errstate(over="ignore"):  # a wild trial step costs inf and is rejected
            c = 0.5 * np.sum(w * r * r)
        for idx, center, P in self.priors:
            d = x[idx] - center
            c += 0.5 * d @ P @ d
        return float(c)

    def normal_equations(self, J, w: np.ndarray, r: np.ndarray | None = None,
                         x: np.ndarray | None = None):
        """N = JᵀWJ + P (priors' precision) and, with r and x, the gradient g = JᵀWr + P(x −
        centre)."""
        given = None if x is None else self.problem.normal_matrix(values_of(self.params, x))
        N = normal_matrix(J, w) if given is None else np.array(given, float)
        for idx, _, P in self.priors:
            N[np.ix_(idx, idx)] += P
        return N, None if r is None else self.gradient(J, w, r, x)

    def gradient(self, J, w: np.ndarray, r: np.ndarray, x: np.ndarray) -> np.ndarray:
        """g = JᵀWr + P(x − centre), the priors' part added per prior group."""
        g = J.T @ (w * r)
        for idx, center, P in self.priors:
            g[idx] += P @ (x[idx] - center)
        return g

    def redundancy(self, counted: np.ndarray | None = None,
                   kept: np.ndarray | None = None) -> float:
        """Rows (each by its :attr:`share`, times ``counted`` — e.g. its relative weight — when
        given; only the ``kept`` ones when given) + the priors' terms − the free parameters, ≥ 1:
        the one count of the redundancy every σ0 of this fit is divided by."""
        share = self.share if kept is None else self.share[kept]
        rows = np.sum(share) if counted is None else np.sum(counted * share)
        return max(float(rows) + self.n_prior - len(self.free), 1.0)

    def dof(self, w: np.ndarray) -> float:
        """Effective redundancy: down-weighted observations count by their relative weight (and
        by their share, :attr:`share`)."""
        return self.redundancy(w * self.sig**2)

    def sigma0(self, r: np.ndarray, x: np.ndarray) -> tuple[float, int]:
        """(σ0, rows skipped as gross) by :func:`calidar.adjust.unit_weight.skipped_sigma0`: the RMS
        of r/σ with the priors' terms over the redundancy, rows beyond GROSS_Z σ0 skipped — recorded
        beside the engine's σ0, not its variance factor (why: docs/validation.md, issue 26)."""
        prior_sq = 2.0 * (self.cost(r, np.zeros_like(r), x))  # the priors' part of the cost
        return skipped_sigma0(r / self.sig, prior_sq, self.n_prior, len(self.free), GROSS_Z,
                              self.share)

    def variance_factor(self, r: np.ndarray, w: np.ndarray, x: np.ndarray) -> float:
        """σ0² without priors (σ relative); max(σ0², 1) with them or with absolute observation σ
        (σ absolute: σ0 < 1 there says the priors or the rows' σ were generous, not that the
        parameters are better known than they allow)."""
        s0 = 2.0 * self.cost(r, w, x) / self.dof(w)
        return s0 if self.n_prior == 0 and not self.absolute_sigma else max(s0, 1.0)


def _levenberg_marquardt(at: Estimate, step_in_sigma: float) -> Estimate:
    """Damped Gauss–Newton steps with IRLS weights from ``at`` until the steps are invisible against
    the parameters' σ (or the cost stops falling, or ``at.max_iter`` steps in all)."""
    fit, x, r, w = at.fit, at.x, at.r, at.w
    lam, history, n_inv_diag = 1e-3, list(at.history), at.step_scale  # n_inv_diag: N hardly changes
    c = fit.cost(r, w, x)
    steps = np.array([p.diff_step for p in fit.free])
    redundancy = fit.redundancy()
    def done(conv: bool) -> Estimate:
        return replace(at, x=x, r=r, w=w, history=history, converged=conv, step_scale=n_inv_diag)

    for it in range(len(history), at.options.max_iter + 1):
        N, g = fit.normal_equations(fit.jacobian(x), w, r, x)
        if n_inv_diag is None:
            n_inv_diag = inverse_diagonal(N)
        dN = np.diag(N).copy()
        dN[dN <= 0] = 1.0
        for _ in range(12):
            dx = -solve_damped(damped(N, lam * dN), g)
            r_new = fit.residuals(x + dx)
            c_new = fit.cost(r_new, w, x + dx)
            if np.isfinite(c_new) and c_new <= c:
                break
            lam *= 10.0
        else:
            return done(False)  # no descent possible: at the minimum to machine precision
        x, r = x + dx, r_new
        lam = max(lam / 10.0, 1e-12)
        w = fit.weights(r)
        c_prev, c = c, fit.cost(r, w, x)
        history.append({"iteration": it, "cost": c, "rms": residual_stats(r)["rms"], "lambda": lam,
                        "values": fit.params.values_with(x)})
        if at.progress:
            at.progress(it, c)
        tol = at.options.tol
        sigma = np.sqrt(n_inv_diag * 2.0 * c / redundancy)  # each parameter's σ at this cost
        if (np.all(np.abs(dx) < tol + 1e-4 * steps) or abs(c_prev - c) <= tol * max(c, 1e-300)
                or np.all(np.abs(dx) <= step_in_sigma * sigma)):
            return done(True)
    return done(False)


def _solution(fit: _Fit, x: np.ndarray, r: np.ndarray, w: np.ndarray, history: list[dict],
              converged: bool, J, N: np.ndarray) -> Solution:
    """The :class:`Solution` at x (covariance = variance factor · N⁻¹, see
    :meth:`_Fit.variance_factor`) from the Jacobian J and normal matrix N there."""
    dof = fit.dof(w)
    sol = Solution.from_normal_matrix(
        fit.params.updated(x), N, 2.0 * fit.cost(r, w, x) / dof, dof,
        variance_factor=fit.variance_factor(r, w, x), residuals=r, weights=w * fit.sig**2,
        before=residual_stats(fit.r0), history=history, converged=converged, jacobian=J,
    )
    # σ0 read as the RMS of r/σ, gross rows skipped (calidar.strips.global_test shows it)
    if fit.robust:
        s0, skipped = fit.sigma0(r, x)
        kept = np.abs(r / fit.sig) <= GROSS_Z * s0
        sol.extra["unit_weight"] = {"sigma0": s0, "rows_skipped": skipped, "gross_z": GROSS_Z,
                                    "redundancy": fit.redundancy(kept=kept)}
    return sol


def _sandwich(fit: _Fit, J, r: np.ndarray, x: np.ndarray,
              sol: Solution) -> tuple[tuple[np.ndarray, np.ndarray] | None, dict]:
    """The robust fit's M-estimator sandwich A⁻¹(f·c_ψ·Σ J_iJ_iᵀ/σ_i² + max(f, 1)·P)A⁻¹
    (:mod:`calidar.adjust.m_estimator`, which says how f is read) at the IRLS solution ``sol``:
    ((covariance, A⁻¹ — the bread of the cluster-robust σ on top), the record for
    ``extra["covariance"]``); (None, the record saying why) where the solution has undetermined
    directions or A is not positive definite, and the IRLS covariance stays."""
    z = r / fit.sig
    s = fit.scale(z)
    k = ROBUST_K.get(fit.robust, 1.0) if fit.robust_k is None else fit.robust_k
    ps, dps = psi(z / s, fit.robust, k)
    c_psi = normal_psi_square(fit.robust, k, s)
    k_factor = small_sample_factor(dps, len(fit.free), float(np.sum(fit.share)))
    prior_sq = 2.0 * fit.cost(r, np.zeros_like(r), x)
    level = (s * s * float(np.sum(ps * ps)) / (c_psi * k_factor) + prior_sq) / fit.redundancy()
    rms_sq = sol.extra["unit_weight"]["sigma0"] ** 2 if fit.robust else level
    factor = variance_factor(level, rms_sq, fit.n_prior == 0 and not fit.absolute_sigma)
    parts = None
    if np.all(np.isfinite(sol.covariance)):
        A, _ = fit.normal_equations(J, dps / fit.sig**2)
        B, _ = fit.normal_equations(J, factor * c_psi / fit.sig**2)
        for idx, _, P in fit.priors:  # the priors' terms: max(f, 1)·P
            B[np.ix_(idx, idx)] += (max(factor, 1.0) - 1.0) * P
        parts = sandwich_covariance(A, B)
    if parts is None:
        return None, {"model": "irls", "reason": "no sandwich: A not positive definite or "
                      "directions not determined"}
    return parts, {"model": "sandwich", "variance_factor": factor, "psi_sigma0": level ** 0.5,
                   "normal_psi_square": c_psi, "huber_k": k_factor, "scale": s}
