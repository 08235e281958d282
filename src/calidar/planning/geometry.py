"""The tie planes a plan will give, sampled analytically: no point is simulated.

For every pair of planned lines whose swaths overlap, a grid of patch cells as
:mod:`calidar.strips.planes` cuts them (≈ 12 points per patch at the sparser strip's
density) is laid over the overlap; each cell's surface (terrain, roof plane) is sampled on
4 × 4 positions and fitted with a plane: its normal, and the surface's scatter about it.
Cells on two surfaces (roof edges), under tree crowns or too rough for the planarity test
are dropped; at most ``max_planes`` per pair are kept, evenly, as the calibrator does.
Each kept cell becomes one row (:mod:`calidar.planning.rows`).
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import lru_cache

import numpy as np

from calidar import frames
from calidar.io.flight_lines import PlanLine
from calidar.sensor import Sensor
from calidar.strips.planes import PlaneSettings

SAMPLES = 4  #: a cell's surface is sampled on SAMPLES × SAMPLES positions
GAP_S = 60.0  #: time between the end of one line's scan and the start of the next (turns)
#: rows per pair that stand for its tie planes (evenly picked over the overlap, each weighing for
#: the planes it stands for: the information is a sum over rows of a smoothly varying geometry)
ROWS_PER_PAIR = 800


@dataclass(frozen=True)
class Instrument:
    """What the plan needs of the sensor beyond sensor.toml (SI)."""

    nominal: Sensor
    pulse_rate_hz: float = 20_000.0
    half_fov_rad: float = np.radians(35.0)
    range_noise_m: float = 0.01
    angle_noise_rad: float = np.radians(0.002)
    #: the platform's attitude motion about the line, σ of roll/pitch and of heading (rad):
    #: turbulence tilts the body, so a heading error of the mounting and one of the trajectory
    #: part (the simulator's UAV: 1.5° and 1°)
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
        swath_m = 2.0 * self.line.height_agl_m * np.tan(inst.half_fov_rad)
        return inst.pulse_rate_hz / (self.line.speed_mps * swath_m)

    def local(self, xy: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Along-track (from the start) and across-track (right) coordinates (m) of positions
        (n, 2)."""
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
    """A line's attitude pattern: times (s), unit turbulence (n, 3) smoothed over 1 s, the crab
    (rad, wandering over 24 s)."""
    from calidar.sim.motion import smooth_noise

    rng = np.random.default_rng(number)
    dt = 0.05
    grid = t0 - 300.0 + np.arange(int((t1 - t0 + 600.0) / dt)) * dt  # ≫ 24 s: a stationary crab
    turbulence = smooth_noise(rng, grid.size, dt, 1.0, 1.0, 3)
    crab = smooth_noise(rng, grid.size, dt, 24.0, heading_sigma)[:, 0]
    return grid, turbulence, crab


def fly_plan(lines: list[PlanLine], terrain) -> list[Flown]:
    """Altitudes (mean terrain height under each line + its height above ground, m) and scan
    windows (s)."""
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
    """The tie planes of one pair: centroids (n, 3), normals (n, 3), per side point counts and
    scatter (m)."""

    a: int  #: index into the flown lines
    b: int
    centroid: np.ndarray
    normal: np.ndarray
    roughness_m: np.ndarray
    count_a: np.ndarray
    count_b: np.ndarray
    #: chance the two patches' normals agree (the row's information is weighed by it)
    agree: np.ndarray
    uneven_m: np.ndarray  #: the part of the roughness two patches on the cell do not share (m)
    weight: float = 1.0  #: tie planes each row stands for

    @property
    def n_planes(self) -> int:
        return int(round(self.centroid.shape[0] * self.weight))


def _overlap_cells(fa: Flown, fb: Flown, inst: Instrument, cell: float) -> tuple[np.ndarray, float]:
    """Centres (n, 2) of the cells inside both swaths (on level ground at the mean height, half a
    cell in), and the cell size (m): ``cell``, or larger when the box would hold over 4e7."""
    ends = np.array([fa.line.start, fa.line.end, fb.line.start, fb.line.end])
    reach = max(fa.line.height_agl_m, fb.line.height_agl_m) * np.tan(inst.half_fov_rad) * 1.5
    lo, hi = ends.min(axis=0) - reach, ends.max(axis=0) + reach
    if np.prod((hi - lo) / cell) > 4e7:
        cell = float(np.sqrt(np.prod(hi - lo) / 4e7))
    gx, gy = np.meshgrid(np.arange(lo[0], hi[0], cell) + cell / 2,
                         np.arange(lo[1], hi[1], cell) + cell / 2)
    xy = np.stack([gx.ravel(), gy.ravel()], axis=1)
    for f in (fa, fb):
        s, c = f.local(xy)
        half = f.line.height_agl_m * np.tan(inst.half_fov_rad)
        keep = (s >= cell / 2) & (s <= f.line.length_m - cell / 2) & (np.abs(c) <= half - cell / 2)
        xy = xy[keep]
    return xy, cell


