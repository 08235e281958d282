"""Control planes as strip-adjustment rows (strips/control_planes.py): each row is the distance of
a strip's points on a surveyed patch from the surveyed plane, along its normal, with the σ of
their scatter and of the plane's survey; the Jacobian is exact; a range offset is recovered from
planes alone within 2σ, and the rows' σ are honest over many draws."""

from __future__ import annotations

import numpy as np
import pytest

from calidar.adjust import Parameter, ParameterSet
from calidar.adjust.solver import numerical_jacobian, solve
from calidar.io.control_planes import ControlPlaneFile
from calidar.sensor import Sensor
from calidar.strips.control import CONTROL_ID, control_pose, near_control
from calidar.strips.control_planes import INSET_M, ControlPlanes, inside
from calidar.strips.problem import StripProblem
from calidar.strips.strip import Pose, georeference_pose

R_LB = np.array([[0.0, 1.0, 0.0], [1.0, 0.0, 0.0], [0.0, 0.0, -1.0]])  #: heading north: body x → north, z → down
#: roofs (x0, y0, side, slope east, height): square patches, some sloping east, some west
ROOFS = [(-30.0, -40.0, 10.0, 0.5, 5.0), (10.0, -35.0, 10.0, -0.5, 6.0), (-20.0, 0.0, 12.0, 0.0, 4.0),
         (15.0, 5.0, 10.0, 0.4, 7.0), (-25.0, 30.0, 10.0, -0.4, 5.0), (5.0, 30.0, 14.0, 0.2, 6.0)]


def _surface(x, y):
    """The scene's height (ground 0 and the roofs) and its east slope at (x, y)."""
    z, s = np.zeros_like(x), np.zeros_like(x)
    for x0, y0, side, slope, h in ROOFS:
        on = (x >= x0) & (x <= x0 + side) & (y >= y0) & (y <= y0 + side)
        z = np.where(on, h + slope * (x - x0), z)
        s = np.where(on, slope, s)
    return z, s


def _strip(range_offset_m: float, rng, m: int = 60000):
    """A level flight north at 60 m, scan ±35°, ranges to the scene measured with ``range_offset_m``
    and 5 mm noise (the beam meets the surface found by fixed-point iteration)."""
    y = rng.uniform(-50.0, 50.0, m)
    theta = rng.uniform(-np.radians(35.0), np.radians(35.0), m)
    rho = np.full(m, 60.0)
    for _ in range(30):  # the beam: x = ρ sin θ, z = 60 − ρ cos θ
        z, _ = _surface(rho * np.sin(theta), y)
        rho = (60.0 - z) / np.cos(theta)
    hit = np.abs(60.0 - rho * np.cos(theta) - _surface(rho * np.sin(theta), y)[0]) < 1e-9  # not on a wall's edge
    m = int(hit.sum())
    return Pose(np.arange(m), np.c_[np.zeros(m), y[hit], np.full(m, 60.0)], np.repeat(R_LB[None], m, axis=0),
                rho[hit] + range_offset_m + rng.normal(0.0, 0.005, m), theta[hit])


def _planes(rng, sigma=0.01, inset=0.3):
    """The roofs surveyed at their corners (pulled ``inset`` inside), 3-D σ ``sigma``."""
    names, xyz = [], []
    for k, (x0, y0, side, slope, h) in enumerate(ROOFS):
        cx = np.array([x0 + inset, x0 + side - inset, x0 + side - inset, x0 + inset])
        cy = np.array([y0 + inset, y0 + inset, y0 + side - inset, y0 + side - inset])
        xyz.append(np.c_[cx, cy, h + slope * (cx - x0)] + rng.normal(0.0, sigma, (4, 3)))
        names += [f"R{k}"] * 4
    xyz = np.vstack(xyz)
    f = ControlPlaneFile(None, np.array(names), xyz, np.full(len(names), sigma), np.arange(2, 2 + len(names)))
    return ControlPlanes.from_file(f, xyz)


def _problem(pose, planes, nominal, free):
    pts = georeference_pose(nominal, pose)
    near = near_control(pts, planes)
    c = planes.rows(7, pose.index[near], pts[near], len(pose.index))
    return StripProblem(nominal, {7: pose, CONTROL_ID: control_pose(planes, pose)}, [c], free), c, pts


