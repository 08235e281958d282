"""Distances P→X from polar observations: the general law of cosines, the method's special
case for A/B (horizontal distances, level with P), and the analytic partials."""

import numpy as np
import pytest

from calidar.rangecal.geometry import distance_law_of_cosines, distance_level, distance_partials, polar_to_local
from calidar.sim.total_station import TotalStationSimConfig, simulate_total_station

NOISE_FREE = TotalStationSimConfig(scanner_sigma_mm=0.0, angle_arcsec=0.0, distance_mm=0.0, distance_ppm=0.0,
                                   range_offset_m=0.0, range_scale_ppm=0.0)


def _pairs(obs):
    p = np.array([[s.p_slope, s.p_va, s.p_hz] for s in obs.setups])[obs.setup]
    return p[:, 0], p[:, 1], p[:, 2], obs.slope, obs.va, obs.hz


def test_law_of_cosines_equals_cartesian_distance():
    rng = np.random.default_rng(0)
    n = 1000
    args = (rng.uniform(1, 50, n), rng.uniform(-1.2, 1.2, n), rng.uniform(0, 2 * np.pi, n),
            rng.uniform(1, 50, n), rng.uniform(-1.2, 1.2, n), rng.uniform(0, 2 * np.pi, n))
    cart = np.linalg.norm(polar_to_local(*args[3:]) - polar_to_local(*args[:3]), axis=1)
    np.testing.assert_allclose(distance_law_of_cosines(*args), cart, rtol=0, atol=1e-9)


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_special_case_for_a_b_agrees_with_general_formula_for_prescribed_geometry(seed):
    obs, _ = simulate_total_station(seed, NOISE_FREE)
    args = _pairs(obs)
    general = distance_law_of_cosines(*args)
    # noise-free: the general formula gives the simulated scanner range (the truth) exactly
    np.testing.assert_allclose(general, obs.scanner, atol=1e-4)  # scanner ranges are written to 0.1 mm
    ab = np.isin(obs.point, ["A", "B"])
    np.testing.assert_allclose(distance_level(*args)[ab], general[ab], rtol=0, atol=1e-9)
    # the special case is special: for C/D (above/below the axis, not level with P) it is wrong
    cd = np.isin(obs.point, ["C", "D"])
    assert np.min(np.abs(distance_level(*args)[cd] - general[cd])) > 0.01


def test_level_formula_fails_when_scanner_not_level():
    obs, _ = simulate_total_station(4, NOISE_FREE)
    s_p, va_p, hz_p, s_x, va_x, hz_x = _pairs(obs)
    ab = np.isin(obs.point, ["A", "B"])
    # raise A/B by 0.2 m (a tilted scan circle): the general formula sees it, the special case does not
    x = polar_to_local(s_x, va_x, hz_x)
    x[:, 2] += 0.2
    s2 = np.linalg.norm(x, axis=1)
    va2 = np.arcsin(x[:, 2] / s2)
    gen = distance_law_of_cosines(s_p, va_p, hz_p, s2, va2, hz_x)[ab]
    lev = distance_level(s_p, va_p, hz_p, s2, va2, hz_x)[ab]
    np.testing.assert_allclose(gen**2 - lev**2, 0.2**2, rtol=1e-6)


def test_partials_match_central_differences():
    rng = np.random.default_rng(5)
    args = np.array([rng.uniform(2, 8, 50), rng.uniform(-0.2, 0.2, 50), rng.uniform(0, 6, 50),
                     rng.uniform(3, 40, 50), rng.uniform(-0.5, 0.5, 50), rng.uniform(0, 6, 50)])
    d, part = distance_partials(*args)
    np.testing.assert_allclose(d, distance_law_of_cosines(*args), atol=1e-9)
    for j, h in enumerate([1e-5, 1e-7, 1e-7, 1e-5, 1e-7, 1e-7]):
        up, dn = args.copy(), args.copy()
        up[j] += h
        dn[j] -= h
        num = (distance_law_of_cosines(*up) - distance_law_of_cosines(*dn)) / (2 * h)
        np.testing.assert_allclose(part[:, j], num, rtol=1e-5, atol=1e-6)


def test_level_check_detects_a_tilted_scanner():
    from dataclasses import replace

    from calidar.rangecal.method import level_check

    obs, _ = simulate_total_station(6)
    ok = level_check(obs)
    assert ok["level"] and ok["max_abs_height_m"] < 0.003
    # raise the first group's A by 2 cm: a scanner rolled by ~0.4°
    i = np.flatnonzero((obs.group == "G1") & (obs.point == "A"))[0]
    x = polar_to_local(obs.slope[i], obs.va[i], obs.hz[i]) + [0, 0, 0.02]
    slope, va = obs.slope.copy(), obs.va.copy()
    slope[i] = np.linalg.norm(x)
    va[i] = np.arcsin(x[2] / slope[i])
    tilted = level_check(replace(obs, slope=slope, va=va, line=np.arange(len(obs)) + 10))
    assert not tilted["level"] and tilted["worst_line"] == i + 10
    assert tilted["max_abs_height_m"] == pytest.approx(0.02, abs=0.003)
