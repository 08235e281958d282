"""Tie planes, overlaps and the strip calibrator on a small synthetic survey (tests/strips_scene.py)."""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest

from calidar.adjust import ParameterSet
from calidar.adjust.solver import numerical_jacobian
from calidar.errors import CalibrationError, InputError
from calidar.sensor import Sensor
from calidar.strips.calibrate import calibrate
from calidar.strips.config import CalibrationConfig, Estimate, StripSettings, TiePlanes
from calidar.strips.parameters import build_parameters
from calidar.strips.problem import StripProblem
from calidar.strips.correspond import moderated_variance
from calidar.strips.overlap import find_overlaps
from calidar.strips.planes import PlaneSettings, fit_patches, match_pair_planes
from calidar.strips.strip import Strip
from calidar.strips.trajectory_errors import TrajectoryModel
from strips_scene import frame, line, survey

TRUTH = Sensor(boresight_roll=np.radians(0.03), boresight_pitch=np.radians(-0.04), boresight_yaw=np.radians(0.05))
LINES = [((-250, -80, 0), 90, 500, 400), ((250, 80, 0), 270, 500, 400), ((0, -250, 0), 0, 500, 400)]


@pytest.fixture(scope="module")
def strips():
    return survey(TRUTH, Sensor(), LINES, n=150_000, noise=0.03)


def _plane_points(rng, n, normal_xy=(0.2, -0.1), offset=0.0, noise=0.01):
    xy = rng.uniform(0, 40, (n, 2))
    z = 5.0 + normal_xy[0] * xy[:, 0] + normal_xy[1] * xy[:, 1] + offset + rng.normal(0, noise, n)
    return np.column_stack([xy, z])


def test_patches_fit_a_known_plane():
    rng = np.random.default_rng(0)
    pts = _plane_points(rng, 20000, noise=0.01)
    p = fit_patches(pts, 4.0, PlaneSettings())
    n_true = np.array([-0.2, 0.1, 1.0]) / np.linalg.norm([-0.2, 0.1, 1.0])
    assert p.keys.size == 100  # every 4 m cell of the 40 m square is planar
    assert np.all(np.abs(p.normal @ n_true) > np.cos(np.radians(0.5)))
    assert np.median(p.rms_m) == pytest.approx(0.01 * n_true[2], rel=0.15)


def test_patch_scatter_is_unbiased_on_small_patches():
    """≈ 12 points a patch (the default): the scatter off the fitted plane counts n − 3 degrees
    of freedom, so the rows' σ match the noise (with n it runs √(9/12) = 13 % low)."""
    rng = np.random.default_rng(2)
    pts = _plane_points(rng, 20000, noise=0.02)
    p = fit_patches(pts, 1.0, PlaneSettings())  # 12.5 points per 1 m cell
    n_true = np.array([-0.2, 0.1, 1.0]) / np.linalg.norm([-0.2, 0.1, 1.0])
    assert p.keys.size > 1000 and np.median(p.count) <= 13
    assert np.sqrt(np.mean(p.rms_m**2)) == pytest.approx(0.02 * n_true[2], rel=0.05)


def test_vegetation_cells_fail_planarity():
    rng = np.random.default_rng(1)
    pts = _plane_points(rng, 20000)
    veg = pts[:, 0] < 20
    pts[veg, 2] += rng.uniform(0, 10, veg.sum())
    p = fit_patches(pts, 4.0, PlaneSettings())
    assert p.keys.size == 50  # only the bare half


def test_tie_plane_residual_is_the_offset_along_the_normal():
    rng = np.random.default_rng(2)
    a = _plane_points(rng, 30000, offset=0.07, noise=0.02)
    b = _plane_points(rng, 30000, noise=0.02)
    c = match_pair_planes(1, a, 2, b, PlaneSettings(cell_m=4.0))
    assert c.n_obs == 100 and c.kind == "point_to_plane"
    assert np.allclose(np.asarray(c.A.sum(axis=1)).ravel(), 1.0)
    r = c.residuals(a, b)
    nz = 1.0 / np.linalg.norm([0.2, -0.1, 1.0])
    assert np.mean(r) == pytest.approx(0.07 * nz, abs=0.002)
    # σ of a row reflects the scatter of both patches' centroids (20 mm noise, ≈ 64 points each)
    assert np.std(r) == pytest.approx(np.median(c.sigma_m), rel=0.35)


