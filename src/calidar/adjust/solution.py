"""The result of an adjustment: estimates, σ, correlations, diagnostics, history."""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
import scipy.linalg as sl

from calidar.adjust.parameters import ParameterSet

#: |correlation| above which two parameters are reported as not separated by the data.
CORRELATION_WARNING = 0.95
#: Relative eigenvalue of the scaled normal matrix below which a direction is unobservable.
RANK_TOLERANCE = 1e-10


def json_ready(obj):
    """``obj`` with what JSON cannot hold made plain: numpy scalars and arrays as Python numbers and
    lists, tuples as lists, non-finite floats (±inf, NaN: "not determined", "no bound") as null.
    solution.json is written through it, so no value a method adds to ``Solution.extra`` can make
    the write fail."""
    if isinstance(obj, dict):
        return {str(k) if isinstance(k, np.generic) else k: json_ready(v) for k, v in obj.items()}
    if isinstance(obj, (list, tuple)):
        return [json_ready(v) for v in obj]
    if isinstance(obj, np.ndarray):
        return json_ready(obj.tolist())
    if isinstance(obj, np.generic):
        obj = obj.item()
    if isinstance(obj, float) and not np.isfinite(obj):
        return None
    return obj


def residual_stats(r: np.ndarray, weights: np.ndarray | None = None) -> dict:
    """Summary statistics of residuals (observation units)."""
    r = np.asarray(r, float)
    out = {
        "n": int(r.size),
        "rms": float(np.sqrt(np.mean(r * r))) if r.size else float("nan"),
        "mean": float(np.mean(r)) if r.size else float("nan"),
        "median": float(np.median(r)) if r.size else float("nan"),
        "max_abs": float(np.max(np.abs(r))) if r.size else float("nan"),
    }
    if weights is not None and r.size:
        out["downweighted_fraction"] = float(np.mean(weights < 0.5))
    return out


def cholesky_inverse(N: np.ndarray) -> np.ndarray | None:
    """N⁻¹ of a symmetric positive definite N by Cholesky (LAPACK potrf, potri); None when N
    is not positive definite (or not finite)."""
    try:
        c, _ = sl.cho_factor(N, lower=True)
    except (np.linalg.LinAlgError, ValueError):
        return None
    inv, info = sl.lapack.dpotri(c, lower=True)
    if info != 0:
        return None
    inv = np.tril(inv)
    return inv + np.tril(inv, -1).T


