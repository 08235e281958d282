"""The one residual protocol every problem of the engine implements, and the solver's options.

After Ceres (a cost function owns its residuals and their Jacobian; ``Solver::Options`` are kept
apart from the problem) and small_gicp (each factor linearises itself): a problem is an object that
holds its parameters (start values, priors, free or fixed), the a-priori σ of its residual rows and,
for any parameter values, its residuals and their Jacobian w.r.t. its free parameters.
:func:`calidar.adjust.solve` takes such a problem and a :class:`SolverOptions` — nothing else.

Problems address their parameters by typed blocks (:class:`Block`: a key that says what each
parameter is — a trajectory knot, a beam's footprint diameter, a setup's polar observation —
resolved once against the parameter set), not by parsing names on every evaluation; the values the
engine hands them (:class:`Values`) are a vector that also reads by name.
"""

from __future__ import annotations

from collections.abc import Callable, Iterator, Mapping, Sequence
from dataclasses import dataclass, field
from typing import Generic, TypeVar

import numpy as np

from calidar.adjust.m_estimator import COVARIANCE_MODELS, ROBUST_K
from calidar.adjust.parameters import ParameterSet

K = TypeVar("K")
#: Jointly Gaussian priors: groups of free parameters (names, correlation matrix R), each its own σ.
PriorCorrelation = Sequence[tuple[Sequence[str], np.ndarray]]

#: stop when every step is below this fraction of its parameter's σ (changes no one can see)
STEP_IN_SIGMA = 1e-3


@dataclass(frozen=True)
class SolverOptions:
    """How the engine iterates — apart from what it estimates (the problem).

    robust: IRLS weights "cauchy" (for clutter), "huber" or None; robust_k: their tuning constant
    (None: 2.385 Cauchy, 1.345 Huber, 95 % efficiency); robust_scale: re-estimate the residuals'
    scale by MAD for those weights (False when σ is trusted); max_iter: Levenberg–Marquardt steps
    at most; tol: relative change of the cost (and absolute step) below which it stops;
    step_in_sigma: stop when every step is below this fraction of its parameter's σ; covariance:
    "irls" (variance factor · N⁻¹, N the IRLS-weighted normal matrix) or "sandwich" (the robust
    fit's M-estimator sandwich, :mod:`calidar.adjust.m_estimator`; for least squares the same
    σ0²·N⁻¹). Whether the
    observations' σ are absolute is the problem's (:attr:`ResidualProblem.absolute_sigma`), not an
    option.
    """

    robust: str | None = "cauchy"
    robust_k: float | None = None
    robust_scale: bool = True
    max_iter: int = 30
    tol: float = 1e-10
    step_in_sigma: float = STEP_IN_SIGMA
    covariance: str = "irls"

    def __post_init__(self):
        if self.covariance not in COVARIANCE_MODELS:
            raise ValueError(f"covariance must be one of {COVARIANCE_MODELS}, "
                             f"got {self.covariance!r}")
        if self.robust is not None and self.robust not in ROBUST_K:
            raise ValueError(f"robust must be one of {sorted(ROBUST_K)} or None, "
                             f"got {self.robust!r}")
        if not (isinstance(self.max_iter, int) and self.max_iter >= 0):
            raise ValueError(f"max_iter must be an integer ≥ 0, got {self.max_iter!r}")
        if not (self.tol >= 0 and self.step_in_sigma >= 0):
            raise ValueError("tol and step_in_sigma must be ≥ 0, "
                             f"got {self.tol}, {self.step_in_sigma}")


class Values(Mapping[str, float]):
    """Parameter values (SI) as the engine hands them to a problem: a vector over the parameter
    set's names (``vector``), read by name like a dict or by a resolved :class:`Block`."""

    __slots__ = ("names", "vector", "_index")

    def __init__(self, names: tuple[str, ...], vector: np.ndarray, index: Mapping[str, int]):
        self.names, self.vector, self._index = names, vector, index

    def __getitem__(self, name: str) -> float:
        return float(self.vector[self._index[name]])

    def __iter__(self) -> Iterator[str]:
        return iter(self.names)

    def __len__(self) -> int:
        return len(self.names)

    def __contains__(self, name) -> bool:
        return name in self._index


