"""VGICP correspondences on synthetic strips with a known rigid misalignment.

The scene (rolling terrain with gable-roofed buildings) is sampled twice, independently,
with 2 cm noise; strip b is then moved by a known small rotation + translation. The
registration must recover that transform, the correspondences must bring the residuals
down to the noise once the truth is applied. The iterated calibration (the outer loop of
calidar.strips.calibrate) is tested on simulated surveys in test_vgicp_calibration.py.
"""

from __future__ import annotations

import json
from dataclasses import replace

import numpy as np
import pytest

from calidar.errors import CalibrationError
from calidar.frames import rpy_to_matrix
from calidar.strips.correspond import Correspondences
from calidar.strips.vgicp import VgicpSettings, match_pair_vgicp, overlap_masks, register

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
    fixed = undo(b, ROT_TRUE, SHIFT_TRUE)
    before, after = c.residuals(a, b), c.residuals(a, fixed)
    if kind == "point_to_plane":
        # b's side: the mean of its k nearest points around a point of a, on b's local plane;
        # a's side: the mean of a's points in the same ball (as many as b's at equal density)
        k = VgicpSettings().num_neighbors
        assert np.all(np.diff(c.B.indptr) == k) and np.allclose(c.B.data, 1.0 / k)
        n_a = np.diff(c.A.indptr)
        assert np.allclose(c.A @ np.ones(a.shape[0]), 1.0) and np.all(n_a >= 1)
        assert np.mean(n_a) == pytest.approx(k, rel=0.2)
        assert c.normal is not None and np.allclose(np.linalg.norm(c.normal, axis=1), 1.0)
        # two means of noisy points along the normal: σ ≈ √(1/n_a + 1/k) · 2 cm, a little more
        # where a's mean lies off b's centroid (the plane's tilt error; measured 1.11 ×), far
        # below a single point of a against b's plane (√(1 + 1/k) · 2 cm = 2.1 cm)
        rms = np.sqrt(np.mean(after**2))
        assert rms < 1.15 * np.sqrt(np.mean(1 / n_a) + 1 / k) * NOISE_M, rms
        assert 0.85 < np.sqrt(np.mean((after / c.sigma_m) ** 2)) < 1.2
        # each row's σ comes from the scatter of b's plane: it predicts the residuals' spread
        assert np.std(after) == pytest.approx(np.median(c.sigma_m), rel=0.15)
        assert np.sqrt(np.mean(before**2)) > 10 * NOISE_M
    else:
        assert np.all(np.diff(c.A.indptr) == 1) and np.all(c.A.data == 1.0)  # point pairs
        assert np.all(np.diff(c.B.indptr) == 1) and np.all(c.B.data == 1.0)
        assert c.normal is None and after.size == 3 * c.n_obs
        d = np.linalg.norm(after.reshape(-1, 3), axis=1)
        # the pair distance is the sampling gap: median nearest-neighbour distance of a
        # Poisson sampling of density λ = 1.5 points/m² is √(ln 2 / (π λ)) = 0.38 m
        # (+10 % for the sampling error of a median of ~1500 pairs and the registration)
        assert np.median(d) < 1.1 * np.sqrt(np.log(2) / (np.pi * 1.5))
        assert np.median(np.linalg.norm(before.reshape(-1, 3), axis=1)) > 2 * np.median(d)


def test_the_unevenness_length_is_estimated_unless_set(strips):
    """ℓ read from b's neighbourhoods by default (issue 26, thirteenth session), recorded on the
    correspondences; a number set in the settings is used as it is, nothing recorded."""
    a, b = strips
    c = match_pair_vgicp(1, a, 2, b, VgicpSettings(max_pairs=1500))
    fit = c.unevenness
    assert fit is not None and 10 <= fit["rows"] <= 300 and fit["sigma_e_m"] > 0
    low, high = fit["length_range_m"]
    assert fit["length_m"] == 0.0 or low <= fit["length_m"] <= high
    fixed = match_pair_vgicp(1, a, 2, b, VgicpSettings(max_pairs=1500, unevenness_length_m=2.0))
    assert fixed.unevenness is None and fixed.n_obs == c.n_obs
    assert not np.allclose(fixed.sigma_m, c.sigma_m)


