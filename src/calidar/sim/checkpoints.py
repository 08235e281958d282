"""Surveyed checkpoints of a simulated survey, with their truth.

The checkpoints stand where a surveyor would put them (ASPRS: open, flat or uniformly sloped
ground away from buildings, ≥ 10 m apart; vegetated ones under tree crowns): on the scene's
true terrain (:meth:`calidar.sim.scene.Scene.terrain_height`), inside the flown area, then
"surveyed" with a normal error of the stated σ. ``truth.json`` gets, per checkpoint, its true
height, the survey error and the delivered data's own vertical error there (the mean of the
ground points' height minus the true terrain, within ``TRUTH_RADIUS_M``), and over the open
ground the RMS error of a TIN of those points (:func:`data_truth`): what ``calidar accuracy``
should find, RMSE_V(data)² ≈ that² + σ².
"""

from __future__ import annotations

import json
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from calidar.errors import InputError
from calidar.sim.scene import CLASS_GROUND

MIN_SEPARATION_M = 10.0  #: checkpoints at least this far apart
BUILDING_CLEARANCE_M = 4.0  #: open ground keeps this far from a building's footprint
CROWN_CLEARANCE_M = 2.0  #: open ground keeps this far from a crown's edge
#: a vegetated checkpoint lies within this fraction of a crown's radius from its centre
UNDER_CROWN = 0.6
#: terrain within SMOOTH_RADIUS_M of a checkpoint departs from a plane by ≤ this (RMS)
SMOOTH_RMS_M = 0.015
SMOOTH_RADIUS_M = 1.5
MAX_SLOPE = 0.25  #: rise over run: uniformly sloped, not steep
#: fraction of the scene's width and length kept clear at its edges (swath ends, turns)
MARGIN = 0.12
VEGETATED_SHARE = 0.25  #: of the checkpoints, when the scene has trees
TRUTH_RADIUS_M = 1.0
MAX_CHECKPOINTS = 1000
MAX_SIGMA_M = 1.0


@dataclass(eq=False)
class SimulatedCheckpoints:
    """Checkpoints in the survey's CRS: as surveyed (``xyz``) and true (``xyz_true``)."""

    ids: list[str]
    xyz: np.ndarray  #: (N, 3) surveyed: true + survey error in z
    xyz_true: np.ndarray  #: (N, 3)
    vegetated: np.ndarray  #: (N,) bool
    sigma_m: float
    #: (N,) the delivered ground points' mean vertical error near each (NaN: none)
    data_dz_m: np.ndarray
    #: RMS vertical error of a TIN of the delivered ground points on open ground (data_truth)
    open_rmse_m: float

    def truth_dict(self) -> dict:
        """truth.json's "checkpoints": each one's true height, survey error and the data's error
        there (m)."""
        points = [{"id": i, "x": float(p[0]), "y": float(p[1]), "z_true": float(p[2]),
                   "survey_error_m": float(s[2] - p[2]), "vegetated": bool(v),
                   "data_dz_m": None if not np.isfinite(d) else float(d)}
                  for i, p, s, v, d in zip(self.ids, self.xyz_true, self.xyz, self.vegetated,
                                           self.data_dz_m)]
        share = float(self.vegetated.mean()) if len(self.ids) else 0.0
        return {"sigma_m": self.sigma_m, "vegetated_share": share,
                "open_ground_tin_rmse_m": self.open_rmse_m, "points": points}

    def write(self, out_dir: str | Path, force: bool = True) -> Path:
        """checkpoints.csv into ``out_dir``, and the truth under "checkpoints" in its truth.json."""
        from calidar.io.checkpoints import write_checkpoints
        from calidar.outputs import write_text_atomic

        out = Path(out_dir)
        sigma = np.full(len(self.ids), self.sigma_m)
        write_checkpoints(out / "checkpoints.csv", self.ids, self.xyz, self.vegetated, sigma,
                          f"simulated checkpoints, survey σ {self.sigma_m} m", force=force)
        truth = out / "truth.json"
        doc = json.loads(truth.read_text(encoding="utf-8")) if truth.exists() else {}
        doc["checkpoints"] = self.truth_dict()
        write_text_atomic(truth, json.dumps(doc, indent=2) + "\n", force=True)
        return out / "checkpoints.csv"


