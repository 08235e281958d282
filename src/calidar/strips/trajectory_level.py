"""The trajectory's accuracy level estimated from the overlaps, when no accuracy file states it.

The trajectory corrections' priors (:mod:`calidar.strips.trajectory_errors`) start from a
stated accuracy; without one, from :data:`calidar.trajectory_accuracy.SURVEY_GRADE`. How wide
those priors really are is a variance-component problem (:mod:`calidar.adjust.variance_components`):
the corrections the overlaps ask for, against the priors' stated covariance, give a factor per
group of priors — four here, each the stated σ's shape kept within it:

- ``position_horizontal``: the knots' east and north shifts; ``position_vertical``: the up shifts;
- ``attitude_horizontal``: the rotations about east and north (roll and pitch, mixed by the
  line's heading); ``heading``: the rotations about up.

A group is estimated only when the data check enough of its priors at the stated σ: its
redundancy rₖ there (how many of its nₖ priors the overlaps determine better than the priors do)
must reach :data:`MIN_REDUNDANCY`; otherwise the stated σ stay ("the data cannot tell"). The
estimate's own relative σ is ≈ 1/√(2m), m the effective number of independent priors behind it
(:mod:`calidar.adjust.variance_elements`; less than rₖ: a Gauss–Markov process sampled every
second is worth far fewer independent priors than it has knots). A group checked at the stated σ
but not at its estimate is *bounded*, not estimated: where its information there, tr(Rₖ²)
(:class:`calidar.adjust.variance_components.Components`; its factor's relative σ 1/√(2 tr Rₖ²)),
falls below :data:`MIN_REDUNDANCY`, it came out so small that the overlaps no longer check its
narrowed priors, and its likelihood is flat from there down to "exact" (the airborne heading of
1.5 cm / 0.001° errors, docs/validation.md, issue 26). The data tell only its upper end
(:func:`calidar.adjust.variance_components.upper_end`, 97.5 % one-sided), and it is held there
while the others are estimated again. Each estimated group then
follows the flight in time (:mod:`calidar.strips.trajectory_level_time`). Each factor is held ≥
:data:`FLOOR_FACTOR` (a trajectory that good is as good as exact for the calibration).

The level is itself an estimate, known to ±1/√(2m): :func:`carry_uncertainty` carries that into
the mounting's covariance (:mod:`calidar.adjust.variance_carry`: the plug-in covariance averaged
over each factor's posterior, plus the spread of the estimate over it; Kackar & Harville 1984).
A bounded group's factor is averaged likewise over what the data allow below its upper end (its
confidence distribution from the same one-sided test, :func:`bounded_nodes`), about the estimate
held at that end: held there alone the mounting's σ were as wide as the bound (airborne yaw
1.29× the σ with the true accuracy file, 1.11× averaged; docs/validation.md, issue 26).
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass, replace

import numpy as np

from calidar.adjust.variance_carry import QUANTILES, carried_covariance
from calidar.adjust.variance_components import (OBSERVATIONS, Components, confidence_nodes,
                                                estimate_components, normal_terms, split_blocks,
                                                upper_end)
from calidar.adjust.variance_elements import estimate_elements
from calidar.errors import CalibrationError
from calidar.strips.trajectory_errors import Knot
from calidar.strips.trajectory_level_time import (LevelOverTime, estimate_over_time,
                                                  over_time_accuracy)
from calidar.trajectory_accuracy import TrajectoryAccuracy

GROUPS = ("position_horizontal", "position_vertical", "attitude_horizontal", "heading")
#: a group's factor is estimated only when the overlaps check at least this many of its priors at
#: the stated σ (its redundancy there; the factor is then known to ±1/√(2·10) ≈ 22 % at that level)
MIN_REDUNDANCY = 10.0
#: the smallest factor on a stated σ (1 % of the survey-grade default: 0.5 mm, 0.00003°)
FLOOR_FACTOR = 0.01
#: a bounded group is held at the σ its update rejects at this one-sided level (0.025: the upper end
#: of a 95 % interval; 0.16, one σ: airborne yaw σ 1.29 → 1.18× the smrmsg's, docs/validation.md)
BOUND_LEVEL = 0.025
SOURCE = "estimated from the overlaps (variance components of the trajectory priors)"


def group_of(knot: Knot | None) -> str | None:
    """The group (:data:`GROUPS`) of a trajectory parameter's knot; None for other parameters."""
    if knot is None:
        return None
    kind, axis = knot.kind, knot.axis
    if kind == "bias":
        return GROUPS[0] if axis < 2 else GROUPS[1]
    return GROUPS[2] if axis < 2 else GROUPS[3]