def test_point_to_plane_rows_carry_no_curvature_error():
    """On a noiseless curved surface (curvature up to 0.05 /m) sampled twice at different
    densities, the residuals at the truth do not follow the curvature: both sides average the
    same ball. A single point of a against b's plane would (measured: slope −0.32 m² on the
    Laplacian, correlation −0.90, RMS 8.6 mm; now −0.018 m², −0.13, 3.4 mm)."""
    def curved(n, rng):
        x, y = rng.uniform(-HALF_M, HALF_M, n), rng.uniform(-HALF_M, HALF_M, n)
        return np.column_stack([x, y, 4.0 * np.sin(x / 12.0) * np.cos(y / 15.0) + 0.3 * np.sin(y / 7.0)])

    rng = np.random.default_rng(5)
    a, b = curved(120_000, rng), curved(60_000, rng)
    c = match_pair_vgicp(1, a, 2, b, VgicpSettings(max_pairs=1500))
    assert c.n_obs > 1000 and np.mean(np.diff(c.A.indptr)) > 1.5 * VgicpSettings().num_neighbors  # denser a
    r = c.residuals(a, b) * np.sign(c.normal[:, 2])  # distance of a's mean above b's plane, m
    x, y = (c.A @ a)[:, 0], (c.A @ a)[:, 1]
    laplacian = (-4.0 * np.sin(x / 12.0) * np.cos(y / 15.0) * (1 / 144 + 1 / 225)
                 - 0.3 * np.sin(y / 7.0) / 49)  # 1/m
    slope = np.sum(r * laplacian) / np.sum(laplacian**2)  # m²
    assert abs(slope) < 0.05, slope
    assert np.sqrt(np.mean(r**2)) < 0.005


def test_strips_cut_at_different_places_keep_the_centroids_together():
    """Both strips keep 20 m blocks in a checkerboard, cut 0.7 m apart (as the ingest's kept
    cells are once each strip's mounting correction moves it). Near a cut one strip's points
    stop inside the ball: its centroid would part from the other's along the plane, b's normal
    error times that lever then biasing the angles (errors in variables; docs/validation.md).
    Measured: mean in-plane offset 24.5 ± 4.0 mm toward the shift with the neighbourhoods
    first found, 6.5 ± 2.5 mm now; its spread 218 → 128 mm."""
    def kept(p, shift_y):
        block = np.floor((p[:, :2] - [0.0, shift_y]) / 20.0).astype(int)
        return p[(block[:, 0] + block[:, 1]) % 2 == 0]

    rng = np.random.default_rng(11)
    a, b = kept(sample(160_000, rng), 0.35), kept(sample(160_000, rng), -0.35)
    c = match_pair_vgicp(1, a, 2, b, VgicpSettings(max_pairs=3000))
    d = c.A @ a - c.B @ b
    d -= np.einsum("ij,ij->i", d, c.normal)[:, None] * c.normal  # in b's plane, m
    assert c.n_obs > 2000
    assert abs(np.mean(d[:, 1])) < 0.015 and abs(np.mean(d[:, 0])) < 0.01
    assert np.std(d[:, 1]) < 0.15


def test_pairs_are_spread_over_the_overlap(strips):
    a, b = strips
    c = match_pair_vgicp(1, a, 2, b, VgicpSettings(max_pairs=400))
    xy = (c.A @ a)[:, :2]
    counts, _, _ = np.histogram2d(xy[:, 0], xy[:, 1], bins=4, range=[[-HALF_M, HALF_M]] * 2)
    assert c.n_obs <= 400 and counts.min() > 0  # every quarter-by-quarter block holds pairs


def test_registration_recovers_the_known_transform(strips):
    a, b = strips
    _, _, area = overlap_masks(a, b, 5.0)
    reg = register(a - CENTER, b - CENTER, VgicpSettings(), area)
    R_true = rpy_to_matrix(*ROT_TRUE)
    angle = np.degrees(np.arccos(np.clip((np.trace(reg.T_ab[:3, :3] @ R_true) - 1) / 2, -1, 1)))
    t_true = -R_true.T @ SHIFT_TRUE  # T_ab = disturbance⁻¹ about CENTER
    # what the matching needs: misregistration across the 140 m half-diagonal well below a
    # tenth of the 0.8 m point spacing (0.03° → 7 cm)
    assert angle < 0.03
    assert np.linalg.norm(reg.T_ab[:3, 3] - t_true) < 0.07


