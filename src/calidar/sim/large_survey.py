"""A fast simulator of large airborne surveys (issue 32): millions of points a second, streamed to
LAZ chunk by chunk, for measuring calibration on 10⁸–10⁹-point flights.

The flight is the one :func:`calidar.sim.survey.simulate_survey` flies for the same
:class:`~calidar.sim.survey_config.SurveyConfig` (its plan, true trajectory, measured trajectory
with the configured errors, smrmsg σ, nominal and true sensors, the same random streams); only
the ground differs: instead of ray-casting a detailed scene (≈ 70 000 points/s), the ground is a
closed-form piecewise-planar height field (:func:`facet_height`: square blocks of ``block_m``,
each flat, a pyramid or a hip roof with its ridge along east or north, slopes up to 1.5 ×
``max_slope``, zero at the block edges so the surface is continuous: planes sloping in both
directions everywhere, what tie planes need). Each pulse's true beam
(:func:`calidar.georef.lidar_point` with the true mounting at the true pose) meets it by
safeguarded Newton steps on the ray's height above the ground (exact in one step once inside the
right facet; bisection if a step leaves the bracket) in one numba loop over a chunk of pulses.
Then, as :func:`calidar.sim.shots.record` does, the instrument records the measured range (true
sensor's range model + noise) and the encoder angle, and the delivered point is
:func:`calidar.georef.forward` of them with the nominal sensor and the measured trajectory — the
same equations as the detailed simulator, so the truth is exact by
construction. One return per pulse, classification ground (flat blocks) or building.

ECEF → the output CRS: PROJ at one anchor per ``CRS_TILE_M`` tile of each chunk (and its
Jacobian by 1 m steps), linear within the tile (as :class:`calidar.crs.TileLinear`): within
0.02 mm of PROJ for 10 m tiles (second-order term ≈ d²/R, d ≲ 20 m), far below the files' 1 mm.
Memory is one chunk (``CHUNK_PULSES``) per process whatever the size; strips can be written by
several processes (``workers``). Example: :func:`simulate_large_survey`.
"""

from __future__ import annotations

from collections.abc import Callable
from concurrent.futures import ProcessPoolExecutor
from dataclasses import dataclass, replace
from pathlib import Path

import laspy
import numpy as np
from numba import njit

from calidar import georef
from calidar.cells import group_cells
from calidar.crs import tile_moved, to_crs
from calidar.georef import lidar_point, pose
from calidar.io.las_write import SCAN_ANGLE_STEP_DEG, LasChunkWriter
from calidar.sim.motion import accuracy_epochs, fly, measured_trajectory, trajectory_sigma
from calidar.sim.patterns import scan_angles
from calidar.sim.scene import CLASS_BUILDING, CLASS_GROUND, Scene
from calidar.sim.survey import (GPS_WEEK_START_S, SIMULATION_DATE, STRIP_ERRORS, SurveyConfig,
                                SurveyResult, check_config, survey_lines, utm_crs)
from calidar.sensor import Sensor
from calidar.trajectory import Trajectory
from calidar.trajectory_accuracy import TrajectoryAccuracy

CHUNK_PULSES = 1_000_000  #: pulses simulated and written at a time (≈ 200 B each while in flight)
CRS_TILE_M = 10.0  #: side of the tiles on which ECEF → CRS is linear (module docstring)
NEWTON_TOL_M = 1e-9  #: |height of the ray above the ground| at which a hit is taken, m
NEWTON_MAX_STEPS = 60
HIP_RATIO = 1.5  #: slope of a hip roof's end facets over its long sides


@dataclass(frozen=True)
class FacetGround:
    """The closed-form ground (module docstring): ``base_m`` up in the scene's ENU frame, blocks
    of ``block_m`` m, facet slopes in [0.25, 1] × ``max_slope`` (rise over run)."""

    base_m: float = 0.0
    block_m: float = 80.0
    max_slope: float = 0.5
    seed: int = 0

    @property
    def top_m(self) -> float:
        """Highest point of the ground (a ridge or apex), ENU up m."""
        return self.base_m + 0.5 * self.max_slope * self.block_m


@njit(cache=True, nogil=True, inline="always")
def _hash(i, j, seed):
    """A reproducible uniform number in [0, 1) for block (i, j) (the classic sine hash)."""
    v = np.sin(i * 12.9898 + j * 78.233 + seed * 37.719) * 43758.5453
    return v - np.floor(v)


