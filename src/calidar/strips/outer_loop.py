"""The strip calibrator's outer loop (:mod:`calidar.strips.calibrate`): one run's fixed inputs and
the loop of matching and adjusting.

:class:`Run` holds what stays fixed over the outer iterations — the strips by id, their overlaps,
the overlap points' poses, the parameters' time spans, the trajectory model, ground control — and
does one iteration's two steps: re-georeference the overlap points and match every pair
(:meth:`Run.match`, as independent tasks through :func:`calidar.strips.distribute.map_pairs` or the
pair processes of :mod:`calidar.strips.processes`), and adjust the parameters to the correspondences
(:meth:`Run.solve`). :func:`outer_loop` repeats them until the mean correspondence distance settles
(ICP, Besl & McKay 1992). Split from :mod:`calidar.strips.calibrate` (issue 26).
"""

from __future__ import annotations

import time
from collections.abc import Sequence
from dataclasses import dataclass, field, replace
from pathlib import Path
from types import SimpleNamespace

import numpy as np
import scipy.sparse as sp

from calidar.adjust import ParameterSet, Solution
from calidar.adjust.solver import Estimate, estimate
from calidar.errors import CalibrationError, CalidarError, InputError
from calidar.memory import release_memory
from calidar.sensor import Sensor
from calidar.strips.control import (CONTROL_ID, ControlPoints, control_pose, control_rows,
                                    near_control)
from calidar.strips.control_survey import SurveyErrors
from calidar.strips.config import StripSettings
from calidar.strips.convergence import NUISANCE, extrapolated, moving
from calidar.strips.correspond import Correspondences
from calidar.strips.distribute import IN_PROCESS_THREADS, map_pairs, thread_map
from calidar.strips.matchers import Matcher
from calidar.strips.overlap import Overlap, find_overlaps, strip_name
from calidar.strips.parameters import sensor_of
from calidar.strips.problem import StripProblem, georeference, union
from calidar.strips.processes import map_in_processes, worth_processes
from calidar.strips.strip import Pose, Strip
from calidar.strips.trajectory_errors import TrajectoryModel, corrections
from calidar.strips.trajectory_level import TrajectoryLevel
from calidar.strips.unevenness_length import pooled_fit

#: an outer iteration's adjustment stops when every step is below this fraction of its σ: the next
#: matching moves the points anyway (the last one is then refined:
#: :data:`calidar.strips.calibrate.FINAL_STEP_IN_SIGMA`)
OUTER_STEP_IN_SIGMA = 0.1


def match_or_error(matcher: Matcher, strip_a_id, points_a, strip_b_id, points_b):
    """``matcher.match(...)``, or the user-facing error it raised for this pair (picklable, for
    map_pairs)."""
    try:
        return matcher.match(strip_a_id, points_a, strip_b_id, points_b)
    except CalidarError as e:
        return e


def _match_in_thread(matcher: Matcher, ov: Overlap, points_a: np.ndarray, pose_a: Pose,
                     points_b: np.ndarray, pose_b: Pose, n_a: int, n_b: int):
    """One pair matched in a thread of this process (:meth:`Run.match`): its points taken from
    each strip's re-georeferenced ones (``pose_*``: their cache, whose rows index them), and its
    correspondences' columns widened to whole-strip indices; or the user-facing error."""
    c = match_or_error(matcher, ov.a, points_a[pose_a.rows_of(ov.index_a)], ov.b,
                       points_b[pose_b.rows_of(ov.index_b)])
    return c if isinstance(c, CalidarError) else _to_strip_columns(c, ov, n_a, n_b)


def pair_threads(matcher: Matcher) -> int:
    """Pairs matched at once in this process's threads: :data:`IN_PROCESS_THREADS` for a matcher
    whose work releases the GIL (the tie planes: numba ``nogil`` kernels), 1 for one that holds it
    (VGICP: worker processes instead, :mod:`calidar.strips.processes`)."""
    return 1 if matcher.holds_gil else IN_PROCESS_THREADS


def _distances(c: Correspondences, r: np.ndarray) -> np.ndarray:
    """Distances (m) of each correspondence from its residuals."""
    return np.abs(r) if c.normal is not None else np.linalg.norm(r.reshape(-1, 3), axis=1)


def _to_strip_columns(c: Correspondences, ov: Overlap, n_a: int, n_b: int) -> Correspondences:
    """Re-index a pair's correspondences from overlap subsets to whole-strip point indices."""
    def widen(m, index, n):
        m = m.tocsr()
        return sp.csr_matrix((m.data, index[m.indices], m.indptr), shape=(m.shape[0], n))

    return replace(c, A=widen(c.A, ov.index_a, n_a), B=widen(c.B, ov.index_b, n_b))


