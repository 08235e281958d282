"""The fast large-survey simulator (calidar.sim.large_survey, issue 32): exact geometry by
construction, the same flight as the detailed simulator, files a calibration reads, and a
boresight error recovered within 3σ."""

from dataclasses import replace

import numpy as np
import pytest

import calidar
from calidar import georef
from calidar.sim.large_survey import (FacetGround, cropped, facet_height, plan_large_survey, shoot,
                                      simulate_chunk, simulate_large_survey, tiled_to_crs)
from calidar.sim.patterns import scan_angles
from calidar.sim.survey import PRESETS, survey_config

ERRORS = {"boresight_roll": np.radians(0.03), "boresight_pitch": np.radians(-0.04), "boresight_yaw": np.radians(0.05)}


def small(density=0.2, **kw):
    scene = replace(PRESETS["airborne"].scene, width_m=1400.0, length_m=1000.0)
    return survey_config("airborne", seed=3, density=density, directions="cross", scene=scene, errors=ERRORS,
                         range_noise_m=0.03, **kw)


@pytest.fixture(scope="module")
def plan():
    return plan_large_survey(small())


def test_the_flight_is_the_detailed_simulators(plan):
    """Same seed, same lines, same measured trajectory as calidar.sim.survey would fly (over its
    own scene: the plan depends on the scene's extent and mean height only)."""
    assert len(plan.lines) >= 4
    assert plan.truth.boresight_yaw == pytest.approx(plan.nominal.boresight_yaw + ERRORS["boresight_yaw"])
    dpos = plan.trajectory.ecef - plan.trajectory_true.ecef
    assert 0.005 < np.std(dpos) < 0.2  # the preset's 3 cm GNSS errors, not zero


def test_a_cropped_plan_flies_the_same_pulses_over_a_smaller_area(plan):
    """cropped (issue 26/32: the 10⁹ run's density in fewer points): the lines' windows cut to the
    box, lines outside it dropped, the same trajectory and pulse rate."""
    box = (200.0, 200.0)  # the two cross lines
    part = cropped(plan, *box)
    assert 0 < len(part.lines) < len(plan.lines)
    whole = {ln.number: k for k, ln in enumerate(plan.lines)}
    for k, line in enumerate(part.lines):
        (a, b), (a0, b0) = part.windows[k], plan.windows[whole[line.number]]
        assert a0 <= a < b <= b0 and part.strip_errors[k] is plan.strip_errors[whole[line.number]]
        tr = plan.trajectory_true
        enu = plan.scene.ecef_to_enu(tr.ecef[(tr.time >= a) & (tr.time <= b)])
        assert np.all(np.abs(enu[:, :2]) <= np.array(box) + 1e-9)
        assert b - a > 1.0  # each kept line crosses the box
    assert part.pulse_rate_hz == plan.pulse_rate_hz


def test_hits_lie_on_the_ground_and_invert_to_the_simulated_ranges_and_angles(plan):
    """The true beams' hits re-georeferenced inversely with the TRUE mounting and trajectory give
    back the simulated ranges and encoder angles (~1e-6), and lie on the closed-form ground."""
    cfg, g = plan.config, plan.ground
    t = np.linspace(*plan.windows[1], 20_000)
    enc = scan_angles(plan.nominal.scanner, t, cfg.scan_rate_hz, cfg.half_fov_rad, cfg.scan_pattern)
    enc = enc + np.random.default_rng(0).normal(0.0, 1e-4, enc.shape)
    rho, hit, kind = shoot(plan, t, enc)
    obs = georef.inverse(plan.trajectory_true, plan.truth, t, plan.scene.enu_to_ecef(hit))
    np.testing.assert_allclose(obs.range_m, plan.truth.measured_range(rho), atol=1e-6)
    np.testing.assert_allclose(obs.angles[:, 0], enc, atol=1e-9)
    np.testing.assert_allclose(obs.angles[:, 1], 0.0, atol=1e-9)
    h = np.array([facet_height(x, y, g.base_m, g.block_m, g.max_slope, g.seed)[0] for x, y in hit[:, :2]])
    np.testing.assert_allclose(hit[:, 2], h, atol=1e-6)
    assert set(np.unique(kind)) == {0, 1, 2, 3}  # flat, pyramids, both gables: slopes both ways
    lo, hi = np.percentile(rho, [1, 99])
    assert 950 < lo and hi < 1150  # 1000 m above ground, ±20° beams


def test_delivered_points_are_the_lidar_equation_of_the_records(plan):
    """The delivered points are georef.forward of the recorded ranges and encoder angles with the
    nominal sensor and the measured trajectory; their true hits are off by the errors only."""
    chunk = simulate_chunk(plan, 0, 5000, 30_000, np.random.default_rng(1))
    obs = georef.inverse(plan.trajectory, plan.nominal, chunk["gps_time"], chunk["ecef"])
    np.testing.assert_allclose(obs.range_m, chunk["range_m"], atol=1e-6)
    np.testing.assert_allclose(obs.angles[:, 0], chunk["angles"], atol=1e-9)
    off = np.linalg.norm(plan.scene.ecef_to_enu(chunk["ecef"]) - chunk["true_enu"], axis=1)
    assert 0.1 < np.median(off) < 3.0  # 0.03–0.05° at 1000 m: 0.5–0.9 m, plus cm noise


def test_tiled_crs_is_proj_to_a_tenth_of_a_millimetre(plan):
    chunk = simulate_chunk(plan, 2, 0, 50_000, np.random.default_rng(2))
    fast = tiled_to_crs(chunk["ecef"], chunk["true_enu"][:, :2], plan.crs)
    np.testing.assert_allclose(fast, georef.to_crs(chunk["ecef"], plan.crs), rtol=0, atol=1e-4)


def test_ground_is_continuous_at_block_edges():
    g = FacetGround(base_m=10.0, block_m=80.0, max_slope=0.5, seed=4)
    edge = np.arange(-400.0, 400.0, 80.0)
    for x in edge:
        for y in np.linspace(-400, 400, 37):
            for a, b in (((x - 1e-9, y), (x + 1e-9, y)), ((y, x - 1e-9), (y, x + 1e-9))):  # east, north edges
                assert facet_height(*a, g.base_m, g.block_m, g.max_slope, g.seed)[0] == pytest.approx(
                    facet_height(*b, g.base_m, g.block_m, g.max_slope, g.seed)[0], abs=1e-6)


@pytest.mark.slow
def test_boresight_recovers_the_error_from_the_written_files(tmp_path):
    """`calidar boresight`'s pipeline on a small fast-simulated survey written to LAZ recovers the
    boresight error within 3σ, with the trajectory model on (the preset's trajectory errors)."""
    from calidar.pipelines.boresight import calibrate_strips

    res = simulate_large_survey(small(density=0.4), tmp_path / "sim", workers=1)
    sim = tmp_path / "sim"
    files = sorted((sim / "strips").glob("*.laz"))
    assert len(files) == len(res.lines)
    assert sum(len(calidar.read_las(f)) for f in files) == res.n_points
    run = calibrate_strips(files, sim / "sbet.out", sim / "sensor.toml", truth=sim / "truth.json")
    sol = run.results["planes"].solution
    for k, v in ERRORS.items():
        assert abs(sol.values[k] - v) < 3 * sol.sigma[k], (k, sol.values[k], v, sol.sigma[k])
        assert sol.sigma[k] < np.radians(0.003)
