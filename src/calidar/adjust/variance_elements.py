"""Variance components per element: each prior carries its own component label, so one
correlated prior group (e.g. a trajectory's shifts over the whole flight, one Gauss–Markov process)
can hold priors of several components (e.g. the same axis in different stretches of time).

The stated prior covariance Σ (precision P = Σ⁻¹) becomes F Σ F with F = diag(fᵢ), fᵢ the σ
factor of element i's component: precision D P D with D = F⁻¹. Each component's factor is
estimated from the marginal variances of its priors' residuals, the fixed point of
E[vᵢ²] = f²Σᵢᵢ − Qᵢᵢ (the ``marginal`` form of
:func:`calidar.adjust.variance_components.estimate_components`, Dempster, Laird & Rubin 1977;
Koch 1999 §3.6.3):

    f²ₖ ← Σ_{i∈k} vᵢ²/Σᵢᵢ / rₖ,   rₖ = nₖ − Σ_{i∈k} Qᵢᵢ/(f²ₖΣᵢᵢ)

with rₖ the component's redundancy (how many of its nₖ priors the data check). The update's
own relative variance is 2/mₖ, mₖ = (tr Cₖ)² / tr(Cₖ²) the effective number of independent
priors behind it, Cₖ = the covariance of the normalised residuals vᵢ/√Σᵢᵢ of k (f²ₖΣ − Q on
k's priors, Satterthwaite 1946): correlated priors (a Gauss–Markov process sampled every
second) count far less than rₖ. Between iterations the caller may pool the raw updates (``pool``:
e.g. a smoothing over time of components that are one quantity at different times), which makes
the estimate a penalised one.
"""

from __future__ import annotations

from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass

import numpy as np

from calidar.adjust.solution import cholesky_inverse
from calidar.errors import CalibrationError

#: pool(raw, effective number, redundancy at the start) → new factors σ² per label (raw: the update
#: each label's own priors give, of relative variance 2 / effective number)
Pool = Callable[[dict[str, float], dict[str, float], dict[str, float]], dict[str, float]]


@dataclass
class ElementComponents:
    """The estimated factors σ² per label and what they rest on."""

    variance: dict[str, float]  #: per label the factor σ² on its stated prior variances
    redundancy: dict[str, float]  #: per label rₖ at the estimate
    redundancy_start: dict[str, float]  #: per label rₖ at the start values
    raw: dict[str, float]  #: per label the last update its own priors gave (before pooling)
    effective: dict[str, float]  #: per label mₖ, the raw update's relative variance being 2/mₖ
    size: dict[str, int]  #: per label nₖ
    iterations: int
    converged: bool


def scaled_normals(JtWJ: np.ndarray, JtWr: np.ndarray, x0: np.ndarray,
                   priors: Sequence[tuple[np.ndarray, np.ndarray, np.ndarray]], scale: np.ndarray,
                   observations: float = 1.0) -> tuple[np.ndarray, np.ndarray]:
    """(N, b) of the linearised problem (the arguments of :func:`estimate_elements`) with each free
    parameter's prior σ multiplied by ``scale[i]``: N = JᵀWJ / σ²_obs + Σ P/(s sᵀ), b the matching
    right-hand side, so that x̂ = x0 + N⁻¹ b."""
    N, b = JtWJ / observations, -JtWr / observations
    for idx, center, P in priors:
        Pf = P / np.outer(scale[idx], scale[idx])
        N[np.ix_(idx, idx)] += Pf
        b[idx] -= Pf @ (x0[idx] - center)
    return N, b


def estimate_elements(JtWJ: np.ndarray, JtWr: np.ndarray, x0: np.ndarray,
                      priors: Sequence[tuple[np.ndarray, np.ndarray, np.ndarray]],
                      labels: Sequence[str | None], start: Mapping[str, float], *,
                      observations: float = 1.0, pool: Pool | None = None, floor: float = 1e-6,
                      tol: float = 1e-3, max_iter: int = 60) -> ElementComponents:
    """The factors σ²ₖ (module docstring) of the linearised problem r(x) = r₀ + J(x − x0) with
    ``JtWJ`` = JᵀWJ, ``JtWr`` = JᵀWr₀ (the observations' variance factor held at ``observations``),
    the engine's ``priors`` (free-parameter positions, centres, stated precision), ``labels[i]``
    the component of free parameter i (None: its prior kept as stated), starting from ``start``
    (every label). Iterates until no factor changes by more than ``tol`` (relative) or ``max_iter``
    times; each factor ≥ ``floor``."""
    lab = np.array([s or "" for s in labels], dtype=object)
    names = sorted(start)
    code = {n: k for k, n in enumerate(names)}
    which = np.array([code.get(s, -1) for s in lab])  # −1: stated
    # Σ: the stated prior covariance
    sigma, centre = np.zeros((lab.size, lab.size)), np.zeros(lab.size)
    for idx, center, P in priors:
        sigma[np.ix_(idx, idx)], centre[idx] = np.linalg.inv(P), center
    sii = np.diag(sigma).copy()
    on = which >= 0
    members = {n: np.flatnonzero(which == k) for n, k in code.items()}
    size = {n: int(np.sum(which == k)) for n, k in code.items()}
    var = np.array([start[n] for n in names], float)
    converged, it, red_start, red, raw = False, 0, None, None, None
    as_dict = lambda a: {n: float(a[k]) for n, k in code.items()}  # noqa: E731
    for it in range(1, max_iter + 1):
        f = np.where(which >= 0, np.sqrt(var[np.maximum(which, 0)]), 1.0)
        N, b = scaled_normals(JtWJ, JtWr, x0, priors, f, observations)
        Q = cholesky_inverse(N)
        if Q is None:
            raise CalibrationError("variance components: the normal matrix is not positive "
                                   "definite")
        x = x0 + Q @ b
        spread = np.bincount(which[on], (x[on] - centre[on]) ** 2 / sii[on], len(names))
        trace = np.bincount(which[on], np.diag(Q)[on] / sii[on], len(names))
        red = np.array([size[n] for n in names]) - trace / var
        red_start = red.copy() if red_start is None else red_start
        raw = np.where(red > 1e-9, spread / np.maximum(red, 1e-9), var)
        eff = {n: _effective(var[code[n]] * sigma[np.ix_(i, i)] - Q[np.ix_(i, i)], sii[i])
               for n, i in members.items()}
        new = pool(as_dict(raw), eff, as_dict(red_start)) if pool else as_dict(raw)
        new = np.maximum(np.array([new[n] for n in names], float), floor)
        change = float(np.max(np.abs(np.log(new / var)))) if names else 0.0
        var = new
        if change < tol:
            converged = True
            break
    return ElementComponents(as_dict(var), as_dict(red), as_dict(red_start), as_dict(raw), eff,
                             size, it, converged)


def _effective(cov: np.ndarray, sii: np.ndarray) -> float:
    """(tr C)² / tr(C²) of C = ``cov`` normalised by √Σᵢᵢ: how many independent priors it is
    worth."""
    if sii.size == 0:
        return 0.0
    C = cov / np.sqrt(np.outer(sii, sii))
    den = float(np.sum(C * C))
    return float(np.trace(C)) ** 2 / den if den > 0 else 0.0
