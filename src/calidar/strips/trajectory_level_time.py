"""The trajectory's accuracy level over the flight: a factor per group and stretch of time.

A GNSS/INS trajectory is not equally good all flight long (satellite geometry, the base line, a
turn's dynamics change its σ over minutes). The flight-wide level
(:mod:`calidar.strips.trajectory_level`) gives the good stretches' knots the priors of the
average, which widens the mounting's σ. Here each group's factor is estimated per *segment*:
each strip's knots cut into stretches of about :data:`SEGMENT_S` seconds (the aircraft flies one
strip at a time, so a stretch of strip is a stretch of the flight). Each segment's priors give
their own variance-component update (:mod:`calidar.adjust.variance_elements`), and those are
pooled in time per group: the log of the factor² is a Gauss–Markov process over the flight
(correlation exp(−|Δt| / :data:`LEVEL_CORRELATION_S`)) about a flight-wide mean, each segment's
update an observation of it with variance 2/rₛ (rₛ its redundancy: a χ² with rₛ degrees of
freedom), and the process's variance τ² estimated from the updates by restricted maximum
likelihood (Patterson & Thompson 1971). Kriging then gives every segment's factor: close to its
own update where that rests on many priors and τ is large, close to the flight-wide mean where it
rests on few or the updates vary no more than their noise (τ = 0: a constant level, as before).

A segment whose priors the overlaps check fewer than :data:`MIN_SEGMENT_REDUNDANCY` times
contributes no update of its own ("cannot tell"): its factor is the pooled prediction of its
neighbours in time and the flight-wide mean.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass

import numpy as np
from scipy.special import digamma

from calidar.adjust.variance_elements import estimate_elements
from calidar.strips.row_variance import trigamma

#: a strip's knots are cut into stretches of about this length (s)
SEGMENT_S = 30.0
#: correlation time of the level's log over the flight (s): a GNSS/INS accuracy changes over minutes
LEVEL_CORRELATION_S = 120.0
#: a segment's own update enters the pooling only when its priors are checked this many times
MIN_SEGMENT_REDUNDANCY = 3.0
SOURCE_OVER_TIME = ("estimated from the overlaps over the flight (variance components of the "
                    "trajectory priors per segment)")
#: the process's σ of log factor² tried (0: a constant level); a factor 0.2–5× over the flight at
#: the most
TAU_GRID = np.linspace(0.0, 1.6, 33)


@dataclass(frozen=True)
class Segment:
    """One stretch of one strip: its knots [first, last] and their times (s)."""

    strip: int
    first: int
    last: int
    t_start: float
    t_end: float

    @property
    def centre(self) -> float:
        return 0.5 * (self.t_start + self.t_end)


def segments_of(knot_times: Mapping[int, np.ndarray],
                segment_s: float | None = None) -> list[Segment]:
    """Each strip's knots (times by strip) cut into ⌈duration / segment_s⌉ stretches of equal
    knot count, sorted by time."""
    out, segment_s = [], segment_s or SEGMENT_S
    for sid, t in knot_times.items():
        n = max(1, math.ceil((t[-1] - t[0]) / segment_s)) if t.size > 1 else 1
        cuts = np.linspace(0, t.size, n + 1).round().astype(int)
        out += [Segment(sid, int(a), int(b) - 1, float(t[a]), float(t[b - 1]))
                for a, b in zip(cuts[:-1], cuts[1:]) if b > a]
    return sorted(out, key=lambda s: s.t_start)


def segment_index(segments: list[Segment]) -> dict[tuple[int, int], int]:
    """(strip, knot) → the segment's position in ``segments``."""
    return {(s.strip, k): i for i, s in enumerate(segments) for k in range(s.first, s.last + 1)}