@njit(cache=True, nogil=True)
def facet_height(x, y, base, block, max_slope, seed):
    """Height (ENU up, m), its gradient ∂h/∂x, ∂h/∂y and the block's kind of the ground at ENU
    (x, y) m. Kinds: 0 flat; 1 a pyramid (four facets of slope s); 2 a hip roof with its ridge
    along east (facets of slope s to north and south, HIP_RATIO·s at the ends); 3 the same along
    north. Every roof is 0 at its block's edges: the ground is continuous, planar by pieces."""
    fi, fj = np.floor(x / block), np.floor(y / block)
    u, v = x / block - fi - 0.5, y / block - fj - 0.5  # in [-0.5, 0.5) within the block
    kind = int(_hash(fi, fj, seed) * 4.0)
    s = max_slope * (0.25 + 0.75 * _hash(fj, fi, seed + 1))
    if kind == 0:
        return base, 0.0, 0.0, 0
    ku, kv = (HIP_RATIO, 1.0) if kind == 2 else ((1.0, HIP_RATIO) if kind == 3 else (1.0, 1.0))
    eu, ev = ku * (0.5 - abs(u)), kv * (0.5 - abs(v))  # the roof is s·block·min(eu, ev)
    if ev < eu:  # a facet sloping north or south
        return base + s * block * ev, 0.0, -s * kv * np.sign(v), kind
    return base + s * block * eu, -s * ku * np.sign(u), 0.0, kind


@njit(cache=True, nogil=True)
def _meet(ox, oy, oz, dx, dy, dz, base, top, block, max_slope, seed):
    """Range along the unit ray o + ρ·d (ENU, d pointing down) to the ground, and the hit's
    kind: safeguarded Newton on f(ρ) = o_z + ρ·d_z − h(o_xy + ρ·d_xy), which falls monotonically
    while |∇h·d_xy| < |d_z| (slopes ≤ 0.75, beams within ~35° of nadir)."""
    lo, hi = (oz - top) / -dz, (oz - base + 1.0) / -dz  # f(lo) ≥ 0 ≥ f(hi)
    rho = (oz - 0.5 * (base + top)) / -dz
    kind = 0
    for _ in range(NEWTON_MAX_STEPS):
        h, gx, gy, kind = facet_height(ox + rho * dx, oy + rho * dy, base, block, max_slope, seed)
        f = oz + rho * dz - h
        if abs(f) < NEWTON_TOL_M:
            break
        if f > 0.0:
            lo = rho
        else:
            hi = rho
        step = rho - f / (dz - gx * dx - gy * dy)
        rho = step if lo < step < hi else 0.5 * (lo + hi)
    return rho, kind


@njit(cache=True, nogil=True)
def _shoot_kernel(tt, pos, q, t, u, r_bs, lever, r_e_enu, origin, base, top, block, max_slope, seed,
                  rho, hit, kind):
    """Per pulse: the true pose at t[k], the beam from the lidar equation (:func:`lidar_point` of
    0 and of the unit scanner vector u[k] with the true mounting r_bs, lever), into the scene's
    ENU (r_e_enu: ENU → ECEF, origin ECEF), met with the ground → rho[k] m, hit[k] ENU m, kind[k].
    Returns how many times lie outside tt."""
    n_out, i, i_prev, theta, s, sign = 0, 0, -1, 0.0, 0.0, 1.0
    no_lever = np.zeros(3)
    for k in range(t.size):
        n_out += not tt[0] <= t[k] <= tt[tt.size - 1]
        i, i_prev, theta, s, sign, px, py, pz, r00, r01, r02, r10, r11, r12, r20, r21, r22 = pose(
            tt, pos, q, t[k], i, i_prev, theta, s, sign)
        ax, ay, az = lidar_point(0.0, 0.0, 0.0, r_bs, lever, px, py, pz,
                                 r00, r01, r02, r10, r11, r12, r20, r21, r22)
        # the unit beam R_eb·R_bs·u: the same equation from the pose's origin, without the lever arm
        bx, by, bz = lidar_point(u[k, 0], u[k, 1], u[k, 2], r_bs, no_lever, 0.0, 0.0, 0.0,
                                 r00, r01, r02, r10, r11, r12, r20, r21, r22)
        ax, ay, az = ax - origin[0], ay - origin[1], az - origin[2]  # its start from the ENU origin
        o = (r_e_enu[0, 0] * ax + r_e_enu[1, 0] * ay + r_e_enu[2, 0] * az,
             r_e_enu[0, 1] * ax + r_e_enu[1, 1] * ay + r_e_enu[2, 1] * az,
             r_e_enu[0, 2] * ax + r_e_enu[1, 2] * ay + r_e_enu[2, 2] * az)
        d = (r_e_enu[0, 0] * bx + r_e_enu[1, 0] * by + r_e_enu[2, 0] * bz,
             r_e_enu[0, 1] * bx + r_e_enu[1, 1] * by + r_e_enu[2, 1] * bz,
             r_e_enu[0, 2] * bx + r_e_enu[1, 2] * by + r_e_enu[2, 2] * bz)
        rho[k], kind[k] = _meet(o[0], o[1], o[2], d[0], d[1], d[2], base, top, block, max_slope,
                                seed)
        for a in range(3):
            hit[k, a] = o[a] + rho[k] * d[a]
    return n_out