@dataclass
class Run:
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
    level: TrajectoryLevel | None = None  #: the trajectory's accuracy level, when estimated
    #: ground control in the adjustment (calidar.strips.control)
    control: ControlPoints | None = None
    near: dict[int, np.ndarray] = field(default_factory=dict)  #: per strip its points near control
    #: VGICP's unevenness ℓ pooled over the pairs at the first matching pass and kept for the
    #: later ones (:func:`calidar.strips.unevenness_length.pooled_fit`'s record; None: not pooled)
    unevenness: dict | None = None
    pair_fits: dict = field(default_factory=dict)  #: (a, b) → its own fit at that pass

    @classmethod
    def start(cls, strips: Sequence[Strip], nominal: Sensor, matcher: Matcher,
              settings: StripSettings, model: TrajectoryModel | None = None,
              control: ControlPoints | None = None) -> "Run":
        by_id = {st.id: st for st in strips}
        if len(by_id) != len(strips):
            raise InputError(None, "strips",
                             "two strips share an id; flight-line ids must be unique")
        s = settings
        names = {i: Path(st.source).name for i, st in by_id.items() if st.source != "<memory>"}
        points = {i: st.points for i, st in by_id.items()}
        overlaps, notes = find_overlaps(points, s.overlap_cell_m, s.min_overlap_cells, names=names)
        if not overlaps:
            listed = f" ({', '.join(strip_name(i, names) for i in by_id)})" if names else ""
            raise CalibrationError(f"no two of the {len(by_id)} strips{listed} overlap (no common "
                                   f"{s.overlap_cell_m:g} m cells); strip calibration needs "
                                   "overlapping flight lines")
        need: dict[int, list[np.ndarray]] = {}
        for o in overlaps:
            need.setdefault(o.a, []).append(o.index_a)
            need.setdefault(o.b, []).append(o.index_b)
        near = ({} if control is None
                else {i: near_control(st.points, control) for i, st in by_id.items()})
        near = {i: v for i, v in near.items() if v.size}
        for i, v in near.items():
            need.setdefault(i, []).append(v)
        need = {i: union(v) for i, v in need.items()}
        spans = {i: st.time_span for i, st in by_id.items()}
        # one trajectory interpolation, each strip's in this process's threads
        poses = dict(zip(need, thread_map(lambda i: by_id[i].pose(need[i]), list(need))))
        if control is not None:
            poses[CONTROL_ID] = control_pose(control, next(iter(poses.values())))
        return cls(by_id, nominal, matcher, s, overlaps, spans, model, need, poses, list(notes),
                   control=control, near=near)

    def headings(self) -> dict[int, float]:
        return {i: st.heading_enu() for i, st in self.by_id.items()}

    def match(self, values: dict[str, float], k: int, client, say, log=None,
              pool=None) -> tuple[list[Correspondences], list[dict], dict]:
        """Re-georeference the overlap points with ``values`` and match every pair (``pool``: worker
        processes, :mod:`calidar.strips.processes`): the usable correspondence sets (whole-strip
        columns), their pairs, and the stage times (s)."""
        clock = time.perf_counter()
        sensor, fix = sensor_of(self.nominal, values), corrections(values, self.model, self.spans)

        def strip_points(i):  # each strip's in this process's threads
            idx = self.need[i]
            return idx, georeference(sensor, fix.get(i), self.poses[i], self.by_id[i].time[idx])

        current = dict(zip(self.need, thread_map(strip_points, list(self.need))))
        times = {"georeference_s": time.perf_counter() - clock}

        say(f"iteration {k + 1}: matching {len(self.overlaps)} pairs ({self.matcher.name})", k,
            self.settings.max_outer)
        clock = time.perf_counter()
        threads = pair_threads(self.matcher)
        if client is None and threads > 1:  # each pair taken and widened in its thread
            found = map_pairs(_match_in_thread, self._thread_tasks(current), threads=threads)
        else:
            found = self._whole_tasks(current, client, log, pool, threads)
        times["match_s"] = time.perf_counter() - clock
        corrs, pairs, skipped = self._usable(found, widened=client is None and threads > 1)
        self._pool_unevenness(corrs)
        if k == 0 and skipped:
            self.warnings.append("strip pairs skipped: " + "; ".join(skipped))
        if not corrs:
            raise CalibrationError("no usable strip pair: " + "; ".join(skipped))
        return corrs + self._control_rows(current), pairs, times

    def _pool_unevenness(self, corrs: list[Correspondences]) -> None:
        """When the pairs read ℓ (the matcher's ``unevenness_length_m`` None: the first matching
        pass), the survey's ℓ from all their rows at once, fixed in the matcher for the later
        passes (each pair's own fit kept for the record)."""
        surfaces = [c.unevenness_surface for c in corrs if c.unevenness_surface is not None]
        if not surfaces:
            return
        fit = pooled_fit(surfaces)
        self.unevenness = fit.to_dict() | {"pairs": len(surfaces)}
        self.pair_fits = {(c.strip_a, c.strip_b): c.unevenness for c in corrs if c.unevenness}
        self.matcher = self.matcher.with_unevenness_length(fit.length_m)

    def _thread_tasks(self, current: dict) -> list[tuple]:
        """Each pair's task for :func:`_match_in_thread`: its strips' re-georeferenced points and
        the pose cache's rows of the overlap's points (taken in the thread)."""
        for pose in self.poses.values():
            pose.rows_of(np.zeros(0, np.int64))  # each row table built here, read in the threads
        return [(self.matcher, o, current[o.a][1], self.poses[o.a], current[o.b][1],
                 self.poses[o.b], len(self.by_id[o.a]), len(self.by_id[o.b]))
                for o in self.overlaps]

    def _whole_tasks(self, current: dict, client, log, pool, threads: int) -> list:
        """Every pair matched from its points taken here (worker processes, Dask or one thread)."""
        def subset(i, index):  # the points ``index`` of strip i (the pose cache's rows, by table)
            return current[i][1][self.poses[i].rows_of(index)]

        tasks = [(self.matcher, o.a, subset(o.a, o.index_a), o.b, subset(o.b, o.index_b))
                 for o in self.overlaps]
        # a GIL-holding matcher: both cores
        if pool is not None and client is None and worth_processes(tasks):
            return map_in_processes(pool, match_or_error, tasks)
        return map_pairs(match_or_error, tasks, client=client, log=log, threads=threads)

    def _control_rows(self, current: dict) -> list[Correspondences]:
        """The control rows of every strip near control, from its re-georeferenced points."""
        found = (self.control.rows(i, idx, current[i][1][self.poses[i].rows_of(idx)],
                                   len(self.by_id[i]))
                 for i, idx in self.near.items())
        return [c for c in found if c is not None]

    def _times(self) -> dict[int, np.ndarray]:
        """Per strip its points' times; the control pseudo-strip's, one per control point, 0 (no
        trajectory)."""
        times = {i: st.time for i, st in self.by_id.items()}
        if self.control is None:
            return times
        return {**times, CONTROL_ID: np.zeros(len(self.control.ids))}

    def _usable(self, found, widened: bool = False
                ) -> tuple[list[Correspondences], list[dict], list[str]]:
        """The sets with enough rows (whole-strip columns; ``widened``: they have them already),
        their pairs, and why the others were skipped."""
        what = self.matcher.label
        corrs, pairs, skipped = [], [], []
        for o, c in zip(self.overlaps, found):
            if isinstance(c, CalidarError):
                skipped.append(f"{o.a}–{o.b}: {c}")
            elif c.n_obs < self.settings.min_correspondences:
                skipped.append(f"{o.a}–{o.b}: only {c.n_obs} {what}, need "
                               f"{self.settings.min_correspondences}")
            else:
                corrs.append(c if widened else
                             _to_strip_columns(c, o, len(self.by_id[o.a]), len(self.by_id[o.b])))
                fit = c.unevenness or self.pair_fits.get((o.a, o.b))
                pairs.append({"a": o.a, "b": o.b, "n_obs": c.n_obs}
                             | ({} if fit is None else {"unevenness": fit}))
        return corrs, pairs, skipped

    def solve(self, corrs: list[Correspondences], params: ParameterSet, step_in_sigma: float,
              step_scale: np.ndarray | None) -> tuple[Estimate, StripProblem]:
        """One adjustment of ``params`` from the correspondences ``corrs``, iterated until every
        step is below ``step_in_sigma`` of its σ (``step_scale``: diag N⁻¹ of an earlier one)."""
        problem = StripProblem(self.nominal, self.poses, corrs, params, self._times(), self.model,
                               self.spans)
        if self.control is not None:  # each control target's survey error: its own nuisance
            problem = SurveyErrors(problem, self.control)
        # σ absolute: StripProblem's
        options = replace(self.settings.adjustment, step_in_sigma=step_in_sigma)
        return estimate(problem, options, step_scale=step_scale), problem

    def clusters(self, problem: StripProblem) -> list[np.ndarray]:
        """The residuals' groupings by trajectory segment for the cluster-robust σ (none without
        ``cluster_s``)."""
        s = self.settings
        strips = self.by_id
        if self.control is not None:
            # each control point its own cluster: their survey errors are independent
            times = np.arange(len(self.control.ids)) * (s.cluster_s or 1.0)
            strips = {**strips, CONTROL_ID: SimpleNamespace(time=times)}
        return problem.clusters(strips, s.cluster_s) if s.cluster_s else []

    def solution(self, est: Estimate, problem: StripProblem) -> Solution:
        """The final adjustment's :class:`Solution`, σ raised by the cluster-robust sandwich."""
        return est.solution(self.clusters(problem) or None)

    def model_check(self, est: Estimate, problem: StripProblem, corrs: list[Correspondences],
                    solution: Solution) -> dict:
        """:func:`calidar.strips.model_check.check` on the final rows: each structural parameter not
        estimated freed in turn, on a problem of the same correspondences with it free too."""
        from calidar.strips.model_check import check

        free = est.parameters.free_names
        shown = [n for n in free if not n.startswith(NUISANCE)]
        rows = getattr(problem, "inner", problem)  # (with control: inside SurveyErrors)

        def with_freed(names):  # the same rows with ``names`` free too
            return StripProblem(self.nominal, self.poses, corrs, [*free, *names], self._times(),
                                self.model, self.spans, same_rows=rows)

        return check(est, with_freed, self.nominal.parameters(),
                     list(self.nominal.scanner.parameters()), self.clusters(problem), shown,
                     solution.sigma)


