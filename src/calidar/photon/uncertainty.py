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
#: a beam with fewer lit CCRs than this is in the small-sample regime (checks.GOOD_CCRS)
FEW_CCRS = 4
#: the deviance's 95 % point there, as a multiple of χ²₁'s: the profile deviance at the truth on
#: 2-CCR passes has a heavier tail than χ²₁ (four nuisance parameters from two chords of ~10 shots;
#: measured in docs/validation.md, "CCR on 2-CCR passes")
SMALL_SAMPLE_LEVEL = 1.2
DISAGREE = 0.25  #: relative difference of two σ reported as a disagreement


@dataclass
class Interval:
    """A 95 % profile-likelihood interval (m); ``open_low``/``open_high``: cut at the search
    limit."""

    low: float
    high: float
    open_low: bool = False
    open_high: bool = False
    #: an end where no profile maximum could be found even near the estimate: the interval is not
    #: honest
    failed: bool = False
    level: float = 3.841  #: the deviance level it was cut at

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
    #: σ (curvature, profile's) where the profile changed it
    profile_sigma: dict[str, tuple[float, float]] = field(default_factory=dict)
    surfaces: list[Surface] = field(default_factory=list)
    #: the free geolocation parameters (biases, footprint diameters;
    #: :data:`calidar.photon.parameters.GEOLOCATION`)
    geolocation: list[str] = field(default_factory=list)

    def sigma(self, name: str) -> float | None:
        """The σ reported for ``name``: from its profile interval where that changed it, else the
        observed information's."""
        if name in self.profile_sigma:
            return self.profile_sigma[name][1]
        return self.observed.get(name)

    def disagreements(self) -> list[str]:
        """Sentences for the geolocation parameters whose reported σ (:meth:`sigma`), bootstrap and
        Cramér–Rao σ differ by more than DISAGREE (or, for the bootstrap, by more than three times
        the sampling error of a σ from its replicates, 1/√(2(R − 1)))."""
        out = []
        reps = 0 if self.bootstrap_values is None else self.bootstrap_values.shape[0]
        boot_tol = max(DISAGREE, 3.0 / np.sqrt(2.0 * max(reps - 1, 1)))
        for n in self.geolocation:
            obs, boot, crb = self.sigma(n), self.bootstrap.get(n), self.cramer_rao.get(n)
            if n in self.profile_sigma:
                what = "σ from the profile interval"
            else:
                what = "observed-information σ"
            if boot and obs and abs(boot / obs - 1.0) > boot_tol:
                out.append(f"{n}: bootstrap σ {boot:.3g} m vs {what} {obs:.3g} m — the "
                           "likelihood is not quadratic here (few CCRs, or a nuisance parameter at "
                           "its bound): the bootstrap's spread is this estimator's at the fitted "
                           "values only")
            if crb and obs and obs / crb - 1.0 > DISAGREE:
                out.append(f"{n}: {what} {obs:.3g} m is {obs / crb:.2f}× the Cramér–Rao σ "
                           f"{crb:.3g} m: this pass's counts hold less than they are expected to")
        return out

    def to_dict(self) -> dict:
        profile = {n: {"low": i.low, "high": i.high, "open_low": i.open_low,
                       "open_high": i.open_high, "failed": i.failed, "deviance_level": i.level}
                   for n, i in self.profile.items()}
        from_profile = {n: {"curvature": a, "profile": b}
                        for n, (a, b) in self.profile_sigma.items()}
        return {"observed_information_sigma": self.observed, "cramer_rao_sigma": self.cramer_rao,
                "bootstrap": self._bootstrap_dict(), "profile_interval_95": profile,
                "sigma_from_profile": from_profile, "disagreements": self.disagreements()}

    def _bootstrap_dict(self) -> dict | None:
        """The bootstrap's replicates, σ and 2.5–97.5 % interval of each parameter (None: off)."""
        values = self.bootstrap_values
        if values is None:
            return None
        intervals = {n: [float(v) for v in np.percentile(values[:, i], [2.5, 97.5])]
                     for i, n in enumerate(self.names)} if values.shape[0] else {}
        return {"replicates": int(values.shape[0]), "requested": self.bootstrap_requested,
                "failed": self.bootstrap_failed, "sigma": self.bootstrap, "interval_95": intervals}


def _bounds(result) -> Bounds:
    s = result.settings
    return Bounds(s.diameter_min, s.diameter_max, s.max_bias)


def _limits(result, name: str) -> tuple[float, float]:
    s = result.settings
    if result.layout.quantity[name] == "footprint_diameter":
        return s.diameter_min, s.diameter_max
    return -s.max_bias, s.max_bias