@dataclass(eq=False)
class LargeSurvey:
    """Everything but the points: the flight of ``config`` over ``ground`` (module docstring);
    :meth:`result` is the :class:`SurveyResult` that writes sbet.out, smrmsg.out, sensor.toml and
    truth.json."""

    config: SurveyConfig
    ground: FacetGround
    scene: Scene  #: the frame (ENU origin) and extent only: no buildings, trees or raster ground
    lines: list
    windows: list  #: scan window (t0, t1) GPS s per line
    trajectory_true: Trajectory
    trajectory: Trajectory  #: measured (sbet.out)
    nominal: Sensor
    truth: Sensor
    crs: str
    strip_errors: list
    accuracy: TrajectoryAccuracy

    @property
    def pulse_rate_hz(self) -> float:
        return self.config.pulse_rate_hz * self.config.density

    def pulses(self, k: int) -> int:
        """Pulses (= points: one return each) of line k."""
        a, b = self.windows[k]
        return int((b - a) * self.pulse_rate_hz)

    def result(self, points: int) -> SurveyResult:
        return SurveyResult(self.config, self.scene, self.lines, self.trajectory_true,
                            self.trajectory, self.nominal, self.truth, self.crs, [],
                            self.strip_errors, self.accuracy, points)


def plan_large_survey(cfg: SurveyConfig, ground: FacetGround | None = None) -> LargeSurvey:
    """The flight of ``cfg`` (as :func:`calidar.sim.survey.simulate_survey` sets it up, the same
    random streams) over the closed-form ground (default: at the origin's height, the scene's
    extent)."""
    check_config(cfg)
    ground = ground or FacetGround(seed=cfg.seed)
    ss = np.random.SeedSequence(cfg.seed)
    rngs = [np.random.default_rng(s) for s in ss.spawn(6)]
    _, rng_motion, rng_nav, rng_strip, _, rng_sigma = rngs
    lat0, lon0, h0 = cfg.origin_deg
    crs = utm_crs(lat0, lon0)
    cell = 100.0
    nx, ny = int(np.ceil(cfg.scene.width_m / cell)), int(np.ceil(cfg.scene.length_m / cell))
    heights = np.full((ny + 1, nx + 1), 0.5 * (ground.base_m + ground.top_m))
    empty = np.zeros(0)
    scene = Scene(np.radians(lat0), np.radians(lon0), h0, -nx * cell / 2, -ny * cell / 2, cell,
                  heights, np.zeros((0, 3, 3)), np.zeros(0, int), np.zeros((0, 3)), empty,
                  np.zeros(0, bool), np.zeros(0, int), [], np.zeros((0, 3)), empty,
                  cfg.scene.extinction_per_m)
    nominal = replace(cfg.nominal, crs=crs)
    params = nominal.parameters()
    truth = nominal.with_parameters(**{k: params[k] + v for k, v in cfg.errors.items()})
    lines = survey_lines(cfg, scene, nominal)
    traj_true, windows = fly(scene, lines, cfg.motion, rng_motion, GPS_WEEK_START_S)
    strip_errors = [{k: rng_strip.normal(0.0, sigma, 3)
                     for k, sigma in zip(STRIP_ERRORS, cfg.strip_error_sigma)} for _ in lines]
    sig_pos, sig_att = trajectory_sigma(cfg, traj_true.time, rng_sigma)
    per_strip = [(a, b, e) for (a, b), e in zip(windows, strip_errors)]
    traj = measured_trajectory(traj_true, rng_nav, sig_pos, sig_att, per_strip)
    accuracy = accuracy_epochs(traj_true.time, sig_pos, sig_att)
    return LargeSurvey(cfg, ground, scene, lines, windows, traj_true, traj, nominal, truth, crs,
                       strip_errors, accuracy)