@dataclass
class Pooled:
    """One group's pooled log factor² per segment: the kriged values, their σ and the fit."""

    log_var: np.ndarray  #: per segment log σ² factor
    sigma: np.ndarray  #: its σ (of log σ², twice that of log σ)
    own: np.ndarray  #: per segment whether its own update entered (redundancy ≥ the minimum)
    tau: float  #: the process's σ of log σ² (REML)
    mean: float  #: the flight-wide mean of log σ²


def pool_in_time(times: np.ndarray, raw: np.ndarray, effective: np.ndarray, fallback: float,
                 own: np.ndarray | None = None, correlation_s: float | None = None) -> Pooled:
    """Kriging of one group's log factor² over the segments (module docstring): ``raw`` the
    segments' own updates σ², ``effective`` the effective number of independent priors behind
    each (its log's variance 2/m), ``own`` which of them enter (default: m ≥
    :data:`MIN_SEGMENT_REDUNDANCY`), ``fallback`` the flight-wide σ² (taken when fewer than two
    segments can tell)."""
    own = effective >= MIN_SEGMENT_REDUNDANCY if own is None else np.asarray(own, bool)
    own = own & (raw > 0) & (effective > 0)
    n = times.size
    if own.sum() < 2:
        return Pooled(np.full(n, math.log(fallback)), np.full(n, np.inf), own, 0.0,
                      math.log(fallback))
    R = np.exp(-np.abs(times[:, None] - times[None, :]) / (correlation_s or LEVEL_CORRELATION_S))
    # log of a χ²ₘ/m: mean ψ(m/2) − log(m/2), variance ψ′(m/2) (not −1/m and 2/m only: m is
    # small here)
    m = effective[own] / 2.0
    y, d = np.log(raw[own]) - (digamma(m) - np.log(m)), trigamma(m)
    Rdd = R[np.ix_(own, own)]
    best = max(((_reml(y, tau**2 * Rdd + np.diag(d)), tau) for tau in TAU_GRID), key=lambda p: p[0])
    tau = best[1]
    V = tau**2 * Rdd + np.diag(d)
    Vi = np.linalg.inv(V)
    one = np.ones(y.size)
    w = float(one @ Vi @ one)
    mu = float(one @ Vi @ y) / w
    C = tau**2 * R[:, own]  # cov(process at every segment, data)
    pred = mu + C @ Vi @ (y - mu)
    # universal kriging variance: the process's, less what the data explain, plus the mean's share
    u = 1.0 - C @ Vi @ one
    var = tau**2 - np.einsum("ij,jk,ik->i", C, Vi, C) + u**2 / w
    return Pooled(pred, np.sqrt(np.maximum(var, 0.0)), own, float(tau), mu)


def _reml(y: np.ndarray, V: np.ndarray) -> float:
    """The restricted log likelihood of y ~ N(μ·1, V), μ unknown (up to a constant)."""
    L = np.linalg.cholesky(V)
    one = np.ones(y.size)
    a, b = np.linalg.solve(L, y), np.linalg.solve(L, one)
    w = float(b @ b)
    mu = float(b @ a) / w
    res = a - mu * b
    return -0.5 * (2.0 * float(np.sum(np.log(np.diag(L)))) + math.log(w) + float(res @ res))


