"""Separability of scanner structural errors from the boresight: the Palmer analysis (what
separates, and why), the generic Jacobian on the wedge and linear models, and the Palmer
parameters through the adjustment engine from control points."""

import numpy as np
import pytest

from calidar.scanners import PalmerScanner
from calidar.scanners import separability as ss
from calidar.scanners.analysis import pattern_angles
from calidar.scanners.sources import build_scanner, error_sources

TRUTH = {"boresight_roll": np.radians(0.05), "boresight_pitch": np.radians(-0.03), "boresight_yaw": np.radians(0.1),
         "eccentricity_ratio": 2e-4, "eccentricity_phase": np.radians(30), "delta_l": np.radians(0.02),
         "delta_r": np.radians(0.02)}


@pytest.fixture(scope="module")
def sep():
    return ss.palmer_separability()


def test_delta_l_is_a_pitch_of_minus_two_delta_l(sep):
    assert sep.mimic["delta_l"] == pytest.approx([0.0, -2.0, 0.0], abs=2e-3)
    assert sep.unexplained["delta_l"] < 0.08
    assert sep.corr("delta_l", "boresight_pitch") > 0.99
    assert abs(sep.corr("delta_l", "boresight_roll")) < 0.01 and abs(sep.corr("delta_l", "boresight_yaw")) < 0.01


def test_delta_l_residual_scales_with_sin_2b():
    """What a boresight cannot take of δ_L comes from the β-dependent incidence: ∝ sin 2B."""
    u = {b: ss.palmer_separability(PalmerScanner(palmer_mirror_tilt=np.radians(b)), n=180).unexplained["delta_l"]
         for b in (3.75, 7.5)}
    assert u[7.5] / u[3.75] == pytest.approx(np.sin(np.radians(15)) / np.sin(np.radians(7.5)), rel=0.05)


def test_delta_r_and_eccentricity_are_separable(sep):
    assert sep.unexplained["delta_r"] > 0.95  # the size of the oval: no rotation changes it
    assert sep.unexplained["eccentricity_cos"] > 0.5 and sep.unexplained["eccentricity_sin"] > 0.5
    # ε sin C moves fore and aft ends sideways like a roll: partly correlated, not degenerate
    assert -0.8 < sep.corr("eccentricity_sin", "boresight_roll") < -0.4
    assert np.min(sep.singular_values) > 0.02


def test_engine_recovers_palmer_parameters_from_control_points():
    sol = ss.control_adjustment(TRUTH, n=2000, noise_m=0.02, seed=1)
    v, s = sol.values, sol.sigma
    assert v["delta_r"] == pytest.approx(TRUTH["delta_r"], rel=0.10)
    assert v["eccentricity_ratio"] == pytest.approx(TRUTH["eccentricity_ratio"], rel=0.10)
    for k in ss.BORESIGHT:
        assert abs(np.degrees(v[k] - TRUTH[k])) < 0.002, k
    for k in TRUTH:  # reported σ consistent with the actual errors
        assert abs(v[k] - TRUTH[k]) < 4 * s[k], k
    assert any("boresight_pitch" in w and "delta_l" in w for w in sol.warnings)
    names = sol.parameters.free_names
    assert sol.correlation[names.index("boresight_pitch"), names.index("delta_l")] > 0.99


def test_fixing_delta_l_moves_it_into_the_pitch():
    free = ss.BORESIGHT + ("eccentricity_ratio", "eccentricity_phase", "delta_r")
    sol = ss.control_adjustment(TRUTH, n=2000, noise_m=0.02, seed=1, free=free)
    pitch_err = sol.values["boresight_pitch"] - TRUTH["boresight_pitch"]
    assert pitch_err == pytest.approx(-2 * TRUTH["delta_l"], rel=0.02)
    # the sin 2B-sized remainder shows in the residuals (2 cm noise → larger RMS)
    assert sol.residuals_after["rms"] > 0.021


def _sep(model):
    sc = build_scanner(model)
    return ss.separability(sc, error_sources(model), pattern_angles(sc, 360), 500.0)


def test_linear_scan_angle_offset_is_a_boresight_roll_exactly():
    sep = _sep("linear")
    assert sep.unexplained["scan_angle_offset"] < 1e-6
    assert sep.mimic["scan_angle_offset"] == pytest.approx([-1.0, 0.0, 0.0], abs=1e-6)
    assert sep.unexplained["scan_angle_scale"] > 0.95  # grows with the scan angle: no rotation does that
    assert abs(sep.corr("scan_angle_offset", "boresight_roll")) == pytest.approx(1.0, abs=1e-6)


def test_wedge_angle_error_changes_the_cone_no_rotation_reproduces():
    sep = _sep("wedge")
    assert sep.unexplained["wedge_angle_error"] > 0.99
    # the eccentricity's two components are alike up to the phase: the same share is their own
    assert sep.unexplained["eccentricity_cos"] == pytest.approx(sep.unexplained["eccentricity_sin"], rel=1e-3)


def test_left_after_boresight_is_the_unexplained_share():
    sep = ss.palmer_separability()
    v = np.radians(0.02)
    left = sep.left_after_boresight("delta_l", v).ravel()
    assert np.linalg.norm(left) == pytest.approx(sep.unexplained["delta_l"] * np.linalg.norm(sep.columns["delta_l"] * v),
                                                 rel=1e-9)
