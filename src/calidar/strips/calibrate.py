"""The strip calibrator: boresight, lever arm, range and scanner parameters from overlapping strips.

An outer loop as in ICP (Besl & McKay 1992) around the one adjustment engine:

1. re-georeference the overlapping points of every strip with the current parameters;
2. match every overlapping pair (tie planes or VGICP) → :class:`Correspondences`,
   as independent tasks through :func:`calidar.strips.distribute.map_pairs`;
3. :func:`calidar.adjust.solve` the parameters from the correspondence residuals, only the
   points the correspondences reference being re-georeferenced at each evaluation;
4. repeat until the mean correspondence distance changes by less than ``threshold_m``.
"""

from __future__ import annotations

import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field, replace

import numpy as np
import scipy.sparse as sp

from calidar.adjust import Parameter, ParameterSet, Solution, solve
from calidar.adjust.solution import residual_stats
from calidar.adjust.solver import numerical_jacobian
from calidar.errors import CalibrationError, CalidarError, InputError
from calidar.scanners.rotating import canonical_eccentricity
from calidar.sensor import Sensor
from calidar.strips.correspond import Correspondences
from calidar.strips.distribute import cluster_client, map_pairs
from calidar.strips.overlap import Overlap, find_overlaps
from calidar.strips.planes import PlaneSettings, match_pair_planes
from calidar.strips.strip import Pose, Strip, georeference_pose, position_table
from calidar.strips.trajectory_errors import PREFIX as TRAJECTORY_PREFIX
from calidar.strips.trajectory_errors import StripCorrection, TrajectoryModel, corrections, parse_name

#: What ``--estimate`` accepts → sensor parameters (name, unit of the engine).
ESTIMATE_GROUPS: dict[str, tuple[tuple[str, str], ...]] = {
    "boresight": (("boresight_roll", "rad"), ("boresight_pitch", "rad"), ("boresight_yaw", "rad")),
    "lever_arm": (("lever_arm_x", "m"), ("lever_arm_y", "m"), ("lever_arm_z", "m")),
    "range_offset": (("range_offset", "m"),),
    "range_scale": (("range_scale", "ppm"),),
    "scan_angle_scale": (("scan_angle_scale", "1"),),
    "scan_angle_offset": (("scan_angle_offset", "rad"),),
    "palmer": (("eccentricity_ratio", "1"), ("eccentricity_phase", "rad"), ("delta_l", "rad"), ("delta_r", "rad")),
    "trajectory_bias": (),  # per strip (and knot): see calidar.strips.trajectory_errors
}
METHODS = ("planes", "vgicp")


@dataclass(frozen=True)
class StripSettings:
    """Settings of the strip calibrator (metres unless named)."""

    overlap_cell_m: float = 5.0  #: grid of the overlap detection
    min_overlap_cells: int = 4
    min_correspondences: int = 10  #: pairs with fewer are skipped with a warning
    max_outer: int = 8  #: outer (re-matching) iterations
    threshold_m: float = 2e-4  #: stop when the mean correspondence distance changes by less
    robust: str | None = "cauchy"
    cluster_s: float | None = 10.0  #: trajectory errors correlate over this time: σ from a cluster-robust covariance
    trajectory: TrajectoryModel = field(default_factory=TrajectoryModel)  #: when estimating trajectory_bias
    planes: PlaneSettings = field(default_factory=PlaneSettings)
    vgicp: object | None = None  #: settings handed to calidar.strips.vgicp.match_pair_vgicp


