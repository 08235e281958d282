"""The maximum of the exact count likelihood, solved by the one engine
(:func:`calidar.adjust.solve`).

The engine minimises ½·Σ r² over residual functions. With one residual per shot,
r_s = √(2·(−log P_s(k_s) + ½)), that sum IS the negative log-likelihood (plus a constant), so
the engine's minimum is the maximum-likelihood estimate, exactly, with its own damping, stop
rule and history; the exact Jacobian ∂r_s = −∂log P_s / r_s comes from the likelihood's score.
(The ½ keeps every r_s ≥ 1 where the shot is unsurprising, so the engine's Gauss–Newton matrix
JᵀJ ≈ Σ score·scoreᵀ: the outer-product (BHHH) approximation of the information.)

What the engine cannot give here is the covariance: its σ0²·(JᵀJ)⁻¹ is a least-squares
formula. σ comes from the observed information instead — the Hessian of the negative
log-likelihood at the estimate, by central differences of the exact score — and the Solution
is rebuilt from it (:meth:`calidar.adjust.Solution.from_normal_matrix`, variance factor 1).

Bounds: the engine has none, so the model's domain (D > 0, Λ > ln 2, q < 1) is enforced by
the likelihood (−inf outside: the engine rejects the step), and the physical bounds (D within
the searched range, Λ ≤ MAX_PEAK, |bias| ≤ max_bias) are checked after the solve: a diameter or
a peak beyond its bound is re-solved held at the bound (the constrained maximum, flagged; q is
held at 0 the same way when the likelihood falls as it grows); a bias beyond its bound is a
:class:`calidar.errors.CalibrationError`.
"""

from __future__ import annotations

from dataclasses import dataclass, field, replace
from functools import cached_property, lru_cache

import numpy as np

from calidar.adjust import (Block, Parameter, ParameterSet, ResidualProblem, Solution,
                            SolverOptions, solve)
from calidar.errors import CalibrationError
from calidar.photon.likelihood import Shots, fisher_information, log_likelihood
from calidar.photon.parameters import BIASES, NAMES, UNITS, parameter_name

STAGE_ONE, MARGIN = 3, 0.0
#: added to every shot's −log P inside its residual (a constant: the minimum is unchanged)
OFFSET = 0.5
MAX_PEAK = 500.0  #: photons; a CCR peak beyond this is not a CCR return
#: a shot-loss rate starting below this is first held at 0 (its bound), then freed if the data ask
LOSS_START = 0.1
#: relative to max(|value|, 1): central-difference steps of the Hessian
STEPS = {"along_track_bias": 1e-4, "cross_track_bias": 1e-4, "footprint_diameter": 1e-4,
         "ccr_peak_photons": 1e-4, "shot_loss_rate": 1e-5}


@dataclass(frozen=True)
class Layout:
    """How the parameters of G beams map to named parameters: one row (b_a, b_c, D, Λ, q) per beam
    (:data:`NAMES`); with ``shared_bias`` one b_a and one b_c for all of them."""

    groups: tuple[str, ...]
    shared_bias: bool = False

    def name(self, g: int, base: str) -> str:
        single = len(self.groups) == 1 or (self.shared_bias and base in BIASES)
        return parameter_name(base, None if single else self.groups[g])

    @property
    def names(self) -> list[str]:
        return list(dict.fromkeys(self.name(g, b) for g in range(len(self.groups)) for b in NAMES))

    def columns(self, names: list[str]) -> np.ndarray:
        """(G, 5) position of each beam's parameter among ``names`` (−1: absent); worked out once
        per list of names (the solver asks on every Jacobian; not to be changed)."""
        return _columns(self, tuple(names))

    @cached_property
    def block(self) -> Block:
        """The parameters as one typed block: key (beam index, quantity), the beam None for a
        shared bias."""
        keys = {}
        for g in range(len(self.groups)):
            for b in NAMES:
                shared = len(self.groups) == 1 or (self.shared_bias and b in BIASES)
                keys.setdefault(self.name(g, b), (None if shared else g, b))
        return Block(tuple(keys), tuple(keys.values()))

    @cached_property
    def quantity(self) -> dict[str, str]:
        """Each parameter's quantity (one of :data:`NAMES`) by its name: the typed block's keys,
        never a name taken apart."""
        return {n: q for n, (_, q) in zip(self.block.names, self.block.keys)}

    def beams(self, name: str) -> range | tuple[int]:
        """The beams (indices into :attr:`groups`) parameter ``name`` belongs to: all for a shared
        one."""
        g = self.block.keys[self.block.names.index(name)][0]
        return range(len(self.groups)) if g is None else (g,)

    @cached_property
    def _cells(self) -> np.ndarray:
        """(G, 5): the position in :attr:`block` of each beam's parameter."""
        return self.columns(list(self.block.names))

    def theta(self, values: dict[str, float], block: Block | None = None) -> np.ndarray:
        """(G, 5) the beams' parameter rows (:data:`NAMES`) from ``values``, read through ``block``
        (:attr:`block` resolved against a problem's parameters, :meth:`Problem.at`) when given."""
        return (block or self.block).take(values)[self._cells]

    def values(self, theta: np.ndarray) -> dict[str, float]:
        out = {}
        for g in range(len(self.groups)):
            for j, b in enumerate(NAMES):
                out.setdefault(self.name(g, b), float(theta[g, j]))
        return out


