"""Ray casting: exact hits on the scene's surfaces, correct occlusion, every roof type present."""

import numpy as np
import pytest

from calidar.sim.raycast import SURFACE_NONE, SURFACE_TERRAIN, cast
from calidar.sim.scene import ROOF_TYPES, SceneSpec, build_scene


@pytest.fixture(scope="module")
def scene():
    return build_scene(SceneSpec(width_m=200.0, length_m=200.0, vegetation_fraction=0.15), 3, np.radians(47.0),
                       np.radians(8.0), 450.0)


def _rays(n, seed, height=80.0, half=0.5):
    rng = np.random.default_rng(seed)
    o = np.column_stack([rng.uniform(-40, 40, n), rng.uniform(-40, 40, n), np.full(n, height)])
    th = rng.uniform(-half, half, n)
    d = np.column_stack([0.1 * rng.normal(size=n), np.sin(th), -np.cos(th)])
    return o, d / np.linalg.norm(d, axis=1)[:, None], 1.0 - rng.random(n)


def test_scene_has_all_roof_types_and_walls(scene):
    assert set(scene.roof_type) == set(ROOF_TYPES)
    walls = ~scene.plane_is_roof
    assert np.allclose(scene.plane_normal[walls, 2], 0.0, atol=1e-12)  # vertical walls
    roofs = scene.plane_normal[scene.plane_is_roof]
    slopes = np.degrees(np.arccos(roofs[:, 2]))
    assert slopes.min() < 1e-6 and slopes.max() > 30  # flat and steep roofs
    aspects = np.degrees(np.arctan2(roofs[:, 0], roofs[:, 1]))[slopes > 1]
    assert np.ptp(aspects) > 300  # faces looking in all directions


def test_hits_lie_exactly_on_surfaces(scene):
    o, d, u = _rays(200_000, 1)
    h = cast(scene, o, d, u)
    assert np.all(h.surface != SURFACE_NONE)  # every ray from inside the scene hits something
    p = o + h.t_solid[:, None] * d
    terr = h.surface == SURFACE_TERRAIN
    assert np.max(np.abs(p[terr, 2] - scene.terrain_height(p[terr, 0], p[terr, 1]))) < 1e-9
    bld = h.surface >= 0
    assert bld.sum() > 10_000 and np.max(np.abs(scene.plane_distance(p[bld], h.surface[bld]))) < 1e-9
    assert np.any(~scene.plane_is_roof[h.surface[bld]])  # walls are hit by slanted rays
    veg = np.isfinite(h.t_vegetation)
    assert 0.02 < veg.mean() < 0.3 and np.all(h.t_vegetation[veg] < h.t_solid[veg])
    pv = o[veg] + h.t_vegetation[veg, None] * d[veg]
    inside = np.min(np.linalg.norm(pv[:500, None, :] - scene.tree_center[None], axis=2) - scene.tree_radius, axis=1)
    assert np.all(inside <= 1e-9)  # crown returns lie inside a crown


def test_nearest_hit_matches_brute_force(scene):
    o, d, u = _rays(2000, 2)
    h = cast(scene, o, d, u)
    v0 = scene.tri[:, 0]
    e1, e2 = scene.tri[:, 1] - v0, scene.tri[:, 2] - v0
    for k in range(len(o)):
        p = np.cross(d[k], e2)
        det = np.einsum("ij,ij->i", e1, p)
        s = o[k] - v0
        uu = np.einsum("ij,ij->i", s, p) / det
        q = np.cross(s, e1)
        vv = q @ d[k] / det
        t = np.einsum("ij,ij->i", e2, q) / det
        ok = (uu >= 0) & (uu <= 1) & (vv >= 0) & (uu + vv <= 1) & (t > 0)
        t_best = t[ok].min() if ok.any() else np.inf
        assert h.t_solid[k] <= t_best + 1e-9
        if h.surface[k] >= 0:
            assert h.t_solid[k] == pytest.approx(t_best, abs=1e-9)


def test_upward_and_outside_rays_miss(scene):
    o = np.array([[0.0, 0.0, 100.0], [1e4, 0.0, 100.0]])
    d = np.array([[0.0, 0.0, 1.0], [0.0, 0.0, -1.0]])
    h = cast(scene, o, d, np.ones(2))
    assert np.all(h.surface == SURFACE_NONE) and np.all(np.isinf(h.t_solid))
