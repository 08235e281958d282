"""The strip calibrator: boresight, lever arm, range and scanner parameters from overlapping strips.

An outer loop as in ICP (Besl & McKay 1992) around the one adjustment engine:

1. re-georeference the overlapping points of every strip with the current parameters;
2. match every overlapping pair (tie planes or VGICP) → :class:`Correspondences`,
   as independent tasks through :func:`calidar.strips.distribute.map_pairs`;
3. :func:`calidar.adjust.solver.estimate` the parameters from the correspondence residuals
   (:class:`calidar.strips.problem.StripProblem`), only the points the correspondences
   reference being re-georeferenced at each evaluation, until every step is below
   :data:`calidar.strips.outer_loop.OUTER_STEP_IN_SIGMA` of its σ;
4. repeat until the mean correspondence distance changes by less than ``threshold_m``; then
   refine the last adjustment to :data:`FINAL_STEP_IN_SIGMA` and compute its σ, once.

Steps 1–4 are :mod:`calidar.strips.outer_loop` (one run's fixed inputs,
:class:`calidar.strips.outer_loop.Run`, and the loop); here the calibration around it: the
parameters, the trajectory accuracy estimated from the overlaps, the last refinement, the model
check and the :class:`CalibrationResult`.

The parameters are in :mod:`calidar.strips.parameters`, the residuals and Jacobian in
:mod:`calidar.strips.problem`, the trajectory corrections in
:mod:`calidar.strips.trajectory_errors`.
"""

from __future__ import annotations

import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field, replace

import numpy as np

from calidar.adjust import ParameterSet, Solution
from calidar.adjust.solver import Estimate
from calidar.adjust.solution import residual_stats
from calidar.memory import release_memory
from calidar.scanners.rotating import canonical_eccentricity
from calidar.sensor import Sensor
from calidar.strips.control import (
    CONTROL_ID, ControlPoints, check_estimate, control_rows, control_summary, with_height_bias,
)
from calidar.strips.control_survey import PREFIX as CONTROL_PREFIX
from calidar.strips.control_survey import with_survey_parameters
from calidar.strips.correspond import Correspondences
from calidar.strips.distribute import cluster_client
from calidar.strips.geometry import geometry_warnings
from calidar.strips.overlap import Overlap
from calidar.strips.config import CalibrationConfig
from calidar.strips.matchers import Matcher
from calidar.strips.outer_loop import OUTER_STEP_IN_SIGMA, Run, mean_distance, outer_loop
from calidar.strips.parameters import build_parameters, sensor_of
from calidar.strips.problem import StripProblem, georeference
from calidar.strips.processes import PROCESSES, pair_processes
from calidar.strips.row_variance import dof_summary, rows_dof
from calidar.strips.strip import Strip
from calidar.strips.trajectory_errors import PREFIX as TRAJECTORY_PREFIX
from calidar.strips.trajectory_errors import StripCorrection, TrajectoryModel, corrections
from calidar.strips.trajectory_level import carry_uncertainty

#: the last outer iteration's adjustment (stopped at OUTER_STEP_IN_SIGMA of its σ) is refined until
#: every step (of ~1 500 parameters with the trajectory model) is below this fraction of its σ — the
#: boresight then moves by < 1e-3 σ more (8.75 M-point survey: 4 LM iterations fewer than at 1e-3 σ)
FINAL_STEP_IN_SIGMA = 0.01


