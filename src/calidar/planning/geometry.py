"""The tie planes a plan will give, sampled analytically: no point is simulated.

For every pair of planned lines whose swaths overlap, a grid of patch cells as
:mod:`calidar.strips.planes` cuts them (≈ 12 points per patch at the sparser strip's
density) is laid over the overlap; each cell's surface (terrain, roof plane) is sampled on
4 × 4 positions and fitted with a plane: its normal, and the surface's scatter about it.
Cells on two surfaces (roof edges), under tree crowns or too rough for the planarity test
are dropped; at most ``max_planes`` per pair are kept, evenly, as the calibrator does.

Each kept cell becomes one point-to-plane row of :class:`~calidar.strips.correspond.Correspondences`,
each side one synthetic point at the patch's centroid with the pose the line has when it
scans it (level flight along the line at the planned height and speed, the scanner's angles
and range to the centroid; a rotating scanner — Palmer oval, wedge cone — sees the patch twice,
ahead and back, and the side averages the two looks); the row's σ is the calibrator's — each side's point scatter over
its point count, plus the noise floor — with the scatter from range and angle noise along the
normal and the surface's own roughness. :class:`calidar.strips.problem.StripProblem` then
builds the same Jacobian the adjustment uses.
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import lru_cache

import numpy as np
import scipy.sparse as sp

from calidar import frames
from calidar.io.flight_lines import PlanLine
from calidar.sensor import Sensor
from calidar.strips.correspond import Correspondences
from calidar.strips.planes import PlaneSettings
from calidar.strips.row_variance import posterior
from calidar.planning.sweep import body_at, pattern_looks, sweep_position
from calidar.strips.strip import Pose

SAMPLES = 4  #: a cell's surface is sampled on SAMPLES × SAMPLES positions
GAP_S = 60.0  #: time between the end of one line's scan and the start of the next (turns)
#: rows per pair that stand for its tie planes (evenly picked over the overlap, each weighing for the
#: planes it stands for: the information is a sum over rows of a smoothly varying geometry)
ROWS_PER_PAIR = 800


@dataclass(frozen=True)
class Instrument:
    """What the plan needs of the sensor beyond sensor.toml (SI)."""

    nominal: Sensor
    pulse_rate_hz: float = 20_000.0
    half_fov_rad: float = np.radians(35.0)
    range_noise_m: float = 0.01
    angle_noise_rad: float = np.radians(0.002)
    #: the platform's attitude motion about the line, σ of roll/pitch and of heading (rad): turbulence
    #: tilts the body, so a heading error of the mounting and one of the trajectory part (the
    #: simulator's UAV: 1.5° and 1°)
    motion_rad: tuple[float, float] = (np.radians(1.5), np.radians(1.0))


@dataclass(frozen=True)
class Flown:
    """A planned line as flown: altitude (m, the terrain's frame), scan window (s)."""

    line: PlanLine
    altitude_m: float
    t0: float

    @property
    def t1(self) -> float:
        return self.t0 + self.line.length_m / self.line.speed_mps

    def density(self, inst: Instrument) -> float:
        """Points per m² on level ground at the planned height."""
        return inst.pulse_rate_hz / (self.line.speed_mps * 2.0 * self.line.height_agl_m * np.tan(inst.half_fov_rad))

    def local(self, xy: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Along-track (from the start) and across-track (right) coordinates (m) of positions (n, 2)."""
        d = self.line.direction
        rel = xy - self.line.start
        return rel @ d, rel @ np.array([d[1], -d[0]])

    def r_lb(self, t: np.ndarray, motion_rad: tuple[float, float] = (0.0, 0.0)) -> np.ndarray:
        """Body (x forward, y right, z down) → local ENU (n, 3, 3) at times ``t`` (s): the line's
        heading, with roll, pitch and heading wobbling about it (``motion_rad``: σ of roll/pitch and
        of heading), as the simulator's platform does (:func:`calidar.sim.motion.fly`: turbulence
        smoothed over 1 s, the heading's 0.3× that plus a crab wandering over 24 s); one fixed
        pattern per line number."""
        t = np.atleast_1d(np.asarray(t, float))
        grid, turb, crab = _wobble(self.line.number, self.t0, self.t1, motion_rad[1])
        roll, pitch = (np.interp(t, grid, motion_rad[0] * turb[:, k]) for k in range(2))
        heading = np.interp(t, grid, crab + 0.3 * motion_rad[1] * turb[:, 2])
        return frames.R_ENU_NED @ frames.rpy_to_matrix(roll, pitch, self.line.azimuth + heading)


@lru_cache(maxsize=256)
def _wobble(number: int, t0: float, t1: float, heading_sigma: float):
    """A line's attitude pattern: times, unit turbulence (n, 3) smoothed over 1 s, the crab (rad, over 24 s)."""
    from calidar.sim.motion import smooth_noise

    rng = np.random.default_rng(number)
    dt = 0.05
    grid = t0 - 300.0 + np.arange(int((t1 - t0 + 600.0) / dt)) * dt  # ≫ 24 s: a stationary crab
    return grid, smooth_noise(rng, grid.size, dt, 1.0, 1.0, 3), smooth_noise(rng, grid.size, dt, 24.0, heading_sigma)[:, 0]


def fly_plan(lines: list[PlanLine], terrain) -> list[Flown]:
    """Altitudes (mean terrain height under each line + its height above ground) and scan windows."""
    out, t = [], 0.0
    for ln in lines:
        s = np.linspace(0.0, 1.0, 50)[:, None]
        xy = ln.start + s * (ln.end - ln.start)
        ground = terrain.mean_height(xy[:, 0], xy[:, 1])
        out.append(Flown(ln, ground + ln.height_agl_m, t))
        t = out[-1].t1 + GAP_S
    return out


@dataclass
class PairPlanes:
    """The tie planes of one pair: centroids (n, 3), normals (n, 3), per side point counts and scatter (m)."""

    a: int  #: index into the flown lines
    b: int
    centroid: np.ndarray
    normal: np.ndarray
    roughness_m: np.ndarray
    count_a: np.ndarray
    count_b: np.ndarray
    agree: np.ndarray  #: chance the two patches' normals agree (the row's information is weighed by it)
    uneven_m: np.ndarray  #: the part of the roughness two patches on the cell do not share (m)
    weight: float = 1.0  #: tie planes each row stands for

    @property
    def n_planes(self) -> int:
        return int(round(self.centroid.shape[0] * self.weight))


def pair_planes(fa: Flown, fb: Flown, ia: int, ib: int, terrain, inst: Instrument,
                settings: PlaneSettings = PlaneSettings()) -> PairPlanes | None:
    """The tie planes lines ``fa`` and ``fb`` share (None: their swaths do not overlap)."""
    da, db = fa.density(inst), fb.density(inst)
    cell = float(np.clip(np.sqrt(settings.target_points / min(da, db)), 0.5, 25.0))
    ends = np.array([fa.line.start, fa.line.end, fb.line.start, fb.line.end])
    reach = max(fa.line.height_agl_m, fb.line.height_agl_m) * np.tan(inst.half_fov_rad) * 1.5
    lo, hi = ends.min(axis=0) - reach, ends.max(axis=0) + reach
    if np.prod((hi - lo) / cell) > 4e7:
        cell = float(np.sqrt(np.prod(hi - lo) / 4e7))
    gx, gy = np.meshgrid(np.arange(lo[0], hi[0], cell) + cell / 2, np.arange(lo[1], hi[1], cell) + cell / 2)
    xy = np.stack([gx.ravel(), gy.ravel()], axis=1)
    for f in (fa, fb):  # inside both swaths (on level ground at the mean height, half a cell in)
        s, c = f.local(xy)
        half = f.line.height_agl_m * np.tan(inst.half_fov_rad)
        keep = (s >= cell / 2) & (s <= f.line.length_m - cell / 2) & (np.abs(c) <= half - cell / 2)
        xy = xy[keep]
    if xy.shape[0] == 0:
        return None
    n_cells = xy.shape[0]
    if n_cells > 2 * ROWS_PER_PAIR:  # cells tried, evenly over the overlap
        xy = xy[np.linspace(0, n_cells - 1, 2 * ROWS_PER_PAIR).astype(np.int64)]
    centroid, normal, rough, uneven = _surface_planes(terrain, xy, cell)
    ok = np.isfinite(centroid[:, 2]) & (rough <= settings.max_rms_m)
    for f in (fa, fb):  # every corner and the centre seen by both lines (no shadow of a roof or crown)
        ok[ok] &= _seen(f, centroid[ok], normal[ok], cell, terrain)
    counts = []
    for f, d in ((fa, da), (fb, db)):  # the points a strip puts in the cell (≈ its density over the tilted face)
        # the pulses falling in the cell's horizontal footprint, denser on what stands closer to the line
        closer = f.line.height_agl_m / np.maximum(f.altitude_m - np.nan_to_num(centroid[:, 2]), 1.0)
        m = np.minimum(d * cell * cell * closer, settings.max_points_per_patch)
        counts.append(m)
        ok &= m >= settings.min_points
    # the normals of the two strips' patches must agree within max_normal_angle_deg: each tilts by
    # ≈ scatter / (√m · cell/√12) per axis; the chance both agree weighs the row (expected information)
    var = rough**2 + inst.range_noise_m**2
    tilt2 = 12.0 * var * (1.0 / counts[0] + 1.0 / counts[1]) / cell**2
    agree = 1.0 - np.exp(-np.radians(settings.max_normal_angle_deg) ** 2 / (2.0 * np.maximum(tilt2, 1e-30)))
    idx = np.flatnonzero(ok)
    if idx.size == 0:
        return None
    planes = min(idx.size * n_cells / xy.shape[0], settings.max_planes)  # the calibrator keeps ≤ max_planes
    if idx.size > ROWS_PER_PAIR:
        idx = idx[np.linspace(0, idx.size - 1, ROWS_PER_PAIR).astype(np.int64)]
    return PairPlanes(ia, ib, centroid[idx], normal[idx], rough[idx], counts[0][idx], counts[1][idx], agree[idx],
                      uneven[idx], planes / idx.size)


def _surface_planes(terrain, xy: np.ndarray, cell: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Per cell centre (n, 2): the surface's centroid (n, 3; NaN height where no tie plane can be),
    unit normal (up) and RMS about the plane fitted to SAMPLES × SAMPLES samples (m)."""
    off = (np.arange(SAMPLES) - (SAMPLES - 1) / 2) * cell / SAMPLES
    ox, oy = [v.ravel() for v in np.meshgrid(off, off)]
    k = ox.size
    x = xy[:, 0, None] + ox[None, :]
    y = xy[:, 1, None] + oy[None, :]
    z, sid = terrain.sample(x, y)
    same = np.all(sid == sid[:, :1], axis=1) & (sid[:, 0] != -3) & np.all(np.isfinite(z), axis=1)
    G = np.stack([np.ones(k), ox, oy], axis=1)  # z = a + b·dx + c·dy
    coef, *_ = np.linalg.lstsq(G, np.where(np.isfinite(z), z, 0.0).T, rcond=None)
    res = np.where(np.isfinite(z), z, 0.0) - (G @ coef).T
    rough = np.sqrt(np.sum(res**2, axis=1) / (k - 3.0))  # 3 plane parameters fitted
    # two regular samplings of the cell offset by one step (the checkerboard's two colours): what their
    # means differ by is the unevenness two strips' patches do not share (smooth relief cancels, rough does not)
    black = ((np.arange(k) // SAMPLES + np.arange(k) % SAMPLES) % 2 == 0)
    uneven = np.abs(res[:, black].mean(axis=1) - res[:, ~black].mean(axis=1)) * np.sqrt(k / 4.0)
    normal = np.stack([-coef[1], -coef[2], np.ones(xy.shape[0])], axis=1)
    normal /= np.linalg.norm(normal, axis=1)[:, None]
    centroid = np.column_stack([xy, np.where(same, coef[0], np.nan)])
    return centroid, normal, rough, uneven


def _seen(f: Flown, centroid: np.ndarray, normal: np.ndarray, cell: float, terrain) -> np.ndarray:
    """Whether line ``f`` sees the cell's centre and four corners (on its plane) at each centroid."""
    off = np.array([[0, 0], [-1, -1], [-1, 1], [1, -1], [1, 1]], float) * 0.4 * cell
    n = centroid.shape[0]
    pts = np.repeat(centroid, len(off), axis=0)
    pts[:, :2] += np.tile(off, (n, 1))
    nn = np.repeat(normal, len(off), axis=0)
    pts[:, 2] -= (nn[:, 0] * np.tile(off[:, 0], n) + nn[:, 1] * np.tile(off[:, 1], n)) / nn[:, 2]
    s, _ = f.local(pts[:, :2])
    origin = np.column_stack([f.line.start + s[:, None] * f.line.direction, np.full(pts.shape[0], f.altitude_m)])
    return np.all(terrain.visible(origin, pts).reshape(n, len(off)), axis=1)


def side_poses(f: Flown, points: np.ndarray, inst: Instrument) -> tuple[Pose, np.ndarray, np.ndarray]:
    """The poses at which line ``f`` scans ``points`` (n, 3) (level flight, the nominal sensor's
    angles and range), their times (s) and the beams' unit directions in the local frame. A linear
    scanner sees each point once (n poses); a rotating one (Palmer oval, wedge cone) twice, looking
    ahead and back (2n: the n fore looks, then the n aft ones)."""
    nominal = inst.nominal
    looks = pattern_looks(nominal)
    branches = [None] if looks is None else looks
    parts = [body_at(f, points, sweep_position(f, points, inst, branch), inst) for branch in branches]
    t, pos, R, d_b = (np.concatenate(v) for v in zip(*parts))
    rho = np.linalg.norm(d_b, axis=1)
    u_s = (d_b / rho[:, None]) @ nominal.r_bs  # R_bsᵀ · u_b
    angles = nominal.scanner.angles(u_s)
    pose = Pose(np.arange(len(rho)), pos, R, nominal.measured_range(rho), angles)
    return pose, t, np.einsum("nij,nj->ni", R, d_b) / rho[:, None]


def point_variance(beam: np.ndarray, normal: np.ndarray, rho: np.ndarray, inst: Instrument) -> np.ndarray:
    """Scatter (m²) along the normal of one point: range noise along the beam, angle noise across it."""
    cos = np.abs(np.einsum("ij,ij->i", beam, normal))
    return (inst.range_noise_m * cos) ** 2 + (rho * inst.angle_noise_rad) ** 2 * (1.0 - cos**2)


def correspondences(flown: list[Flown], pairs: list[PairPlanes], inst: Instrument,
                    settings: PlaneSettings = PlaneSettings(), terrain=None, cache: dict | None = None):
    """Synthetic poses per strip, the pairs' Correspondences, each strip's point times, and the
    variance (m²) the rows' residuals really have (in the Correspondences' order). A rotating scanner's
    side averages the looks that see the patch (``terrain``: which do; a wall or crown hides one look
    of many patches beside buildings, and a one-look patch moves as that look's points do). ``cache``:
    each side's poses and looks kept across calls (candidate lines tried one by one)."""
    poses, times, corrs = {}, {}, []
    parts: dict[int, list] = {k: [] for k in range(len(flown))}
    used = {k: 0 for k in range(len(flown))}
    for p in pairs:
        cols, var, own = [], [], []
        n = p.centroid.shape[0]
        for side, k, m in ((0, p.a, p.count_a), (1, p.b, p.count_b)):
            pose, t, beam, seen = _side(flown[k], p.centroid, inst, terrain, cache)
            looks = len(t) // n  # a rotating scanner's patch: half its points seen ahead, half back
            parts[k].append((pose, t))
            cols.append((used[k] + np.arange(n * looks).reshape(looks, n).T, seen / seen.sum(axis=1, keepdims=True)))
            used[k] += n * looks
            points = np.sum(point_variance(beam, np.tile(p.normal, (looks, 1)), inst.nominal.true_range(pose.range_m),
                                           inst).reshape(looks, n).T * cols[-1][1], axis=1)
            # as the calibrator weighs its rows (strips/planes.py): each side's posterior variance, and b's plane's
            # prediction variance at a's centroid, whose in-plane offset spreads by both centroids' (1/m each)
            lev = 1.0 + (2.0 * (1.0 + m / p.count_a) / m if side == 1 else 0.0)
            var.append(posterior(points + p.roughness_m**2, m - 3, sampled=False)[0] * lev / m)
            own.append((points + p.uneven_m**2) / m)
        agree = np.maximum(p.agree, 1e-3) * p.weight  # a row standing for `weight` planes weighs as much
        # what the residual really scatters by: the points' noise and the unevenness the patches do not share
        # (the rest lies under both and cancels: σ0 ≈ 0.5 of the calibrator on the built-in scene)
        corrs.append((p.a, p.b, cols, p.normal, np.sqrt((var[0] + var[1] + settings.noise_floor_m**2) / agree),
                      (own[0] + own[1]) / agree))
    for k, items in parts.items():
        if not items:
            continue
        sid = flown[k].line.number
        cat = [np.concatenate([getattr(pz, f) for pz, _ in items]) for f in ("position", "r_lb", "range_m", "angles")]
        poses[sid] = Pose(np.arange(used[k]), *cat)
        times[sid] = np.concatenate([t for _, t in items])
    out, noise = [], []
    for a, b, cols, normal, sigma, real in corrs:
        ids = flown[a].line.number, flown[b].line.number
        out.append(Correspondences(*ids, _selector(cols[0], used[a]), _selector(cols[1], used[b]), normal, sigma))
        noise.append(real)
    return poses, times, out, np.concatenate(noise)


def _side(f: Flown, centroid: np.ndarray, inst: Instrument, terrain, cache: dict | None):
    """:func:`side_poses` of one side of a pair and which looks see each patch (n, looks), from ``cache``
    when the same line (number, window) scanned the same tie planes before."""
    key = ("side", f.line.to_json(), f.t0, id(centroid))
    if cache is not None and key in cache:
        return cache[key]
    pose, t, beam = side_poses(f, centroid, inst)
    n = centroid.shape[0]
    looks = len(t) // n
    seen = np.ones((n, looks))
    if looks > 1 and terrain is not None:
        origin = pose.position + np.einsum("nij,j->ni", pose.r_lb, inst.nominal.lever_arm)
        seen = terrain.visible(origin, np.tile(centroid, (looks, 1))).reshape(looks, n).T.astype(float)
        seen[seen.sum(axis=1) == 0] = 1.0  # seen from above the line (pair_planes), not from either look
    if cache is not None:
        cache[key] = (pose, t, beam, seen)
    return pose, t, beam, seen


def _selector(picked: tuple[np.ndarray, np.ndarray], n_points: int) -> sp.csr_matrix:
    """Rows averaging k points each with weights (the patch's centroid): ``picked`` = (columns, weights), (n, k)."""
    cols, weights = picked
    n, k = cols.shape
    return sp.csr_matrix((weights.ravel(), cols.ravel(), np.arange(0, n * k + 1, k)), shape=(n, n_points))