def shoot(plan: LargeSurvey, t: np.ndarray, angles: np.ndarray):
    """The true beams at GPS times t (N,) with encoder angles (N,) or (N, k) rad (noise included)
    met with the ground: true ranges (N,) m, hits (N, 3) in the scene's ENU m, block kinds (N,)."""
    g, tr, truth = plan.ground, plan.trajectory_true, plan.truth
    t = np.ascontiguousarray(t, float)
    u = np.ascontiguousarray(truth.scanner.directions(angles), float)
    rho, hit, kind = np.empty(t.size), np.empty((t.size, 3)), np.empty(t.size, np.int8)
    c = np.ascontiguousarray
    if _shoot_kernel(tr.time, c(tr.ecef), c(tr.q_eb), t, u, c(truth.r_bs),
                     c(truth.lever_arm, float), c(plan.scene.r_e_enu), plan.scene.origin_ecef,
                     g.base_m, g.top_m, g.block_m, g.max_slope, g.seed, rho, hit, kind):
        tr.check_covers(t)
    return rho, hit, kind


def simulate_chunk(plan: LargeSurvey, k: int, first: int, count: int,
                   rng: np.random.Generator) -> dict:
    """Pulses ``first`` … ``first + count`` of line k as delivered (the fields of
    :class:`calidar.sim.survey.Strip` but ``line``, ``xyz``, ``surface``; ``kind`` the ground
    block's) — :func:`calidar.sim.shots.record` over the closed-form ground."""
    cfg, nominal = plan.config, plan.nominal
    t = plan.windows[k][0] + np.arange(first, first + count) / plan.pulse_rate_hz
    enc = scan_angles(nominal.scanner, t, cfg.scan_rate_hz * np.sqrt(cfg.density), cfg.half_fov_rad,
                      cfg.scan_pattern)
    noisy = enc
    if cfg.angle_noise_rad:
        noisy = enc + rng.normal(0.0, cfg.angle_noise_rad, np.shape(enc))
    rho, hit, kind = shoot(plan, t, noisy)
    measured = plan.truth.measured_range(rho + rng.normal(0.0, cfg.range_noise_m, rho.size))
    ecef = georef.forward(plan.trajectory, nominal, t, measured, enc)
    u = nominal.scanner.directions(enc)
    cls = np.where(kind == 0, CLASS_GROUND, CLASS_BUILDING).astype(np.uint8)
    # intensity: reflectance × (R₀/R)² with speckle, as calidar.sim.shots.intensity
    speckle = rng.uniform(0.8, 1.2, rho.size)
    refl = np.where(kind == 0, 0.35, 0.5) * (cfg.height_agl_m / rho) ** 2 * speckle
    return dict(ecef=ecef, gps_time=t, range_m=measured, angles=enc,
                scan_angle_deg=np.degrees(np.arctan2(u[:, 1], u[:, 2])), classification=cls,
                intensity=np.clip(refl * 40000, 1, 65535).astype(np.uint16), kind=kind,
                true_enu=hit)


def tiled_to_crs(ecef: np.ndarray, key_xy: np.ndarray, crs: str,
                 tile_m: float = CRS_TILE_M) -> np.ndarray:
    """ECEF (N, 3) → ``crs``, PROJ at one anchor per tile of ``key_xy`` (N, 2) m (any planar
    coordinates of the points, e.g. ENU) and linear within it (module docstring)."""
    rows, anchor = group_cells(np.floor(key_xy / tile_m).astype(np.int64))
    at = to_crs(ecef[anchor], crs)
    jac = np.stack([to_crs(ecef[anchor] + step, crs) - at for step in np.eye(3)], axis=2)
    return tile_moved(at[rows], jac, rows, ecef - ecef[anchor][rows])


