"""The strip calibrator: boresight, lever arm, range and scanner parameters from overlapping strips.

An outer loop as in ICP (Besl & McKay 1992) around the one adjustment engine:

1. re-georeference the overlapping points of every strip with the current parameters;
2. match every overlapping pair (tie planes or VGICP) → :class:`Correspondences`,
   as independent tasks through :func:`calidar.strips.distribute.map_pairs`;
3. :func:`calidar.adjust.solver.estimate` the parameters from the correspondence residuals
   (:class:`calidar.strips.problem.StripProblem`), only the points the correspondences
   reference being re-georeferenced at each evaluation, until every step is below
   :data:`OUTER_STEP_IN_SIGMA` of its σ;
4. repeat until the mean correspondence distance changes by less than ``threshold_m``; then
   refine the last adjustment to :data:`FINAL_STEP_IN_SIGMA` and compute its σ, once.

The parameters are in :mod:`calidar.strips.parameters`, the residuals and Jacobian in
:mod:`calidar.strips.problem`, the trajectory corrections in
:mod:`calidar.strips.trajectory_errors`.
"""

from __future__ import annotations

import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field, replace
from pathlib import Path
from types import SimpleNamespace

import numpy as np
import scipy.sparse as sp

from calidar.adjust import ParameterSet, Solution
from calidar.adjust.solver import Estimate, estimate
from calidar.adjust.solution import residual_stats
from calidar.errors import CalibrationError, CalidarError, InputError
from calidar.scanners.rotating import canonical_eccentricity
from calidar.sensor import Sensor
from calidar.strips.control import (
    CONTROL_ID, ControlPoints, check_estimate, control_pose, control_rows, control_summary,
    near_control, with_height_bias,
)
from calidar.strips.control_survey import PREFIX as CONTROL_PREFIX
from calidar.strips.control_survey import SurveyErrors, with_survey_parameters
from calidar.strips.correspond import Correspondences
from calidar.strips.row_variance import dof_summary, rows_dof
from calidar.strips.distribute import cluster_client, map_pairs
from calidar.strips.geometry import geometry_warnings
from calidar.strips.overlap import Overlap, find_overlaps, strip_name
from calidar.strips.config import CalibrationConfig, StripSettings
from calidar.strips.matchers import Matcher
from calidar.strips.parameters import build_parameters, sensor_of
from calidar.strips.processes import PROCESSES, map_in_processes, pair_processes, worth_processes

#: an outer iteration's adjustment stops when every step is below this fraction of its σ: the next
#: matching moves the points anyway; the last one is then refined until every step (of ~1 500
#: parameters with the trajectory model) is below FINAL_STEP_IN_SIGMA of its σ — the boresight
#: then moves by < 1e-3 σ more (8.75 M-point survey: 4 LM iterations fewer than at 1e-3 σ)
OUTER_STEP_IN_SIGMA = 0.1
FINAL_STEP_IN_SIGMA = 0.01
from calidar.strips.problem import StripProblem, georeference, union
from calidar.strips.strip import Pose, Strip
from calidar.strips.trajectory_errors import PREFIX as TRAJECTORY_PREFIX
from calidar.strips.trajectory_errors import StripCorrection, TrajectoryModel, corrections
from calidar.strips.trajectory_level import carry_uncertainty


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
    row_sigma: np.ndarray | None = field(default=None, repr=False)  #: a-priori σ of residuals_after, m

    @property
    def method(self) -> str:
        """The matcher's name ("planes", "vgicp")."""
        return self.matcher.name

    @property
    def warnings(self) -> list[str]:
        return self.solution.warnings

    def max_trajectory_shift_m(self) -> float:
        """The largest estimated trajectory shift at any knot (m; 0 without trajectory corrections)."""
        return max((float(np.abs(c.shift).max()) for c in self.corrections.values()), default=0.0)

    def georeference(self, strip: Strip, calibrated: bool = True, index=None, trajectory: bool = True) -> np.ndarray:
        """A strip's points (local m) with the calibrated (or nominal) sensor and, when
        ``trajectory``, its trajectory correction."""
        if not calibrated:
            return strip.points if index is None else strip.points[index]
        pose = strip.pose(index)  # (the calibration's pose caches, 112 B a point, are not kept)
        fix = self.corrections.get(strip.id) if trajectory else None
        return georeference(self.sensor, fix, pose, strip.time[pose.index])