def test_rows_are_distances_from_the_surveyed_planes_and_the_jacobian_is_exact():
    rng = np.random.default_rng(1)
    pose, planes, nominal = _strip(0.0, rng), _planes(rng), Sensor()
    free = ["range_offset", "lever_arm_z", "boresight_roll"]
    problem, c, pts = _problem(pose, planes, nominal, free)
    assert c.n_obs == len(ROOFS) and c.strip_b == CONTROL_ID
    values = {"range_offset": 0.05, "lever_arm_z": 0.0, "boresight_roll": 0.0}
    moved = georeference_pose(nominal.with_parameters(range_offset=0.05), pose)
    for k, (x0, y0, side, slope, h) in enumerate(ROOFS):  # independently: the points on roof k, inset
        on = ((moved[:, 0] > x0 + 0.3 + INSET_M) & (moved[:, 0] < x0 + side - 0.3 - INSET_M)
              & (moved[:, 1] > y0 + 0.3 + INSET_M) & (moved[:, 1] < y0 + side - 0.3 - INSET_M))
        p = moved[on].mean(axis=0)
        n = planes.normal[k]
        assert problem(values)[k] == pytest.approx(n @ (p - planes.local[k]), abs=2e-3)
        # the plane as surveyed: within a few mm of the roof, its normal the roof's
        assert np.allclose(n, np.array([-slope, 0.0, 1.0]) / np.hypot(1.0, slope), atol=3e-3)
    shift = problem(values) - problem({**values, "range_offset": 0.0})  # 5 cm too long: lower along the normal
    assert np.all(shift > 0.03) and np.all(shift < 0.05 + 1e-9)
    params = ParameterSet([Parameter(n, values[n], "rad" if n.startswith("bore") else "m") for n in free])
    J = problem.jacobian(values, params.free)
    Jn = numerical_jacobian(problem, params, np.array([values[n] for n in free]))
    np.testing.assert_allclose(J, Jn, atol=1e-6)


def test_points_off_the_patch_or_off_the_plane_are_left_out():
    rng = np.random.default_rng(2)
    planes = _planes(rng, sigma=0.0005)
    x0, y0, side, slope, h = ROOFS[2]  # the flat roof: a grid of points on it, a chimney in its middle
    gx, gy = np.meshgrid(np.arange(x0, x0 + side, 0.25), np.arange(y0, y0 + side, 0.25))
    p = np.c_[gx.ravel(), gy.ravel(), np.full(gx.size, h)]
    chimney = (np.abs(p[:, 0] - (x0 + 6)) < 0.6) & (np.abs(p[:, 1] - (y0 + 6)) < 0.6)
    p[chimney, 2] += 1.0
    c = planes.rows(3, np.arange(len(p)), p, len(p))
    used = c.A.tocsr()[0].indices
    assert not np.any(chimney[used])
    assert np.all(inside(p[used, :2], planes.hulls[2], INSET_M - 1e-9))
    assert used.size == np.sum(inside(p[:, :2], planes.hulls[2], INSET_M) & ~chimney)
    assert c.n_obs == 1 and abs(c.normal[0, 2] - 1.0) < 1e-3


def test_a_range_offset_is_recovered_from_planes_alone_with_honest_sigma():
    """Six roofs, no control point, no overlap: the range offset within 2σ, and over 40 draws (new
    noise, new survey errors) the RMS of error / a-priori σ within 0.8–1.25 (±0.11 sampling at n = 40)."""
    nominal, z = Sensor(), []
    for seed in range(40):
        rng = np.random.default_rng(100 + seed)
        pose, planes = _strip(0.05, rng, 30000), _planes(rng, sigma=0.01)
        problem, c, _ = _problem(pose, planes, nominal, ["range_offset"])
        params = ParameterSet([Parameter("range_offset", 0.0, "m")])
        sol = solve(problem, params, sigma=problem.sigma, jacobian_fn=lambda v: problem.jacobian(v, params.free),
                    robust=None)
        if seed == 0:
            assert sol.sigma["range_offset"] < 0.01 and abs(sol.values["range_offset"] - 0.05) < 2 * sol.sigma["range_offset"]
        # the a-priori σ (the rows' own): the solver scales by σ0 from 6 rows, whose t(5) spread is √(5/3)
        z.append((sol.values["range_offset"] - 0.05) / (sol.sigma["range_offset"] / sol.sigma0))
    assert 0.8 < np.sqrt(np.mean(np.square(z))) < 1.25, np.sqrt(np.mean(np.square(z)))
    assert abs(np.mean(z)) < 0.5