@dataclass(frozen=True)
class Block(Generic[K]):
    """Parameters of one kind addressed by typed keys: ``keys[i]`` says what the parameter
    ``names[i]`` is (e.g. a :class:`calidar.strips.trajectory_errors.Knot`); resolved once, when
    the problem is built, against its parameters' layout (``over``: their names in the engine's
    vector order, ``positions``: where this block's sit in it), and read on every evaluation as a
    vector (:meth:`take`) without looking at a name again."""

    names: tuple[str, ...]
    keys: tuple[K, ...]
    over: tuple[str, ...] | None = field(default=None, repr=False, compare=False)
    positions: np.ndarray | None = field(default=None, repr=False, compare=False)

    @classmethod
    def of(cls, names: ParameterSet | Sequence[str], layout: Mapping[str, K]) -> "Block[K]":
        """The parameters among ``names`` (a problem's :class:`ParameterSet`, or their names in
        order) that ``layout`` (name → key) knows, in the layout's order, with their positions."""
        over = names.layout()[0] if isinstance(names, ParameterSet) else tuple(names)
        index = {n: i for i, n in enumerate(over)}
        hit = [(n, k) for n, k in layout.items() if n in index]
        return cls(tuple(n for n, _ in hit), tuple(k for _, k in hit), over,
                   np.array([index[n] for n, _ in hit], dtype=np.intp))

    def take(self, values: Mapping[str, float]) -> np.ndarray:
        """This block's values (SI) in key order: a gather from a :class:`Values` vector of the
        layout it was resolved against, else by name."""
        if isinstance(values, Values) and self.positions is not None \
                and (values.names is self.over or values.names == self.over):
            return values.vector[self.positions]
        return np.array([values[n] for n in self.names], dtype=float)


def values_of(params: ParameterSet, x: np.ndarray) -> Values:
    """``params``' values with the free ones from ``x``, as :class:`Values`."""
    names, index, free, start = params.layout()
    vector = start.copy()
    vector[free] = x
    return Values(names, vector, index)


class ResidualProblem:
    """What the engine solves: ``parameters`` (start values SI, priors, free flags), the
    a-priori σ of each residual row (``sigma``: scalar or (n,)), jointly Gaussian priors
    (``prior_correlation``) and, for given values, the residuals (n,) in observation units and
    their Jacobian (n, n_free) w.r.t. ``parameters.free`` — dense or scipy.sparse.

    Subclasses implement :meth:`residuals` and, where they can, an analytic :meth:`jacobian`
    (the default is central differences with each parameter's step); :meth:`normal_matrix` may
    replace JᵀWJ (a likelihood's expected information: Fisher scoring). The engine asks for the
    residuals at every trial step and for the Jacobian only where a step was taken.

    >>> import numpy as np
    >>> from calidar.adjust import (Block, Parameter, ParameterSet, ResidualProblem, SolverOptions,
    ...                             solve)
    >>> class Mean(ResidualProblem):  # y_i = μ + e_i, σ = 0.5
    ...     def __init__(self, y):
    ...         self.y, self.sigma = y, 0.5
    ...         self.parameters = ParameterSet([Parameter("mu", 0.0, "m")])
    ...         self.mu = Block.of(self.parameters, {"mu": "mean"})
    ...     def residuals(self, values):
    ...         return self.mu.take(values)[0] - self.y
    ...     def jacobian(self, values):
    ...         return np.ones((self.y.size, 1))
    >>> sol = solve(Mean(np.array([1.0, 2.0, 3.0, 6.0])), SolverOptions(robust=None))
    >>> round(sol.values["mu"], 9), round(float(sol.sigma["mu"]), 6)  # the mean, σ = s/√n
    (3.0, 1.080123)
    """

    parameters: ParameterSet
    sigma: float | np.ndarray = 1.0
    prior_correlation: PriorCorrelation = ()
    #: the rows' σ are absolute (each row's own noise, as the strips' from their points' scatter),
    #: not only relative weights: the covariance is then never shrunk by an a-posteriori σ0 below 1,
    #: priors or not (only raised by one above 1; cf. ``absolute_sigma`` of
    #: scipy.optimize.curve_fit). False: σ0²·N⁻¹ without priors.
    absolute_sigma: bool = False

    def residuals(self, values: Mapping[str, float]) -> np.ndarray:
        raise NotImplementedError

    def jacobian(self, values: Mapping[str, float]):
        params = self.parameters
        x = np.array([values[n] for n in params.free_names], float)
        return numerical_jacobian(self.residuals, params, x)

    def normal_matrix(self, values: Mapping[str, float]) -> np.ndarray | None:
        """The normal matrix to use instead of JᵀWJ, or None (the usual Gauss–Newton one)."""
        return None

    def evaluate(self, values: Mapping[str, float], jacobian: bool = True):
        """(residuals, Jacobian or None) at ``values``: both at once, as Ceres' ``Evaluate``."""
        return self.residuals(values), (self.jacobian(values) if jacobian else None)