def test_overlaps_found_and_disjoint_strips_reported():
    xy1 = np.random.default_rng(3).uniform(0, 100, (5000, 2))
    pairs, notes = find_overlaps({1: xy1, 2: xy1 + [60, 0], 3: xy1 + [1000, 0]})
    assert [(p.a, p.b) for p in pairs] == [(1, 2)]
    assert pairs[0].area_m2 == pytest.approx(40 * 100, rel=0.15)
    assert len(notes) == 1 and "strip 3 overlaps no other strip" in notes[0]


def test_calibration_recovers_boresight(strips):
    res = calibrate(strips, Sensor())
    sol = res.solution
    for name in ("boresight_roll", "boresight_pitch", "boresight_yaw"):
        err = sol.values[name] - getattr(TRUTH, name)
        assert abs(np.degrees(err)) < 0.002, name
        assert abs(err) < 3 * sol.sigma[name], name
    assert len(res.pairs) == 3 and all(p["n_obs"] > 300 for p in res.pairs)
    # the outer loop settled and the strips now agree much better than delivered
    assert abs(res.outer[-1]["mean_distance_m"] - res.outer[-2]["mean_distance_m"]) < TiePlanes().threshold_m
    assert np.sqrt(np.mean(res.residuals_after**2)) < 0.3 * np.sqrt(np.mean(res.residuals_before**2))
    # solution.json / the report say the same: "before" is the first matching at the nominal sensor
    doc = sol.to_dict()["residuals"]
    assert doc["before"]["rms"] == pytest.approx(np.sqrt(np.mean(res.residuals_before**2)))
    assert doc["after"]["rms"] < 0.3 * doc["before"]["rms"]


def test_centroid_shortcut_equals_full_regeoreferencing(strips):
    """The O(n_obs) centroid form must give the lidar equation's residuals exactly."""
    pts = {s.id: s.points for s in strips}
    c = match_pair_planes(1, pts[1], 2, pts[2])
    poses = {s.id: s.pose() for s in strips[:2]}
    nominal = Sensor(lever_arm_x=0.2, range_offset=0.01)
    full = StripProblem(nominal, poses, [c], ["scan_angle_scale"])
    assert full.centroids is None
    vals = build_parameters(nominal, Estimate.of("boresight", "lever_arm", "range_offset", "range_scale"), {}).values()
    vals.update(boresight_roll=1e-3, boresight_yaw=-2e-3, lever_arm_x=0.3, range_offset=0.05, range_scale=1e-4)
    fast = StripProblem(nominal, poses, [c], ["boresight_roll", "lever_arm_x", "range_offset"])
    assert fast.centroids is not None
    assert np.max(np.abs(fast(vals) - full(vals))) < 1e-9
    # boresight alone: lever arm and range model fixed at the nominal values, folded into constants
    only = StripProblem(nominal, poses, [c], ["boresight_roll"])
    vals_b = {**nominal.parameters(), "boresight_roll": 1e-3, "boresight_yaw": -2e-3}
    assert np.max(np.abs(only(vals_b) - full(vals_b))) < 1e-9


def test_moderated_scatter_makes_the_weighted_mean_honest():
    """Rows weighted by their own 12-point scatter (ν = 9) claim too small a σ for a weighted
    mean (the quiet-by-chance rows dominate: variance ratio ≈ ν/(ν − 4) = 1.8 in theory);
    the moderated scatter's claim holds."""
    rng = np.random.default_rng(11)
    n_rows, n_trials, nu = 400, 400, 9
    z_raw, z_mod = [], []
    for _ in range(n_trials):
        scale = rng.uniform(0.8, 1.25, n_rows)  # a little real heterogeneity
        s2 = scale**2 * rng.chisquare(nu, n_rows) / nu  # each row's own scatter estimate
        r = scale * rng.standard_normal(n_rows)  # independent of s2 (Gaussian noise)
        for var, out in ((s2, z_raw), (moderated_variance(s2, nu), z_mod)):
            w = 1.0 / var
            out.append((w @ r / w.sum()) * np.sqrt(w.sum()))  # estimate / its claimed σ
    assert np.std(z_raw) > 1.15  # the per-row weights' claim is optimistic
    assert 0.9 < np.std(z_mod) < 1.1
    assert moderated_variance(np.zeros(0), nu).size == 0