@dataclass
class Problem(ResidualProblem):
    """The likelihood of the counts of ``shots`` as a function of named parameters; with
    ``parameters`` (:meth:`at`) the engine's problem: one residual per shot whose squares sum to
    −log L (+ const), its exact Jacobian, the Fisher information as the normal matrix."""

    shots: Shots
    layout: Layout
    jitter: float
    _last: dict = field(default_factory=dict, repr=False, compare=False)
    _information: dict = field(default_factory=dict, repr=False, compare=False)
    parameters: ParameterSet | None = field(default=None, repr=False, compare=False)
    #: the layout's block resolved against :attr:`parameters` (:meth:`at`): the engine's values
    #: gathered by position
    block: Block | None = field(default=None, repr=False, compare=False)

    def with_counts(self, counts: list[np.ndarray]) -> "Problem":
        return Problem(self.shots.with_counts(np.concatenate(counts)), self.layout, self.jitter,
                       _information=self._information)

    def at(self, parameters: ParameterSet) -> "Problem":
        """This problem solved for ``parameters`` (the caches shared; the parameters' block
        resolved once)."""
        layout = self.layout.block
        block = Block.of(parameters, dict(zip(layout.names, layout.keys)))
        same = block.names == layout.names
        return replace(self, parameters=parameters, block=block if same else None)

    def nll_terms(self, values: dict[str, float]) -> tuple[np.ndarray, np.ndarray]:
        """(log P, score) per shot at ``values``; the last evaluation is kept (the engine asks for
        the residuals and then the Jacobian at the same point)."""
        theta = self.layout.theta(values, self.block)
        key = theta.tobytes()
        if self._last.get("key") != key:
            self._last.update(key=key, terms=log_likelihood(theta, self.shots, self.jitter))
        return self._last["terms"]

    def nll(self, values: dict[str, float]) -> float:
        return float(-self.nll_terms(values)[0].sum())

    def gradient(self, values: dict[str, float], names: list[str]) -> np.ndarray:
        """∂(−log L)/∂ the parameters ``names``."""
        _, score = self.nll_terms(values)
        return -self._scatter(score, names).sum(axis=0)

    def _scatter(self, score: np.ndarray, names: list[str]) -> np.ndarray:
        """Per-shot derivatives w.r.t. ``names`` from the per-shot group-row derivatives (n, 5)."""
        cols = self.layout.columns(names)[self.shots.group]  # (n, 5)
        out = np.zeros((score.shape[0], len(names)))
        for j in range(score.shape[1]):
            use = cols[:, j] >= 0
            np.add.at(out, (np.flatnonzero(use), cols[use, j]), score[use, j])
        return out

    def residuals(self, values: dict[str, float]) -> np.ndarray:
        logp, _ = self.nll_terms(values)
        with np.errstate(invalid="ignore"):
            return np.sqrt(2.0 * (OFFSET - logp))

    def jacobian(self, values: dict[str, float], free: list[str] | None = None) -> np.ndarray:
        """∂residuals/∂ the parameters ``free`` (default: the free ones of :attr:`parameters`)."""
        free = self.parameters.free_names if free is None else free
        logp, score = self.nll_terms(values)
        r = np.sqrt(2.0 * (OFFSET - logp))
        return -self._scatter(score, free) / r[:, None]

    def normal_matrix(self, values: dict[str, float]) -> np.ndarray:
        """Fisher scoring: the engine's normal matrix is the expected information
        (:meth:`scoring_information`)."""
        return self.scoring_information(values, self.parameters.free_names)

    def information(self, values: dict[str, float], names: list[str]) -> np.ndarray:
        """Expected (Fisher) information of the counts w.r.t. ``names`` at ``values``."""
        return fisher_information(self.layout.theta(values), self.shots, self.jitter,
                                  self.layout.columns(names), len(names))

    def scoring_information(self, values: dict[str, float], names: list[str]) -> np.ndarray:
        """The Fisher information for the solver's steps: recomputed only when some parameter moved
        by more than a quarter of its σ since a computation for these parameters. It changes slowly
        and does not depend on the counts, so problems that differ only in their counts (the
        bootstrap's) share it; the gradient, and so the maximum, stay exact."""
        x = np.array([values[n] for n in names])
        held = self._information.setdefault(tuple(names), [])
        for x0, info, sigma in held:
            if np.all(np.abs(x - x0) <= 0.25 * sigma):
                return info
        info = self.information(values, names)
        sigma = np.sqrt(np.clip(np.diag(np.linalg.pinv(info)), 1e-30, None))
        held.insert(0, (x, info, sigma))
        del held[32:]
        return info

    def hessian(self, values: dict[str, float], names: list[str]) -> np.ndarray:
        """Observed information: the Hessian of −log L w.r.t. ``names`` (central differences of the
        score)."""
        h = np.zeros((len(names), len(names)))
        for j, nm in enumerate(names):
            step = STEPS[self.layout.quantity[nm]] * max(abs(values[nm]), 1.0)
            hi, lo = dict(values), dict(values)
            hi[nm] += step
            # a shot-loss rate at its bound 0: forward differences
            if self.layout.quantity[nm] == "shot_loss_rate" and values[nm] < step:
                h[:, j] = (self.gradient(hi, names) - self.gradient(lo, names)) / step
                continue
            lo[nm] -= step
            h[:, j] = (self.gradient(hi, names) - self.gradient(lo, names)) / (2.0 * step)
        return 0.5 * (h + h.T)