@dataclass
class LevelOverTime:
    """Per group (estimated flight-wide) the pooled factor per segment."""

    segments: list[Segment]
    groups: dict[str, Pooled]  #: per group its pooled log factor² per segment
    #: per group each segment's redundancy at the flight-wide level
    redundancy: dict[str, np.ndarray]
    iterations: int
    converged: bool

    def to_dict(self, base_sigma: Mapping[str, float]) -> dict:
        """solution.json's block: per segment its strip, times and per group σ (``base_sigma``:
        the group's stated σ, m or °) with its factor's relative σ and whether its own priors
        told."""
        segs = []
        for i, s in enumerate(self.segments):
            row = {"strip": s.strip, "t_start_s": s.t_start, "t_end_s": s.t_end}
            for g, p in self.groups.items():
                relative = float(np.expm1(0.5 * p.sigma[i])) if np.isfinite(p.sigma[i]) else None
                row[g] = {"sigma": base_sigma[g] * self.factor(g, i),
                          "sigma_factor": self.factor(g, i), "relative_sigma": relative,
                          "own": bool(p.own[i]), "redundancy": float(self.redundancy[g][i])}
            segs.append(row)
        return {"segment_s": SEGMENT_S, "correlation_s": LEVEL_CORRELATION_S,
                "min_effective": MIN_SEGMENT_REDUNDANCY,
                "iterations": self.iterations, "converged": self.converged,
                "tau_log_sigma": {g: 0.5 * p.tau for g, p in self.groups.items()},
                "flight_mean_factor": {g: float(np.exp(0.5 * p.mean))
                                       for g, p in self.groups.items()},
                "segments": segs}

    def factor(self, group: str, segment: int) -> float:
        """The σ factor of a group in a segment (1 for a group not here)."""
        g = self.groups.get(group)
        return 1.0 if g is None else float(np.exp(0.5 * g.log_var[segment]))

    def factors_at_knots(self, knot_times: Mapping[int, np.ndarray],
                         group: str) -> tuple[np.ndarray, np.ndarray]:
        """Every knot's time and the group's σ factor there (sorted by time; knots of two strips at
        one time: their mean)."""
        where = segment_index(self.segments)
        t = np.concatenate([knot_times[s] for s in knot_times])
        f = np.concatenate([[self.factor(group, where[(s, k)]) for k in range(knot_times[s].size)]
                            for s in knot_times])
        order = np.argsort(t, kind="stable")
        times, inverse = np.unique(t[order], return_inverse=True)
        return times, np.bincount(inverse, f[order]) / np.bincount(inverse)


def estimate_over_time(terms: tuple, priors, knots: list, groups: list[str | None],
                       knot_times: Mapping[int, np.ndarray], start: Mapping[str, float],
                       observations: float, floor: float) -> LevelOverTime:
    """The level per group and segment (module docstring) for an adjustment's ``terms``
    (:func:`calidar.adjust.variance_components.normal_terms`) and prior groups ``priors``, its free
    parameters' ``knots`` (:class:`calidar.strips.trajectory_errors.Knot` or None) and ``groups``,
    the strips' ``knot_times``, starting from the flight-wide factors² ``start`` (the groups
    estimated there; the others keep their stated σ) with the observations' factor² held at
    ``observations``; each factor² ≥ ``floor``."""
    segments = segments_of(knot_times)
    where = segment_index(segments)
    labels = [f"{g}@{where[(k.strip, k.knot)]}" if g in start and k is not None else None
              for g, k in zip(groups, knots)]
    present = {g: sorted({int(s.split("@")[1]) for s in labels if s and s.split("@")[0] == g})
               for g in start}
    times = np.array([s.centre for s in segments])
    pooled: dict[str, Pooled] = {}
    own: dict[str, bool] = {}  # fixed at the flight-wide level: which segments tell

    def pool(raw: dict, effective: dict, red_start: dict) -> dict:
        out = {}
        if not own:
            own.update({n: m >= MIN_SEGMENT_REDUNDANCY for n, m in effective.items()})
        for g, segs in present.items():
            names = [f"{g}@{i}" for i in segs]
            p = pool_in_time(times[segs], np.array([raw[n] for n in names]),
                             np.array([effective[n] for n in names]), start[g],
                             own=np.array([own[n] for n in names]))
            pooled[g] = p
            out |= {n: float(np.exp(v)) for n, v in zip(names, p.log_var)}
        return out

    first = {f"{g}@{i}": float(start[g]) for g, segs in present.items() for i in segs}
    comps = estimate_elements(terms[0], terms[1], terms[4], priors, labels, first,
                              observations=observations, pool=pool, floor=floor, tol=0.01)
    full = {}
    # onto every segment (a group absent from one: its flight-wide σ² there)
    for g, segs in present.items():
        p = pooled[g]
        n = len(segments)
        log_var, sig, own = np.full(n, math.log(start[g])), np.full(n, np.inf), np.zeros(n, bool)
        log_var[segs], sig[segs], own[segs] = p.log_var, p.sigma, p.own
        full[g] = Pooled(log_var, sig, own, p.tau, p.mean)
    red = {g: np.array([comps.redundancy_start.get(f"{g}@{i}", 0.0) for i in range(len(segments))])
           for g in present}
    return LevelOverTime(segments, full, red, comps.iterations, comps.converged)