def test_vegetation_clutter_is_left_out_of_point_to_plane_pairs():
    rng = np.random.default_rng(3)
    a = sample(60_000, rng, vegetation=0.3)
    b = disturb(sample(60_000, rng, vegetation=0.3))
    c = match_pair_vgicp(1, a, 2, b, VgicpSettings(max_pairs=1500))
    after = c.residuals(a, undo(b, ROT_TRUE, SHIFT_TRUE))
    assert c.n_obs > 300
    assert np.median(np.abs(after)) < 1.5 * NOISE_M
    assert np.mean(np.abs(after) < 0.1) > 0.9


def test_small_overlap_is_refused_with_the_reason():
    rng = np.random.default_rng(5)
    a = sample(30_000, rng, x_range=(-100, 0))
    b = sample(30_000, rng, x_range=(-1, 100))  # 1 m wide common band
    with pytest.raises(CalibrationError, match=r"too little overlap for VGICP \(\d+ and \d+ points"):
        match_pair_vgicp(4, a, 9, b)


def test_too_few_correspondences_is_refused():
    rng = np.random.default_rng(6)
    a = sample(20_000, rng)
    b = sample(20_000, rng) + [0.0, 0.0, 3.0]  # 3 m apart: beyond the pair distance
    # fine 1 m voxels only (no coarsening for point count): cannot lock in
    settings = VgicpSettings(voxel_m=(1.0,), max_registration_points=10**6, min_pairs=50)
    with pytest.raises(CalibrationError, match="too few VGICP correspondences"):
        match_pair_vgicp(1, a, 2, b, settings)


# ---- the calibration with VGICP correspondences against the survey simulator's truth ----

from calidar.strips.calibrate import calibrate  # noqa: E402
from calidar.strips.config import CalibrationConfig, Estimate, StripSettings, Vgicp  # noqa: E402
from calidar.sim.survey import simulate_survey, survey_config  # noqa: E402
from calidar.strips.trajectory_errors import TrajectoryModel  # noqa: E402
from test_strips_sim import AIRBORNE_TRAJECTORY, ANGLES, _check_angles, _simulate, uav_lever_arm_survey  # noqa: E402  (issue 4's surveys)

VGICP = CalibrationConfig(matchers=(Vgicp(threshold_m=1e-3),))  #: re-matching moves the mean distance by ~0.1 mm: stop at 1 mm


@pytest.fixture(scope="module")
def airborne():
    res = _simulate("airborne", "cross", 0.3)
    return res, res.calibration_strips()


def test_airborne_cross_lines_boresight(airborne):
    """With the trajectory's errors modelled, as `calidar boresight` does by default (without the
    model this survey's roll reads +3.7σ off at σ0 2.35: its 3 cm / 0.002° errors differ line to
    line and the σ, scaled by σ0, do not carry that; the tie planes read +3.2σ)."""
    res, strips = airborne
    result = calibrate(strips, res.nominal, VGICP, trajectory=AIRBORNE_TRAJECTORY)
    _check_angles(result.solution, res.truth.parameters())
    assert result.method == "vgicp" and len(result.pairs) >= 10
    assert all(p["n_obs"] >= VgicpSettings().min_pairs for p in result.pairs)
    mean = [o["mean_distance_m"] for o in result.outer]
    assert mean[-1] < 0.1 and abs(mean[-1] - mean[-2]) < VGICP.matchers[0].threshold_m  # converged


def test_start_half_a_degree_from_the_truth_converges(airborne):
    res, strips = airborne
    far = res.nominal.with_parameters(**{n: res.truth.parameters()[n] + np.radians(0.5) for n in ANGLES})
    result = calibrate(strips, far, VGICP, trajectory=AIRBORNE_TRAJECTORY)
    _check_angles(result.solution, res.truth.parameters())
    assert result.outer[0]["mean_distance_m"] > result.outer[-1]["mean_distance_m"]


