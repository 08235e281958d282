"""USGS Lidar Base Specification swath checks: known answers (issue 28)."""

from __future__ import annotations

import numpy as np
import pytest

from calidar.strips.cell_moments import CellMoments
from calidar.strips.quality import PairQuality
from calidar.strips.usgs import common_level, expected_range, levels_met, line_precision, summary, usgs_checks

#: the specification's table 2 as read for this test (m): QL → intraswath, interswath RMSDz, max |dz|
TABLE = {"QL0": (0.03, 0.04, 0.08), "QL1": (0.06, 0.08, 0.16), "QL2": (0.06, 0.08, 0.16), "QL3": (0.12, 0.16, 0.32)}


def _met(value, column):
    return [ql for ql, t in TABLE.items() if value <= t[column]]


@pytest.mark.parametrize("value", [0.01, 0.03, 0.045, 0.06, 0.07, 0.11, 0.15, 0.2, 0.33])
def test_levels_met_follow_the_table(value):
    for k, check in enumerate(("intraswath max diff", "interswath RMSDz", "interswath max |dz|")):
        assert levels_met(value, check) == _met(value, k)
    assert levels_met(None, "interswath RMSDz") == []


def test_expected_range_of_normal_samples_matches_the_published_constants():
    # d2 of statistical process control (ASTM E2587, from Tippett 1925)
    for n, d2 in ((2, 1.128), (5, 2.326), (10, 3.078), (25, 3.931)):
        assert expected_range(np.array([n]))[0] == pytest.approx(d2, abs=0.001)


def _cells(rng, slope_deg, noise, n_cells, per_cell=30, cell=2.0, x0=0.0):
    """Points of ``n_cells`` cells of ``cell`` m on a plane of the slope, with normal height noise;
    also the true max diff of 4 of each cell's points (a sample area of the specification)."""
    pts, ranges = [], []
    g = np.tan(np.radians(slope_deg))
    for k in range(n_cells):
        n = per_cell + k % 7
        xy = rng.uniform(0, cell, (n, 2)) + [x0 + cell * (k % 50), cell * (k // 50)]
        e = rng.normal(0, noise, n)
        pts.append(np.column_stack([xy, 100 + g * xy[:, 0] + e]))
        ranges.append(np.ptp(e[:4]))
    return np.vstack(pts), np.array(ranges)


def test_line_precision_estimates_the_cells_max_diff_from_their_moments():
    rng = np.random.default_rng(1)
    smooth, ranges = _cells(rng, 4.0, 0.012, 1500)
    trees, _ = _cells(rng, 0.0, 0.4, 300, x0=200.0)  # rough: not smooth
    steep, _ = _cells(rng, 30.0, 0.012, 300, x0=400.0)  # steeper than 10°
    m = CellMoments.of_points(np.vstack([smooth, trees, steep]), 2.0)
    p = line_precision(7, m)
    assert p.line == 7 and p.n_cells == 1500
    assert p.sigma_m == pytest.approx(0.012, rel=0.03)
    assert p.max_diff_m == pytest.approx(np.sqrt(np.mean(ranges**2)), rel=0.04)  # the points' real max diffs


def _pair(a, b, cells, rms, worst):
    return PairQuality(a, b, cells, 0.0, rms, worst, 0.0)


def test_checks_pool_the_pairs_and_name_the_level():
    lines = [line_precision(1, CellMoments.of_points(_cells(np.random.default_rng(2), 2.0, 0.008, 400)[0], 2.0))]
    pairs = [_pair(1, 2, 1000, 0.05, 0.12), _pair(2, 3, 3000, 0.03, 0.07), _pair(1, 3, 0, None, None)]
    intra, rmsdz, worst = usgs_checks(pairs, lines)
    pooled = np.sqrt((1000 * 0.05**2 + 3000 * 0.03**2) / 4000)  # 0.0361 m
    assert rmsdz.value_m == pytest.approx(pooled) and rmsdz.n_cells == 4000
    assert rmsdz.levels_met == _met(pooled, 1) == ["QL0", "QL1", "QL2", "QL3"] and rmsdz.status == "meets QL0"
    assert worst.value_m == 0.12 and worst.levels_met == ["QL1", "QL2", "QL3"] and worst.status == "meets QL1"
    assert intra.value_m == lines[0].max_diff_m and intra.levels_met == _met(intra.value_m, 0)
    common = [ql for ql in TABLE if ql in _met(intra.value_m, 0) and ql in _met(0.12, 2)][0]
    assert summary([intra, rmsdz, worst]) == f"USGS swath checks: all measured checks meet {common}"
    assert common_level([intra, rmsdz, worst]) == common
    bad = usgs_checks([_pair(1, 2, 10, 0.2, 0.5)], [])
    assert bad[0].status == "not measured" and bad[1].status == bad[2].status == "meets no quality level"
    assert "not all meet any" in summary(bad) and common_level(bad) is None