def profile_nll(result, fixed: dict[str, float],
                start: dict[str, float]) -> tuple[float, dict[str, float]]:
    """−log L maximised over every parameter but ``fixed``; (inf, start) when no maximum within
    the bounds."""
    try:
        fit = maximise(result.problem, {**start, **fixed}, _bounds(result), fixed=fixed,
                       max_iter=30, covariance=False)
    except CalibrationError:
        return np.inf, start
    return fit.nll, fit.solution.values


#: first step of a profile interval's search, by kind of parameter: σ clipped to [min, max] (m)
PROFILE_STEP = {"footprint_diameter": (0.1, 1.0), "bias": (0.05, 0.5)}
PROFILE_EVALUATIONS = 14  #: profile maxima per side at most
ROOT_TOLERANCE = 0.03  #: on the signed root √deviance


def profile_interval(result, name: str, level: float = CHI2_95[1]) -> Interval:
    """The profile-likelihood interval of ``name``: where the deviance 2·(−log L_profile − −log
    L_max) reaches ``level``, every other parameter re-maximised.

    Each side is bracketed first — steps from the estimate that start at σ (clipped to
    PROFILE_STEP: a curvature σ from a flat or ragged maximum can be far off either way) and grow
    with the signed root's slope — and then closed by regula falsi on the root. A point without a
    maximum within the bounds (a bias or peak beyond its limit) is beyond the interval; a maximum
    from the previous point's solution above the level is checked from the estimate too (a warm
    start can sit in another mode)."""
    sol = result.solution
    v0 = sol.values[name]
    lo_lim, hi_lim = _limits(result, name)
    target = np.sqrt(level)
    diameter = result.layout.quantity[name] == "footprint_diameter"
    small, large = PROFILE_STEP["footprint_diameter" if diameter else "bias"]
    sigma = sol.sigma.get(name, np.nan)
    h = float(np.clip(sigma, small, large)) if np.isfinite(sigma) and sigma > 0 else large
    ends = []
    for side in (-1.0, 1.0):
        limit = lo_lim if side < 0 else hi_lim
        ends.append(_side(result, name, v0, side * h, limit, target))
    (lo, open_lo, bad_lo), (hi, open_hi, bad_hi) = ends
    return Interval(float(min(lo, v0)), float(max(hi, v0)), bool(open_lo), bool(open_hi),
                    bool(bad_lo or bad_hi), float(level))


def _root(result, name: str, v: float, start: dict[str, float],
          target: float) -> tuple[float, dict[str, float]]:
    """The signed-root size √deviance of the profile at ``name`` = v (inf: no maximum within the
    bounds), from ``start``, re-tried from the estimate when that gives more than ``target`` or
    none."""
    best = result.estimate.fit.nll
    nll, at = profile_nll(result, {name: v}, start)
    if start is not result.solution.values and not 2.0 * (nll - best) < target**2:
        nll2, at2 = profile_nll(result, {name: v}, result.solution.values)
        if nll2 < nll:
            nll, at = nll2, at2
    return (np.sqrt(max(2.0 * (nll - best), 0.0)) if np.isfinite(nll) else np.inf), at


def _side(result, name: str, v0: float, step: float, limit: float,
          target: float) -> tuple[float, bool, bool]:
    """One end of the interval: (value, open — cut at ``limit`` below the level or never reached,
    failed — no profile maximum within a first step of the estimate)."""
    a, ra, start = v0, 0.0, result.solution.values
    v = v0 + step
    for _ in range(PROFILE_EVALUATIONS):
        v = float(np.clip(v, min(v0, limit), max(v0, limit)))
        r, at = _root(result, name, v, start, target)
        if r >= target:
            end, rb = _close(result, name, (a, ra), (v, r), target, start)
            return end, False, bool(not np.isfinite(rb) and abs(end - v0) < abs(step))
        if v == limit:
            return v, True, False
        d = abs(v - a)
        slope = (r - ra) / d  # of the root, per metre outward
        if slope > 0:  # 1.2 × the linear extrapolation to the level, 0.5–4 × the last step
            size = float(np.clip(1.2 * (target - r) / slope, 0.5 * d, 4.0 * d))
        else:
            size = 2.0 * d
        a, ra, start = v, r, at
        v = v + np.sign(step) * size
    return v, True, False


def _close(result, name: str, lo: tuple[float, float], hi: tuple[float, float], target: float,
           start: dict[str, float]) -> tuple[float, float]:
    """Regula falsi on the signed root between ``lo`` (below the level) and ``hi`` (at or above it);
    an infinite end is bisected. (the end, the root there)"""
    (a, ra), (b, rb) = lo, hi
    for _ in range(5):
        if abs(rb - target) < ROOT_TOLERANCE:
            return b, rb
        v = a + (b - a) * (target - ra) / (rb - ra) if np.isfinite(rb) else 0.5 * (a + b)
        r, at = _root(result, name, v, start, target)
        if abs(r - target) < ROOT_TOLERANCE:
            return v, r
        if r < target:
            a, ra, start = v, r, at
        else:
            b, rb = v, r
    return (b, rb) if not np.isfinite(rb) else (a + (b - a) * (target - ra) / (rb - ra), target)