def _smooth(scene, x, y) -> np.ndarray:
    """Where the terrain around (x, y) is a plane within SMOOTH_RMS_M and not steeper than
    MAX_SLOPE."""
    g = np.linspace(-SMOOTH_RADIUS_M, SMOOTH_RADIUS_M, 5)
    dx, dy = (a.ravel() for a in np.meshgrid(g, g))
    h = scene.terrain_height(x[:, None] + dx, y[:, None] + dy)  # (N, 25)
    a = np.c_[np.ones_like(dx), dx, dy]
    coef, *_ = np.linalg.lstsq(a, np.nan_to_num(h).T, rcond=None)
    rms = np.sqrt(np.mean((a @ coef - np.nan_to_num(h).T) ** 2, axis=0))
    gentle = np.hypot(coef[1], coef[2]) <= MAX_SLOPE
    return np.isfinite(h).all(axis=1) & (rms <= SMOOTH_RMS_M) & gentle


def _clear_of_buildings(scene, x, y) -> np.ndarray:
    """Where (x, y) lies outside every building's box grown by BUILDING_CLEARANCE_M."""
    ok = np.ones(x.size, bool)
    for b in np.unique(scene.plane_building):
        planes = np.flatnonzero(scene.plane_building == b)
        v = scene.tri[np.isin(scene.tri_plane, planes)].reshape(-1, 3)
        lo = v[:, :2].min(axis=0) - BUILDING_CLEARANCE_M
        hi = v[:, :2].max(axis=0) + BUILDING_CLEARANCE_M
        ok &= ~((x >= lo[0]) & (x <= hi[0]) & (y >= lo[1]) & (y <= hi[1]))
    return ok


def _crown_distance(scene, x, y) -> tuple[np.ndarray, np.ndarray]:
    """(distance to the nearest crown's centre over its radius, distance beyond its edge) per
    point."""
    if scene.tree_radius.size == 0:
        return np.full(x.size, np.inf), np.full(x.size, np.inf)
    centre = scene.tree_center
    d = np.hypot(x[:, None] - centre[None, :, 0], y[:, None] - centre[None, :, 1])
    return (d / scene.tree_radius).min(axis=1), (d - scene.tree_radius).min(axis=1)


def _pick(x, y, count: int, taken: list) -> list[int]:
    """Greedily up to ``count`` of the candidates, each MIN_SEPARATION_M from the others and
    ``taken``."""
    chosen = []
    for i in range(x.size):
        if len(chosen) == count:
            break
        if all(np.hypot(x[i] - px, y[i] - py) >= MIN_SEPARATION_M for px, py in taken):
            taken.append((x[i], y[i]))
            chosen.append(i)
    return chosen


def _candidates(scene, count: int, rng) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """``count`` random places inside the flown area; masks of those fit for an open and a vegetated
    checkpoint."""
    x0, x1, y0, y1 = scene.extent
    mx, my = MARGIN * (x1 - x0), MARGIN * (y1 - y0)
    cand = rng.uniform([x0 + mx, y0 + my], [x1 - mx, y1 - my], (count, 2))
    x, y = cand[:, 0], cand[:, 1]
    ok = _smooth(scene, x, y) & _clear_of_buildings(scene, x, y)
    ratio, beyond = _crown_distance(scene, x, y)
    return cand, ok & (beyond >= CROWN_CLEARANCE_M), ok & (ratio <= UNDER_CROWN)


def place_checkpoints(scene, n: int, rng,
                      vegetated_share: float = VEGETATED_SHARE) -> tuple[np.ndarray, np.ndarray]:
    """ENU (x, y) (N, 2) of ``n`` checkpoints and which are vegetated; an error when the scene has
    no room."""
    cand, open_ok, veg_ok = _candidates(scene, max(50 * n, 10_000), rng)
    x, y = cand[:, 0], cand[:, 1]
    n_veg = int(round(n * vegetated_share)) if scene.tree_radius.size else 0
    taken: list = []
    veg = np.flatnonzero(veg_ok)
    veg = veg[_pick(x[veg], y[veg], n_veg, taken)]
    open_ = np.flatnonzero(open_ok)
    open_ = open_[_pick(x[open_], y[open_], n - veg.size, taken)]
    if open_.size + veg.size < n:
        raise InputError(None, "--checkpoints",
                         f"room for {open_.size + veg.size} checkpoints {MIN_SEPARATION_M:g} m "
                         "apart on open, smooth ground and under trees in this scene; expected ≤ "
                         "that many")
    idx = np.r_[open_, veg]
    return cand[idx], np.r_[np.zeros(open_.size, bool), np.ones(veg.size, bool)]


