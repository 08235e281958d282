"""Range calibration against simulated truth: accuracy, honest σ and 95 % intervals,
outlier tests, the two-step method, acceptance, the file round trip."""

import numpy as np
import pytest

from calidar.errors import CalibrationError
from calidar.io.total_station import read_observations, write_observations
from calidar.rangecal import calibrate, truth_parameters
from calidar.rangecal.fit import acceptance
from calidar.sim.total_station import TotalStationSimConfig, simulate_total_station


def test_recovers_simulated_offset_within_two_sigma():
    obs, truth = simulate_total_station(0)
    sol = calibrate(obs).solution
    t = truth_parameters(truth)
    assert abs(sol.values["range_offset"] - t["range_offset"]) < 2 * sol.sigma["range_offset"]
    assert abs(sol.values["range_scale"] - t["range_scale"]) < 3 * sol.sigma["range_scale"]
    # and σ is of the size the stated precisions imply (≈ 2 mm scanner noise over 34 targets)
    assert 0.2e-3 < sol.sigma["range_offset"] < 2e-3


def test_95_percent_intervals_cover_truth_over_200_runs():
    hits = {"range_offset": 0, "range_scale": 0}
    z = []
    for seed in range(1000, 1200):
        obs, truth = simulate_total_station(seed)
        res = calibrate(obs)
        t = truth_parameters(truth)
        for name in hits:
            lo, hi = res.fit.interval(name)
            hits[name] += lo <= t[name] <= hi
        z.append((res.solution.values["range_offset"] - t["range_offset"]) / res.solution.sigma["range_offset"])
    for name, n in hits.items():
        assert 180 <= n <= 198, f"{name}: {n / 2:.1f} % of 95 % intervals contain the truth"
    assert 0.8 < np.std(z) < 1.2  # reported σ consistent with the actual errors


def test_intervals_use_student_t_when_redundancy_is_small():
    cfg = TotalStationSimConfig(n_setups=1, groups_per_setup=1, e_per_setup=2)
    res = calibrate(simulate_total_station(3, cfg)[0])
    assert res.solution.dof == pytest.approx(4)
    assert res.fit.t_factor == pytest.approx(2.776, abs=1e-3)  # t(0.975, 4)


def test_data_snooping_rejects_gross_errors_only():
    cfg = TotalStationSimConfig(outliers=2)
    found = 0
    for seed in range(10):
        obs, truth = simulate_total_station(seed, cfg)
        res = calibrate(obs)
        bad = {(o["group"], o["point"]) for o in truth["outliers"]}
        got = {(r["group"], r["point"]) for r in res.fit.rejected}
        found += len(bad & got)
        assert len(got - bad) <= 1  # a false alarm is allowed at α = 0.001 only rarely
        t = truth_parameters(truth)
        assert abs(res.solution.values["range_offset"] - t["range_offset"]) < 3 * res.solution.sigma["range_offset"]
    assert found >= 19  # 20 gross errors of 10–25 σ


def test_two_step_method_intervals_cover_truth():
    # with no scale error ΔS estimates the offset and Δ (range error left after ΔS) is zero
    cfg = TotalStationSimConfig(range_scale_ppm=0.0)
    hits_ds = hits_d = 0
    for seed in range(2000, 2200):
        obs, truth = simulate_total_station(seed, cfg)
        m = calibrate(obs).method
        hits_ds += abs(m.delta_s - truth["range_offset_m"]) <= m.delta_s_half_width
        hits_d += abs(m.delta) <= m.delta_half_width
    assert 180 <= hits_ds <= 198 and 180 <= hits_d <= 198, (hits_ds, hits_d)


def test_two_step_method_in_solution_json():
    res = calibrate(simulate_total_station(7, TotalStationSimConfig(groups_per_setup=4))[0])
    m = res.method
    assert len(m.groups) == 8 and m.e_delta.size == 10
    np.testing.assert_allclose(np.mean(m.group_delta_s), m.delta_s)
    doc = res.solution.to_dict()
    assert doc["two_step_method"]["delta_s_m"] == pytest.approx(m.delta_s)
    assert len(doc["two_step_method"]["e_points"]) == 10
    iv = doc["intervals95"]["range_offset"]
    assert iv["low"] < doc["parameters"]["range_offset"]["value"] < iv["high"]


def test_acceptance_against_tolerance():
    obs, truth = simulate_total_station(2, TotalStationSimConfig(range_offset_m=0.010, range_scale_ppm=0.0))
    res = calibrate(obs)
    assert acceptance(res.fit, 0.015)["passed"]
    assert not acceptance(res.fit, 0.009)["passed"]
    a = acceptance(res.fit, 0.015)
    assert 0.010 < a["max_bound95_m"] < 0.015


def test_one_distance_only_is_a_clear_error_unless_the_scale_is_fixed():
    obs, truth = simulate_total_station(1, TotalStationSimConfig(n_setups=1, groups_per_setup=1, e_per_setup=0,
                                                                 range_scale_ppm=0.0))
    with pytest.raises(CalibrationError, match="range_scale cannot be separated"):
        calibrate(obs)
    res = calibrate(obs, fix_scale=True)
    sol = res.solution
    assert "range_scale" not in sol.sigma and res.fit.interval("range_scale") is None
    assert abs(sol.values["range_offset"] - truth["range_offset_m"]) < 3 * sol.sigma["range_offset"]
    assert acceptance(res.fit, 1.0)["passed"]


@pytest.mark.parametrize("unit,vertical", [("deg", "zd"), ("gon", "va"), ("gon", "zd"), ("deg", "va")])
def test_file_round_trip_in_every_angle_convention(tmp_path, unit, vertical):
    obs, _ = simulate_total_station(5)
    path = write_observations(tmp_path / "obs.csv", obs, unit, vertical)
    back = read_observations(path)
    np.testing.assert_allclose(back.va, obs.va, atol=2e-9)
    np.testing.assert_allclose(np.mod(back.hz - obs.hz + 1, 2 * np.pi) - 1, 0, atol=2e-9)
    np.testing.assert_allclose(back.slope, obs.slope, atol=6e-5)
    np.testing.assert_array_equal(back.point, obs.point)
    np.testing.assert_array_equal(back.group, obs.group)
    assert back.setups[1].p_slope == pytest.approx(obs.setups[1].p_slope, abs=6e-5)
    assert back.scanner_sigma == obs.scanner_sigma
    assert back.setups[0].angle_sigma == pytest.approx(obs.setups[0].angle_sigma)


def test_optimistic_precision_stops_snooping_with_a_warning():
    # the file claims ten times better precisions than the instruments have: the global test
    # fails and snooping stops at 20 % of the targets instead of throwing the data away
    from dataclasses import replace

    obs, _ = simulate_total_station(9)
    setups = [replace(s, angle_sigma=s.angle_sigma / 10, distance_sigma_m=s.distance_sigma_m / 10,
                      distance_sigma_ppm=s.distance_sigma_ppm / 10) for s in obs.setups]
    obs = replace(obs, scanner_sigma=0.2e-3, setups=setups)
    res = calibrate(obs)
    assert not res.fit.global_test["passed"]
    assert len(res.fit.rejected) <= 0.2 * len(obs) + 1
    assert any("too optimistic" in w for w in res.solution.warnings)