@pytest.mark.parametrize("point_to_point", [False, True])
def test_trajectory_columns_of_the_jacobian_are_exact(strips, point_to_point):
    """The analytic (sparse) columns of the knots equal central differences of the residuals,
    along the normals and in 3D, on the first call (pattern built) and a later one (values only)."""
    pts = {s.id: s.points for s in strips}
    c = match_pair_planes(1, pts[1], 2, pts[2])
    if point_to_point:
        c = replace(c, normal=None)
    poses = {s.id: s.pose() for s in strips[:2]}
    spans = {s.id: (float(s.time.min()), float(s.time.max())) for s in strips[:2]}
    model = TrajectoryModel(block_s=2.0, position_sigma_m=0.03, attitude_sigma_rad=1e-5, correlation_s=20.0,
                            attitude_correlation_s=3.0)
    params = build_parameters(Sensor(), Estimate.of("boresight"), spans, model)
    rng = np.random.default_rng(3)
    params = ParameterSet(replace(p, value=rng.normal(0.0, p.prior_sigma)) if p.prior_sigma else p for p in params)
    problem = StripProblem(Sensor(), poses, [c], params.free_names, {s.id: s.time for s in strips[:2]}, model, spans)
    problem.jacobian(params.values(), params.free)
    moved = ParameterSet(replace(p, value=p.value + rng.normal(0.0, p.prior_sigma or 1e-4)) for p in params)
    analytic = problem.jacobian(moved.values(), moved.free).toarray()
    numeric = numerical_jacobian(problem, moved, moved.x())
    assert analytic.shape == numeric.shape and np.count_nonzero(analytic[:, 3:]) > 0
    assert np.max(np.abs(analytic - numeric)) < 1e-6 * np.max(np.abs(numeric))
    # each row touches at most two knots per strip, kind and axis
    assert np.max(np.count_nonzero(analytic[:, 3:], axis=1)) <= 2 * 2 * 6


def test_per_strip_trajectory_bias_is_recovered(strips):
    shifted = [replace(s, points=s.points + ([0.0, 0.0, 0.15] if s.id == 2 else 0.0)) for s in strips]
    # the delivered points moved: rebuild strip 2's observations from them
    s2 = shifted[1]
    shifted[1] = Strip.from_ecef(2, frame().to_ecef(s2.points), s2.time, s2.trajectory, Sensor(), frame())
    res = calibrate(shifted, Sensor(), trajectory=TrajectoryModel())  # free strip shifts
    up = res.solution.values["trajectory_bias_up_2"]
    assert up == pytest.approx(-0.15, abs=0.01)
    assert "trajectory_bias_up_1" not in res.solution.values  # strip 1 is the datum


def test_too_few_planes_is_a_clear_error(strips):
    with pytest.raises(CalibrationError, match=r"no usable strip pair: 1–2: only \d+ tie planes, need 100000"):
        calibrate(strips, Sensor(), CalibrationConfig(solver=StripSettings(min_correspondences=100_000)))


def test_non_overlapping_strips_are_a_clear_error():
    far = [((-250, -80, 0), 90, 500, 400), ((-250, 3000, 0), 90, 500, 400)]
    st = survey(TRUTH, Sensor(), far, n=20_000)
    with pytest.raises(CalibrationError, match="no two of the 2 strips overlap"):
        calibrate(st, Sensor())


def test_trajectory_not_covering_the_strip_names_it():
    traj = line((-250, -80, 0), 90, 500, 400, t0=1000.0)
    pts = np.zeros((3, 3)) + frame().origin_ecef
    with pytest.raises(InputError, match=r"<memory>: time: 2 of 3 points of strip 7 .* outside the trajectory"):
        Strip.from_ecef(7, pts, np.array([1001.0, 5000.0, 6000.0]), traj, Sensor(), frame())


def test_unknown_estimate_names_are_rejected():
    assert Estimate.of("boresight", "lever_arm_x").names() == ["boresight", "lever_arm_x"]
    assert Estimate.of("lever_arm_x", "lever_arm_y", "lever_arm_z").names() == ["lever_arm"]
    assert "lever_arm" not in Estimate.of("boresight", "lever_arm_x") and "lever_arm_x" in Estimate.of("lever_arm")
    with pytest.raises(InputError, match=r"estimate: expected one or more of the groups .* got \['wobble'\]"):
        Estimate.of("boresight", "wobble")
    with pytest.raises(InputError, match="estimate: expected one or more"):
        Estimate(frozenset({"boresight"}))  # a group is no parameter name


def test_same_result_in_process_and_on_a_local_dask_cluster(strips):
    config = CalibrationConfig(solver=StripSettings(max_outer=2))
    local = calibrate(strips[:2], Sensor(), config).solution
    dask = calibrate(strips[:2], Sensor(), config, workers=2).solution
    for name in ("boresight_roll", "boresight_pitch", "boresight_yaw"):
        assert dask.values[name] == pytest.approx(local.values[name], abs=1e-12)


