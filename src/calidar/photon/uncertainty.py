"""σ of the CCR calibration, all from the one likelihood the estimate maximises.

- observed information: the inverse Hessian of −log L at the estimate (the Solution's covariance);
- Cramér–Rao: the inverse expected (Fisher) information at the estimate — the smallest σ any
  unbiased estimate from these shots could have;
- parametric bootstrap: counts simulated shot by shot from the fitted model
  (:func:`calidar.photon.likelihood.simulate_counts`), each replicate re-solved by the same code
  as the estimate (segments → grid search → maximum likelihood, same bounds);
- profile-likelihood 95 % intervals: where 2·(−log L_profile − −log L_max) = 3.84, every other
  parameter re-maximised (asymmetric, and cut at the search limits when the data do not close them);
- the profile surface of −log L over cross-track bias × footprint diameter (for the report).
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from calidar.errors import CalibrationError
from calidar.photon.estimate import estimate
from calidar.photon.fit import Bounds, maximise
from calidar.photon.likelihood import count_distribution, simulate_counts
from calidar.photon.parameters import GEOLOCATION

CHI2_95 = {1: 3.841, 2: 5.991}  #: 95 % points of χ² with 1 and 2 degrees of freedom
DISAGREE = 0.25  #: relative difference of two σ reported as a disagreement


@dataclass
class Interval:
    """A 95 % profile-likelihood interval (m); ``open_low``/``open_high``: cut at the search limit."""

    low: float
    high: float
    open_low: bool = False
    open_high: bool = False

    def covers(self, v: float) -> bool:
        return self.low <= v <= self.high


@dataclass
class Surface:
    """2·(−log L − its minimum), profiled, over cross-track bias × diameter of one beam."""

    group: int  #: the beam's index in the layout
    x_name: str
    y_name: str
    x: np.ndarray
    y: np.ndarray
    deviance: np.ndarray  #: (len(y), len(x))


@dataclass
class Uncertainty:
    names: list[str]  #: the free parameters
    observed: dict[str, float]
    cramer_rao: dict[str, float]
    bootstrap: dict[str, float] = field(default_factory=dict)
    bootstrap_values: np.ndarray | None = None  #: (replicates, len(names))
    bootstrap_failed: int = 0
    bootstrap_requested: int = 0
    profile: dict[str, Interval] = field(default_factory=dict)
    surfaces: list[Surface] = field(default_factory=list)

    def disagreements(self) -> list[str]:
        """Sentences for the geolocation parameters whose observed-information, bootstrap and
        Cramér–Rao σ differ by more than DISAGREE (or, for the bootstrap, by more than three times
        the sampling error of a σ from its replicates, 1/√(2(R − 1)))."""
        out = []
        reps = 0 if self.bootstrap_values is None else self.bootstrap_values.shape[0]
        boot_tol = max(DISAGREE, 3.0 / np.sqrt(2.0 * max(reps - 1, 1)))
        for n in self.names:
            if n.split("[")[0] not in GEOLOCATION:
                continue
            obs, boot, crb = self.observed.get(n), self.bootstrap.get(n), self.cramer_rao.get(n)
            if boot and obs and abs(boot / obs - 1.0) > boot_tol:
                out.append(f"{n}: bootstrap σ {boot:.3g} m vs observed-information σ {obs:.3g} m — the likelihood "
                           "is not quadratic here (few CCRs, or a nuisance parameter at its bound); the bootstrap σ "
                           "and the profile interval are the ones to use")
            if crb and obs and obs / crb - 1.0 > DISAGREE:
                out.append(f"{n}: observed-information σ {obs:.3g} m is {obs / crb:.2f}× the Cramér–Rao σ {crb:.3g} m: "
                           "this pass's counts hold less than they are expected to")
        return out

    def to_dict(self) -> dict:
        boot = None if self.bootstrap_values is None else {
            "replicates": int(self.bootstrap_values.shape[0]), "requested": self.bootstrap_requested,
            "failed": self.bootstrap_failed, "sigma": self.bootstrap,
            "interval_95": {n: [float(v) for v in np.percentile(self.bootstrap_values[:, i], [2.5, 97.5])]
                            for i, n in enumerate(self.names)} if self.bootstrap_values.shape[0] else {}}
        return {"observed_information_sigma": self.observed, "cramer_rao_sigma": self.cramer_rao, "bootstrap": boot,
                "profile_interval_95": {n: {"low": i.low, "high": i.high, "open_low": i.open_low,
                                            "open_high": i.open_high} for n, i in self.profile.items()},
                "disagreements": self.disagreements()}


def _bounds(result) -> Bounds:
    s = result.settings
    return Bounds(s.diameter_min, s.diameter_max, s.max_bias)


def _limits(result, name: str) -> tuple[float, float]:
    s = result.settings
    if name.startswith("footprint_diameter"):
        return s.diameter_min, s.diameter_max
    return -s.max_bias, s.max_bias


def profile_nll(result, fixed: dict[str, float], start: dict[str, float]) -> tuple[float, dict[str, float]]:
    """−log L maximised over every parameter but ``fixed``; (inf, start) when no maximum within the bounds."""
    try:
        fit = maximise(result.problem, {**start, **fixed}, _bounds(result), fixed=fixed, max_iter=30,
                       covariance=False)
    except CalibrationError:
        return np.inf, start
    return fit.nll, fit.solution.values


def profile_interval(result, name: str, level: float = CHI2_95[1]) -> Interval:
    """The profile-likelihood interval of ``name``: the signed root √deviance is near-linear in the
    value, so each side is found by a few secant steps from the Wald guess."""
    sol = result.solution
    best, v0 = result.estimate.fit.nll, sol.values[name]
    sigma = sol.sigma.get(name, np.nan)
    lo_lim, hi_lim = _limits(result, name)
    target = np.sqrt(level)
    ends = []
    for side in (-1.0, 1.0):
        limit = lo_lim if side < 0 else hi_lim
        step = 1.96 * sigma if np.isfinite(sigma) and sigma > 0 else 0.5
        v, closed, start = v0 + side * step, False, sol.values
        for _ in range(6):
            v = float(np.clip(v, lo_lim, hi_lim))
            nll, start = profile_nll(result, {name: v}, start)
            root = np.sqrt(max(2.0 * (nll - best), 0.0))
            if abs(root - target) < 0.02 or (v == limit and root < target):
                closed = root >= target - 0.02
                break
            v = v0 + (v - v0) * target / max(root, 0.25)
        ends.append((v, not closed and v == limit))
    (lo, open_lo), (hi, open_hi) = ends
    return Interval(float(min(lo, v0)), float(max(hi, v0)), bool(open_lo), bool(open_hi))


def surface(result, group: int, points: int) -> Surface:
    """The profile deviance over cross-track bias × diameter of beam ``group``, ±3σ (at least ±0.5 m
    and ±1 m) around the estimate, within the search limits."""
    lay, sol = result.layout, result.solution
    xn, yn = lay.name(group, "cross_track_bias"), lay.name(group, "footprint_diameter")
    v = sol.values
    sx, sy = max(3 * sol.sigma.get(xn, 0.2), 0.5), max(3 * sol.sigma.get(yn, 0.4), 1.0)
    lo_y, hi_y = _limits(result, yn)
    xs = np.linspace(v[xn] - sx, v[xn] + sx, points)
    ys = np.linspace(max(v[yn] - sy, lo_y), min(v[yn] + sy, hi_y), points)
    dev = np.full((points, points), np.inf)
    start = v
    for i, y in enumerate(ys):
        row_start = start
        for j, x in enumerate(xs[:: 1 if i % 2 == 0 else -1]):
            jj = j if i % 2 == 0 else points - 1 - j
            nll, start = profile_nll(result, {xn: float(x), yn: float(y)}, start)
            dev[i, jj] = 2.0 * (nll - result.estimate.fit.nll)
        start = start if np.isfinite(dev[i]).any() else row_start
    return Surface(group, xn, yn, xs, ys, np.maximum(dev, 0.0))


def bootstrap(result, replicates: int, seed: int, progress=None) -> tuple[np.ndarray, int]:
    """(replicates × free parameters) re-estimates from counts simulated from the fitted model, and
    how many replicates had no estimate (a beam without two lit CCRs, or an estimate beyond the bounds)."""

    sol, prob = result.solution, result.problem
    names = sol.parameters.free_names
    table, _ = count_distribution(prob.layout.theta(sol.values), prob.shots, prob.jitter)
    split = np.cumsum([w.shot_x.size for w in result.windows])[:-1]
    rng = np.random.default_rng(seed)
    out, failed = [], 0
    for r in range(replicates):
        counts = np.split(simulate_counts(table, rng), split)
        try:
            est = estimate(result.windows, prob, result.settings, result.system.shot_spacing, counts, covariance=False)
            out.append([est.fit.solution.values[n] for n in names])
        except CalibrationError:
            failed += 1
        if progress:
            progress("bootstrap", r + 1, replicates)
    return np.array(out).reshape(-1, len(names)), failed


def assess(result, progress=None) -> Uncertainty:
    """Every σ and interval of :mod:`calidar.photon.uncertainty` for a calibration result."""
    sol, prob, settings = result.solution, result.problem, result.settings
    names = sol.parameters.free_names
    info = prob.information(sol.values, names)
    crb = np.sqrt(np.clip(np.diag(np.linalg.pinv(info)), 0.0, None))
    u = Uncertainty(names, {n: float(s) for n, s in sol.sigma.items()}, dict(zip(names, map(float, crb))))
    if settings.bootstrap:
        values, failed = bootstrap(result, settings.bootstrap, settings.seed, progress)
        u.bootstrap_values, u.bootstrap_failed, u.bootstrap_requested = values, failed, settings.bootstrap
        if values.shape[0] >= 2:
            u.bootstrap = dict(zip(names, map(float, values.std(axis=0, ddof=1))))
    for n in names:
        if n.split("[")[0] in GEOLOCATION:
            u.profile[n] = profile_interval(result, n)
    if settings.surface_points:
        u.surfaces = [surface(result, g, settings.surface_points) for g in range(len(result.layout.groups))
                      if result.layout.name(g, "footprint_diameter") in names]
    return u
