"""No trajectory accuracy file: the trajectory's accuracy level estimated from the overlaps
(calidar.strips.trajectory_level) against the simulator's truth."""

from __future__ import annotations

import functools

import numpy as np
import pytest

from calidar.sim.survey import simulate_survey, survey_config
from calidar.strips.calibrate import calibrate
from calidar.strips.trajectory_errors import TrajectoryModel
from calidar.strips.trajectory_level import MIN_REDUNDANCY
from calidar.trajectory_accuracy import SURVEY_GRADE

ERRORS = {"boresight_roll": np.radians(0.03), "boresight_pitch": np.radians(-0.04), "boresight_yaw": np.radians(0.05)}
ANGLES = tuple(ERRORS)
#: the boresight pipeline's model without an accuracy file: survey-grade priors, their level estimated
MODEL = TrajectoryModel(1.0, correlation_s=20.0, attitude_correlation_s=3.5, accuracy=SURVEY_GRADE, estimate_level=True)


@functools.lru_cache(maxsize=1)
def _survey(gnss_m: float, attitude_deg: float, seed: int = 3):
    cfg = survey_config("airborne", seed=seed, density=0.3, directions="cross", errors=ERRORS, range_noise_m=0.03,
                        gnss_noise_m=gnss_m, attitude_noise_rad=np.radians(attitude_deg))
    return simulate_survey(cfg)


def _calibrate(gnss_m: float, attitude_deg: float, model=MODEL, seed: int = 3):
    res = _survey(gnss_m, attitude_deg, seed)
    out = calibrate(res.calibration_strips(), res.nominal, trajectory=model)
    return res, out


@pytest.mark.slow
def test_small_trajectory_errors_are_recognised():
    """Trajectory errors a third of the survey-grade default's (1.5 cm, 0.001°): every group of
    priors the overlaps can check comes out within a factor 1.6 of the truth (the factor's own σ
    is ≈ 10 % with 50–150 redundant priors; the simulator's errors are smoother than the model's
    Gauss–Markov process), the boresight within 3σ of its truth."""
    res, out = _calibrate(0.015, 0.001)
    level = out.solution.extra["trajectory_accuracy_estimate"]
    assert level["source"] == "data"
    truth = {"position_horizontal": 0.015, "position_vertical": 0.015, "attitude_horizontal": 0.001, "heading": 0.001}
    medians = out.trajectory_model.accuracy.medians()
    found = {"position_horizontal": medians["north_rms_m"], "position_vertical": medians["down_rms_m"],
             "attitude_horizontal": medians["roll_rms_deg"], "heading": medians["heading_rms_deg"]}
    estimated = [g for g, v in level["groups"].items() if v["estimated"]]
    assert {"position_horizontal", "position_vertical", "attitude_horizontal"} <= set(estimated)
    for g in set(estimated) - {"heading"}:  # heading: the test below
        assert 1 / 1.6 < found[g] / truth[g] < 1.6, (g, found[g], truth[g])
    truth_values = res.truth.parameters()
    for n in ANGLES:
        err = out.solution.values[n] - truth_values[n]
        assert abs(err) < 3 * out.solution.sigma[n], (n, err / out.solution.sigma[n])


@pytest.mark.slow
def test_small_heading_errors_are_bounded_not_mismeasured():
    """The heading group of the survey above (true 0.001°: 0.125 × the survey-grade 0.008°). The
    overlaps check its priors at the default (redundancy 62–73 on seeds 3–6) but hardly at the
    level they point to: its information tr(R²) there is 0.0, 0.0, 3.8, 7.8 (seeds 3–6; the
    factor's relative σ 1/√(2 tr R²) ≥ 25 %), its restricted likelihood's 95 % interval 0.01–0.13,
    0.01–0.13, 0.02–0.23, 0.08–0.31 × the default — it cannot be measured within 1.6× (estimated,
    it came out 0.51, 0.07, 0.88, 2.19 × the truth with a stated ±14–17 %). So it is bounded, not
    estimated, and held at the upper end the data leave it: 0.168, 0.206, 0.271, 0.361 × the
    default on seeds 3–6, 1.3–2.9 × the truth (benchmarks/strips_heading_level.py)."""
    res, out = _calibrate(0.015, 0.001)
    level = out.solution.extra["trajectory_accuracy_estimate"]
    heading = level["groups"]["heading"]
    assert heading.get("bounded") and not heading["estimated"], heading
    assert heading["redundancy_at_stated_sigma"] >= MIN_REDUNDANCY > heading["information"]
    found = out.trajectory_model.accuracy.medians()["heading_rms_deg"]
    assert 0.001 <= found < 3 * 0.001, found  # a bound: never below the truth, still informative
    truth = res.truth.parameters()
    err = out.solution.values["boresight_yaw"] - truth["boresight_yaw"]
    assert abs(err) < 3 * out.solution.sigma["boresight_yaw"], err / out.solution.sigma["boresight_yaw"]


@pytest.mark.slow
def test_an_exact_trajectory_shrinks_the_sigma_towards_the_model_off():
    """An exact trajectory (no GNSS/INS error at all) and no accuracy file: the overlaps say so —
    every group's level comes out at the floor, where they no longer check it (information tr R²
    0.2, 9.4, 0.6, 0.0), so each is bounded, held at the upper end the data leave it, 4 %, 1 %,
    5 % and 11 % of the survey-grade default (before issue 26's eleventh session: reported as
    estimated, at 1–1.4 %) — and yaw's σ comes within 2× of the trajectory model switched off
    (measured 0.00018° against 0.00014° since the twelfth session averages it over the range the
    data allow below those ends, 0.00026° held at them; stated before the eleventh session:
    0.00017° against 0.00011°; with the survey-grade default as priors 0.00188°); every angle
    within 3σ of its truth."""
    res, out = _calibrate(0.0, 0.0)
    level = out.solution.extra["trajectory_accuracy_estimate"]
    assert level["source"] == "data"
    groups = level["groups"].values()
    assert all(v.get("bounded") and v["sigma_factor"] <= 0.15 for v in groups), level["groups"]
    _, off = _calibrate(0.0, 0.0, model=None)
    assert out.solution.sigma["boresight_yaw"] < 2.0 * off.solution.sigma["boresight_yaw"]
    truth = res.truth.parameters()
    for n in ANGLES:
        err = out.solution.values[n] - truth[n]
        assert abs(err) < 3 * out.solution.sigma[n], (n, err / out.solution.sigma[n])