@dataclass
class TrajectoryLevel:
    """The estimated level: per group the factor applied to the stated σ and whether it was
    estimated, what it rests on, and the accuracy it makes."""

    base: TrajectoryAccuracy  #: the σ started from (the survey-grade default)
    components: Components
    #: per group (present in the adjustment): estimated, or the data cannot tell
    estimated: dict[str, bool]
    accuracy: TrajectoryAccuracy  #: ``base`` × the factors
    #: the estimated groups' factors per segment of the flight
    over_time: LevelOverTime | None = None
    #: per estimated group the effective number m of independent priors behind its factor (its
    #: relative σ 1/√(2m); correlated priors count less than their redundancy rₖ)
    effective: dict[str, float] | None = None
    #: per non-trajectory parameter the factor on its σ from the level's own uncertainty
    #: (:func:`carry_uncertainty`)
    carried: dict[str, float] | None = None
    #: per bounded group (checked at the stated σ, not at its estimate): its held factor (the
    #: upper end the data leave it), its information tr(Rₖ²) at the estimate it was bounded from
    #: and its redundancy at the stated σ
    bounded: dict[str, tuple[float, float, float]] | None = None
    #: per bounded group its factor at the nodes of its confidence distribution below the held
    #: upper end (:data:`calidar.adjust.variance_carry.QUANTILES`; :func:`bounded_nodes`): what
    #: :func:`carry_uncertainty` averages the mounting's covariance over
    nodes: dict[str, tuple[float, ...]] | None = None

    def factor(self, group: str) -> float:
        if group in (self.bounded or {}):
            return self.bounded[group][0]
        return self.components.sigma_factor(group) if self.estimated.get(group) else 1.0

    def relative_sigma(self, group: str) -> float:
        """The estimated factor's relative σ: 1/√(2m) with m its priors' effective number when
        known, else 1/√(2rₖ)."""
        m = (self.effective or {}).get(group)
        if m is None:
            return self.components.relative_sigma(group)
        return float("inf") if m <= 0 else 1.0 / math.sqrt(2.0 * m)

    @property
    def any_estimated(self) -> bool:
        return any(self.estimated.values())

    @property
    def from_data(self) -> bool:
        """Whether any group's level comes from the data (estimated or bounded)."""
        return self.any_estimated or bool(self.bounded)

    def headline(self) -> str:
        """'position 2.9/4.4 cm (horizontal/vertical), attitude 0.0020/0.0079°
        (roll·pitch/heading)'."""
        m = self.accuracy.medians()
        return (f"position {m['north_rms_m'] * 100:.2g}/{m['down_rms_m'] * 100:.2g} cm "
                "(horizontal/vertical), attitude "
                f"{m['roll_rms_deg']:.2g}/{m['heading_rms_deg']:.2g}° (roll·pitch/heading)")

    def undetermined(self) -> list[str]:
        """The groups the data cannot tell, with their redundancy: 'heading (r = 3.1 < 10)'."""
        return [f"{g.replace('_', ' ')} (redundancy {self.components.redundancy_start[g]:.1f} < "
                f"{MIN_REDUNDANCY:g})"
                for g, ok in self.estimated.items() if not ok and g not in (self.bounded or {})]

    def to_dict(self) -> dict:
        c = self.components
        m = self.accuracy.medians()
        bounded = self.bounded or {}
        groups = {g: {"estimated": ok, "sigma_factor": self.factor(g),
                      "sigma_factor_relative_sigma": self.relative_sigma(g) if ok else None,
                      "redundancy": float(c.redundancy[g]),
                      "information": float(bounded[g][1] if g in bounded else c.information[g]),
                      "redundancy_at_stated_sigma": float(bounded[g][2] if g in bounded
                                                          else c.redundancy_start[g]),
                      "priors": int(c.size[g])} | self._bounded_dict(g)
                  for g, ok in self.estimated.items()}
        return {"source": "data" if self.from_data else "default", "method": SOURCE,
                "headline": self.headline(),
                "position_m": {"horizontal": m["north_rms_m"], "vertical": m["down_rms_m"]},
                "attitude_deg": {"roll_pitch": m["roll_rms_deg"], "heading": m["heading_rms_deg"]},
                "min_redundancy": MIN_REDUNDANCY, "iterations": c.iterations,
                "converged": c.converged,
                "observations_sigma0": float(np.sqrt(c.variance[OBSERVATIONS])),
                "groups": groups} | self._over_time_dict() | self._carried_dict()

    def _bounded_dict(self, group: str) -> dict:
        if group not in (self.bounded or {}):
            return {}
        nodes = (self.nodes or {}).get(group)
        return {"bounded": True} | ({} if nodes is None else {"sigma_factor_nodes": list(nodes)})

    def _carried_dict(self) -> dict:
        if self.carried is None:
            return {}
        return {"sigma_widened_by_level_uncertainty": dict(self.carried)}

    def _over_time_dict(self) -> dict:
        """The level per segment of the flight (solution.json's "over_time"), σ in m and degrees."""
        if self.over_time is None:
            return {}
        pos, att = self.base.position_m[0], np.degrees(self.base.attitude_rad[0])
        stated = {"position_horizontal": pos[0], "position_vertical": pos[2],
                  "attitude_horizontal": att[0], "heading": att[2]}
        return {"over_time": self.over_time.to_dict(stated)}