@dataclass
class CalibrationResult:
    """What a strip calibration produced."""

    solution: Solution
    sensor: Sensor  #: calibrated
    nominal: Sensor
    strips: list[Strip]
    overlaps: list[Overlap]
    method: str
    pairs: list[dict]  #: per used pair: a, b, n_obs
    residuals_before: np.ndarray  #: first correspondences at the nominal sensor, m
    residuals_after: np.ndarray  #: last correspondences at the calibrated sensor, m
    outer: list[dict]  #: per outer iteration: mean distance, observations, values (SI)
    corrections: dict[int, StripCorrection]  #: estimated trajectory corrections per strip
    poses: dict[int, Pose] = field(default_factory=dict, repr=False)  #: cached poses of the overlap points

    @property
    def warnings(self) -> list[str]:
        return self.solution.warnings

    def max_trajectory_shift_m(self) -> float:
        """The largest estimated trajectory shift at any knot (m; 0 without trajectory corrections)."""
        return max((float(np.abs(c.shift).max()) for c in self.corrections.values()), default=0.0)

    def georeference(self, strip: Strip, calibrated: bool = True, index=None) -> np.ndarray:
        """A strip's points (local m) with the calibrated (or nominal) sensor and its trajectory correction."""
        if not calibrated:
            return strip.points if index is None else strip.points[index]
        pose = None
        if index is not None and strip.id in self.poses:
            try:
                pose = self.poses[strip.id].take(self.poses[strip.id].rows_of(np.asarray(index)))
            except KeyError:
                pose = None
        pose = strip.pose(index) if pose is None else pose
        return _georeference(self.sensor, self.corrections.get(strip.id), pose, strip.time[pose.index])


#: Single parameters ``--estimate`` also accepts (e.g. lever_arm_x,lever_arm_y without z).
SINGLE_PARAMETERS = {name: ((name, unit),) for g in ESTIMATE_GROUPS.values() for name, unit in g}


def parse_estimate(items: str | Sequence[str]) -> list[str]:
    """'boresight,lever_arm' (or a list) → validated group or single-parameter names."""
    names = [s.strip() for s in (items.split(",") if isinstance(items, str) else items) if s.strip()]
    known = {**ESTIMATE_GROUPS, **SINGLE_PARAMETERS}
    unknown = [n for n in names if n not in known]
    if unknown or not names:
        raise InputError(None, "--estimate", f"expected a comma-separated subset of {sorted(ESTIMATE_GROUPS)} "
                         f"or single parameters such as lever_arm_x, got {items!r}")
    return names


def build_parameters(nominal: Sensor, estimate: Sequence[str], spans: dict[int, tuple[float, float]],
                     trajectory: TrajectoryModel = TrajectoryModel()) -> ParameterSet:
    """The engine's parameters: every sensor parameter (estimated ones free) plus, with
    ``trajectory_bias``, the trajectory corrections of strips with time spans {id: (t0, t1)} s."""
    free = {name for g in estimate for name, _ in {**ESTIMATE_GROUPS, **SINGLE_PARAMETERS}[g]}
    units = {name: unit for g in ESTIMATE_GROUPS.values() for name, unit in g}
    params = [Parameter(name, value, units.get(name, "1"), free=name in free)
              for name, value in nominal.parameters().items() if name in units]
    if "trajectory_bias" in estimate:
        params += trajectory.parameters(spans)
    return ParameterSet(params)


def _sensor(nominal: Sensor, values: dict[str, float]) -> Sensor:
    own = set(nominal.parameters())
    return nominal.with_parameters(**{k: v for k, v in values.items() if k in own})


def _georeference(sensor: Sensor, correction: StripCorrection | None, pose: Pose, time: np.ndarray) -> np.ndarray:
    """Points (local m) of cached poses with ``sensor`` and a strip's trajectory correction (or None)."""
    pts = georeference_pose(sensor, pose)
    return pts if correction is None else correction.apply(pts, pose.position, time)


def _matcher(method: str, settings: StripSettings) -> tuple[Callable, object]:
    if method == "planes":
        return match_pair_planes, settings.planes
    if method == "vgicp":
        from calidar.strips.vgicp import match_pair_vgicp

        from calidar.strips.vgicp import VgicpSettings

        return match_pair_vgicp, settings.vgicp or VgicpSettings()
    raise InputError(None, "--method", f"expected one of {list(METHODS)}, got {method!r}")


def _union(indices: list[np.ndarray]) -> np.ndarray:
    """Sorted union of point-index arrays (O(N), unlike a hash-based unique)."""
    return np.flatnonzero(np.bincount(np.concatenate(indices)))


def _compact(m: sp.csr_matrix, cols: np.ndarray) -> sp.csr_matrix:
    """``m`` restricted to its columns ``cols`` (sorted, holding every column m references)."""
    return sp.csr_matrix((m.data, position_table(cols)[m.indices], m.indptr), shape=(m.shape[0], cols.size))