def las_record(header: laspy.LasHeader, xyz: np.ndarray, chunk: dict,
               source_id: int) -> laspy.PackedPointRecord:
    """A chunk's points as LAS point format 6 records of ``header`` (1 of 1 returns)."""
    fmt = header.point_format
    rec = np.zeros(xyz.shape[0], fmt.dtype())
    for a, name in enumerate("XYZ"):
        rec[name] = np.round((xyz[:, a] - header.offsets[a]) / header.scales[a])
    rec["intensity"] = chunk["intensity"]
    rec["bit_fields"] = 1 | (1 << 4)  # return 1 of 1
    rec["classification"] = chunk["classification"]
    rec["scan_angle"] = np.round(chunk["scan_angle_deg"] / SCAN_ANGLE_STEP_DEG)
    rec["point_source_id"] = source_id
    rec["gps_time"] = chunk["gps_time"]
    return laspy.PackedPointRecord(rec, fmt)


def write_large_strip(plan: LargeSurvey, k: int, out: Path,
                      chunk_pulses: int = CHUNK_PULSES) -> int:
    """Line k as ``out/strips/line_NNN.laz``, simulated and written one chunk at a time; returns its
    points. Random numbers per (seed, line, chunk): any line can be written alone, in any order."""
    line = plan.lines[k]
    path = out / "strips" / f"line_{line.number:03d}.laz"
    offsets = np.floor(to_crs(plan.scene.origin_ecef[None], plan.crs)[0] / 1000.0) * 1000.0
    n = plan.pulses(k)
    with LasChunkWriter(path, plan.crs, offsets, force=True) as writer:
        writer.header.creation_date = SIMULATION_DATE
        for c, first in enumerate(range(0, n, chunk_pulses)):
            rng = np.random.default_rng([plan.config.seed, 32, k, c])
            chunk = simulate_chunk(plan, k, first, min(chunk_pulses, n - first), rng)
            xyz = tiled_to_crs(chunk["ecef"], chunk["true_enu"][:, :2], plan.crs)
            writer.write_record(las_record(writer.header, xyz, chunk, line.number))
    return n


def _write_lines(args) -> int:
    """A worker's lines (a process of :func:`simulate_large_survey`)."""
    plan, lines, out, chunk_pulses = args
    return sum(write_large_strip(plan, k, out, chunk_pulses) for k in lines)


def simulate_large_survey(cfg: SurveyConfig, out: str | Path, ground: FacetGround | None = None,
                          workers: int = 1, chunk_pulses: int = CHUNK_PULSES,
                          progress: Callable[[str, int, int], None] | None = None) -> SurveyResult:
    """Simulate ``cfg`` over the closed-form ground into ``out`` (strips/line_NNN.laz, sbet.out,
    smrmsg.out, sensor.toml, truth.json; existing files replaced), the strips written by
    ``workers`` processes. Returns the result (no points held: ``streamed_points``).

    >>> import tempfile, calidar
    >>> from calidar.sim.large_survey import simulate_large_survey
    >>> cfg = calidar.survey_config("airborne", seed=1, density=0.05,
    ...                             errors={"boresight_roll": 1e-3})
    >>> res = simulate_large_survey(cfg, Path(tempfile.mkdtemp()) / "sim")
    >>> res.n_points > 10_000, res.truth.boresight_roll
    (True, 0.001)
    """
    out = Path(out)
    plan = plan_large_survey(cfg, ground)
    (out / "strips").mkdir(parents=True, exist_ok=True)
    workers = max(1, min(workers, len(plan.lines)))
    order = sorted(range(len(plan.lines)), key=plan.pulses, reverse=True)
    shares = [order[w::workers] for w in range(workers)]
    if workers == 1:
        points = _write_lines((plan, order, out, chunk_pulses))
    else:
        with ProcessPoolExecutor(workers) as pool:
            points = sum(pool.map(_write_lines, [(plan, s, out, chunk_pulses) for s in shares]))
    if progress:
        progress("simulating lines", len(plan.lines), len(plan.lines))
    res = plan.result(points)
    res.write(out, force=True)  # sbet.out, smrmsg.out, sensor.toml, truth.json (no strips held)
    return res