def estimate_level(est, base: TrajectoryAccuracy, layout: Mapping[str, Knot],
                   knot_times: Mapping[int, np.ndarray] | None = None) -> TrajectoryLevel:
    """The trajectory's level from an adjustment ``est`` (a :class:`calidar.adjust.solver.Estimate`
    whose trajectory priors came from ``base``, its trajectory parameters' knots by name
    ``layout``): groups with redundancy below :data:`MIN_REDUNDANCY` are held at their stated σ,
    groups bounded (module docstring) at their upper end, and the others estimated again without
    them. With the strips' ``knot_times`` the estimated groups then follow the flight in time
    (:mod:`calidar.strips.trajectory_level_time`)."""
    terms = normal_terms(est)
    knots = [layout.get(p.name) for p in est.fit.free]
    groups = [group_of(k) for k in knots]
    blocks = split_blocks(est.fit.priors, groups)
    present = [g for g in GROUPS if any(b.group == g for b in blocks)]
    comps, fixed, bounded = _components(terms, blocks, present)
    estimated = {g: g not in fixed for g in present}
    level = TrajectoryLevel(base, comps, estimated, base, bounded=bounded or None,
                            nodes=bounded_nodes(terms, blocks, comps, bounded) or None)
    source = SOURCE if level.from_data else base.source
    level.accuracy = scaled(base, *(level.factor(g) for g in GROUPS), source=source)
    if knot_times is not None and level.any_estimated:
        start = {g: comps.variance[g] for g in present if estimated[g]}
        held = scaled(base, *(bounded.get(g, (1.0,))[0] for g in GROUPS), source=source)
        priors = _held_priors(est.fit.priors, groups, bounded)
        try:
            elements = estimate_elements(terms[0], terms[1], terms[4], priors, groups,
                                         start, observations=comps.variance[OBSERVATIONS],
                                         max_iter=1)
            level.effective = elements.effective
            level.over_time = estimate_over_time(terms, priors, knots, groups, knot_times,
                                                 start, comps.variance[OBSERVATIONS],
                                                 FLOOR_FACTOR**2)
        # a normal matrix singular at some segment's factors: the flight-wide level stays
        except CalibrationError:
            return level
        level.accuracy = over_time_accuracy(held, level.over_time, knot_times)
    return level


def _components(terms: tuple, blocks: list, present: list[str]) -> tuple[Components, list[str],
                                                                        dict]:
    """The groups' factors (:func:`estimate_level`): the components estimated, the groups held
    (weak at their stated σ, bounded at their upper end) and per bounded group (factor,
    information tr(Rₖ²) at its estimate, redundancy at the stated σ)."""
    fixed, held, bounded = ["other"], {}, {}
    while True:  # tol: 1 % in variance, ½ % in σ — well inside the factors' own ±1/√(2rₖ)
        try:
            comps = estimate_components(*terms, blocks, fixed=fixed, floor=FLOOR_FACTOR**2,
                                        marginal=True, tol=0.01, start=held)
        except CalibrationError:  # a normal matrix singular at some factors: nothing estimated
            fixed, held, bounded = ["other", *present], {}, {}
            return estimate_components(*terms, blocks, fixed=fixed, max_iter=1), fixed, bounded
        # judged at the stated σ: a group the data do not check there is held at it
        free = [g for g in present if g not in fixed]
        weak = [g for g in free if comps.redundancy_start[g] < MIN_REDUNDANCY]
        if weak:
            fixed += weak
            continue
        # checked at the stated σ but not at its estimate: only its upper end is known
        loose = [g for g in free if comps.information[g] < MIN_REDUNDANCY]
        if not loose:
            return comps, fixed, bounded
        for g in loose:
            held[g] = upper_end(terms, blocks, comps.variance, g, level=BOUND_LEVEL)
            bounded[g] = (float(np.sqrt(held[g])), float(comps.information[g]),
                          float(comps.redundancy_start[g]))
        fixed += loose