def test_rows_sigma_are_absolute_with_the_trajectory_model_off(strips, monkeypatch):
    """The rows' σ come from their points' own scatter (absolute): with the trajectory model off, a
    σ0 below 1 must not shrink the angles' σ (issue 26: on the UAV surveys σ0 ≈ 0.7 came from the
    sloped rows' generous σ while roll's flat-ground rows' σ held, and the shrunk σ left roll's RMS
    error/σ at 1.46; docs/validation.md). The IRLS covariance (the default) is N⁻¹ of the final weights,
    here exactly; the M-estimator sandwich (an option) takes its variance factor as the ψ's level q raised
    by 1/σ0² of the skipped σ0 where that is below 1, and records the IRLS σ beside its own."""
    from calidar.adjust import SolverOptions, solver

    captured = []
    original = solver.Estimate.solution
    monkeypatch.setattr(solver.Estimate, "solution", lambda self, clusters=None: captured.append(self) or original(self, clusters))
    irls = StripSettings(cluster_s=None, adjustment=SolverOptions(robust="cauchy", covariance="irls"))
    sol = calibrate(strips, Sensor(), CalibrationConfig(trajectory=None, solver=irls)).solution
    est = captured[-1]
    assert 0.5 < sol.sigma0 < 0.99  # the synthetic rows' σ are a little generous (0.94): the case at stake
    N = est.fit.normal_equations(est.fit.jacobian(est.x), est.w)[0]
    names = [p.name for p in est.fit.free]
    angles = ("boresight_roll", "boresight_pitch", "boresight_yaw")
    idx = [names.index(n) for n in angles]
    np.testing.assert_allclose(np.diag(sol.covariance)[idx], np.diag(np.linalg.inv(N))[idx], rtol=1e-6)
    assert StripSettings().adjustment.covariance == "irls"  # the default the Monte-Carlo ran on
    sandwich = StripSettings(cluster_s=None, adjustment=SolverOptions(robust="cauchy", covariance="sandwich"))
    sand = calibrate(strips, Sensor(), CalibrationConfig(trajectory=None, solver=sandwich)).solution
    record, skipped = sand.extra["covariance"], sand.extra["unit_weight"]["sigma0"]
    assert record["model"] == "sandwich"
    q = record["psi_sigma0"] ** 2
    assert record["variance_factor"] == pytest.approx(q * max(1.0, 1.0 / skipped**2), rel=1e-12)
    for n in angles:
        assert record["irls_sigma"][n] == pytest.approx(sol.sigma[n], rel=1e-6)


def test_rows_sigma_match_the_residuals_at_the_truth():
    """Issue 26: two strips of one plane with 3 mm noise and the default ≈ 12-point patches, matched where
    they coincide: the rows' residuals scatter as their σ say (RMS of r/σ ≈ 1; a fixed 2 mm floor made
    them 0.5). The t-distribution of a σ estimated from ν + ν0 = 29 degrees of freedom allows ≈ +2 %."""
    rng = np.random.default_rng(26)
    a = _plane_points(rng, 60000, noise=0.003)
    b = _plane_points(rng, 60000, noise=0.003)
    c = match_pair_planes(1, a, 2, b)
    z = c.residuals(a, b) / c.sigma_m
    assert z.size > 2000
    assert np.sqrt(np.mean(z**2)) == pytest.approx(1.0, abs=0.05)
    # the global test's σ0 over them, with the factor for their recorded degrees of freedom
    from calidar.adjust.solver import robust_weights
    from calidar.strips.row_variance import consistency, dof_summary

    s = 1.4826 * np.median(np.abs(z))
    w = robust_weights(z / s, "cauchy")
    assert np.all(c.dof > 9)  # two sides of ≥ 6 points (inf where the pair's rows pool fully)
    assert np.sqrt(np.sum(w * z * z) / np.sum(w) / consistency("cauchy", dof_summary(c.dof))) == pytest.approx(1.0, abs=0.05)


def _hat_weights_numpy(points, A, target):
    """plane_point_weights as numpy wrote it before its kernels (issue 32, eleventh session)."""
    import scipy.sparse as sp

    from calidar.strips.pca import eigh3

    rows = np.repeat(np.arange(A.shape[0]), np.diff(A.indptr))
    mean = A @ points
    d = points[A.indices] - mean[rows]
    cov = np.zeros((A.shape[0], 3, 3))
    for i in range(3):
        for j in range(i, 3):
            cov[:, i, j] = cov[:, j, i] = np.bincount(rows, A.data * d[:, i] * d[:, j], A.shape[0])
    lam, vec = eigh3(cov)
    axes = vec[:, :, 1:]
    coef = np.einsum("ri,rij->rj", target - mean, axes) / np.clip(lam[:, 1:], 1e-12, None)
    h = A.data * (1.0 + np.einsum("kj,kj->k", coef[rows], np.einsum("ki,kij->kj", d, axes[rows])))
    weights = sp.csr_matrix((h, A.indices.copy(), A.indptr.copy()), shape=A.shape)
    return weights, np.bincount(rows, h * h, A.shape[0])