def _match_or_error(matcher: Matcher, strip_a_id, points_a, strip_b_id, points_b):
    """``matcher.match(...)``, or the user-facing error it raised for this pair (picklable, for map_pairs)."""
    try:
        return matcher.match(strip_a_id, points_a, strip_b_id, points_b)
    except CalidarError as e:
        return e


def _mean_distance(c: Correspondences, r: np.ndarray) -> np.ndarray:
    """Distances (m) of each correspondence from its residuals."""
    return np.abs(r) if c.normal is not None else np.linalg.norm(r.reshape(-1, 3), axis=1)


def _to_strip_columns(c: Correspondences, ov: Overlap, n_a: int, n_b: int) -> Correspondences:
    """Re-index a pair's correspondences from overlap subsets to whole-strip point indices."""
    def widen(m, index, n):
        m = m.tocsr()
        return sp.csr_matrix((m.data, index[m.indices], m.indptr), shape=(m.shape[0], n))

    return replace(c, A=widen(c.A, ov.index_a, n_a), B=widen(c.B, ov.index_b, n_b))


@dataclass
class _Run:
    """One calibration's fixed inputs: strips by id, overlaps, the overlap points' poses, the
    parameters' time spans and the trajectory model (None: no corrections)."""

    by_id: dict[int, Strip]
    nominal: Sensor
    matcher: Matcher
    settings: StripSettings
    overlaps: list[Overlap]
    spans: dict[int, tuple[float, float]]
    model: TrajectoryModel | None
    need: dict[int, np.ndarray]  #: per strip the points inside any of its overlaps
    poses: dict[int, Pose]
    warnings: list[str]
    level: object | None = None  #: calidar.strips.trajectory_level.TrajectoryLevel, when estimated
    control: ControlPoints | None = None  #: ground control in the adjustment (calidar.strips.control)
    near: dict[int, np.ndarray] = field(default_factory=dict)  #: per strip its points near control

    @classmethod
    def start(cls, strips: Sequence[Strip], nominal: Sensor, matcher: Matcher, settings: StripSettings,
              model: TrajectoryModel | None = None, control: ControlPoints | None = None) -> "_Run":
        by_id = {st.id: st for st in strips}
        if len(by_id) != len(strips):
            raise InputError(None, "strips", "two strips share an id; flight-line ids must be unique")
        s = settings
        names = {i: Path(st.source).name for i, st in by_id.items() if st.source != "<memory>"}
        overlaps, notes = find_overlaps({i: st.points for i, st in by_id.items()}, s.overlap_cell_m, s.min_overlap_cells,
                                        names=names)
        if not overlaps:
            listed = f" ({', '.join(strip_name(i, names) for i in by_id)})" if names else ""
            raise CalibrationError(f"no two of the {len(by_id)} strips{listed} overlap (no common "
                                   f"{s.overlap_cell_m:g} m cells); strip calibration needs overlapping flight lines")
        need: dict[int, list[np.ndarray]] = {}
        for o in overlaps:
            need.setdefault(o.a, []).append(o.index_a)
            need.setdefault(o.b, []).append(o.index_b)
        near = {} if control is None else {i: near_control(st.points, control) for i, st in by_id.items()}
        near = {i: v for i, v in near.items() if v.size}
        for i, v in near.items():
            need.setdefault(i, []).append(v)
        need = {i: union(v) for i, v in need.items()}
        spans = {i: st.time_span for i, st in by_id.items()}
        poses = {i: by_id[i].pose(idx) for i, idx in need.items()}  # one trajectory interpolation
        if control is not None:
            poses[CONTROL_ID] = control_pose(control, next(iter(poses.values())))
        return cls(by_id, nominal, matcher, s, overlaps, spans, model, need, poses, list(notes), control=control, near=near)

    def headings(self) -> dict[int, float]:
        return {i: st.heading_enu() for i, st in self.by_id.items()}

    def match(self, values: dict[str, float], k: int, client, say, log=None,
              pool=None) -> tuple[list[Correspondences], list[dict], dict]:
        """Re-georeference the overlap points with ``values`` and match every pair (``pool``: worker
        processes, :mod:`calidar.strips.processes`): the usable correspondence sets (whole-strip
        columns), their pairs, and the stage times (s)."""
        clock = time.perf_counter()
        sensor, fix = sensor_of(self.nominal, values), corrections(values, self.model, self.spans)
        current = {i: (idx, georeference(sensor, fix.get(i), self.poses[i], self.by_id[i].time[idx]))
                   for i, idx in self.need.items()}
        times = {"georeference_s": time.perf_counter() - clock}

        def subset(i, index):  # the points ``index`` of strip i (the pose cache's rows, by table)
            return current[i][1][self.poses[i].rows_of(index)]

        tasks = [(self.matcher, o.a, subset(o.a, o.index_a), o.b, subset(o.b, o.index_b)) for o in self.overlaps]
        say(f"iteration {k + 1}: matching {len(tasks)} pairs ({self.matcher.name})", k, self.settings.max_outer)
        clock = time.perf_counter()
        if pool is not None and client is None and worth_processes(tasks):  # a GIL-holding matcher: both cores
            found = map_in_processes(pool, _match_or_error, tasks)
        else:
            found = map_pairs(_match_or_error, tasks, client=client, log=log)
        times["match_s"] = time.perf_counter() - clock
        corrs, pairs, skipped = self._usable(found)
        if k == 0 and skipped:
            self.warnings.append("strip pairs skipped: " + "; ".join(skipped))
        if not corrs:
            raise CalibrationError("no usable strip pair: " + "; ".join(skipped))
        return corrs + self._control_rows(current), pairs, times

    def _control_rows(self, current: dict) -> list[Correspondences]:
        """The control rows of every strip near control, from its re-georeferenced points."""
        found = (self.control.rows(i, idx, current[i][1][self.poses[i].rows_of(idx)], len(self.by_id[i]))
                 for i, idx in self.near.items())
        return [c for c in found if c is not None]

    def _times(self) -> dict[int, np.ndarray]:
        """Per strip its points' times; the control pseudo-strip's, one per control point, 0 (no trajectory)."""
        times = {i: st.time for i, st in self.by_id.items()}
        return times if self.control is None else {**times, CONTROL_ID: np.zeros(len(self.control.ids))}

    def _usable(self, found) -> tuple[list[Correspondences], list[dict], list[str]]:
        what = self.matcher.label
        corrs, pairs, skipped = [], [], []
        for o, c in zip(self.overlaps, found):
            if isinstance(c, CalidarError):
                skipped.append(f"{o.a}–{o.b}: {c}")
            elif c.n_obs < self.settings.min_correspondences:
                skipped.append(f"{o.a}–{o.b}: only {c.n_obs} {what}, need {self.settings.min_correspondences}")
            else:
                corrs.append(_to_strip_columns(c, o, len(self.by_id[o.a]), len(self.by_id[o.b])))
                pairs.append({"a": o.a, "b": o.b, "n_obs": c.n_obs})
        return corrs, pairs, skipped

    def solve(self, corrs: list[Correspondences], params: ParameterSet, step_in_sigma: float,
              step_scale: np.ndarray | None) -> tuple[Estimate, StripProblem]:
        """One adjustment of ``params`` from the correspondences ``corrs``, iterated until every
        step is below ``step_in_sigma`` of its σ (``step_scale``: diag N⁻¹ of an earlier one)."""
        problem = StripProblem(self.nominal, self.poses, corrs, params, self._times(), self.model, self.spans)
        if self.control is not None:  # each control target's survey error its own nuisance parameter
            problem = SurveyErrors(problem, self.control)
        # the rows' σ are absolute (each side's scatter): σ0 < 1 never shrinks the angles' σ, with the
        # trajectory model off too (issue 26: there σ0 ≈ 0.7 came from the sloped rows' generous σ and
        # shrank roll's, whose flat-ground rows' σ hold, to 1/1.45 of its error; docs/validation.md)
        options = replace(self.settings.adjustment, step_in_sigma=step_in_sigma, absolute_sigma=True)
        return estimate(problem, options, step_scale=step_scale), problem

    def clusters(self, problem: StripProblem) -> list[np.ndarray]:
        """The residuals' groupings by trajectory segment for the cluster-robust σ (none without ``cluster_s``)."""
        s = self.settings
        strips = self.by_id
        if self.control is not None:  # each control point its own cluster: their survey errors are independent
            strips = {**strips, CONTROL_ID: SimpleNamespace(time=np.arange(len(self.control.ids)) * (s.cluster_s or 1.0))}
        return problem.clusters(strips, s.cluster_s) if s.cluster_s else []

    def solution(self, est: Estimate, problem: StripProblem) -> Solution:
        """The final adjustment's :class:`Solution`, σ raised by the cluster-robust sandwich."""
        return est.solution(self.clusters(problem) or None)

    def model_check(self, est: Estimate, problem: StripProblem, corrs: list[Correspondences], solution: Solution) -> dict:
        """:func:`calidar.strips.model_check.check` on the final rows: each structural parameter not
        estimated freed in turn, on a problem of the same correspondences with it free too."""
        from calidar.strips.model_check import check

        free = est.parameters.free_names
        shown = [n for n in free if not n.startswith((TRAJECTORY_PREFIX, CONTROL_PREFIX))]
        return check(est, lambda names: StripProblem(self.nominal, self.poses, corrs, [*free, *names], self._times(),
                                                      self.model, self.spans),
                     self.nominal.parameters(), list(self.nominal.scanner.parameters()), self.clusters(problem), shown,
                     solution.sigma)


