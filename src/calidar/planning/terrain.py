"""What the planned lines will see: flat ground, a DEM, or the simulator's built-in scene.

Each terrain answers one question, :meth:`sample`: at horizontal positions (m, the plan's
frame), the surface height and which surface it is (−1 terrain, ≥ 0 a roof plane of the
scene, :data:`VEGETATION` under a tree crown: no tie plane there, NaN height outside).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np


TERRAIN, VEGETATION = -1, -3


@dataclass(frozen=True)
class FlatTerrain:
    """Level ground at ``height_m`` everywhere."""

    height_m: float = 0.0
    name: str = "flat"

    def sample(self, x, y) -> tuple[np.ndarray, np.ndarray]:
        x = np.asarray(x, float)
        return np.full(x.shape, self.height_m), np.full(x.shape, TERRAIN, np.int64)

    def mean_height(self, x, y) -> float:
        return self.height_m

    def visible(self, origins, targets) -> np.ndarray:
        """Whether each target (n, 3) is seen from its origin (n, 3): on open ground, always."""
        return np.ones(len(targets), bool)


@dataclass(frozen=True)
class GridTerrain:
    """Heights on a regular grid (a DEM): node (i, j) at x0 + j·dx, y0 − i·dy (north-up rows)."""

    heights: np.ndarray  #: (ny, nx) m, NaN = no data
    x0: float
    y0: float
    dx: float
    dy: float
    name: str = "dem"

    def sample(self, x, y) -> tuple[np.ndarray, np.ndarray]:
        """Bilinear heights; NaN outside the grid or next to no-data."""
        x, y = np.asarray(x, float), np.asarray(y, float)
        ny, nx = self.heights.shape
        u, v = (x - self.x0) / self.dx, (self.y0 - y) / self.dy
        inside = (u >= 0) & (u <= nx - 1) & (v >= 0) & (v <= ny - 1)
        j = np.clip(np.floor(u).astype(np.int64), 0, max(nx - 2, 0))
        i = np.clip(np.floor(v).astype(np.int64), 0, max(ny - 2, 0))
        fu, fv = np.clip(u - j, 0, 1), np.clip(v - i, 0, 1)
        h = self.heights
        j1, i1 = np.minimum(j + 1, nx - 1), np.minimum(i + 1, ny - 1)
        # bilinear: the row i's two corners, then the row i + 1's (the sum's order kept)
        row_i = h[i, j] * (1 - fu) * (1 - fv) + h[i, j1] * fu * (1 - fv)
        z = row_i + h[i1, j] * (1 - fu) * fv + h[i1, j1] * fu * fv
        z = np.where(inside, z, np.nan)
        return z, np.full(z.shape, TERRAIN, np.int64)

    def mean_height(self, x, y) -> float:
        z, _ = self.sample(x, y)
        return float(np.nanmean(z)) if np.any(np.isfinite(z)) else float(np.nanmean(self.heights))

    def visible(self, origins, targets) -> np.ndarray:
        """Whether each target is seen from its origin (a DEM holds no occluders at the planned
        heights)."""
        return np.ones(len(targets), bool)


@dataclass(frozen=True)
class SceneTerrain:
    """The simulator's scene (:mod:`calidar.sim.scene`): its terrain, roof planes and tree
    crowns."""

    scene: object  #: calidar.sim.scene.Scene
    name: str = "scene"

    def sample(self, x, y) -> tuple[np.ndarray, np.ndarray]:
        """Vertical rays from above: the first solid surface; under a crown: VEGETATION."""
        from calidar.sim.raycast import cast

        x, y = np.asarray(x, float), np.asarray(y, float)
        shape = x.shape
        x, y = x.ravel(), y.ravel()
        top = float(np.nanmax(self.scene.heights)) + 200.0
        o = np.stack([x, y, np.full(x.size, top)], axis=1)
        d = np.tile([0.0, 0.0, -1.0], (x.size, 1))
        # u = 1: a ray through a crown returns from it
        hits = cast(self.scene, o, d, np.ones(x.size))
        z = np.where(np.isfinite(hits.t_solid), top - hits.t_solid, np.nan)
        surface = np.where(hits.surface >= 0, hits.surface, TERRAIN).astype(np.int64)
        surface = np.where(np.isfinite(hits.t_vegetation), VEGETATION, surface)
        return z.reshape(shape), surface.reshape(shape)

    def mean_height(self, x, y) -> float:
        return float(np.mean(self.scene.heights))

    def visible(self, origins, targets) -> np.ndarray:
        """Whether each target (n, 3) is what a beam from its origin (n, 3) hits: no wall, roof or
        tree crown in between (shadows behind buildings and trees hold no tie planes)."""
        from calidar.sim.raycast import cast

        d = targets - origins
        dist = np.linalg.norm(d, axis=1)
        # u = 1: any crown returns
        hits = cast(self.scene, origins, d / dist[:, None], np.ones(len(targets)))
        return (np.abs(hits.t_solid - dist) < 0.3) & ~np.isfinite(hits.t_vegetation)


def scene_terrain(cfg) -> SceneTerrain:
    """The scene the simulator builds for the survey configuration ``cfg`` (a
    :class:`calidar.sim.survey.SurveyConfig`: its scene, origin and seed, as
    ``simulate_survey``)."""
    from calidar.sim.scene import build_scene, scene_seed

    lat0, lon0, h0 = cfg.origin_deg
    seed = scene_seed(cfg.seed, cfg.scene_seed)
    scene = build_scene(cfg.scene, seed, np.radians(lat0), np.radians(lon0), h0)
    return SceneTerrain(scene, f"scene:{cfg.preset}:{seed}")