def lit_ccrs(result, name: str) -> int:
    """Lit CCR segments of the beam(s) parameter ``name`` belongs to."""
    groups = set(result.layout.beams(name))
    return sum(1 for s in result.estimate.segments if s.window.group in groups)


def interval_level(result, name: str) -> float:
    """The deviance level of ``name``'s 95 % profile interval: χ²₁'s, × SMALL_SAMPLE_LEVEL below
    FEW_CCRS."""
    return CHI2_95[1] * (SMALL_SAMPLE_LEVEL if lit_ccrs(result, name) < FEW_CCRS else 1.0)


def sigma_from_profile(result) -> dict[str, tuple[float, float]]:
    """σ of each geolocation parameter from its 95 % profile interval: the wider half / 1.96 when
    the interval is closed on both sides, else at least that (an open or failed end bounds it from
    below; with a nuisance parameter held at its bound the profile keeps it there, so the observed
    information's σ, which profiles it out
    (:func:`calidar.photon.fit.observed_information_solution`), stays when wider).

    The observed information is the curvature at one point; where the likelihood is far from
    quadratic (two chords: a CCR peak the data do not see, a shot-loss rate at its bound 0) that σ
    is too small or, at a near-singular Hessian, meaninglessly large (docs/validation.md, "CCR on
    2-CCR passes"). The covariance's rows and columns are scaled (correlations kept); returns
    {name: (curvature σ, σ now)} of those changed."""
    sol, u, out = result.solution, result.uncertainty, {}
    names = sol.parameters.free_names
    # the profile keeps them at the bound; the curvature profiled them out
    held = bool(result.estimate.fit.at_limit)
    cov = sol.covariance.copy()
    for i, n in enumerate(names):
        iv, s = u.profile.get(n), sol.sigma[n]
        if iv is None:
            continue
        half = max(sol.values[n] - iv.low, iv.high - sol.values[n]) / 1.96
        closed = not (iv.open_low or iv.open_high or iv.failed) and not held
        new = half if closed and half > 0 else max(half, s) if np.isfinite(s) else half
        if not np.isfinite(new) or new <= 0 or abs(new - s) <= 1e-3 * new:
            continue
        out[n] = (float(s), float(new))
        if np.isfinite(s) and s > 0:
            cov[i, :] *= new / s
            cov[:, i] *= new / s
        else:  # no curvature σ: the profile's alone
            cov[i, :] = cov[:, i] = 0.0
            cov[i, i] = new**2
    sol.covariance = cov
    return out


def surface(result, group: int, points: int) -> Surface:
    """The profile deviance over cross-track bias × diameter of beam ``group``, ±3σ (at least ±0.5
    m and ±1 m) around the estimate, within the search limits."""
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
    """(replicates × free parameters) re-estimates from counts simulated from the fitted model,
    and how many replicates had no estimate (a beam without two lit CCRs, or an estimate beyond the
    bounds)."""

    sol, prob = result.solution, result.problem
    names = sol.parameters.free_names
    table, _ = count_distribution(prob.layout.theta(sol.values), prob.shots, prob.jitter)
    split = np.cumsum([w.shot_x.size for w in result.windows])[:-1]
    rng = np.random.default_rng(seed)
    out, failed = [], 0
    for r in range(replicates):
        counts = np.split(simulate_counts(table, rng), split)
        try:
            est = estimate(result.windows, prob, result.settings, result.system.shot_spacing,
                           counts, covariance=False)
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
    geolocation = [n for n in names if result.layout.quantity[n] in GEOLOCATION]
    u = Uncertainty(names, {n: float(s) for n, s in sol.sigma.items()},
                    dict(zip(names, map(float, crb))), geolocation=geolocation)
    if settings.bootstrap:
        values, failed = bootstrap(result, settings.bootstrap, settings.seed, progress)
        u.bootstrap_values, u.bootstrap_failed = values, failed
        u.bootstrap_requested = settings.bootstrap
        if values.shape[0] >= 2:
            u.bootstrap = dict(zip(names, map(float, values.std(axis=0, ddof=1))))
    for n in names:
        if result.layout.quantity[n] in GEOLOCATION:
            u.profile[n] = profile_interval(result, n, interval_level(result, n))
    if settings.surface_points:
        beams = range(len(result.layout.groups))
        u.surfaces = [surface(result, g, settings.surface_points) for g in beams
                      if result.layout.name(g, "footprint_diameter") in names]
    return u
