"""The plan's predicted σ against the strip adjustment's own σ on a simulated survey of the same plan,
and the plain-words diagnosis of poor plans."""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest

from calidar.io.flight_lines import PlanLine
from calidar.planning.findings import findings
from calidar.planning.geometry import Instrument, fly_plan
from calidar.planning.predict import PlanSettings, predict
from calidar.planning.simulate import simulate_and_calibrate
from calidar.planning.suggest import suggest
from calidar.planning.terrain import FlatTerrain, scene_terrain
from calidar.sensor import Sensor
from calidar.sim.survey import survey_config


def line(n, x0, y0, x1, y1, h=80.0):
    return PlanLine(n, np.array([x0, y0], float), np.array([x1, y1], float), h, 8.0)


OPPOSITE = [line(1, -30, -60, -30, 60), line(2, -30, 60, -30, -60), line(3, 30, -60, 30, 60), line(4, 30, 60, 30, -60)]
INSTRUMENT = Instrument(Sensor(lever_arm_x=0.05, lever_arm_z=0.12), pulse_rate_hz=2000.0)


@pytest.fixture(scope="module")
def scene():
    base = survey_config("uav", scene_seed=3)
    base = replace(base, scene=replace(base.scene, width_m=200.0, length_m=200.0))
    return base, scene_terrain(base)


def test_predicted_sigma_matches_the_adjustments_own_on_a_simulated_survey(scene):
    """The prediction (no point simulated) against the σ the strip calibrator reports for one simulated
    survey of the plan (the calibrator's σ are honest: docs/validation.md): within 15 %."""
    base, terrain = scene
    settings = PlanSettings(estimate=("boresight",))
    pred = predict(OPPOSITE, terrain, INSTRUMENT, settings)
    run = simulate_and_calibrate(fly_plan(OPPOSITE, terrain), INSTRUMENT, settings, pred.names, 5, base)
    for name, sigma in zip(pred.names, pred.reported):
        assert sigma == pytest.approx(run["sigma"][name], rel=0.15), name
    # the expected error: the same estimator with the rows' real scatter, at most what it reports
    assert np.all(pred.sigma <= pred.reported * 1.001)


def test_one_height_plan_named_poor_for_the_along_track_lever_arm(scene):
    """Boresight and horizontal lever arm from lines at one height: the along-track lever arm is not
    determined (pitch moves points alike, the trajectory's position errors hide the rest); lines at a
    second height determine it better."""
    _, terrain = scene
    settings = PlanSettings(estimate=("boresight", "lever_arm_x", "lever_arm_y"))
    poor = predict(OPPOSITE[:2], terrain, INSTRUMENT, settings)
    assert poor.poor
    x = poor.names.index("lever_arm_x")
    assert not poor.determined(x)
    why = next(f for f in findings(poor) if f["parameter"] == "lever_arm_x")
    assert "80 m" in why["why"] and "pitch" in why["why"] and "two heights" in why["action"]
    higher = [*OPPOSITE[:2], line(5, -30, -60, -30, 60, 130.0), line(6, -30, 60, -30, -60, 130.0)]
    better = predict(higher, terrain, INSTRUMENT, settings)
    assert better.reported[better.names.index("lever_arm_x")] < 0.9 * poor.reported[x]


def test_flat_ground_does_not_show_pitch_or_heading():
    """Level flight over flat ground: a pitch or heading error only moves points horizontally on a
    horizontal surface, so the tie planes cannot see them (σ infinite, named not determined); roll tilts
    the swath and is determined."""
    inst = replace(INSTRUMENT, motion_rad=(0.0, 0.0))
    pred = predict(OPPOSITE, FlatTerrain(0.0), inst, PlanSettings(estimate=("boresight",)))
    sigma = dict(zip(pred.names, pred.sigma))
    assert np.isfinite(sigma["boresight_roll"]) and pred.determined(pred.names.index("boresight_roll"))
    assert not np.isfinite(sigma["boresight_pitch"]) and not np.isfinite(sigma["boresight_yaw"])
    assert pred.poor


def test_suggestion_improves_the_worst_parameter(scene):
    """The candidates are tried one by one; the first suggestion lowers the worst parameter's σ."""
    _, terrain = scene
    settings = PlanSettings(estimate=("boresight",))
    pred = predict(OPPOSITE, terrain, INSTRUMENT, settings)
    found = suggest(OPPOSITE, terrain, INSTRUMENT, settings, pred)
    worst = pred.names[pred.worst()]
    assert found and found[0].parameter == worst
    assert found[0].sigma_after < 0.8 * found[0].sigma_before
    assert all(a.sigma_after <= b.sigma_after for a, b in zip(found, found[1:]))