def _match_or_error(match: Callable, strip_a_id, points_a, strip_b_id, points_b, settings):
    """``match(...)``, or the user-facing error it raised for this pair (picklable, for map_pairs)."""
    try:
        return match(strip_a_id, points_a, strip_b_id, points_b, settings)
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


class _Centroids:
    """C = A · P(θ) for one side of a correspondence set, in O(n_obs) per evaluation.

    With P = r + R_lb · (R_bs · v_s + a_b) and v_s = (ρ_m − offset) / (1 + scale) · u (the
    lidar equation with the sensor's range model), the averages of r, R_lb, R_lb·ρ_m·u and
    R_lb·u are taken once; boresight, lever arm and range offset/scale then act on them
    exactly. (Scanner-angle parameters change u: see ``_Problem``.)
    """

    def __init__(self, A: sp.csr_matrix, poses: Pose, nominal: Sensor, range_free: bool, lever_free: bool):
        """A: averaging weights over a strip's points (columns = strip point indices); poses:
        cached poses holding every point A references."""
        n = A.shape[0]
        cols = _union([A.indices])  # only the points this side references
        A, pose = _compact(A, cols), poses.take(poses.rows_of(cols))
        u = nominal.scanner.directions(pose.angles)
        self.rowsum = np.asarray(A.sum(axis=1)).ravel()
        self.r = A @ pose.position  #: weighted sums of the IMU positions
        R = (A @ pose.r_lb.reshape(-1, 9)).reshape(n, 3, 3)
        if lever_free:
            self.R, self.const = R, self.r
        else:  # a fixed lever arm adds a constant
            self.R, self.const = None, self.r + R @ nominal.lever_arm
        # with a fixed range model v_s is fixed: one average instead of two
        rho = pose.range_m if range_free else nominal.true_range(pose.range_m)
        self.M_rho = np.empty((n, 3, 3, 3))
        self.M_u = np.empty((n, 3, 3, 3)) if range_free else None
        for k in range(3):
            self.M_rho[..., k] = (A @ (pose.r_lb * (rho * u[:, k])[:, None, None]).reshape(-1, 9)).reshape(n, 3, 3)
            if range_free:
                self.M_u[..., k] = (A @ (pose.r_lb * u[:, None, None, k]).reshape(-1, 9)).reshape(n, 3, 3)

    def __call__(self, sensor: Sensor) -> np.ndarray:
        M = self.M_rho if self.M_u is None else (self.M_rho - sensor.range_offset * self.M_u) / (1.0 + sensor.range_scale)
        n = M.shape[0]
        out = self.const + (M.reshape(n * 3, 9) @ sensor.r_bs.ravel()).reshape(n, 3)
        return out if self.R is None else out + self.R @ sensor.lever_arm