def unit_diagonal(N: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(N scaled to a unit diagonal, D⁻¹ N D⁻¹, and d = √diag N): the scaling under which a normal
    matrix's condition number says how well its parameters are determined, whatever their units."""
    d = np.sqrt(np.clip(np.diag(N), 1e-300, None))
    return N / np.outer(d, d), d


def factor_rcond(c: np.ndarray, A: np.ndarray) -> tuple[float, int]:
    """LAPACK's estimate (dpocon, O(n²)) of the reciprocal 1-norm condition number of the symmetric
    positive definite A from its lower Cholesky factor c, and LAPACK's info."""
    rcond, info = sl.lapack.dpocon(c, float(np.max(np.sum(np.abs(A), axis=0))), uplo="L")
    return float(rcond), int(info)


def determined(N: np.ndarray) -> bool:
    """Whether N, scaled to a unit diagonal, is positive definite with a reciprocal condition of at
    least :data:`RANK_TOLERANCE` — what :meth:`Solution.from_normal_matrix` inverts whole. A
    Cholesky factorisation of N alone is no test: on exactly dependent columns it fails or succeeds
    on a rounding-sized pivot depending on the CPU and the OpenBLAS build."""
    Ns, _ = unit_diagonal(N)
    try:
        c, _ = sl.cho_factor(Ns, lower=True)
    except (np.linalg.LinAlgError, ValueError):
        return False
    rcond, info = factor_rcond(c, Ns)
    return info == 0 and rcond >= RANK_TOLERANCE


def _inverse(Ns: np.ndarray) -> tuple[np.ndarray, float, np.ndarray | None, np.ndarray | None]:
    """(Ns⁻¹, condition number, None, None) for a well-conditioned Ns (Cholesky; the condition
    number is LAPACK's 1-norm estimate from the factor, O(n²), where eigenvalues cost O(n³) ×
    4 — 0.14 s for 1 300 parameters); for a rank-deficient one (reciprocal condition below
    RANK_TOLERANCE, or not positive definite) the inverse on the determined subspace, the
    eigenvalue ratio, the eigenvalues and eigenvectors, whose null directions the warnings name."""
    try:
        c, _ = sl.cho_factor(Ns, lower=True)
        rcond, info = factor_rcond(c, Ns)
    except (np.linalg.LinAlgError, ValueError):
        rcond, info = 0.0, 1
    if info == 0 and rcond >= RANK_TOLERANCE:
        inv, info = sl.lapack.dpotri(c, lower=True)
        if info == 0:
            inv = np.tril(inv)
            return inv + np.tril(inv, -1).T, 1.0 / rcond, None, None
    evals, evecs = np.linalg.eigh(Ns)
    keep = evals >= RANK_TOLERANCE * evals[-1]
    cond = float(evals[-1] / max(evals[0], 1e-300))
    return (evecs[:, keep] / evals[keep]) @ evecs[:, keep].T, cond, evals, evecs


def _observability_warnings(names, prior, jacobian, evecs, bad) -> list[str]:
    """Warnings for the free parameters no observation depends on (columns of ``jacobian`` all
    zero, no prior) and for the combinations of parameters along the normal matrix's singular
    directions (eigenvectors ``evecs`` where ``bad``)."""
    warnings = []
    zero_cols = []
    if jacobian is not None and jacobian.size:
        used = np.asarray(abs(jacobian).sum(axis=0)).ravel() > 0  # dense or sparse
        zero_cols = [names[j] for j in range(len(names)) if not used[j] and not prior[j]]
        for nm in zero_cols:
            warnings.append(f"{nm} is not observable: no observation depends on it; its value is "
                            "the start value")
    for k in np.flatnonzero(bad):
        v = evecs[:, k]
        involved = [names[j] for j in np.argsort(-np.abs(v))
                    if abs(v[j]) > 0.2 and names[j] not in zero_cols]
        if involved:
            warnings.append("the data cannot separate " + " and ".join(involved) + ": only a "
                            "combination of them is determined (a singular direction of the "
                            "normal equations)")
    return warnings


@dataclass
class Solution:
    """Estimates with their covariance and diagnostics. Values/σ SI inside; JSON in display
    units."""

    parameters: ParameterSet
    covariance: np.ndarray  #: (n_free, n_free), SI
    sigma0: float  #: a-posteriori standard deviation of unit weight
    dof: float  #: effective redundancy (robustly down-weighted observations count partly)
    condition_number: float
    warnings: list[str] = field(default_factory=list)
    residuals: np.ndarray = field(default_factory=lambda: np.zeros(0))
    residuals_before: dict = field(default_factory=dict)
    residuals_after: dict = field(default_factory=dict)
    history: list[dict] = field(default_factory=list)
    converged: bool = True
    extra: dict = field(default_factory=dict)  #: method-specific results for the JSON
    #: free parameters named so are nuisance (e.g. hundreds of trajectory corrections):
    #: solution.json gives their values and σ but leaves them out of the correlation matrix and
    #: the history
    nuisance_prefix: str | None = None

    @classmethod
    def from_normal_matrix(cls, params, N, sigma0_sq, dof, *, residuals, weights, before, history,
                           converged, jacobian=None, variance_factor=None) -> "Solution":
        """The solution of normal matrix N (priors included): covariance = variance_factor · N⁻¹
        (default σ0²), with warnings for directions the data cannot determine."""
        names = params.free_names
        prior = [p.prior_sigma is not None for p in params.free]  # constrained by their priors
        Ns, d = unit_diagonal(N)
        cov_s, cond, evals, evecs = _inverse(Ns)
        bad = np.zeros(0, bool) if evecs is None else evals < RANK_TOLERANCE * evals[-1]
        warnings = _observability_warnings(names, prior, jacobian, evecs, bad)
        cov = (sigma0_sq if variance_factor is None else variance_factor) * cov_s / np.outer(d, d)
        sig = np.sqrt(np.clip(np.diag(cov), 0, None))
        if np.any(bad):
            # directions with no information: σ is infinite along them
            for k in np.flatnonzero(bad):
                sig[np.abs(evecs[:, k]) > 0.2] = np.inf
            np.fill_diagonal(cov, np.where(np.isinf(sig), np.inf, np.diag(cov)))
        with np.errstate(invalid="ignore", divide="ignore"):
            corr = cov / np.outer(sig, sig)
        for i, j in zip(*np.nonzero(np.triu(np.abs(np.nan_to_num(corr)) > CORRELATION_WARNING, 1))):
            if not (prior[i] and prior[j]):  # two parameters held by priors: nuisance, no warning
                warnings.append(
                    f"{names[i]} and {names[j]} are strongly correlated (ρ = {corr[i, j]:+.3f}): "
                    "the data barely separate them and their σ are large"
                )
        return cls(
            parameters=params, covariance=cov, sigma0=float(np.sqrt(sigma0_sq)), dof=float(dof),
            condition_number=cond, warnings=warnings, residuals=residuals,
            residuals_before=before, residuals_after=residual_stats(residuals, weights),
            history=history, converged=converged,
        )

    @property
    def sigma(self) -> dict[str, float]:
        """σ of each free parameter (SI)."""
        sigma = np.sqrt(np.clip(np.diag(self.covariance), 0, None))
        return dict(zip(self.parameters.free_names, sigma))

    @property
    def correlation(self) -> np.ndarray:
        s = np.sqrt(np.clip(np.diag(self.covariance), 1e-300, None))
        with np.errstate(invalid="ignore"):
            return self.covariance / np.outer(s, s)

    @property
    def values(self) -> dict[str, float]:
        return self.parameters.values()

    def to_dict(self, truth: dict[str, float] | None = None) -> dict:
        """The ``solution.json`` document: display units; ``truth`` (SI) adds truth and error."""
        sig = self.sigma
        params = {}
        for p in self.parameters:
            entry = {"value": p.to_display(p.value), "sigma": None, "unit": p.display_unit,
                     "free": p.free}
            if p.name in sig:
                s = sig[p.name]
                entry["sigma"] = p.to_display(s) if np.isfinite(s) else None
            if truth and p.name in truth:
                entry["truth"] = p.to_display(truth[p.name])
                entry["error"] = p.to_display(p.value - truth[p.name])
            params[p.name] = entry
        shown = [i for i, n in enumerate(self.parameters.free_names)
                 if not (self.nuisance_prefix and n.startswith(self.nuisance_prefix))]
        corr = self.correlation[np.ix_(shown, shown)]
        free = [self.parameters.free[i] for i in shown]
        return {
            "parameters": params,
            "correlation": {
                "names": [p.name for p in free],
                "matrix": [[None if not np.isfinite(v) else round(float(v), 6) for v in row]
                           for row in corr],
            },
            "residuals": {"before": self.residuals_before, "after": self.residuals_after},
            "sigma0": self.sigma0,
            "dof": self.dof,
            "condition_number": self.condition_number,
            "converged": self.converged,
            "warnings": self.warnings,
            "history": [
                {**{k: v for k, v in h.items() if k != "values"},
                 "values": {p.name: p.to_display(h["values"][p.name]) for p in free}}
                for h in self.history
            ],
            **self.extra,
        }
