"""The strip adjustment's problem: the residuals of every correspondence for given parameter
values, and their Jacobian.

Residuals are cheap because the lidar equation is linear in what boresight, lever arm and
range model act on: per correspondence row its weighted sums are taken once
(:class:`calidar.strips.centroids.Centroids`) and every evaluation costs O(rows). Their
derivatives are exact and analytic (boresight, lever arm, range offset and scale; the
trajectory corrections, linear in their knots, as sparse columns). Scanner-angle parameters
change u: then every referenced point is re-georeferenced and the Jacobian comes from central
differences.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import replace

import numpy as np
import scipy.sparse as sp

from calidar.adjust import Block, Parameter, ParameterSet, ResidualProblem, Values
from calidar.adjust.residuals import numerical_jacobian
from calidar.sensor import Sensor
from calidar.strips.centroids import Centroids, compact, correction_derivatives, union
from calidar.strips.correspond import Correspondences
from calidar.strips.distribute import IN_PROCESS_THREADS, thread_map
from calidar.strips.parameters import sensor_of
from calidar.strips.shared_patches import counted_once
from calidar.strips.strip import Pose, Strip, georeference_pose
from calidar.strips.trajectory_errors import (StripCorrection, TrajectoryModel, corrections,
                                              corrections_of, knot_scatter)

#: a height shift common to every strip (m, up; a vertical trajectory bias): the overlaps cannot see
#: it, ground control can (the control pseudo-strip, id -1, is not shifted; calidar.strips.control)
HEIGHT_BIAS = "height_bias"
CONTROL_STRIP = -1


def georeference(sensor: Sensor, correction: StripCorrection | None, pose: Pose,
                 time: np.ndarray) -> np.ndarray:
    """Points (local m) of cached poses with ``sensor`` and a strip's trajectory correction (or
    None)."""
    pts = georeference_pose(sensor, pose)
    return pts if correction is None else correction.apply(pts, pose.position, time)


class StripProblem(ResidualProblem):
    """Residuals of all correspondences for given parameter values (SI), with cached poses; given
    the :class:`ParameterSet` to solve, the engine's problem
    (:class:`calidar.adjust.ResidualProblem`): row σ, the trajectory knots' correlated priors,
    and the sensor and the knots read from the engine's values as typed blocks (sensor names;
    :class:`calidar.strips.trajectory_errors.Knot`)."""

    #: the rows' σ are absolute, each side's from its points' scatter (the matchers' rows,
    #: :mod:`calidar.strips.row_variance`), a control row's from its survey: σ0 < 1 never shrinks
    #: the angles' σ, with the trajectory model off too (issue 26: there σ0 ≈ 0.7 came from the
    #: sloped rows' generous σ and shrank roll's, whose flat-ground rows' σ hold, to 1/1.45 of its
    #: error; docs/validation.md)
    absolute_sigma = True

    def __init__(self, nominal: Sensor, poses: dict[int, Pose], corrs: list[Correspondences],
                 free: Sequence[str] | ParameterSet, times: dict[int, np.ndarray] | None = None,
                 trajectory: TrajectoryModel | None = None,
                 spans: dict[int, tuple[float, float]] | None = None, *,
                 same_rows: StripProblem | None = None):
        """poses: per strip, cached poses holding at least every point the correspondences
        reference; free: the free parameters' names, or the ParameterSet to solve (the engine's
        problem then); times: per strip, the GPS times (s) of all its points; trajectory, spans:
        the model of trajectory corrections (None: no corrections) and the strips' time spans;
        ``same_rows``: a problem built from the same ``corrs``, ``times`` and trajectory model,
        whose rows (counted once, their columns compacted, σ, times) are taken, not built again
        (the model check's problems with more parameters free)."""
        self.nominal = nominal
        self.trajectory, self.spans = trajectory, spans or {}
        if isinstance(free, ParameterSet):
            self.parameters, free = free, free.free_names
            self._blocks()
        corrs = list(corrs)
        if same_rows is not None:
            self._rows_of(same_rows)
        else:
            self._rows(corrs, times)
        # (counting once changes the sets' σ, not their averaging matrices A and B)
        scanner_free = set(free) & set(nominal.scanner.parameters())
        range_free = bool(set(free) & {"range_offset", "range_scale"})
        lever_free = any(f.startswith("lever_arm") for f in free)
        #: the model check's problems (``same_rows``) built and evaluated in one thread: the run's
        #: peak memory is set there, and each thread's arena holds its own working arrays
        self.threads = 1 if same_rows is not None else IN_PROCESS_THREADS
        self.centroids = None if scanner_free else _centroids(
            corrs, poses, nominal, range_free, lever_free, self.threads)
        #: per strip its cached poses and the rows of every referenced point, for re-georeferencing
        #: them all (scanner parameters free): taken a strip at a time at each call, not held as
        #: copies (the model check's 1.4 M rows: 0.17 GiB at 8.75 M points)
        self.pose_rows: dict[int, tuple[Pose, np.ndarray]] = {} if self.centroids is not None else {
            i: (poses[i], poses[i].rows_of(idx)) for i, idx in self.index.items()}
        self._pattern = None  # the trajectory Jacobian's sparsity, built on its first call

    def _rows(self, corrs: list[Correspondences], times: dict[int, np.ndarray] | None) -> None:
        """The rows: each patch several pairs use counted once, the points referenced per strip,
        the sets' columns compacted to them, σ, the rows' times."""
        corrs, shares = counted_once(corrs)  # a patch several pairs use, counted once
        #: each residual's share of an observation in the redundancy (the engine's σ0)
        self.row_share = np.concatenate(shares) if shares else np.zeros(0)
        used: dict[int, list[np.ndarray]] = {}
        for c in corrs:
            used.setdefault(c.strip_a, []).append(c.A.indices)
            used.setdefault(c.strip_b, []).append(c.B.indices)
        self.index = {i: union(v) for i, v in used.items()}
        self.time = ({i: times[i][idx] for i, idx in self.index.items()} if self.trajectory
                     else {})
        self.corrs = [replace(c, A=compact(c.A, self.index[c.strip_a]),
                              B=compact(c.B, self.index[c.strip_b])) for c in corrs]
        self.sigma = np.concatenate([_row_sigma(c) for c in self.corrs])
        self._knots: dict[tuple[int, int], tuple] = {}  # (set, side) → the rows' knots and weights
        self.row_time = [(self._side_time(c.A, c.strip_a), self._side_time(c.B, c.strip_b))
                         for c in self.corrs]

    def _rows_of(self, other: StripProblem) -> None:
        """:meth:`_rows` taken from a problem on the same rows (the arrays shared, read only)."""
        if (other.trajectory is None) != (self.trajectory is None):
            raise ValueError("same_rows: a problem with the same trajectory model")
        for name in ("row_share", "index", "time", "corrs", "sigma", "row_time"):
            setattr(self, name, getattr(other, name))
        self._knots = dict(other._knots)

    def pose(self, strip_id: int) -> Pose:
        """The cached poses of every point of strip ``strip_id`` the rows reference, in index order
        (scanner parameters free)."""
        pose, rows = self.pose_rows[strip_id]
        return pose.take(rows)

    def _side_time(self, m: sp.csr_matrix, strip_id: int) -> np.ndarray | None:
        """The weighted mean GPS time (s) of each row of one side (None: no trajectory model)."""
        if not self.time:
            return None
        return (m @ self.time[strip_id]) / np.maximum(np.asarray(m.sum(axis=1)).ravel(), 1e-300)

    def _blocks(self) -> None:
        """The sensor's and the trajectory knots' typed blocks of :attr:`parameters`, resolved
        once."""
        params = self.parameters
        self.sensor_block = Block.of(params, {n: n for n in self.nominal.parameters()})
        if self.trajectory is None:
            self.knot_block, self._scatter, self.prior_correlation = None, None, ()
            return
        self.knot_block = Block.of(params, self.trajectory.layout(self.spans))
        self._scatter = knot_scatter(self.knot_block.keys, self.trajectory, self.spans)
        self.prior_correlation = self.trajectory.prior_correlation(self.spans)

    def _read(self, values: Mapping[str, float]) -> tuple[Sensor, dict[int, StripCorrection]]:
        """The sensor and the strips' trajectory corrections at ``values``: by typed block from the
        engine's :class:`Values`, by name from a plain mapping (other names ignored)."""
        if not isinstance(values, Values) or not hasattr(self, "sensor_block"):
            return sensor_of(self.nominal, values), corrections(values, self.trajectory, self.spans)
        named = dict(zip(self.sensor_block.names, self.sensor_block.take(values)))
        sensor = self.nominal.with_parameters(**named)
        if self.knot_block is None:
            return sensor, {}
        knots = self.knot_block.take(values)
        return sensor, corrections_of(knots, self._scatter, self.trajectory, self.spans)

    def residuals(self, values: Mapping[str, float]) -> np.ndarray:
        """The residuals (n,) at ``values`` (SI): :meth:`__call__`."""
        return self(values)

    def clusters(self, strips: Mapping[int, Strip], block_s: float) -> list[np.ndarray]:
        """Groupings of the residuals by trajectory segment (strip, time block of ``block_s``):
        (n, 2) the segments of the a-side and b-side points (residuals sharing a segment share
        its trajectory error), and (n,) the pair with its a-side segment."""
        dyadic, by_pair = [], []
        for k, c in enumerate(self.corrs):
            block = [np.floor(m @ strips[sid].time[self.index[sid]] / block_s).astype(np.int64)
                     for sid, m in ((c.strip_a, c.A), (c.strip_b, c.B))]
            g = np.stack([(np.int64(c.strip_a) << 32) + block[0],
                          (np.int64(c.strip_b) << 32) + block[1]], axis=1)
            p = (np.int64(k) << 32) + block[0]
            rep = 3 if c.normal is None else 1
            dyadic.append(np.repeat(g, rep, axis=0))
            by_pair.append(np.repeat(p, rep))
        return [np.concatenate(dyadic), np.concatenate(by_pair)]

    def split(self, r: np.ndarray) -> list[tuple[Correspondences, np.ndarray]]:
        """Residuals (n,) cut into one array per correspondence set."""
        sizes = [c.n_obs * (3 if c.normal is None else 1) for c in self.corrs]
        return list(zip(self.corrs, np.split(r, np.cumsum(sizes)[:-1])))

    def __call__(self, values: Mapping[str, float]) -> np.ndarray:
        sensor, fix = self._read(values)
        if self.centroids is None:  # scanner parameters free: re-georeference every point used
            h = values.get(HEIGHT_BIAS, 0.0)

            def strip_points(i):  # (one strip's pose rows taken at a time, in each thread)
                return _shifted(georeference(sensor, fix.get(i), self.pose(i), self.time.get(i)),
                                h, i)

            pts = dict(zip(self.pose_rows,
                           thread_map(strip_points, list(self.pose_rows), self.threads)))
            return np.concatenate([c.residuals(pts[c.strip_a], pts[c.strip_b]) for c in self.corrs])
        out = []
        for k, (c, sides, times) in enumerate(zip(self.corrs, self.centroids, self.row_time)):
            p = []
            for s, (side, sid, t) in enumerate(zip(sides, (c.strip_a, c.strip_b), times)):
                q = side(sensor)
                f = fix.get(sid)
                if f is not None:
                    q = f.apply(q, side.r, t, side.rowsum, self._row_knots(k, s, f, t))
                p.append(_shifted(q, values.get(HEIGHT_BIAS, 0.0), sid, side.rowsum))
            d = p[0] - p[1]
            out.append(d.ravel() if c.normal is None else np.einsum("ij,ij->i", d, c.normal))
        return np.concatenate(out)

    def _row_knots(self, k: int, side: int, f: StripCorrection, time: np.ndarray):
        """``f.knots(time)`` for side 0 (a) or 1 (b) of correspondence set k, computed once (fixed
        times)."""
        if (k, side) not in self._knots:
            self._knots[k, side] = f.knots(time)
        return self._knots[k, side]

    def jacobian(self, values: Mapping[str, float], free: Sequence[Parameter] | None = None):
        """∂residuals/∂(``free``, default :attr:`parameters`' free ones), (n, n_free): analytic
        for the sensor's parameters in the centroid form, exact sparse columns for the trajectory
        corrections (linear in them; two knots per strip and row, so the matrix is returned
        sparse when they are present); central differences when scanner parameters are free.
        The sparsity pattern is built on the first call; later calls only fill in the values."""
        free = self.parameters.free if free is None else free
        layout = self.trajectory.layout(self.spans) if self.trajectory else {}
        traj = {p.name: layout.get(p.name) for p in free}
        if self.centroids is None:
            at = ParameterSet(replace(p, value=values[p.name]) for p in free)
            return numerical_jacobian(self, at, np.array([values[p.name] for p in free]))
        sensor_free = [j for j, p in enumerate(free) if traj.get(p.name) is None]
        sensor_cols = self._sensor_columns(values, [free[j].name for j in sensor_free])
        if not any(traj.values()):
            return sensor_cols
        if self._pattern is None:
            self._pattern = self._jacobian_pattern(free, traj, sensor_free)
        mask, indices, indptr, knot_weights = self._pattern
        ns = len(sensor_free)
        V = np.zeros(mask.shape)  # rows × (sensor columns, a-side and b-side 2 knots × 6)
        V[:, :ns] = sensor_cols
        sensor, _ = self._read(values)
        start = 0
        for c, sides, weights in zip(self.corrs, self.centroids, knot_weights):
            per = 3 if c.normal is None else 1
            block = V[start:start + c.n_obs * per]
            for s, (sign, side, w) in enumerate(zip((1.0, -1.0), sides, weights)):
                if w is not None:
                    D = correction_derivatives(side, sensor, c.normal)
                    # (rows, per, 2 knots, 6): the knot's share w of the one-knot derivative
                    knot_d = sign * D[:, :, None, :] * w[:, None, :, None]
                    block[:, ns + 12 * s:ns + 12 * (s + 1)] = knot_d.reshape(-1, 12)
            start += c.n_obs * per
        return sp.csr_matrix((V[mask], indices, indptr), shape=(mask.shape[0], len(free)))

    def _sensor_columns(self, values: Mapping[str, float], names: Sequence[str]) -> np.ndarray:
        """Analytic ∂residuals/∂(sensor parameters ``names``), dense (n, len(names)): per side
        ∂C/∂θ, turned by the side's trajectory tilt (the shift does not depend on θ)."""
        if HEIGHT_BIAS in names:
            return _with_height_column(self, values, names)
        sensor, fix = self._read(values)
        out = []
        for k, (c, sides, times) in enumerate(zip(self.corrs, self.centroids, self.row_time)):
            d = np.zeros((c.n_obs, 3, len(names)))
            ids = (c.strip_a, c.strip_b)
            for s, (sign, side, sid, t) in enumerate(zip((1.0, -1.0), sides, ids, times)):
                dq = side.derivatives(sensor, names)
                f = fix.get(sid)
                if f is not None:
                    k0, k1, frac = self._row_knots(k, s, f, t)
                    w = (1.0 - frac)[:, None] * f.tilt[k0] + frac[:, None] * f.tilt[k1]
                    dq = dq + np.cross(w[:, :, None], dq, axis=1)
                d += sign * dq
            if c.normal is None:
                out.append(d.reshape(-1, len(names)))
            else:
                out.append(np.einsum("nik,ni->nk", d, c.normal))
        return np.concatenate(out)

    def _jacobian_pattern(self, free: Sequence[Parameter], traj: dict, sensor_free: list[int]):
        """The Jacobian's sparsity: a mask over rows × (sensor columns, per side two knots ×
        (shift, tilt) × 3 axes), its CSR column indices and row pointers, and per
        correspondence set and side the knots' interpolation weights (n_obs, 2) (None: no
        correction for that strip)."""
        column = {traj[p.name]: j for j, p in enumerate(free) if traj[p.name]}
        fix = corrections({p.name: 0.0 for p in free}, self.trajectory, self.spans)
        ns = len(sensor_free)
        C = np.full((self.sigma.size, ns + 24), -1, dtype=np.int64)
        C[:, :ns] = sensor_free
        knot_weights, start = [], 0
        for i, (c, times) in enumerate(zip(self.corrs, self.row_time)):
            per = 3 if c.normal is None else 1
            weights = []
            for s, (sid, t) in enumerate(zip((c.strip_a, c.strip_b), times)):
                f = fix.get(sid)
                if f is None:
                    weights.append(None)
                    continue
                k0, k1, frac = self._row_knots(i, s, f, t)
                colmap = _knot_columns(column, sid, f.shift.shape[0])
                w = np.stack([1.0 - frac, frac], axis=1)
                cols = np.where(w[:, :, None] != 0, np.stack([colmap[k0], colmap[k1]], axis=1), -1)
                row_cols = np.repeat(cols.reshape(-1, 12), per, axis=0)
                C[start:start + c.n_obs * per, ns + 12 * s:ns + 12 * (s + 1)] = row_cols
                weights.append(w)
            knot_weights.append(weights)
            start += c.n_obs * per
        mask = C >= 0
        indptr = np.concatenate([[0], np.cumsum(np.count_nonzero(mask, axis=1))])
        return mask, C[mask], indptr, knot_weights


def _centroids(corrs: list[Correspondences], poses: dict[int, Pose], nominal: Sensor,
               range_free: bool, lever_free: bool,
               threads: int) -> list[tuple[Centroids, Centroids]]:
    """Each correspondence set's two :class:`Centroids` (a, b), built ``threads`` at once in this
    process (:func:`calidar.strips.distribute.thread_map`: each side's sums its own, in order)."""
    sides = [(m, poses[sid]) for c in corrs for m, sid in ((c.A, c.strip_a), (c.B, c.strip_b))]
    for _, pose in sides:
        pose.rows_of(np.zeros(0, np.int64))  # each pose's row table built once, here

    def build(side):
        return Centroids(side[0], side[1], nominal, range_free, lever_free)

    built = thread_map(build, sides, threads)
    return list(zip(built[0::2], built[1::2]))


def _row_sigma(c: Correspondences) -> np.ndarray:
    """The σ (m) of each residual of ``c``: its rows' σ, three times for 3D rows."""
    per_row = np.broadcast_to(np.asarray(c.sigma_m, float), (c.n_obs,))
    return np.repeat(per_row, 3 if c.normal is None else 1)


def _knot_columns(column: dict, strip_id: int, n_knots: int) -> np.ndarray:
    """The Jacobian columns of each knot's (bias x, y, z, tilt x, y, z) of strip ``strip_id``,
    (n_knots, 6), −1 where not free."""
    return np.array([[column.get((kind, ax, strip_id, k), -1)
                      for kind in ("bias", "tilt") for ax in range(3)] for k in range(n_knots)])


def _shifted(q: np.ndarray, h: float, strip_id: int,
             rowsum: np.ndarray | None = None) -> np.ndarray:
    """Points (or weighted sums, with ``rowsum``) of a strip raised by the common height bias
    ``h`` (m); the control pseudo-strip stays."""
    if h == 0.0 or strip_id == CONTROL_STRIP:
        return q
    up = np.array([0.0, 0.0, h])
    return q + (up if rowsum is None else rowsum[:, None] * up)


def _with_height_column(problem: StripProblem, values: Mapping[str, float],
                        names: Sequence[str]) -> np.ndarray:
    """:meth:`StripProblem._sensor_columns` with the :data:`HEIGHT_BIAS` column: each strip side's
    row sums along the normal's up part (e_up for 3D rows), signed a − b; the control side 0."""
    own = [n for n in names if n != HEIGHT_BIAS]
    J = np.zeros((problem.sigma.size, len(names)))
    if own:
        J[:, [names.index(n) for n in own]] = problem._sensor_columns(values, own)
    col, start = [], 0
    for c, sides in zip(problem.corrs, problem.centroids):
        d = np.zeros((c.n_obs, 3))
        for sign, side, sid in zip((1.0, -1.0), sides, (c.strip_a, c.strip_b)):
            if sid != CONTROL_STRIP:
                d[:, 2] += sign * side.rowsum
        col.append(d.ravel() if c.normal is None else np.einsum("ij,ij->i", d, c.normal))
    J[:, names.index(HEIGHT_BIAS)] = np.concatenate(col)
    return J