def vertical_errors(scene, ecef: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """ENU x, y (N, 2) of points (ECEF) and their height above the true terrain there (N,) m."""
    enu = scene.ecef_to_enu(ecef)
    return enu[:, :2], enu[:, 2] - scene.terrain_height(enu[:, 0], enu[:, 1])


def ground_errors(scene, strips) -> tuple[np.ndarray, np.ndarray]:
    """ENU x, y (K, 2) and vertical errors (K,) of the ground points (class 2) of ``strips``
    (objects with ``ecef`` and ``classification``), finite ones only."""
    xy, e = [], []
    for s in strips:
        pxy, pe = vertical_errors(scene, s.ecef[s.classification == CLASS_GROUND])
        xy.append(pxy[np.isfinite(pe)])
        e.append(pe[np.isfinite(pe)])
    return np.concatenate(xy), np.concatenate(e)


def data_truth(scene, strips, cp_xy: np.ndarray, rng=None,
               places: int = 2000) -> tuple[np.ndarray, np.ndarray, float]:
    """What the delivered ``strips`` should show at checkpoints:

    - per checkpoint (``cp_xy``, ENU) the mean vertical error of the ground points within
      TRUTH_RADIUS_M (NaN: none) and their standard deviation about it: a TIN there gives the
      mean up to a noise of about that deviation / √2 (overlapping strips that disagree, noise);
    - over ``places`` random places fit for an open checkpoint, the RMS error a TIN surface has
      there: sqrt(S² + v/2), S² the mean square of the local mean errors and v the mean local
      variance of the points about it (a linear interpolation in a triangle at a uniformly random
      place weights its corners' independent errors by Σw² = 1/2 on average).
    """
    from scipy.spatial import cKDTree

    xy, e = ground_errors(scene, strips)
    tree = cKDTree(xy)
    around = tree.query_ball_point(cp_xy, TRUTH_RADIUS_M)
    dz = np.array([e[k].mean() if len(k) else np.nan for k in around])
    sd = np.array([e[k].std(ddof=1) if len(k) > 1 else np.nan for k in around])
    rng = np.random.default_rng(0) if rng is None else rng
    cand, open_ok, _ = _candidates(scene, places, rng)
    near = [k for k in tree.query_ball_point(cand[open_ok], TRUTH_RADIUS_M) if len(k) >= 3]
    mean_sq = np.mean([e[k].mean() ** 2 for k in near])
    var = np.mean([e[k].var(ddof=1) for k in near])
    return dz, sd, float(np.sqrt(mean_sq + var / 2.0))


def check_checkpoint_options(n: int, sigma_m: float) -> None:
    """``--checkpoints`` in [0, MAX_CHECKPOINTS] and ``--checkpoint-sigma`` in [0, MAX_SIGMA_M]
    m."""
    from calidar.validate import integer, number

    integer(n, "--checkpoints", 0, MAX_CHECKPOINTS)
    number(sigma_m, "--checkpoint-sigma", 0.0, MAX_SIGMA_M, "m")


def simulate_checkpoints(result, n: int, sigma_m: float = 0.02, seed: int = 0,
                         vegetated_share: float = VEGETATED_SHARE) -> SimulatedCheckpoints:
    """``n`` checkpoints for a :class:`calidar.sim.survey.SurveyResult` (its strips in memory),
    surveyed with σ ``sigma_m``."""
    from calidar.crs import to_crs

    check_checkpoint_options(n, sigma_m)
    if not result.strips:
        raise InputError(None, "--checkpoints",
                         "the strips were handed over as simulated; expected them in memory")
    rng = np.random.default_rng(np.random.SeedSequence([int(seed), 2028]))
    scene = result.scene
    xy, veg = place_checkpoints(scene, n, rng, vegetated_share)
    enu = np.c_[xy, scene.terrain_height(xy[:, 0], xy[:, 1])]
    true = to_crs(scene.enu_to_ecef(enu), result.crs)
    surveyed = true.copy()
    surveyed[:, 2] += rng.normal(0.0, sigma_m, len(xy)) if sigma_m > 0 else 0.0
    dz, _, open_rmse = data_truth(scene, result.strips, xy, rng)
    ids = [f"{'VVA' if v else 'NVA'}{k + 1:03d}" for k, v in enumerate(veg)]
    return SimulatedCheckpoints(ids, surveyed, true, veg, float(sigma_m), dz, open_rmse)