@lru_cache(maxsize=64)
def _columns(layout: Layout, names: tuple[str, ...]) -> np.ndarray:
    pos = {n: i for i, n in enumerate(names)}
    return np.array([[pos.get(layout.name(g, b), -1) for b in NAMES]
                     for g in range(len(layout.groups))])


@dataclass
class Fit:
    """A maximum-likelihood solve: the Solution (σ from the observed information), −log L, flags."""

    solution: Solution
    nll: float
    at_limit: list[str] = field(default_factory=list)  #: parameters held at a bound


def parameter_set(layout: Layout, start: dict[str, float],
                  fixed: dict[str, float] | None = None) -> ParameterSet:
    """Named parameters at ``start``; those in ``fixed`` held at the given value."""
    fixed = fixed or {}
    return ParameterSet(Parameter(n, float(fixed.get(n, start[n])), UNITS[q], free=n not in fixed,
                                  step=STEPS[q]) for n, q in layout.quantity.items())


def maximise(problem: Problem, start: dict[str, float], bounds,
             fixed: dict[str, float] | None = None, max_iter: int = 60,
             covariance: bool = True) -> Fit:
    """The maximum likelihood from ``start`` (parameters in ``fixed`` held), within ``bounds``
    (:class:`Bounds`); the covariance from the observed information (``covariance=False``: the
    engine's, when only the estimate is wanted)."""
    fixed, kind, layout = dict(fixed or {}), problem.layout.quantity, problem.layout

    def loss(n):  # a free shot-loss rate
        return kind[n] == "shot_loss_rate" and n not in fixed

    at_zero = {n: 0.0 for n in start if loss(n) and start[n] < LOSS_START}
    sol = _solve(problem, parameter_set(layout, start, {**fixed, **at_zero}), max_iter)
    # q = 0 is the constrained maximum where −log L grows with q (Kuhn–Tucker); free the others
    if at_zero:
        grow = problem.gradient(sol.values, list(at_zero))
        at_zero = {n: 0.0 for n, g in zip(at_zero, grow) if g >= 0}
        if len(at_zero) < len(grow):
            freed = {n: max(start[n], 0.02) for n in sol.values if loss(n) and n not in at_zero}
            params = parameter_set(layout, {**sol.values, **freed}, {**fixed, **at_zero})
            sol = _solve(problem, params, max_iter)
    values = sol.values
    held = bounds.beyond(values, fixed, layout)
    if held:
        sol = _solve(problem, parameter_set(layout, values, {**fixed, **at_zero, **held}), max_iter)
        values = sol.values
    bounds.check(values, layout)
    held_names = sorted(held) + sorted(at_zero)
    if covariance:
        sol = observed_information_solution(problem, sol, held_names)
    return Fit(sol, problem.nll(values), held_names)