def outer_loop(run: Run, params: ParameterSet, client, say, log, pool, threshold_m: float) -> tuple:
    """Match and solve until the mean correspondence distance settles and no estimated parameter
    is still moving (:func:`calidar.strips.convergence.moving`, the verdict's rule), jumping ahead
    along steady steps (:func:`calidar.strips.convergence.extrapolated`): (the outer iterations,
    the last estimate, its problem, correspondences and pairs, the first residuals and control
    rows)."""
    s = run.settings
    outer: list[dict] = []
    first_residuals = first_control = est = problem = pairs = None
    jumped = -3  # the iteration count at the last jump: the rule reads three iterations after it
    for k in range(s.max_outer):
        step_scale = None if est is None else est.step_scale
        # the last iteration's problem (its centroids) and rows freed before this one builds its own
        est = problem = corrs = None
        corrs, pairs, times = run.match(params.values(), k, client, say, log, pool)
        release_memory()  # the matching threads' working arrays, freed in their own arenas
        n_obs = sum(c.n_obs for c in corrs)
        say(f"iteration {k + 1}: solving {n_obs} observations", k, s.max_outer)
        clock = time.perf_counter()
        est, problem = run.solve(corrs, params, OUTER_STEP_IN_SIGMA, step_scale)
        release_memory()  # the solve's Jacobians and normal matrices
        times["solve_s"] = time.perf_counter() - clock
        if first_residuals is None:
            first_residuals = problem(params.values())
            first_control = control_rows(problem, first_residuals)
        params = est.parameters
        outer.append({"iteration": k + 1, "mean_distance_m": mean_distance(problem, est.r),
                      "n_obs": int(problem.sigma.size), "n_pairs": len(corrs),
                      "solver_iterations": len(est.history) - 1, **times,
                      "values": params.values()})
        settled = len(outer) > 1 and abs(
            outer[-2]["mean_distance_m"] - outer[-1]["mean_distance_m"]) < threshold_m
        if len(outer) - jumped < 3:  # the steps since the jump: not yet three iterations
            continue
        sigma = _sigma(est)
        still = moving([o["values"] for o in outer], sigma, NUISANCE)
        if settled and still is None:
            say("outer iterations settled", s.max_outer, s.max_outer)
            break
        ahead = None if still is None else extrapolated(
            [o["values"] for o in outer], sigma, params.free_names, NUISANCE)
        if ahead is not None:
            outer[-1]["extrapolated"] = True
            params = ParameterSet(replace(p, value=ahead[p.name]) if p.free else p
                                  for p in params)
            jumped = len(outer)
    else:
        change = (abs(outer[-1]["mean_distance_m"] - outer[-2]["mean_distance_m"])
                  if len(outer) > 1 else float("nan"))
        run.warnings.append(f"the outer loop stopped after {s.max_outer} iterations before it "
                            "converged (mean correspondence distance's last change "
                            f"{change * 1e3:.2g} mm)")
    return outer, est, problem, corrs, pairs, first_residuals, first_control


def _sigma(est: Estimate) -> dict[str, float]:
    """The free parameters' σ at ``est`` (diag N⁻¹ of its step scale times its variance factor):
    the scale of :func:`calidar.strips.convergence.moving`."""
    if est.step_scale is None:
        return {}
    factor = est.fit.variance_factor(est.r, est.w, est.x)
    return dict(zip(est.parameters.free_names, np.sqrt(est.step_scale * factor)))


def mean_distance(problem: StripProblem, residuals: np.ndarray) -> float:
    """The mean correspondence distance (m) of the residuals."""
    return float(np.mean(np.concatenate([_distances(c, r) for c, r in problem.split(residuals)])))