def calibrate(strips: Sequence[Strip], nominal: Sensor, config: CalibrationConfig = CalibrationConfig(), *,
              scheduler: str | None = None, workers: int | None = None, **options) -> CalibrationResult:
    """:func:`calibrate_with_client` with ONE Dask client (``scheduler`` address or a LocalCluster
    of ``workers`` processes, None: in-process) for every outer iteration's pair matching."""
    with cluster_client(scheduler, workers) as client:
        return calibrate_with_client(strips, nominal, config, client=client, **options)


def calibrate_with_client(strips: Sequence[Strip], nominal: Sensor, config: CalibrationConfig = CalibrationConfig(),
                          *, matcher: Matcher | None = None, trajectory: TrajectoryModel | None = None, client=None,
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
    run = _Run.start(strips, nominal, matcher, s, trajectory, control)
    params = build_parameters(nominal, config.estimate, run.spans, trajectory,
                              run.headings() if trajectory is not None else None)
    params = with_survey_parameters(params, control)
    processes = pair_processes(PROCESSES if client is None and getattr(matcher, "holds_gil", False) else 1)
    with processes as pool:
        outer, est, problem, corrs, pairs, first_residuals, first_control = _outer_loop(
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
        say("model check: freeing the parameters not estimated", s.max_outer, s.max_outer)
        solution.extra["model_check"] = run.model_check(est, problem, corrs, solution)
    outer[-1].update(mean_distance_m=_mean(problem, est.r), solver_iterations=len(est.history) - 1,
                     solve_s=outer[-1]["solve_s"] + time.perf_counter() - clock, values=est.parameters.values())
    say("calibrated", s.max_outer, s.max_outer)
    if run.control is not None:
        solution.extra["control"] = control_summary(run.control, first_control,
                                                    control_rows(problem, problem(solution.parameters.values())))
    return _result(run, solution, problem, pairs, outer, first_residuals, strips)


def _outer_loop(run: _Run, params: ParameterSet, client, say, log, pool, threshold_m: float) -> tuple:
    """Match and solve until the mean correspondence distance settles: (the outer iterations, the last
    estimate, its problem, correspondences and pairs, the first residuals and control rows)."""
    s = run.settings
    outer: list[dict] = []
    first_residuals = first_control = est = problem = pairs = None
    for k in range(s.max_outer):
        corrs, pairs, times = run.match(params.values(), k, client, say, log, pool)
        say(f"iteration {k + 1}: solving {sum(c.n_obs for c in corrs)} observations", k, s.max_outer)
        clock = time.perf_counter()
        est, problem = run.solve(corrs, params, OUTER_STEP_IN_SIGMA, None if est is None else est.step_scale)
        times["solve_s"] = time.perf_counter() - clock
        if first_residuals is None:
            first_residuals = problem(params.values())
            first_control = control_rows(problem, first_residuals)
        params = est.parameters
        outer.append({"iteration": k + 1, "mean_distance_m": _mean(problem, est.r), "n_obs": int(problem.sigma.size),
                      "n_pairs": len(corrs), "solver_iterations": len(est.history) - 1, **times,
                      "values": params.values()})
        if len(outer) > 1 and abs(outer[-2]["mean_distance_m"] - outer[-1]["mean_distance_m"]) < threshold_m:
            say("outer iterations settled", s.max_outer, s.max_outer)
            break
    else:
        change = abs(outer[-1]["mean_distance_m"] - outer[-2]["mean_distance_m"]) if len(outer) > 1 else float("nan")
        run.warnings.append(f"the outer loop stopped after {s.max_outer} iterations before the mean correspondence "
                            f"distance settled (last change {change * 1e3:.2g} mm)")
    return outer, est, problem, corrs, pairs, first_residuals, first_control


def _trajectory_level(run: _Run, est: Estimate, corrs: list[Correspondences], say) -> tuple[Estimate, StripProblem]:
    """No accuracy file: the trajectory priors' level estimated from the overlaps
    (:mod:`calidar.strips.trajectory_level`), the model's accuracy replaced by it and the last
    matching adjusted again with those priors."""
    from calidar.strips.trajectory_level import estimate_level

    say("estimating the trajectory's accuracy from the overlaps", run.settings.max_outer, run.settings.max_outer)
    run.level = estimate_level(est, run.model.accuracy, run.model.layout(run.spans), run.model.knot_times(run.spans))
    run.model = replace(run.model, accuracy=run.level.accuracy, estimate_level=False)
    sigma = {p.name: p.prior_sigma for p in run.model.parameters(run.spans, run.headings())}
    params = ParameterSet(replace(p, prior_sigma=sigma[p.name]) if p.name in sigma else p for p in est.parameters)
    return run.solve(corrs, params, OUTER_STEP_IN_SIGMA, None)


def _mean(problem: StripProblem, residuals: np.ndarray) -> float:
    """The mean correspondence distance (m) of the residuals."""
    return float(np.mean(np.concatenate([_mean_distance(c, r) for c, r in problem.split(residuals)])))


def _result(run: _Run, solution: Solution, problem: StripProblem, pairs: list[dict], outer: list[dict],
            first_residuals: np.ndarray, strips: Sequence[Strip]) -> CalibrationResult:
    """The last solve as a :class:`CalibrationResult`: canonical values, "before" statistics from
    the first matching at the nominal sensor, warnings, the outer loop's record."""
    canonical_eccentricity(solution)
    params = solution.parameters
    # "before" for the user: the first matching at the nominal sensor (the last solve started
    # from the previous outer iteration's values)
    solution.residuals_before = residual_stats(first_residuals)
    if run.model is not None or run.control is not None:
        prefixes = ((TRAJECTORY_PREFIX,) if run.model is not None else ()) + ((CONTROL_PREFIX,) if run.control is not None else ())
        solution.nuisance_prefix = prefixes[0] if len(prefixes) == 1 else prefixes
    if run.level is not None:
        solution.extra["trajectory_accuracy_estimate"] = run.level.to_dict()
    used_pairs = [(p["a"], p["b"]) for p in pairs]
    solution.warnings = run.warnings + geometry_warnings([run.by_id[i] for i in problem.index if i != CONTROL_ID], used_pairs,
                                                         params.free_names) + solution.warnings
    sensor, fix = sensor_of(run.nominal, params.values()), corrections(params.values(), run.model, run.spans)
    fix = with_height_bias(fix, params.values().get("height_bias", 0.0), run.spans)
    solution.extra["strips"] = {"method": run.matcher.name, "robust": run.settings.robust, "pairs": pairs, "outer_iterations": [
        {kk: v for kk, v in o.items() if kk != "values"} for o in outer],
        "row_dof": dof_summary(np.concatenate([rows_dof(c) for c in problem.corrs]))}
    return CalibrationResult(solution, sensor, run.nominal, list(strips), run.overlaps, run.matcher, pairs,
                             first_residuals, solution.residuals, outer, fix, run.model, problem.sigma)