def test_pairs_without_enough_overlap_are_skipped_by_name(airborne):
    res, strips = airborne
    from calidar.strips.overlap import find_overlaps

    overlaps, _ = find_overlaps({s.id: s.points for s in strips}, 5.0, 4)
    by_id = {s.id: s for s in strips}
    cell = VgicpSettings().overlap_cell_m
    sizes = np.sort([min(m.sum() for m in overlap_masks(by_id[o.a].points[o.index_a], by_id[o.b].points[o.index_b],
                                                        cell)[:2]) for o in overlaps])
    gap = np.argmax(sizes[1:] / sizes[:-1])  # a limit in the widest gap: the pairs below it fall short
    limit = int(np.sqrt(sizes[gap] * sizes[gap + 1]))
    config = CalibrationConfig(matchers=(Vgicp(VgicpSettings(min_overlap_points=limit)),), solver=StripSettings(max_outer=2))
    result = calibrate(strips, res.nominal, config)
    warning = next(w for w in result.warnings if w.startswith("strip pairs skipped"))
    used = {(p["a"], p["b"]) for p in result.pairs}
    named = {(o.a, o.b) for o in overlaps if f"{o.a}–{o.b}: too little overlap for VGICP" in warning}
    assert used and named and used.isdisjoint(named)
    assert used | named == {(o.a, o.b) for o in overlaps}, warning  # every pair is used or skipped by name
    none = CalibrationConfig(matchers=(Vgicp(VgicpSettings(min_overlap_points=10**9)),))
    with pytest.raises(CalibrationError, match="no usable strip pair: .*too little overlap for VGICP"):
        calibrate(strips, res.nominal, none)


@pytest.mark.slow
def test_airborne_with_30_percent_vegetation():
    res = _simulate("airborne", "cross", 0.3, vegetation=0.3)
    result = calibrate(res.calibration_strips(), res.nominal, VGICP, trajectory=AIRBORNE_TRAJECTORY)
    _check_angles(result.solution, res.truth.parameters())


@pytest.mark.slow
def test_uav_lever_arm():
    """The planes issue's UAV survey (5 cm lever-arm errors, 5 mm GNSS noise), boresight known:
    x and y within 1 cm, each error under 3σ with the GNSS error modelled (5 mm per 2 s block)."""
    res = uav_lever_arm_survey()
    truth = res.truth.parameters()
    model = TrajectoryModel(block_s=2.0, position_sigma_m=0.005, correlation_s=20.0)
    sol = calibrate(res.calibration_strips(), res.nominal, replace(VGICP, estimate=Estimate.of("lever_arm_x", "lever_arm_y")),
                    trajectory=model).solution
    for name in ("lever_arm_x", "lever_arm_y"):
        err = sol.values[name] - truth[name]
        assert abs(err) < 0.01 and abs(err) < 3 * sol.sigma[name], (name, err, sol.sigma[name])


def test_both_methods_run_and_are_compared_in_the_report(cli, tmp_path):
    cfg = survey_config("uav", seed=2, density=0.1, directions="cross", range_noise_m=0.03,
                        errors={"boresight_roll": np.radians(0.05), "boresight_pitch": np.radians(-0.04),
                                "boresight_yaw": np.radians(0.1)})
    sim = simulate_survey(cfg).write(tmp_path / "sim")
    args = [*sorted((sim / "strips").glob("*.laz")), "--trajectory", sim / "sbet.out", "--sensor", sim / "sensor.toml",
            "--truth", sim / "truth.json"]
    code, _, err = cli("boresight", *args, "--method", "planes,icp", "--out", tmp_path / "bad")
    assert code == 1 and "--method" in err and "planes, vgicp" in err
    out = tmp_path / "both"
    code, _, err = cli("boresight", *args, "--method", "planes,vgicp", "--out", out)
    assert code == 0, err
    docs = {m: json.loads((out / f"solution_{m}.json").read_text()) for m in ("planes", "vgicp")}
    assert (out / "sensor_planes.toml").exists() and (out / "sensor_vgicp.toml").exists()
    assert not (out / "solution.json").exists()
    for name in ANGLES:  # the same data and model: the two estimates agree within their σ
        a, b = docs["planes"]["parameters"][name], docs["vgicp"]["parameters"][name]
        assert abs(a["value"] - b["value"]) < 3 * np.hypot(a["sigma"], b["sigma"]), name
    # each method's global test reads σ0 as its matcher declares (and the solution records)
    assert docs["planes"]["strips"]["sigma0_reading"] == "t_model"
    assert docs["vgicp"]["strips"]["sigma0_reading"] == "skipped_rms"
    tests = {m: next(f for f in d["verdict"]["findings"] if f["check"] == "global test") for m, d in docs.items()}
    assert "right in the mean, not row by row" in tests["vgicp"]["detail"]
    assert "right in the mean, not row by row" not in tests["planes"]["detail"]
    html = (out / "report.html").read_text()
    assert "planes and vgicp compared" in html and "|difference| / combined σ" in html