@dataclass
class CalibrationResult:
    """What a strip calibration produced."""

    solution: Solution
    sensor: Sensor  #: calibrated
    nominal: Sensor
    strips: list[Strip]
    overlaps: list[Overlap]
    matcher: Matcher  #: how the correspondences were found
    pairs: list[dict]  #: per used pair: a, b, n_obs
    residuals_before: np.ndarray  #: first correspondences at the nominal sensor, m
    residuals_after: np.ndarray  #: last correspondences at the calibrated sensor, m
    outer: list[dict]  #: per outer iteration: mean distance, observations, values (SI)
    corrections: dict[int, StripCorrection]  #: estimated trajectory corrections per strip
    trajectory_model: TrajectoryModel | None = None  #: the corrections' model (None: not estimated)
    #: a-priori σ of residuals_after, m
    row_sigma: np.ndarray | None = field(default=None, repr=False)

    @property
    def method(self) -> str:
        """The matcher's name ("planes", "vgicp")."""
        return self.matcher.name

    @property
    def warnings(self) -> list[str]:
        return self.solution.warnings

    def max_trajectory_shift_m(self) -> float:
        """The largest estimated trajectory shift at any knot (m; 0 without corrections)."""
        return max((float(np.abs(c.shift).max()) for c in self.corrections.values()), default=0.0)

    def georeference(self, strip: Strip, calibrated: bool = True, index=None,
                     trajectory: bool = True) -> np.ndarray:
        """A strip's points (local m) with the calibrated (or nominal) sensor and, when
        ``trajectory``, its trajectory correction."""
        if not calibrated:
            return strip.points if index is None else strip.points[index]
        pose = strip.pose(index)  # (the calibration's pose caches, 112 B a point, are not kept)
        fix = self.corrections.get(strip.id) if trajectory else None
        return georeference(self.sensor, fix, pose, strip.time[pose.index])


def calibrate(strips: Sequence[Strip], nominal: Sensor,
              config: CalibrationConfig = CalibrationConfig(), *,
              scheduler: str | None = None, workers: int | None = None,
              **options) -> CalibrationResult:
    """:func:`calibrate_with_client` with ONE Dask client (``scheduler`` address or a LocalCluster
    of ``workers`` processes, None: in-process) for every outer iteration's pair matching."""
    with cluster_client(scheduler, workers) as client:
        return calibrate_with_client(strips, nominal, config, client=client, **options)


def calibrate_with_client(strips: Sequence[Strip], nominal: Sensor,
                          config: CalibrationConfig = CalibrationConfig(),
                          *, matcher: Matcher | None = None,
                          trajectory: TrajectoryModel | None = None, client=None,
                          progress: Callable[[str, int, int], None] | None = None, log=None,
                          control: ControlPoints | None = None) -> CalibrationResult:
    """Calibrate the sensor from overlapping strips (all in one :class:`LocalFrame`).

    ``config``: what to estimate and how the adjustment runs (:class:`CalibrationConfig`);
    ``matcher``: how the pairs are matched (None: the first of ``config.matchers``);
    ``trajectory``: the trajectory model whose corrections are estimated too (None: the
    trajectory is taken as exact; :meth:`calidar.strips.config.TrajectorySettings.model` makes
    one from ``config.trajectory`` and the trajectory's accuracy); ``client``: an open Dask client
    for the pair matching or None (see :func:`map_pairs`; ``log``: a TaskLog of what its tasks
    sent back); ``progress(description, done, total)`` is told each outer iteration's stages;
    ``control``: ground control points in the strips' local frame, observed beside the overlaps
    (:mod:`calidar.strips.control`). Raises :class:`CalibrationError` when no pair of strips
    overlaps with enough correspondences.
    """
    s, matcher = config.solver, matcher or config.matchers[0]
    threshold_m = matcher.threshold_m if s.threshold_m is None else s.threshold_m
    say = progress or (lambda text, done, total: None)
    check_estimate(config.estimate, control)
    run = Run.start(strips, nominal, matcher, s, trajectory, control)
    params = build_parameters(nominal, config.estimate, run.spans, trajectory,
                              run.headings() if trajectory is not None else None)
    params = with_survey_parameters(params, control)
    in_processes = client is None and matcher.holds_gil
    processes = pair_processes(PROCESSES if in_processes else 1)
    with processes as pool:
        outer, est, problem, corrs, pairs, first_residuals, first_control = outer_loop(
            run, params, client, say, log, pool, threshold_m)
    if run.model is not None and run.model.estimate_level:
        est, problem = _trajectory_level(run, est, corrs, say)
    say("refining the last adjustment and its σ", s.max_outer, s.max_outer)
    clock = time.perf_counter()
    est = est.refine(FINAL_STEP_IN_SIGMA)  # the last matching's adjustment, then its covariance
    solution = run.solution(est, problem)
    if run.level is not None:  # the estimated level's own uncertainty carried into the mounting's σ
        carry_uncertainty(run.level, est, solution, run.model.layout(run.spans))
    if config.model_check:
        release_memory()  # the refine's arrays, before the model check builds its problems
        say("model check: freeing the parameters not estimated", s.max_outer, s.max_outer)
        solution.extra["model_check"] = run.model_check(est, problem, corrs, solution)
    outer[-1].update(mean_distance_m=mean_distance(problem, est.r),
                     solver_iterations=len(est.history) - 1,
                     solve_s=outer[-1]["solve_s"] + time.perf_counter() - clock,
                     values=est.parameters.values())
    say("calibrated", s.max_outer, s.max_outer)
    if run.control is not None:
        final_rows = control_rows(problem, problem(solution.parameters.values()))
        solution.extra["control"] = control_summary(run.control, first_control, final_rows)
    return _result(run, solution, problem, pairs, outer, first_residuals, strips)


