"""The strip calibration's configuration: typed values, checked when they are made and handed
down unchanged.

- :class:`Estimate`: the sensor parameters to estimate (a set of names, made from groups such as
  ``boresight`` or single parameters such as ``lever_arm_x``);
- :class:`TrajectorySettings`: the trajectory model's knots, Gauss–Markov correlation times and,
  optionally, one σ for every epoch (:mod:`calidar.strips.trajectory_errors`);
- :class:`StripSettings`: how the adjustment runs (overlap grid, outer loop, clusters, the engine's
  :class:`calidar.adjust.SolverOptions`);
- the matchers (:mod:`calidar.strips.matchers`), each with its own settings, by name in
  :data:`MATCHERS`;
- ground control's kinds (points, planes) by name in :data:`CONTROL_KINDS`;
- :class:`CalibrationConfig`: all of them, what :func:`calidar.strips.calibrate.calibrate` takes.

SI units inside (radians, metres, seconds); degrees appear only where a user reads or writes them.

>>> config = CalibrationConfig(Estimate.of("boresight", "lever_arm_z"), matchers=(Vgicp(),))
>>> sorted(config.estimate.parameters)
['boresight_pitch', 'boresight_roll', 'boresight_yaw', 'lever_arm_z']
>>> config.estimate.names(), [m.name for m in config.matchers]
(['boresight', 'lever_arm_z'], ['vgicp'])
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

from calidar.adjust.residuals import SolverOptions
from calidar.errors import InputError
from calidar.strips.control import ControlPoints
from calidar.strips.control_cloud import ControlCloud
from calidar.strips.control_planes import ControlPlanes
from calidar.strips.matchers import Matcher, TiePlanes, Vgicp
from calidar.strips.parameters import ESTIMATE_GROUPS, SINGLE_PARAMETERS
from calidar.strips.trajectory_errors import SHAPES, TrajectoryModel
from calidar.trajectory_accuracy import MAX_ATTITUDE_SIGMA_RAD, MAX_POSITION_SIGMA_M

#: the matchers by the name ``--method`` and the outputs use
MATCHERS: dict[str, type] = {m.name: m for m in (TiePlanes, Vgicp)}
#: ground control's kinds by name (``--control FILE``: points, or surfaces (planes) when the file
#: names a plane column, or a reference cloud when it is LAS/LAZ): each answers the calibrator's
#: questions (:class:`calidar.strips.control.ControlPoints`)
CONTROL_KINDS: dict[str, type] = {c.kind: c for c in (ControlPoints, ControlPlanes, ControlCloud)}


def control_kind(name: str | None) -> type:
    """The kind of ground control of this name (solution.json's ``control.kind``; None, as files
    written before there were kinds: the first, control points)."""
    return CONTROL_KINDS[name] if name is not None else next(iter(CONTROL_KINDS.values()))


def control_action() -> str:
    """What the verdict tells a user to give when ground control is missing: every kind's file."""
    ways = [k.how_to_give for k in CONTROL_KINDS.values()]
    listed = "; ".join(ways[:-1]) + "; or " + ways[-1] if len(ways) > 1 else ways[0]
    return f"give ground control: calidar boresight --control FILE ({listed})"
#: the groups an :class:`Estimate` is made of (the trajectory's errors are the trajectory model's)
GROUPS: dict[str, tuple[str, ...]] = {g: tuple(n for n, _ in p) for g, p in ESTIMATE_GROUPS.items()}
MAX_TRAJECTORY_BLOCK_S = 600.0  #: s, the knots' spacing (longer: no trajectory correction at all)
MAX_CORRELATION_S = 86400.0  #: s, correlation times (a day: constant errors)


def matchers_named(*names: str) -> tuple[Matcher, ...]:
    """The matchers of these names (:data:`MATCHERS`), each with its default settings."""
    unknown = [n for n in names if n not in MATCHERS]
    if unknown or not names:
        raise InputError(None, "method",
                         f"expected one or more of {', '.join(MATCHERS)}, got {list(names)}")
    return tuple(MATCHERS[n]() for n in names)


@dataclass(frozen=True)
class Estimate:
    """The sensor parameters to estimate, by the engine's names (``boresight_roll``, ...)."""

    parameters: frozenset[str]

    def __post_init__(self):
        unknown = sorted(set(self.parameters) - set(SINGLE_PARAMETERS))
        if unknown or not self.parameters:
            raise InputError(None, "estimate",
                             f"expected one or more of the groups {sorted(GROUPS)} or single "
                             f"parameters such as lever_arm_x, got {unknown or 'none'}")

    @classmethod
    def of(cls, *names: str) -> Estimate:
        """The parameters of groups (``boresight``) and single parameters (``lever_arm_x``)."""
        unknown = [n for n in names if n not in GROUPS and n not in SINGLE_PARAMETERS]
        if unknown or not names:
            raise InputError(None, "estimate",
                             f"expected one or more of the groups {sorted(GROUPS)} or single "
                             f"parameters such as lever_arm_x, got {unknown or 'none'}")
        return cls(frozenset(p for n in names for p in GROUPS.get(n, (n,))))

    def __contains__(self, name: str) -> bool:
        """A parameter, or a group whose every parameter is estimated."""
        return all(p in self.parameters for p in GROUPS.get(name, (name,)))

    def names(self) -> list[str]:
        """The shortest list of group and single-parameter names that makes it (as a user would)."""
        groups = [g for g, ps in GROUPS.items() if g in self]
        covered = {p for g in groups for p in GROUPS[g]}
        return groups + [p for p in SINGLE_PARAMETERS if p in self.parameters and p not in covered]