def bounded_nodes(terms: tuple, blocks: list, comps: Components,
                  bounded: Mapping[str, tuple]) -> dict[str, tuple[float, ...]]:
    """Per bounded group its σ factor at :data:`~calidar.adjust.variance_carry.QUANTILES` of its
    confidence distribution between :data:`FLOOR_FACTOR` and its held upper end, the others at
    their estimates (:func:`calidar.adjust.variance_components.confidence_nodes`: the update's
    one-sided test, whose 97.5 % point is that upper end); empty where a normal matrix is
    singular at some factor (the held factor's plug-in σ then stay)."""
    out = {}
    for g, (held, *_) in bounded.items():
        try:
            v = confidence_nodes(terms, blocks, comps.variance, g, QUANTILES, FLOOR_FACTOR**2,
                                 held**2)
        except CalibrationError:
            continue
        out[g] = tuple(float(f) for f in np.sqrt(v))
    return out


def _held_priors(priors, groups: list[str | None], bounded: Mapping[str, tuple]) -> list:
    """The engine's prior groups with the bounded groups' priors at their held factor."""
    f = np.array([bounded[g][0] if g in bounded else 1.0 for g in groups])
    return [(idx, c, P / np.outer(f[idx], f[idx])) for idx, c, P in priors]


def scaled(base: TrajectoryAccuracy, horizontal: float, vertical: float, tilt: float,
           heading: float, source: str) -> TrajectoryAccuracy:
    """``base`` with its position σ north/east × ``horizontal``, down × ``vertical``, its attitude σ
    roll/pitch × ``tilt`` and heading × ``heading``."""
    pos = base.position_m * np.array([horizontal, horizontal, vertical])
    att = base.attitude_rad * np.array([tilt, tilt, heading])
    return replace(base, position_m=pos, attitude_rad=att, source=source)


def carry_uncertainty(level: TrajectoryLevel, est, solution, layout: Mapping[str, Knot]) -> None:
    """The level's own uncertainty carried into ``solution``'s covariance (a
    :class:`calidar.adjust.solution.Solution` of the adjustment ``est`` with the level's priors):
    each estimated group's factor at its flight-wide effective number m of independent priors,
    each bounded group's over its nodes below the upper end it is held at (``level.nodes``)
    (:mod:`calidar.adjust.variance_carry`). Only the non-trajectory parameters' block changes (the
    trajectory corrections keep their plug-in σ); the ratio of their σ to the plug-in goes to
    ``level.carried`` (below 1 where a bounded group's range narrows them more than the estimated
    groups' uncertainty widens them)."""
    effective = {g: m for g, m in (level.effective or {}).items() if level.estimated.get(g)}
    # a bounded group: over its confidence distribution below the upper end it is held at
    nodes = {g: np.square(np.array(f) / level.factor(g)) for g, f in (level.nodes or {}).items()}
    names = [p.name for p in est.fit.free]
    groups = [group_of(layout.get(n)) for n in names]
    where = {n: i for i, n in enumerate(solution.parameters.free_names)}
    cov = solution.covariance
    own = np.array([i for i, (n, g) in enumerate(zip(names, groups))
                    if g is None and np.isfinite(cov[where[n], where[n]])], int)
    if not (effective or nodes) or own.size == 0:
        return
    terms = normal_terms(est)
    try:
        Q, delta = carried_covariance(terms[0], terms[1], terms[4], est.fit.priors, groups,
                                      effective, own, nodes=nodes)
    except CalibrationError:  # a normal matrix singular at some factor: the plug-in σ stay
        return
    pos = np.array([where[names[i]] for i in own])
    # the solution's covariance is its variance factor × N⁻¹: ΔQ scaled alike
    factor = float(np.median(np.diag(cov)[pos] / np.diag(Q)))
    before = np.sqrt(np.diag(cov)[pos])
    cov[np.ix_(pos, pos)] += factor * delta
    level.carried = {names[i]: float(np.sqrt(cov[p, p]) / b) for i, p, b in zip(own, pos, before)}
