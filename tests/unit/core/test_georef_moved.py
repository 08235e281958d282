"""to_crs_moved: the CRS coordinates of points moved by metres, from a Jacobian per tile."""

from __future__ import annotations

import numpy as np
import pytest

from calidar import georef


@pytest.mark.parametrize("crs, span", [("EPSG:32611", 3000.0), ("EPSG:4979", 0.03)])
def test_moved_points_match_the_full_transform(crs, span):
    rng = np.random.default_rng(3)
    base = np.array([500000.0, 4100000.0, 1500.0]) if crs == "EPSG:32611" else np.array([-117.0, 37.0, 1500.0])
    xyz = base + rng.uniform(-span, span, (20000, 3)) * [1, 1, 0]
    ecef = georef.from_crs(xyz, crs)
    moved = ecef + rng.normal(0.0, 2.0, ecef.shape)  # a few metres, as a new mounting moves points
    got = georef.to_crs_moved(moved, ecef, xyz, crs)
    want = georef.to_crs(moved, crs)
    back = georef.from_crs(got, crs)  # compare in metres whatever the CRS units
    assert np.max(np.linalg.norm(back - georef.from_crs(want, crs), axis=1)) < 1e-4
    assert np.max(np.linalg.norm(back - moved, axis=1)) < 1e-4
    assert np.max(np.linalg.norm(moved - ecef, axis=1)) > 5.0  # the moves are not trivial