def _positive(value: float, what: str, unit: str, hi: float) -> None:
    if not (isinstance(value, (int, float)) and math.isfinite(value) and 0 < value <= hi):
        raise InputError(None, what,
                         f"expected a finite number > 0 and ≤ {hi:g} {unit}, got {value}")


@dataclass(frozen=True)
class TrajectorySettings:
    """The trajectory model (:class:`calidar.strips.trajectory_errors.TrajectoryModel`) as a user
    sets it: knots every ``block_s`` s, Gauss–Markov correlation times (position, attitude) s (the
    integral time ∫₀^∞ ρ), their ``shape`` (position, attitude: "gm1" or "gm2", first- or
    second-order Gauss–Markov, :func:`calidar.strips.trajectory_errors.gauss_markov`) and
    ``sigma`` (position m, attitude rad), one σ for every epoch and axis instead of the
    trajectory's stated accuracy (None: the accuracy of the trajectory's file, or estimated)."""

    block_s: float = 1.0
    correlation_s: tuple[float, float] = (20.0, 3.5)
    sigma: tuple[float, float] | None = None
    shape: tuple[str, str] = ("gm1", "gm1")

    def __post_init__(self):
        _positive(self.block_s, "trajectory block (--trajectory-block)", "s",
                  MAX_TRAJECTORY_BLOCK_S)
        if len(self.correlation_s) != 2:
            got = len(self.correlation_s)
            raise InputError(None, "trajectory correlation (--trajectory-correlation)",
                             f"expected 2 times (position, attitude), got {got}")
        for v in self.correlation_s:
            _positive(v, "trajectory correlation (--trajectory-correlation)", "s",
                      MAX_CORRELATION_S)
        if len(self.shape) != 2 or any(v not in SHAPES for v in self.shape):
            raise InputError(None, "trajectory shape", "expected 2 of "
                             f"{', '.join(SHAPES)} (position, attitude), got {self.shape!r}")
        if self.sigma is not None:
            if len(self.sigma) != 2:
                raise InputError(None, "trajectory sigma (--trajectory-sigma)",
                                 f"expected 2 values (position m, attitude), got {len(self.sigma)}")
            _positive(self.sigma[0], "trajectory sigma (--trajectory-sigma)", "m",
                      MAX_POSITION_SIGMA_M)
            _positive(self.sigma[1], "trajectory sigma (--trajectory-sigma)", "rad",
                      MAX_ATTITUDE_SIGMA_RAD)

    def model(self, accuracy=None, estimate_level: bool = False) -> TrajectoryModel:
        """The model with priors from ``accuracy`` (a TrajectoryAccuracy), else from :attr:`sigma`;
        ``estimate_level``: the priors' level estimated from the overlaps."""
        pos, att = (None, None) if accuracy is not None or self.sigma is None else self.sigma
        return TrajectoryModel(self.block_s, pos, att, *self.correlation_s, accuracy,
                               estimate_level, tuple(self.shape))


@dataclass(frozen=True)
class StripSettings:
    """How the strip adjustment runs (metres unless named)."""

    overlap_cell_m: float = 5.0  #: grid of the overlap detection
    min_overlap_cells: int = 4
    min_correspondences: int = 10  #: pairs with fewer are skipped with a warning
    max_outer: int = 40  #: outer (re-matching) iterations at most (calidar.strips.convergence)
    #: stop when the mean correspondence distance changes by less (None: the matcher's threshold_m)
    threshold_m: float | None = None
    #: trajectory errors correlate over this time: σ from a cluster-robust covariance
    cluster_s: float | None = 10.0
    #: how the engine iterates each adjustment (robust loss "cauchy", "huber" or None, its k and MAD
    #: scale, max_iter, tol) and its covariance: the IRLS model's, on which the issue-26 Monte-Carlo
    #: ran ("sandwich": the M-estimator's, an option — docs/validation.md, "The robust fit's
    #: covariance"); each outer iteration sets its own step_in_sigma
    #: (:func:`calidar.strips.calibrate.calibrate`)
    adjustment: SolverOptions = SolverOptions(robust="cauchy")

    def __post_init__(self):
        for name in ("overlap_cell_m", "min_overlap_cells", "min_correspondences", "max_outer"):
            _positive(getattr(self, name), f"solver {name}", "", 1e9)
        for name in ("threshold_m", "cluster_s"):
            if getattr(self, name) is not None:
                _positive(getattr(self, name), f"solver {name}", "", 1e9)
        if not isinstance(self.adjustment, SolverOptions):
            raise InputError(None, "solver adjustment",
                             f"expected SolverOptions, got {self.adjustment!r}")

    @property
    def robust(self) -> str | None:
        """The robust loss of the adjustment's IRLS weights (None: least squares)."""
        return self.adjustment.robust


@dataclass(frozen=True)
class CalibrationConfig:
    """A strip calibration's configuration: what to estimate, with which matchers (one calibration
    each, in order), the trajectory model (None: the trajectory taken as exact) and the
    adjustment."""

    estimate: Estimate = field(default_factory=lambda: Estimate.of("boresight"))
    matchers: tuple[Matcher, ...] = (TiePlanes(),)
    trajectory: TrajectorySettings | None = field(default_factory=TrajectorySettings)
    solver: StripSettings = field(default_factory=StripSettings)
    #: after the adjustment, free each structural parameter not estimated in turn and test whether
    #: the overlaps see it and it moves the estimated ones (:mod:`calidar.strips.model_check`)
    model_check: bool = True

    def __post_init__(self):
        names = [m.name for m in self.matchers]
        if not names or len(set(names)) != len(names):
            raise InputError(None, "method", f"expected one or more of {', '.join(MATCHERS)}, "
                             f"each once, got {names}")
        if not isinstance(self.model_check, bool):
            raise InputError(None, "model check (--model-check)",
                             f"expected on or off (true or false), got {self.model_check!r}")