@pytest.mark.slow
def test_uav_walls_right_with_the_default_and_a_wrong_option_fails_with_exit_3(cli, tmp_path):
    """Issue 26's survey (`calidar simulate survey --preset uav --seed 7 --boresight-error 0.05,-0.03,0.1
    --directions cross`): its walls are crossed by single scan lines, whose 12 points gave VGICP rows
    with any normal about the line. With the default (neighbourhoods must span a plane) every VGICP
    angle is within 3σ and 0.01° of the truth (measured: 1.4/0.2/1.5σ) and the two methods agree; fed
    the old options (min_spread 0: lines kept; max_scatter_ratio off: a's ball unchecked) and one fixed σ for
    every row, VGICP's rows do not fit their σ (σ0 2.19): the global test FAILs, so does every angle
    ("not determined") and `calidar boresight` exits 3. (Until the outer loop ran on while a parameter
    still moved — 27 Nov, seventh session — that run stopped after 2 iterations with yaw 8.6 combined σ
    off the tie planes', and the disagreement failed it too; the loop now takes yaw to 2.3σ of the
    truth and the two agree: the disagreement's FAIL is tested in tests/unit/strips/test_verdict.py.)"""
    cfg = survey_config("uav", seed=7, directions="cross", errors={
        "boresight_roll": np.radians(0.05), "boresight_pitch": np.radians(-0.03), "boresight_yaw": np.radians(0.1)})
    sim = simulate_survey(cfg).write(tmp_path / "sim")
    args = [*sorted((sim / "strips").glob("*.laz")), "--trajectory", sim / "sbet.out", "--sensor", sim / "sensor.toml",
            "--truth", sim / "truth.json", "--method", "planes,vgicp"]
    code, _, err = cli("boresight", *args, "--out", tmp_path / "ok")
    docs = {m: json.loads((tmp_path / "ok" / f"solution_{m}.json").read_text()) for m in ("planes", "vgicp")}
    for name in ANGLES:
        p = docs["vgicp"]["parameters"][name]
        assert abs(p["error"]) < 0.01 and abs(p["error"]) < 3 * p["sigma"], (name, p)
    found = {f["check"]: f for f in docs["vgicp"]["verdict"]["findings"]}
    assert found["planes and vgicp agree"]["status"] == "pass" and code in (0, 3)
    assert (code == 3) == any(d["verdict"]["status"] == "fail" for d in docs.values())
    # the wrong options, as a user would give them: neighbourhoods along a line kept, a's ball not checked
    # against b's plane (that check alone drops most of those rows: with it, min_spread 0 passes) and one fixed
    # σ for every row (each row's own scatter, since issue 26's third session a posterior variance per row, weighs
    # those rows down enough that the first two alone now pass: yaw 1.15σ from the truth; docs/validation.md)
    wrong = tmp_path / "wrong.toml"
    wrong.write_text('method = ["planes", "vgicp"]\n\n[vgicp]\nmin_spread = 0.0\nmax_scatter_ratio = 1e9\nsigma_m = 0.005\n')
    code, stdout, err = cli("boresight", *args, "--config", wrong, "--out", tmp_path / "wrong")
    assert code == 3, err
    doc = json.loads((tmp_path / "wrong" / "solution_vgicp.json").read_text())
    found = {f["check"]: f for f in doc["verdict"]["findings"]}
    assert doc["verdict"]["status"] == "fail" and found["global test"]["status"] == "fail"
    assert doc["sigma0"] > 1.5, doc["sigma0"]
    for name in ANGLES:
        assert found[name]["status"] == "fail" and "not determined" in found[name]["detail"], found[name]
    assert "fail global test" in " ".join(stdout.split())