def _solve(problem: Problem, params: ParameterSet, max_iter: int) -> Solution:
    """The engine on the likelihood: exact gradient, Fisher information as its normal matrix
    (Fisher scoring, :meth:`Problem.scoring_information`)."""
    return solve(problem.at(params), SolverOptions(robust=None, max_iter=max_iter))


def observed_information_solution(problem: Problem, sol: Solution,
                                  held: list[str] = ()) -> Solution:
    """``sol`` with its covariance (and warnings) from the observed information at its estimate.

    Parameters ``held`` at a bound are profiled out, not taken as known: the information on the
    free ones is the Schur complement H_ff − H_fh·H_hh⁻¹·H_hf of the Hessian over both (the
    curvature of the profile likelihood, every held parameter re-maximised, to second order). Their
    σ then carry the held parameters' uncertainty: held at 0, a shot-loss rate still trades lost
    shots for a smaller footprint (docs/validation.md, "CCR on 2-CCR passes", compares it with q
    taken as known). Where −log L is not convex (the Hessian not positive definite) nothing is
    profiled; the profile-likelihood intervals still re-maximise them."""
    free = sol.parameters.free_names
    h = problem.hessian(sol.values, free + list(held))
    nf = len(free)
    info, profiled = h[:nf, :nf], []
    if held:
        hh = h[nf:, nf:]
        def convex(m):
            return np.all(np.linalg.eigvalsh(m) > 0)

        if np.all(np.isfinite(h)) and convex(hh) and convex(h):
            info = info - h[:nf, nf:] @ np.linalg.solve(hh, h[nf:, :nf])
            profiled = list(held)
    dof = max(len(problem.shots) - len(free), 1)
    new = Solution.from_normal_matrix(sol.parameters, info, 1.0, dof, residuals=sol.residuals,
                                      weights=np.ones(sol.residuals.size),
                                      before=sol.residuals_before, history=sol.history,
                                      converged=sol.converged, variance_factor=1.0)
    if profiled:
        them = "it" if len(profiled) == 1 else "them"
        new.warnings.append(f"{', '.join(profiled)} held at a bound: the other parameters' σ are "
                            f"those with {them} profiled out (Schur complement of the observed "
                            "information), not with it taken as known")
    elif held:
        new.warnings.append(f"{', '.join(held)} held at a bound where −log L is not convex in it: "
                            "σ of the others assume it known; use the profile-likelihood intervals")
    return replace(new, residuals_after=sol.residuals_after)


@dataclass(frozen=True)
class Bounds:
    """Physical bounds on the estimate (m unless stated)."""

    diameter_min: float
    diameter_max: float
    max_bias: float

    def beyond(self, values: dict[str, float], fixed: dict[str, float],
               layout: Layout) -> dict[str, float]:
        """The free diameters outside [min, max] and CCR peak photons above MAX_PEAK, mapped to the
        bound they crossed (each parameter's quantity from ``layout``'s typed block)."""
        out = {}
        for n, v in values.items():
            if n in fixed:
                continue
            q = layout.quantity[n]
            if q == "footprint_diameter" and not self.diameter_min <= v <= self.diameter_max:
                out[n] = self.diameter_min if v < self.diameter_min else self.diameter_max
            elif q == "ccr_peak_photons" and v > MAX_PEAK:
                out[n] = MAX_PEAK
        return out

    def check(self, values: dict[str, float], layout: Layout) -> None:
        """A CalibrationError naming the first parameter beyond its physical bound."""
        for n, v in values.items():
            base = layout.quantity[n]
            bad = ((base in BIASES and abs(v) > self.max_bias)
                   or (base == "ccr_peak_photons" and v > MAX_PEAK)
                   or (base == "shot_loss_rate" and not 0.0 <= v < 1.0) or not np.isfinite(v))
            if bad:
                expected = {"ccr_peak_photons": f"≤ {MAX_PEAK:g} photons",
                            "shot_loss_rate": "in [0, 1)"}
                what = expected.get(base, f"within ±{self.max_bias:g} m (--max-bias)")
                raise CalibrationError(f"the likelihood maximum has {n} = {v:.4g}, expected "
                                       f"{what}: the CCR returns do not fit one footprint (check "
                                       "the CCR survey, its heights and the pass)")