class _Problem:
    """Residuals of all correspondences for given parameter values (SI), with cached poses."""

    def __init__(self, nominal: Sensor, poses: dict[int, Pose], corrs: list[Correspondences], free: Sequence[str],
                 times: dict[int, np.ndarray] | None = None, trajectory: TrajectoryModel | None = None,
                 spans: dict[int, tuple[float, float]] | None = None):
        """poses: per strip, cached poses holding at least every point the correspondences reference;
        times: per strip, the GPS times (s) of all its points; trajectory, spans: the model of
        trajectory corrections (None: no corrections) and the strips' time spans."""
        self.nominal = nominal
        self.trajectory, self.spans = trajectory, spans or {}
        used: dict[int, list[np.ndarray]] = {}
        for c in corrs:
            used.setdefault(c.strip_a, []).append(c.A.indices)
            used.setdefault(c.strip_b, []).append(c.B.indices)
        self.index = {i: _union(v) for i, v in used.items()}
        self.time = {i: times[i][idx] for i, idx in self.index.items()} if trajectory else {}

        scanner_free = set(free) & set(nominal.scanner.parameters())
        range_free = bool(set(free) & {"range_offset", "range_scale"})
        lever_free = any(f.startswith("lever_arm") for f in free)
        self.centroids = None if scanner_free else [
            tuple(_Centroids(m, poses[sid], nominal, range_free, lever_free)
                  for m, sid in ((c.A, c.strip_a), (c.B, c.strip_b))) for c in corrs]
        #: poses of every referenced point, for re-georeferencing them all (scanner parameters free)
        self.pose: dict[int, Pose] = {} if self.centroids is not None else {
            i: poses[i].take(poses[i].rows_of(idx)) for i, idx in self.index.items()}
        self.corrs = [replace(c, A=_compact(c.A, self.index[c.strip_a]), B=_compact(c.B, self.index[c.strip_b]))
                      for c in corrs]
        self.sigma = np.concatenate([
            np.repeat(np.broadcast_to(np.asarray(c.sigma_m, float), (c.n_obs,)), 3 if c.normal is None else 1)
            for c in self.corrs])
        self._pattern = None  # the trajectory Jacobian's sparsity, built on its first call
        self._knots: dict[tuple[int, int], tuple] = {}  # (set, side) → the rows' knots and weights
        self.row_time = [tuple((m @ self.time[sid]) / np.maximum(np.asarray(m.sum(axis=1)).ravel(), 1e-300)
                               if self.time else None for m, sid in ((c.A, c.strip_a), (c.B, c.strip_b)))
                         for c in self.corrs]

    def clusters(self, strips: dict[int, Strip], block_s: float) -> list[np.ndarray]:
        """Groupings of the residuals by trajectory segment (strip, time block of ``block_s``):
        (n, 2) the segments of the a-side and b-side points (residuals sharing a segment share
        its trajectory error), and (n,) the pair with its a-side segment."""
        dyadic, by_pair = [], []
        for k, c in enumerate(self.corrs):
            block = [np.floor(m @ strips[sid].time[self.index[sid]] / block_s).astype(np.int64)
                     for sid, m in ((c.strip_a, c.A), (c.strip_b, c.B))]
            g = np.stack([(np.int64(c.strip_a) << 32) + block[0], (np.int64(c.strip_b) << 32) + block[1]], axis=1)
            p = (np.int64(k) << 32) + block[0]
            rep = 3 if c.normal is None else 1
            dyadic.append(np.repeat(g, rep, axis=0))
            by_pair.append(np.repeat(p, rep))
        return [np.concatenate(dyadic), np.concatenate(by_pair)]

    def split(self, r: np.ndarray) -> list[tuple[Correspondences, np.ndarray]]:
        """The residual vector cut into each pair's part."""
        sizes = [c.n_obs * (3 if c.normal is None else 1) for c in self.corrs]
        return list(zip(self.corrs, np.split(r, np.cumsum(sizes)[:-1])))

    def __call__(self, values: dict[str, float]) -> np.ndarray:
        sensor = _sensor(self.nominal, values)
        fix = corrections(values, self.trajectory, self.spans)
        if self.centroids is None:  # scanner parameters free: re-georeference every referenced point
            pts = {i: _georeference(sensor, fix.get(i), p, self.time.get(i)) for i, p in self.pose.items()}
            return np.concatenate([c.residuals(pts[c.strip_a], pts[c.strip_b]) for c in self.corrs])
        out = []
        for k, (c, sides, times) in enumerate(zip(self.corrs, self.centroids, self.row_time)):
            p = []
            for s, (side, sid, t) in enumerate(zip(sides, (c.strip_a, c.strip_b), times)):
                q = side(sensor)
                f = fix.get(sid)
                p.append(q if f is None else f.apply(q, side.r, t, side.rowsum, self._row_knots(k, s, f, t)))
            d = p[0] - p[1]
            out.append(d.ravel() if c.normal is None else np.einsum("ij,ij->i", d, c.normal))
        return np.concatenate(out)

    def _row_knots(self, k: int, side: int, f: StripCorrection, time: np.ndarray):
        """``f.knots(time)`` for side 0 (a) or 1 (b) of correspondence set k, computed once (fixed times)."""
        if (k, side) not in self._knots:
            self._knots[k, side] = f.knots(time)
        return self._knots[k, side]

    def jacobian(self, values: dict[str, float], free: Sequence[Parameter]):
        """∂residuals/∂(free parameters), (n, n_free): central differences for the sensor's
        parameters, exact columns for the trajectory corrections (linear in them; two knots
        per strip and row, so the matrix is returned sparse when they are present). The
        sparsity pattern is built on the first call; later calls only fill in the values."""
        traj = {p.name: parse_name(p.name) for p in free} if self.trajectory else {}
        if self.centroids is None or not any(traj.values()):
            return numerical_jacobian(self, ParameterSet(replace(p, value=values[p.name]) for p in free),
                                      np.array([values[p.name] for p in free]))
        sensor_free = [j for j, p in enumerate(free) if traj[p.name] is None]
        if self._pattern is None:
            self._pattern = self._jacobian_pattern(free, traj, sensor_free)
        mask, indices, indptr, knot_weights = self._pattern
        ns = len(sensor_free)
        V = np.zeros(mask.shape)  # rows × (sensor columns, a-side and b-side 2 knots × 6)
        if sensor_free:
            sub = ParameterSet(replace(free[j], value=values[free[j].name]) for j in sensor_free)
            V[:, :ns] = numerical_jacobian(lambda v: self({**values, **v}), sub, sub.x())
        sensor = _sensor(self.nominal, values)
        start = 0
        for c, sides, weights in zip(self.corrs, self.centroids, knot_weights):
            per = 3 if c.normal is None else 1
            block = V[start:start + c.n_obs * per]
            for s, (sign, side, w) in enumerate(zip((1.0, -1.0), sides, weights)):
                if w is not None:
                    D = _correction_derivatives(side, sensor, c.normal)
                    block[:, ns + 12 * s:ns + 12 * (s + 1)] = (sign * D[:, :, None, :] * w[:, None, :, None]).reshape(-1, 12)
            start += c.n_obs * per
        return sp.csr_matrix((V[mask], indices, indptr), shape=(mask.shape[0], len(free)))

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
                colmap = np.array([[column.get((kind, ax, sid, k), -1) for kind in ("bias", "tilt") for ax in range(3)]
                                   for k in range(f.shift.shape[0])])  # (n_knots, 6), −1 where not free
                w = np.stack([1.0 - frac, frac], axis=1)
                cols = np.where(w[:, :, None] != 0, np.stack([colmap[k0], colmap[k1]], axis=1), -1)
                C[start:start + c.n_obs * per, ns + 12 * s:ns + 12 * (s + 1)] = np.repeat(cols.reshape(-1, 12), per, axis=0)
                weights.append(w)
            knot_weights.append(weights)
            start += c.n_obs * per
        mask = C >= 0
        indptr = np.concatenate([[0], np.cumsum(np.count_nonzero(mask, axis=1))])
        return mask, C[mask], indptr, knot_weights