def _points_in_cell(f: Flown, density: float, centroid: np.ndarray, cell: float,
                    settings: PlaneSettings) -> np.ndarray:
    """The points a strip puts in each cell (≈ its density over the tilted face): the pulses
    falling in the cell's horizontal footprint, denser on what stands closer to the line."""
    below_m = np.maximum(f.altitude_m - np.nan_to_num(centroid[:, 2]), 1.0)
    closer = f.line.height_agl_m / below_m
    return np.minimum(density * cell * cell * closer, settings.max_points_per_patch)


def _agreement(rough: np.ndarray, counts: list[np.ndarray], cell: float, inst: Instrument,
               settings: PlaneSettings) -> np.ndarray:
    """The chance the normals of the two strips' patches agree within max_normal_angle_deg: each
    tilts by ≈ scatter / (√m · cell/√12) per axis; it weighs the row (expected information)."""
    var = rough**2 + inst.range_noise_m**2
    tilt2 = 12.0 * var * (1.0 / counts[0] + 1.0 / counts[1]) / cell**2
    max_angle2 = np.radians(settings.max_normal_angle_deg) ** 2
    return 1.0 - np.exp(-max_angle2 / (2.0 * np.maximum(tilt2, 1e-30)))


def pair_planes(fa: Flown, fb: Flown, ia: int, ib: int, terrain, inst: Instrument,
                settings: PlaneSettings = PlaneSettings()) -> PairPlanes | None:
    """The tie planes lines ``fa`` and ``fb`` share (None: their swaths do not overlap)."""
    da, db = fa.density(inst), fb.density(inst)
    cell = float(np.clip(np.sqrt(settings.target_points / min(da, db)), 0.5, 25.0))
    xy, cell = _overlap_cells(fa, fb, inst, cell)
    if xy.shape[0] == 0:
        return None
    n_cells = xy.shape[0]
    if n_cells > 2 * ROWS_PER_PAIR:  # cells tried, evenly over the overlap
        xy = xy[np.linspace(0, n_cells - 1, 2 * ROWS_PER_PAIR).astype(np.int64)]
    centroid, normal, rough, uneven = _surface_planes(terrain, xy, cell)
    ok = np.isfinite(centroid[:, 2]) & (rough <= settings.max_rms_m)
    for f in (fa, fb):  # every corner and the centre seen by both lines (no roof's shadow)
        ok[ok] &= _seen(f, centroid[ok], normal[ok], cell, terrain)
    counts = [_points_in_cell(f, d, centroid, cell, settings) for f, d in ((fa, da), (fb, db))]
    for m in counts:
        ok &= m >= settings.min_points
    agree = _agreement(rough, counts, cell, inst, settings)
    idx = np.flatnonzero(ok)
    if idx.size == 0:
        return None
    # the calibrator keeps ≤ max_planes
    planes = min(idx.size * n_cells / xy.shape[0], settings.max_planes)
    if idx.size > ROWS_PER_PAIR:
        idx = idx[np.linspace(0, idx.size - 1, ROWS_PER_PAIR).astype(np.int64)]
    return PairPlanes(ia, ib, centroid[idx], normal[idx], rough[idx], counts[0][idx],
                      counts[1][idx], agree[idx], uneven[idx], planes / idx.size)


def _surface_planes(terrain, xy: np.ndarray,
                    cell: float) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Per cell centre (n, 2): the surface's centroid (n, 3; NaN height where no tie plane can
    be), unit normal (up), RMS about the plane fitted to SAMPLES × SAMPLES samples (m) and the
    unevenness two strips' patches do not share (m).

    The unevenness: two regular samplings of the cell offset by one step (the checkerboard's two
    colours); what their means differ by is what two patches do not share (smooth relief
    cancels, rough does not)."""
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
    black = ((np.arange(k) // SAMPLES + np.arange(k) % SAMPLES) % 2 == 0)
    uneven = np.abs(res[:, black].mean(axis=1) - res[:, ~black].mean(axis=1)) * np.sqrt(k / 4.0)
    normal = np.stack([-coef[1], -coef[2], np.ones(xy.shape[0])], axis=1)
    normal /= np.linalg.norm(normal, axis=1)[:, None]
    centroid = np.column_stack([xy, np.where(same, coef[0], np.nan)])
    return centroid, normal, rough, uneven


def _seen(f: Flown, centroid: np.ndarray, normal: np.ndarray, cell: float,
          terrain) -> np.ndarray:
    """Whether line ``f`` sees the cell's centre and four corners (on its plane) at each
    centroid."""
    off = np.array([[0, 0], [-1, -1], [-1, 1], [1, -1], [1, 1]], float) * 0.4 * cell
    n = centroid.shape[0]
    pts = np.repeat(centroid, len(off), axis=0)
    pts[:, :2] += np.tile(off, (n, 1))
    nn = np.repeat(normal, len(off), axis=0)
    pts[:, 2] -= (nn[:, 0] * np.tile(off[:, 0], n) + nn[:, 1] * np.tile(off[:, 1], n)) / nn[:, 2]
    s, _ = f.local(pts[:, :2])
    on_line = f.line.start + s[:, None] * f.line.direction
    origin = np.column_stack([on_line, np.full(pts.shape[0], f.altitude_m)])
    return np.all(terrain.visible(origin, pts).reshape(n, len(off)), axis=1)