def _trajectory_level(run: Run, est: Estimate, corrs: list[Correspondences],
                      say) -> tuple[Estimate, StripProblem]:
    """No accuracy file: the trajectory priors' level estimated from the overlaps
    (:mod:`calidar.strips.trajectory_level`), the model's accuracy replaced by it and the last
    matching adjusted again with those priors."""
    from calidar.strips.trajectory_level import estimate_level

    say("estimating the trajectory's accuracy from the overlaps", run.settings.max_outer,
        run.settings.max_outer)
    run.level = estimate_level(est, run.model.accuracy, run.model.layout(run.spans),
                               run.model.knot_times(run.spans))
    run.model = replace(run.model, accuracy=run.level.accuracy, estimate_level=False)
    sigma = {p.name: p.prior_sigma for p in run.model.parameters(run.spans, run.headings())}
    params = ParameterSet(replace(p, prior_sigma=sigma[p.name]) if p.name in sigma else p
                          for p in est.parameters)
    return run.solve(corrs, params, OUTER_STEP_IN_SIGMA, None)


def _result(run: Run, solution: Solution, problem: StripProblem, pairs: list[dict],
            outer: list[dict], first_residuals: np.ndarray,
            strips: Sequence[Strip]) -> CalibrationResult:
    """The last solve as a :class:`CalibrationResult`: canonical values, "before" statistics from
    the first matching at the nominal sensor, warnings, the outer loop's record."""
    canonical_eccentricity(solution)
    params = solution.parameters
    # "before" for the user: the first matching at the nominal sensor (the last solve started
    # from the previous outer iteration's values)
    solution.residuals_before = residual_stats(first_residuals)
    if run.model is not None or run.control is not None:
        prefixes = (((TRAJECTORY_PREFIX,) if run.model is not None else ())
                    + ((CONTROL_PREFIX,) if run.control is not None else ()))
        solution.nuisance_prefix = prefixes[0] if len(prefixes) == 1 else prefixes
    if run.level is not None:
        solution.extra["trajectory_accuracy_estimate"] = run.level.to_dict()
    used_pairs = [(p["a"], p["b"]) for p in pairs]
    adjusted = [run.by_id[i] for i in problem.index if i != CONTROL_ID]
    solution.warnings = (run.warnings + geometry_warnings(adjusted, used_pairs, params.free_names)
                         + solution.warnings)
    sensor = sensor_of(run.nominal, params.values())
    fix = corrections(params.values(), run.model, run.spans)
    fix = with_height_bias(fix, params.values().get("height_bias", 0.0), run.spans)
    iterations = [{kk: v for kk, v in o.items() if kk != "values"} for o in outer]
    solution.extra["strips"] = {
        "method": run.matcher.name, "robust": run.settings.robust, "pairs": pairs,
        "sigma0_reading": run.matcher.sigma0_reading, "outer_iterations": iterations,
        "row_dof": dof_summary(np.concatenate([rows_dof(c) for c in problem.corrs]))}
    if run.unevenness is not None:  # VGICP's ℓ pooled over the survey's pairs
        solution.extra["strips"]["unevenness"] = run.unevenness
    return CalibrationResult(solution, sensor, run.nominal, list(strips), run.overlaps, run.matcher,
                             pairs, first_residuals, solution.residuals, outer, fix, run.model,
                             problem.sigma)