def _correction_derivatives(side: _Centroids, sensor: Sensor, normal: np.ndarray | None) -> np.ndarray:
    """∂(a side's corrected weighted sums)/∂(shift x, y, z, tilt x, y, z) of one knot carrying
    all the weight, (n, per, 6): shift → row sums · e, rotation → e × (sums − IMU sums); along
    the normals (per = 1) or in 3D (per = 3)."""
    v = side(sensor) - side.r
    if normal is not None:  # (e × v) · n = e · (v × n)
        return np.concatenate([side.rowsum[:, None] * normal, np.cross(v, normal)], axis=1)[:, None, :]
    D = np.zeros((v.shape[0], 3, 6))
    D[:, [0, 1, 2], [0, 1, 2]] = side.rowsum[:, None]
    D[:, :, 3:] = np.stack([np.cross(e, v) for e in np.eye(3)], axis=2)
    return D


def geometry_warnings(strips: Sequence[Strip], pairs: Sequence[tuple[int, int]], free: Sequence[str]) -> list[str]:
    """Plain-words warnings about parameters the flight geometry cannot determine."""
    heading = {s.id: s.heading_enu() for s in strips}
    kinds = set()
    for a, b in pairs:
        d = abs((heading[a] - heading[b] + np.pi) % (2 * np.pi) - np.pi)
        kinds.add("same" if d < np.radians(30) else "opposite" if d > np.radians(150) else "cross")
    out = []
    if kinds == {"same"}:
        hit = [p for p in ("boresight_pitch", "lever_arm_x", "lever_arm_y", "lever_arm_z") if p in free]
        if hit:
            out.append(
                f"{', '.join(hit)} poorly determined: all overlapping strips are parallel and flown the same way, "
                "so these errors shift every strip by the same amount and the overlaps cannot see it "
                "(fly lines in the opposite direction and across)")
    elif "cross" not in kinds and any(p.startswith("lever_arm") for p in free):
        out.append("lever arm weakly determined: no cross lines, only parallel strips (fly a line across them)")
    if "lever_arm_z" in free:
        out.append("lever_arm_z is determined only through attitude changes (a vertical lever-arm error shifts "
                   "every strip up or down alike); expect a large σ")
    return out