def over_time_accuracy(base, level: LevelOverTime, knot_times: Mapping[int, np.ndarray]):
    """``base`` (a :class:`calidar.trajectory_accuracy.TrajectoryAccuracy`) at every knot's time
    × the factors of the knot's segment: position north/east × horizontal, down × vertical,
    roll/pitch × attitude horizontal, heading × heading (the knots' priors then take exactly
    them)."""
    from calidar.trajectory_accuracy import TrajectoryAccuracy

    cols = {"position_horizontal": (0, [0, 1]), "position_vertical": (0, [2]),
            "attitude_horizontal": (1, [0, 1]), "heading": (1, [2])}
    times = None
    for g in cols:
        t, f = level.factors_at_knots(knot_times, g)
        if times is None:
            times = t
            pos, att = (a.copy() for a in base.at(times))
        part, axes = cols[g]
        (pos, att)[part][:, axes] *= f[:, None]
    return TrajectoryAccuracy(times, pos, att, None, SOURCE_OVER_TIME, False)


#: the report's table of the level over the flight (:func:`level_table_rows`)
LEVEL_TABLE_HEADER = ["strip", "time (s from the first)", "position horizontal (cm)",
                      "position vertical (cm)",
                      "roll·pitch (°)", "heading (°)"]
_COLUMNS = (("position_horizontal", 100.0, "{:.2g}"), ("position_vertical", 100.0, "{:.2g}"),
            ("attitude_horizontal", 1.0, "{:.2g}"), ("heading", 1.0, "{:.2g}"))


def level_table_text(over_time: dict) -> str:
    """What the table of the level over the flight shows (solution.json's "over_time" block)."""
    tau = ", ".join(f"{g.replace('_', ' ')} " + (f"×e^±{v:.2f}" if v > 0 else "constant")
                    for g, v in over_time["tau_log_sigma"].items())
    return ("No accuracy file: the trajectory's σ estimated from the overlaps per segment of each "
            f"strip (about {over_time['segment_s']:g} s), pooled over the flight (a process of "
            f"correlation time {over_time['correlation_s']:g} s; estimated spread {tau}). Each σ ± "
            "the relative σ of its factor; \"(pooled)\": the segment's own priors could not tell "
            f"(fewer than {over_time['min_effective']:g} independent ones), its σ comes from its "
            "neighbours in time or, when fewer than two segments can tell, from the flight-wide "
            "level; \"–\": a group the overlaps cannot tell, the survey-grade default kept.")


def level_table_rows(over_time: dict) -> list[list[str]]:
    """One row per segment: strip, time span from the first segment's start, each group's σ."""
    segs = over_time["segments"]
    t0 = segs[0]["t_start_s"] if segs else 0.0
    rows = []
    for s in segs:
        row = [str(s["strip"]), f"{s['t_start_s'] - t0:.0f}–{s['t_end_s'] - t0:.0f}"]
        for g, unit, fmt in _COLUMNS:
            v = s.get(g)
            if v is None:
                row.append("–")
                continue
            rel = "" if v["relative_sigma"] is None else f" ± {100 * v['relative_sigma']:.0f} %"
            row.append(fmt.format(v["sigma"] * unit) + rel + ("" if v["own"] else " (pooled)"))
        rows.append(row)
    return rows
