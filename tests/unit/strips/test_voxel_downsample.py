"""calidar's voxel downsampling against small_gicp's ``voxelgrid_sampling``, the reference it
replaces: the same voxels in the same order, each mean to its last bits (bit for bit where the
sums are exact in any order); docs/validation.md, issue 32, twelfth session."""

from __future__ import annotations

import numpy as np
import pytest
import small_gicp

from calidar.strips.voxel_downsample import voxel_downsample


def _reference(points: np.ndarray, leaf: float) -> np.ndarray:
    return small_gicp.voxelgrid_sampling(points, leaf, 1).points()[:, :3]


def _surface(seed: int, n: int = 40_000) -> np.ndarray:
    """A rough terrain with a wall, about the origin (negative coordinates on every axis)."""
    rng = np.random.default_rng(seed)
    xy = rng.uniform(-400.0, 400.0, (n, 2))
    z = 3.0 * np.sin(xy[:, 0] / 37.0) + 0.05 * rng.standard_normal(n) - 1.0
    wall = np.abs(xy[:, 0] - 50.0) < 1.0
    z[wall] += rng.uniform(0.0, 12.0, wall.sum())
    return np.column_stack([xy, z])


@pytest.mark.parametrize("leaf", [4.4, 1.0, 0.25, 1 / 3])
def test_same_voxels_as_small_gicp(leaf):
    points = _surface(7)
    got, want = voxel_downsample(points, leaf), _reference(points, leaf)
    assert got.shape == want.shape and 1_000 < len(got) < len(points)
    # the same voxels in the same order, each mean summed in another order: the last bits only
    # (|coordinates| ≤ 400 m → ulp 6e-14 m)
    assert np.abs(got - want).max() <= 1e-12


def test_bit_for_bit_where_the_sums_are_exact():
    """Coordinates on a 1/8 m lattice within ±512 m: every partial sum is exact, so the order of
    the sum cannot matter, and the means must be small_gicp's to the bit — points on the voxels'
    faces included (the floor, not a truncation, for negative coordinates)."""
    rng = np.random.default_rng(11)
    points = rng.integers(-4096, 4096, (30_000, 3)).astype(np.float64) / 8.0
    points[:, 2] /= 16.0
    for leaf in (2.0, 0.5, 1.25):
        got, want = voxel_downsample(points, leaf), _reference(points, leaf)
        assert got.shape == want.shape
        assert np.array_equal(got, want)


def test_one_point_and_none():
    point = np.array([[-0.3, 2.7, -1e-9]])
    assert np.array_equal(voxel_downsample(point, 1.0), _reference(point, 1.0))
    assert voxel_downsample(np.empty((0, 3)), 1.0).shape == (0, 3)
