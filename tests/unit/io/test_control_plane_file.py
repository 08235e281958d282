"""Control-surface files (calidar.io.control_planes): read as written, the plane fitted with its
covariance against an independent computation, and every bad file named by file, line and field."""

from __future__ import annotations

import numpy as np
import pytest

from calidar.errors import InputError
from calidar.io.control_planes import (
    check_plane, fit_plane, is_plane_file, read_control_planes, write_control_planes,
)

ROOF = np.array([[0.0, 0.0, 10.0], [8.0, 0.0, 10.0], [8.0, 6.0, 13.0], [0.0, 6.0, 13.0]])  # slope 0.5 north


def _file(tmp_path, text: str, name="planes.csv"):
    p = tmp_path / name
    p.write_text(text)
    return p


def test_a_written_file_reads_back_and_is_told_from_a_point_file(tmp_path):
    xyz = np.vstack([ROOF, ROOF + [20.0, 0.0, 1.0]])
    p = write_control_planes(tmp_path / "c.csv", ["R1"] * 4 + ["R2"] * 4, xyz, np.full(8, 0.01), "two roofs")
    f = read_control_planes(p)
    assert f.planes() == ["R1", "R2"] and np.allclose(f.xyz, xyz, atol=5e-4) and list(f.lines) == list(range(3, 11))
    assert is_plane_file(p)
    assert not is_plane_file(_file(tmp_path, "id,x,y,z,sigma\nA,1,2,3,0.01\n", "points.csv"))


def test_the_plane_and_its_covariance_match_an_independent_fit():
    """Weighted least squares z = a + b·dx + c·dy about the weighted centroid; the height σ of a
    3-D σ on a slope s is σ·√(1 + s²) (the error is along the normal)."""
    rng = np.random.default_rng(0)
    sigma = np.array([0.01, 0.02, 0.01, 0.01])
    c, coef, cov = fit_plane(ROOF, sigma)
    assert np.allclose(coef[1:], [0.0, 0.5]) and coef[0] == pytest.approx(c[2])
    w = 1.0 / (sigma**2 * 1.25)
    X = np.c_[np.ones(4), ROOF[:, :2] - c[:2]]
    np.testing.assert_allclose(cov, np.linalg.inv(X.T @ (w[:, None] * X)), rtol=1e-9)
    # Monte-Carlo: 3-D errors of σ move the fitted height at the centroid as cov[0, 0] says
    heights = []
    for _ in range(4000):
        p = ROOF + rng.normal(0.0, 1.0, (4, 3)) * sigma[:, None]
        cc, cf, _ = fit_plane(p, sigma)
        heights.append(cf[0] + (c[:2] - cc[:2]) @ cf[1:] - c[2])  # the plane's height at the true centroid
    assert np.std(heights) == pytest.approx(np.sqrt(cov[0, 0]), rel=0.06)


@pytest.mark.parametrize("text, field, words", [
    ("plane,x,y,z\nR1,0,0,1\n", "sigma", ["line 1", "no sigma column"]),
    ("x,y,z,sigma,plane\nnan,0,1,0.01,R1\n", "x", ["line 2", "'nan'"]),
    ("plane,x,y,z,sigma\nR1,0,0,1,0\n", "sigma", ["line 2", "σ > 0"]),
    ("plane,x,y,z,sigma\nR1,0,0,1,0.01\nR1,5,0,1,0.01\n", "plane", ["line 2", "'R1' has 2 point(s)"]),
    ("plane,x,y,z,sigma\n,0,0,1,0.01\n", "plane", ["line 2", "empty"]),
    ("plane,x,y,z,sigma\n", None, ["no points"]),
    ("plane,x,y,z,sigma\nR1,0,0\n", None, ["line 2", "3 values"]),
])
def test_bad_files_name_the_line_and_the_field(tmp_path, text, field, words):
    with pytest.raises(InputError) as e:
        read_control_planes(_file(tmp_path, text))
    msg = str(e.value)
    assert "planes.csv" in msg and all(w in msg for w in words), msg
    if field:
        assert e.value.field == field


@pytest.mark.parametrize("xyz, field, words", [
    (np.array([[0.0, 0.0, 1.0], [5.0, 0.1, 1.0], [10.0, 0.0, 1.0]]), "x/y", ["lie along a line"]),
    (np.array([[0.0, 0.0, 0.0], [2.0, 0.0, 6.0], [0.0, 5.0, 0.0]]), "z", ["slopes 72°", "wall"]),
    (np.vstack([ROOF + [[0, 0, 0], [0, 0, 0], [0, 0, 0.2], [0, 0, 0]], [4.0, 3.0, 11.5]]), "z",
     ["line 4", "point 3 of plane 'R1'", "off the plane"]),  # the centre tells which corner is off
])
def test_points_that_make_no_plane_are_named(tmp_path, xyz, field, words):
    p = write_control_planes(tmp_path / "planes.csv", ["R1"] * len(xyz), xyz, np.full(len(xyz), 0.01))
    f = read_control_planes(p)
    with pytest.raises(InputError) as e:
        check_plane(f, np.arange(len(xyz)), f.xyz)
    assert e.value.field == field and all(w in str(e.value) for w in words), str(e.value)


def test_a_short_ridge_is_a_plane_within_its_own_uncertainty(tmp_path):
    """A hip roof's facet: two corners 1.4 m apart tell the tilt poorly; the others' plane at the
    far corner is uncertain by more than the point's σ, and a fair survey is not refused."""
    rng = np.random.default_rng(5)
    facet = np.array([[0.0, 0.0, 0.0], [14.0, 0.0, 0.0], [7.7, 4.0, 2.0], [6.3, 4.0, 2.0]])
    for _ in range(50):
        xyz = facet + rng.normal(0.0, 0.01, facet.shape)
        f = read_control_planes(write_control_planes(tmp_path / "p.csv", ["H"] * 4, xyz, np.full(4, 0.01), force=True))
        check_plane(f, np.arange(4), f.xyz)
