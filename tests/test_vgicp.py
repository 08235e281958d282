"""VGICP correspondences on synthetic strips with a known rigid misalignment.

The scene (rolling terrain with gable-roofed buildings) is sampled twice, independently,
with 2 cm noise; strip b is then moved by a known small rotation + translation. The
registration must recover that transform, the correspondences must bring the residuals
down to the noise once the truth is applied, and the iterated adjustment (the engine of
calidar.adjust driven by ``iterate_vgicp``) must recover the transform from a 0.5° start.
"""

from __future__ import annotations

import numpy as np
import pytest

from calidar.adjust import Parameter, ParameterSet, solve
from calidar.errors import CalibrationError
from calidar.frames import rpy_to_matrix
from calidar.strips.correspond import Correspondences
from calidar.strips.vgicp import (PairSkipped, VgicpSettings, iterate_vgicp, match_pair_vgicp,
                                  match_pairs_vgicp, overlap_masks, register)

NOISE_M = 0.02
HALF_M = 100.0
BUILDINGS = [(-60, -40, 20, 30, 8, 0.3), (40, 30, 25, 18, 10, -0.5), (10, -70, 15, 15, 6, 1.0),
             (-40, 60, 30, 12, 7, 0.0), (70, -50, 18, 26, 9, 0.8)]  # x, y, width, length, height m, azimuth rad


def surface(x, y):
    """Heights (m) of rolling terrain with gable roofs (slope 0.6) at (x, y) m."""
    z = 3.0 * np.sin(x / 40.0) * np.cos(y / 55.0) + 0.02 * x
    for cx, cy, w, length, h, az in BUILDINGS:
        u = (x - cx) * np.cos(az) + (y - cy) * np.sin(az)
        v = -(x - cx) * np.sin(az) + (y - cy) * np.cos(az)
        inside = (np.abs(u) < w / 2) & (np.abs(v) < length / 2)
        z = np.where(inside, z + h + 0.6 * (w / 2 - np.abs(u)), z)
    return z


def sample(n, rng, x_range=(-HALF_M, HALF_M), vegetation=0.0):
    """n points (m) of the scene with NOISE_M noise; a fraction ``vegetation`` of them are
    clutter scattered 0.5–15 m above the ground."""
    x = rng.uniform(*x_range, n)
    y = rng.uniform(-HALF_M, HALF_M, n)
    z = surface(x, y) + rng.normal(0.0, NOISE_M, n)
    veg = rng.random(n) < vegetation
    z[veg] += rng.uniform(0.5, 15.0, veg.sum())
    return np.column_stack([x, y, z])


ROT_TRUE = np.radians([0.3, -0.2, 0.5])  # roll, pitch, heading of the disturbance
SHIFT_TRUE = np.array([0.8, -0.5, 0.3])  # m
CENTER = np.array([0.0, 0.0, 5.0])


def disturb(p, rot=ROT_TRUE, shift=SHIFT_TRUE):
    """Move points (m) by R(rot) about CENTER, then by shift."""
    return (p - CENTER) @ rpy_to_matrix(*rot).T + CENTER + shift


def undo(p, rot, shift):
    """Inverse of :func:`disturb`."""
    return (p - CENTER - shift) @ rpy_to_matrix(*rot) + CENTER


@pytest.fixture(scope="module")
def strips():
    rng = np.random.default_rng(7)
    a = sample(60_000, rng)
    b = disturb(sample(60_000, rng))
    return a, b


@pytest.mark.parametrize("kind", ["point_to_plane", "point_to_point"])
def test_correspondences_bring_residuals_to_noise(strips, kind):
    a, b = strips
    c = match_pair_vgicp(1, a, 2, b, VgicpSettings(kind=kind, max_pairs=1500))
    assert isinstance(c, Correspondences) and c.method == "vgicp" and (c.strip_a, c.strip_b) == (1, 2)
    assert 300 <= c.n_obs <= 1500
    for m in (c.A, c.B):  # one 1.0 per row: point pairs
        assert np.all(np.diff(m.indptr) == 1) and np.all(m.data == 1.0)
    fixed = undo(b, ROT_TRUE, SHIFT_TRUE)
    before, after = c.residuals(a, b), c.residuals(a, fixed)
    if kind == "point_to_plane":
        assert c.normal is not None and np.allclose(np.linalg.norm(c.normal, axis=1), 1.0)
        # two noisy points along the normal: σ = √2 · 2 cm
        assert np.sqrt(np.mean(after**2)) < 1.5 * np.sqrt(2) * NOISE_M
        assert np.sqrt(np.mean(before**2)) > 10 * NOISE_M
    else:
        assert c.normal is None and after.size == 3 * c.n_obs
        d = np.linalg.norm(after.reshape(-1, 3), axis=1)
        # the pair distance is the sampling gap: median nearest-neighbour distance of a
        # Poisson sampling of density λ = 1.5 points/m² is √(ln 2 / (π λ)) = 0.38 m
        assert np.median(d) < np.sqrt(np.log(2) / (np.pi * 1.5))
        assert np.median(np.linalg.norm(before.reshape(-1, 3), axis=1)) > 2 * np.median(d)