def test_plane_point_weights_kernels_have_numpys_bits():
    """The hat weights and their Σ h² from the two kernels equal numpy's, bit for bit: the rows of
    a real pair's tie planes (local coordinates of 10⁴ m, targets off the centroids) and random
    rows (1 to 40 points, weights of both signs, a degenerate row of one point repeated)."""
    import scipy.sparse as sp

    from calidar.strips.planes import _averaging, patch_cell_size, plane_point_weights

    truth = Sensor(boresight_roll=np.radians(0.03), boresight_pitch=np.radians(-0.04))
    strips = survey(truth, Sensor(), [((-250, -80, 0), 90, 500, 400), ((250, 80, 0), 270, 500, 400)],
                    n=40_000)
    pts_a, pts_b = (np.ascontiguousarray(s.points + 1e4) for s in strips)
    s = PlaneSettings()
    cell = patch_cell_size(pts_a, s.target_points)
    pa, pb = fit_patches(pts_a, cell, s), fit_patches(pts_b, cell, s)
    _, ia, ib = np.intersect1d(pa.keys, pb.keys, assume_unique=True, return_indices=True)
    A, _ = _averaging(pa, ia, s.max_points_per_patch, pts_a.shape[0])
    B, _ = _averaging(pb, ib, s.max_points_per_patch, pts_b.shape[0])
    rng = np.random.default_rng(32)
    counts = rng.integers(1, 41, 300)
    indptr = np.r_[0, np.cumsum(counts)]
    indices = rng.integers(0, 500, indptr[-1])
    indices[indptr[7]:indptr[8]] = indices[indptr[7]]
    R = sp.csr_matrix((rng.normal(0.1, 0.3, indptr[-1]), indices, indptr), shape=(300, 500))
    cloud = rng.normal(0.0, 5.0, (500, 3)) + 1e4
    assert A.shape[0] > 100
    for M, pts, target in [(A, pts_a, B @ pts_b), (R, cloud, cloud[:300] + rng.normal(0, 3, (300, 3)))]:
        got, want = plane_point_weights(pts, M, target), _hat_weights_numpy(pts, M, target)
        assert np.array_equal(got[0].data, want[0].data, equal_nan=True)
        assert np.array_equal(got[0].indices, want[0].indices)
        assert np.array_equal(got[1], want[1], equal_nan=True)


def test_patches_take_the_planarity_tests_eigenvectors_bit_for_bit():
    """fit_patches takes the planar cells' eigenvalues and axes from the planarity test's one eigh3
    over all cells (issue 32, eleventh session: it decomposed them twice); eigh3 works matrix by
    matrix, so the subset's decomposition is the same bits as decomposing the subset."""
    from calidar.strips.pca import eigh3

    rng = np.random.default_rng(32)
    g = rng.normal(0.0, 1.0, (5000, 3, 3)) * rng.lognormal(0.0, 2.0, (5000, 1, 1))
    cov = g @ np.transpose(g, (0, 2, 1))
    cov[::7, 2, :] = cov[::7, :, 2] = 0.0  # flat cells: a zero eigenvalue
    cov[11] = np.eye(3) * 0.5
    keep = rng.random(5000) < 0.4
    whole, part = eigh3(cov), eigh3(cov[keep])
    assert np.array_equal(whole[0][keep], part[0]) and np.array_equal(whole[1][keep], part[1])
    s = PlaneSettings()
    pts = rng.normal(0.0, [20.0, 20.0, 0.01], (20_000, 3))
    p = fit_patches(pts, 2.0, s)
    assert p.keys.size > 50
    mean, c = _patch_covariances(pts, p)
    lam, vec = eigh3(c)
    assert np.array_equal(p.spread_m2, np.clip(lam[:, 1:], 1e-12, None))
    assert np.array_equal(p.axes, vec[:, :, 1:])


def _patch_covariances(points, p):
    from calidar.strips.planes import _cell_moments

    return _cell_moments(np.ascontiguousarray(points), p.order, p.start, p.count)