def calibrate(strips: Sequence[Strip], nominal: Sensor, *, scheduler: str | None = None,
              workers: int | None = None, **options) -> CalibrationResult:
    """:func:`_calibrate` with ONE Dask client (``scheduler`` address or a LocalCluster of
    ``workers`` processes, None: in-process) for every outer iteration's pair matching."""
    with cluster_client(scheduler, workers) as client:
        return _calibrate(strips, nominal, client=client, **options)


def _calibrate(strips: Sequence[Strip], nominal: Sensor, *, method: str = "planes",
               estimate: Sequence[str] = ("boresight",), settings: StripSettings | None = None,
               client=None, progress: Callable[[str], None] | None = None) -> CalibrationResult:
    """Calibrate the sensor from overlapping strips (all in one :class:`LocalFrame`).

    ``estimate``: groups of :data:`ESTIMATE_GROUPS`; ``client``: an open Dask client for the
    pair matching or None (see :func:`map_pairs`). Raises :class:`CalibrationError` when no pair of
    strips overlaps with enough correspondences.
    """
    s = settings or StripSettings()
    estimate = parse_estimate(estimate)
    say = progress or (lambda msg: None)
    match, match_settings = _matcher(method, s)
    what = "tie planes" if method == "planes" else "correspondences"
    by_id = {st.id: st for st in strips}
    if len(by_id) != len(strips):
        raise InputError(None, "strips", "two strips share an id; flight-line ids must be unique")
    overlaps, notes = find_overlaps({i: st.points for i, st in by_id.items()}, s.overlap_cell_m, s.min_overlap_cells)
    if not overlaps:
        raise CalibrationError(f"no two of the {len(by_id)} strips overlap (no common {s.overlap_cell_m:g} m cells); "
                               "strip calibration needs overlapping flight lines")
    spans = {i: (float(st.time.min()), float(st.time.max())) for i, st in by_id.items()}
    params = build_parameters(nominal, estimate, spans, s.trajectory)
    model = s.trajectory if "trajectory_bias" in estimate else None
    warnings = list(notes)
    outer: list[dict] = []
    first_residuals = None
    prev_mean = None
    solution = None
    need: dict[int, list[np.ndarray]] = {}  # points of each strip inside any of its overlaps
    for o in overlaps:
        need.setdefault(o.a, []).append(o.index_a)
        need.setdefault(o.b, []).append(o.index_b)
    need = {i: _union(v) for i, v in need.items()}
    poses = {i: by_id[i].pose(idx) for i, idx in need.items()}  # one trajectory interpolation
    for k in range(s.max_outer):
        clock = time.perf_counter()
        sensor, fix = _sensor(nominal, params.values()), corrections(params.values(), model, spans)
        current = {i: (idx, _georeference(sensor, fix.get(i), poses[i], by_id[i].time[idx])) for i, idx in need.items()}
        times = {"georeference_s": time.perf_counter() - clock}

        def subset(i, index):
            idx, pts = current[i]
            return pts[np.searchsorted(idx, index)]

        tasks = [(match, o.a, subset(o.a, o.index_a), o.b, subset(o.b, o.index_b), match_settings) for o in overlaps]
        say(f"iteration {k + 1}: matching {len(tasks)} pairs ({method})")
        clock = time.perf_counter()
        found = map_pairs(_match_or_error, tasks, client=client)
        times["match_s"] = time.perf_counter() - clock
        corrs, pairs, skipped = [], [], []
        for o, c in zip(overlaps, found):
            if isinstance(c, CalidarError):
                skipped.append(f"{o.a}–{o.b}: {c}")
                continue
            if c.n_obs < s.min_correspondences:
                skipped.append(f"{o.a}–{o.b}: only {c.n_obs} {what}, need {s.min_correspondences}")
                continue
            corrs.append(_to_strip_columns(c, o, len(by_id[o.a]), len(by_id[o.b])))
            pairs.append({"a": o.a, "b": o.b, "n_obs": c.n_obs})
        if k == 0 and skipped:
            warnings.append("strip pairs skipped: " + "; ".join(skipped))
        if not corrs:
            raise CalibrationError("no usable strip pair: " + "; ".join(skipped))
        say(f"iteration {k + 1}: solving {sum(c.n_obs for c in corrs)} observations")
        clock = time.perf_counter()
        problem = _Problem(nominal, poses, corrs, params.free_names, {i: st.time for i, st in by_id.items()},
                           model, spans)
        clusters = problem.clusters(by_id, s.cluster_s) if s.cluster_s else None
        solution = solve(problem, params, sigma=problem.sigma, robust=s.robust, clusters=clusters,
                         jacobian_fn=lambda v, free=params.free: problem.jacobian(v, free),
                         prior_correlation=model.prior_correlation(spans) if model else ())
        times["solve_s"] = time.perf_counter() - clock
        if first_residuals is None:
            first_residuals = problem(params.values())
        params = solution.parameters
        mean = float(np.mean(np.concatenate([_mean_distance(c, r) for c, r in problem.split(solution.residuals)])))
        outer.append({"iteration": k + 1, "mean_distance_m": mean, "n_obs": int(problem.sigma.size),
                      "n_pairs": len(corrs), "solver_iterations": len(solution.history) - 1, **times,
                      "values": params.values()})
        if prev_mean is not None and abs(prev_mean - mean) < s.threshold_m:
            break
        prev_mean = mean
    else:
        change = abs(outer[-1]["mean_distance_m"] - outer[-2]["mean_distance_m"]) if len(outer) > 1 else float("nan")
        warnings.append(f"the outer loop stopped after {s.max_outer} iterations before the mean correspondence "
                        f"distance settled (last change {change * 1e3:.2g} mm)")
    canonical_eccentricity(solution)
    params = solution.parameters
    # "before" for the user: the first matching at the nominal sensor (the last solve started
    # from the previous outer iteration's values)
    solution.residuals_before = residual_stats(first_residuals)
    if model is not None:
        solution.nuisance_prefix = TRAJECTORY_PREFIX
    used_pairs = [(p["a"], p["b"]) for p in pairs]
    solution.warnings = warnings + geometry_warnings([by_id[i] for i in problem.index], used_pairs,
                                                     params.free_names) + solution.warnings
    sensor, fix = _sensor(nominal, params.values()), corrections(params.values(), model, spans)
    solution.extra["strips"] = {"method": method, "pairs": pairs, "outer_iterations": [
        {kk: v for kk, v in o.items() if kk != "values"} for o in outer]}
    return CalibrationResult(solution, sensor, nominal, list(strips), overlaps, method, pairs,
                             first_residuals, solution.residuals, outer, fix, poses)


def truth_to_si(doc: dict, params: ParameterSet) -> dict[str, float]:
    """A truth.json document (display units: deg, m, ppm, as solution.json) → SI values by name.

    Values are read from ``doc["parameters"]`` (or ``doc`` itself), each a number or
    {"value": ...}; names the parameters do not know are ignored.
    """
    doc = doc.get("parameters", doc) if isinstance(doc.get("parameters"), dict) else doc
    out = {}
    for p in params:
        v = doc.get(p.name)
        if isinstance(v, dict):
            v = v.get("value")
        if isinstance(v, (int, float)) and not isinstance(v, bool):
            out[p.name] = float(v) / p.to_display(1.0)
    return out