class FunctionProblem(ResidualProblem):
    """A problem from plain functions of the values (name → SI): ``residual_fn`` and optionally
    ``jacobian_fn`` (else central differences) and ``normal_fn``."""

    def __init__(self, residual_fn: Callable[[Mapping[str, float]], np.ndarray],
                 parameters: ParameterSet, sigma: float | np.ndarray = 1.0, jacobian_fn=None,
                 prior_correlation: PriorCorrelation = (), normal_fn=None,
                 absolute_sigma: bool = False):
        self.residual_fn, self.jacobian_fn, self.normal_fn = residual_fn, jacobian_fn, normal_fn
        self.parameters, self.sigma, self.prior_correlation = parameters, sigma, prior_correlation
        self.absolute_sigma = absolute_sigma

    def residuals(self, values):
        return self.residual_fn(values)

    def jacobian(self, values):
        return super().jacobian(values) if self.jacobian_fn is None else self.jacobian_fn(values)

    def normal_matrix(self, values):
        return None if self.normal_fn is None else self.normal_fn(values)


def numerical_jacobian(fn: Callable[[Mapping[str, float]], np.ndarray], params: ParameterSet,
                       x: np.ndarray) -> np.ndarray:
    """Central differences of fn w.r.t. the free parameters, (n_obs, n_free)."""
    cols = []
    for j, p in enumerate(params.free):
        h = p.diff_step
        xp, xm = x.copy(), x.copy()
        xp[j] += h
        xm[j] -= h
        cols.append((fn(params.values_with(xp)) - fn(params.values_with(xm))) / (2.0 * h))
    return np.stack(cols, axis=1) if cols else np.zeros((0, 0))


def prior_groups(free, prior_correlation: PriorCorrelation
                 ) -> list[tuple[np.ndarray, np.ndarray, np.ndarray]]:
    """Priors as (free-parameter positions, centres, precision matrix) groups: the correlated
    groups given, and the other parameters with a prior_sigma as one diagonal group."""
    pos = {p.name: i for i, p in enumerate(free)}
    out, joint = [], set()
    for names, R in prior_correlation:
        idx = np.array([pos[nm] for nm in names], dtype=int)
        if any(free[i].prior_sigma is None for i in idx):
            raise ValueError("prior_correlation: every parameter of a group needs a prior_sigma")
        d = np.array([free[i].prior_sigma for i in idx])
        precision = np.linalg.inv(np.asarray(R, float)) / np.outer(d, d)  # Σ⁻¹ = D⁻¹R⁻¹D⁻¹
        out.append((idx, np.array([free[i].prior_center for i in idx]), precision))
        joint.update(idx.tolist())
    alone = [i for i, p in enumerate(free) if p.prior_sigma is not None and i not in joint]
    idx = np.array(alone, dtype=int)
    if idx.size:
        out.append((idx, np.array([free[i].prior_center for i in idx]),
                    np.diag([1.0 / free[i].prior_sigma ** 2 for i in idx])))
    return out