def test_pairs_are_spread_over_the_overlap(strips):
    a, b = strips
    c = match_pair_vgicp(1, a, 2, b, VgicpSettings(max_pairs=400))
    xy = (c.A @ a)[:, :2]
    counts, _, _ = np.histogram2d(xy[:, 0], xy[:, 1], bins=4, range=[[-HALF_M, HALF_M]] * 2)
    assert c.n_obs <= 400 and counts.min() > 0  # every quarter-by-quarter block holds pairs


def test_registration_recovers_the_known_transform(strips):
    a, b = strips
    _, _, area = overlap_masks(a, b, 5.0)
    reg, _, _ = register(a - CENTER, b - CENTER, VgicpSettings(), area)
    R_true = rpy_to_matrix(*ROT_TRUE)
    angle = np.degrees(np.arccos(np.clip((np.trace(reg.T_ab[:3, :3] @ R_true) - 1) / 2, -1, 1)))
    t_true = -R_true.T @ SHIFT_TRUE  # T_ab = disturbance⁻¹ about CENTER
    assert angle < 0.02
    assert np.linalg.norm(reg.T_ab[:3, 3] - t_true) < 0.05


def test_vegetation_clutter_is_left_out_of_point_to_plane_pairs():
    rng = np.random.default_rng(3)
    a = sample(60_000, rng, vegetation=0.3)
    b = disturb(sample(60_000, rng, vegetation=0.3))
    c = match_pair_vgicp(1, a, 2, b, VgicpSettings(max_pairs=1500))
    after = c.residuals(a, undo(b, ROT_TRUE, SHIFT_TRUE))
    assert c.n_obs > 300
    assert np.median(np.abs(after)) < 1.5 * NOISE_M
    assert np.mean(np.abs(after) < 0.1) > 0.9


def test_small_overlap_is_skipped_with_a_warning_naming_the_pair():
    rng = np.random.default_rng(5)
    a = sample(30_000, rng, x_range=(-100, 0))
    b = sample(30_000, rng, x_range=(-1, 100))  # 1 m wide common band
    c = sample(30_000, rng, x_range=(-60, 40))
    with pytest.raises(PairSkipped, match="strips 4–9 skipped: too little overlap"):
        match_pair_vgicp(4, a, 9, b)
    usable, skipped = match_pairs_vgicp([(4, a, 9, b), (4, a, 6, c)])
    assert [(u.strip_a, u.strip_b) for u in usable] == [(4, 6)]
    assert len(skipped) == 1 and "strips 4–9" in skipped[0]
    with pytest.raises(CalibrationError, match="no usable strip pair.*strips 4–9"):
        match_pairs_vgicp([(4, a, 9, b)])


def test_too_few_correspondences_is_skipped():
    rng = np.random.default_rng(6)
    a = sample(20_000, rng)
    b = sample(20_000, rng) + [0.0, 0.0, 3.0]  # 3 m apart: beyond the pair distance
    settings = VgicpSettings(voxel_m=(1.0,), min_pairs=50)  # fine voxels only: cannot lock in
    with pytest.raises(PairSkipped, match="too few correspondences"):
        match_pair_vgicp(1, a, 2, b, settings)


NAMES = ("roll", "pitch", "heading", "tx", "ty", "tz")


def rigid_solve(a, b_moved, start_deg, kind, **options):
    """Recover the disturbance of b by the ICP-style outer loop over the adjustment engine
    (options: scheduler / workers of iterate_vgicp)."""
    def georeference(v):
        return {1: a, 2: undo(b_moved, [v["roll"], v["pitch"], v["heading"]], [v["tx"], v["ty"], v["tz"]])}

    def solve_once(corr, values):
        params = ParameterSet([Parameter(n, values[n], "rad" if i < 3 else "m") for i, n in enumerate(NAMES)])
        sigma = np.concatenate([np.full(c.n_obs * (3 if c.normal is None else 1), c.sigma_m) for c in corr])

        def residual(v):
            pts = georeference(v)
            return np.concatenate([c.residuals(pts[c.strip_a], pts[c.strip_b]) for c in corr])
        return solve(residual, params, sigma=sigma)

    start = dict(zip(NAMES, [*np.radians(start_deg), 0.0, 0.0, 0.0]))
    return iterate_vgicp(georeference, [(1, 2)], solve_once, start, VgicpSettings(kind=kind, max_pairs=1500),
                         **options)


@pytest.mark.parametrize("kind", ["point_to_plane", "point_to_point"])
def test_iterated_adjustment_converges_from_half_a_degree(kind):
    rng = np.random.default_rng(11)
    a = sample(60_000, rng)
    b = disturb(sample(60_000, rng))
    start = np.degrees(ROT_TRUE) + [0.5, -0.5, 0.5]  # 0.5° from the truth on each axis
    sol = rigid_solve(a, b, start, kind)
    rounds = sol.extra["vgicp_rounds"]
    assert len(rounds) >= 2 and rounds[-1]["mean_distance_m"] < rounds[0]["mean_distance_m"]
    assert abs(rounds[-1]["mean_distance_m"] - rounds[-2]["mean_distance_m"]) < 1e-3
    v, s = sol.values, sol.sigma
    for i, name in enumerate(NAMES):
        truth = ROT_TRUE[i] if i < 3 else SHIFT_TRUE[i - 3]
        err = v[name] - truth
        assert abs(err) < 3 * s[name], (name, err, s[name])
        # a 200 m × 200 m patch with five buildings: heading about the vertical is the weakest
        assert abs(err) < (np.radians(0.02) if i < 3 else 0.03), (name, err)
