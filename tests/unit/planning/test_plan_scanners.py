"""Plans for rotating scanners (Palmer oval, wedge cone) and the plan that cannot part pitch from the
along-track lever arm: the synthetic poses land on the patches, each point is seen ahead and back, the
sensor.toml's scanner sets the swath, and gentle hills flown at one height are named poor for the right
reason, the second height the suggestion names separating them."""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest

from calidar.io.flight_lines import PlanLine
from calidar.planning.findings import findings
from calidar.planning.geometry import Instrument, fly_plan
from calidar.planning.rows import side_poses
from calidar.planning.predict import PlanSettings, predict
from calidar.planning.simulate import FLAT_SCENE
from calidar.planning.sweep import pattern_half_fov
from calidar.planning.suggest import suggest
from calidar.planning.terrain import FlatTerrain, scene_terrain
from calidar.scanners.palmer import PalmerScanner
from calidar.scanners.wedge import WedgeScanner
from calidar.sensor import Sensor
from calidar.sim.survey import survey_config
from calidar.strips.strip import georeference_pose


def line(n, x0, y0, x1, y1, h=80.0):
    return PlanLine(n, np.array([x0, y0], float), np.array([x1, y1], float), h, 8.0)


def rotating(scanner, **mounting) -> Instrument:
    nominal = Sensor(lever_arm_x=0.05, lever_arm_z=0.12, scanner=scanner, **mounting)
    return Instrument(nominal, pulse_rate_hz=2000.0, half_fov_rad=pattern_half_fov(nominal))


@pytest.mark.parametrize("scanner", [PalmerScanner(), WedgeScanner()], ids=["palmer", "wedge"])
def test_rotating_scanner_sees_each_point_ahead_and_back(scanner):
    """Every point inside the swath gets two poses (the pattern's fore and aft branches) whose nominal
    georeferencing lands on it (< 5 mm, with the platform wobbling and a 3° boresight yaw); the fore
    look comes first, the beam pointing forward in the body frame, the aft one back. The points span 0.7 of the nominal
    half swath: this line's roll wobble reaches −4.8° (3.2σ of its 1.5°), which moves the pattern
    6.7 m sideways, so points at 0.74–0.8 of it lie off the pattern when it passes (no look reaches
    them; 0.7 keeps the edge, where the secant steps fail and the bracketing takes over)."""
    inst = rotating(scanner, boresight_yaw=np.radians(3.0))
    f = fly_plan([line(1, -7, -60, -7, 60)], FlatTerrain(0.0))[0]
    half = 80.0 * np.tan(inst.half_fov_rad)
    rng = np.random.default_rng(1)
    pts = np.column_stack([-7.0 + rng.uniform(-0.7, 0.7, 300) * half, rng.uniform(-35, 35, 300),
                           rng.uniform(-3, 3, 300)])
    pose, t, beam = side_poses(f, pts, inst)
    assert len(t) == 2 * len(pts)
    back = georeference_pose(inst.nominal, pose)
    assert np.max(np.linalg.norm(back - np.tile(pts, (2, 1)), axis=1)) < 0.005
    assert np.all(t[:300] < t[300:])
    # ahead and back in the body frame (x forward): near the pattern's edge the aft look is within 2°
    # of vertical, so the body's wobble can lean it forward in the local frame (one point here: +0.14°)
    forward = np.einsum("nji,nj->ni", pose.r_lb, beam)[:, 0]
    assert np.all(forward[:300] > 0) and np.all(forward[300:] < 0)


def test_linear_scanner_keeps_one_look():
    """A linear scanner: one pose per point, in the scan plane (the georeferencing lands on it)."""
    inst = Instrument(Sensor(lever_arm_x=0.05, lever_arm_z=0.12), pulse_rate_hz=2000.0)
    f = fly_plan([line(1, -7, -60, -7, 60)], FlatTerrain(0.0))[0]
    pts = np.column_stack([np.linspace(-40, 26, 50), np.linspace(-30, 30, 50), np.zeros(50)])
    pose, t, _ = side_poses(f, pts, inst)
    assert len(t) == 50
    assert np.max(np.linalg.norm(georeference_pose(inst.nominal, pose) - pts, axis=1)) < 0.02


def test_palmer_swath_from_its_pattern_and_a_plan_predicted():
    """The Palmer's swath is its oval's across-track half width (±10.5° for A = 45°, B = 7.5°), not a
    field of view; four lines over sloping ground give finite σ for the boresight."""
    inst = rotating(PalmerScanner())
    assert np.degrees(inst.half_fov_rad) == pytest.approx(10.55, abs=0.1)
    lines = [line(1, -7, -60, -7, 60), line(2, -7, 60, -7, -60), line(3, 7, -60, 7, 60), line(4, 7, 60, 7, -60)]
    base = survey_config("uav", scene_seed=3)
    terrain = scene_terrain(replace(base, scene=replace(base.scene, width_m=200.0, length_m=200.0)))
    pred = predict(lines, terrain, inst, PlanSettings(estimate=("boresight",)))
    assert np.all(np.isfinite(pred.reported)) and not pred.poor
    assert all(p["tie_planes"] > 300 for p in pred.pairs)


def test_gentle_hills_at_one_height_cannot_part_pitch_from_the_lever_arm():
    """Gentle hills (2 m relief, no roof or tree), a steady platform, four lines at 80 m: every point
    moves along track by height × pitch + lever_arm_x with the height the same within a few %, so the
    plan is named poor with |ρ| > 0.95 and the one height as the reason; the suggestion is a line at a
    second height, and it lowers both σ by over 25 %."""
    base = survey_config("uav", scene_seed=3)
    scene = replace(base.scene, width_m=300.0, length_m=300.0, **{**FLAT_SCENE, "relief_m": 2.0})
    terrain = scene_terrain(replace(base, scene=scene))
    inst = replace(Instrument(Sensor(lever_arm_x=0.05, lever_arm_z=0.12), pulse_rate_hz=2000.0),
                   motion_rad=(np.radians(0.3), np.radians(0.3)))
    lines = [line(1, -30, -60, -30, 60), line(2, -30, 60, -30, -60), line(3, 30, -60, 30, 60),
             line(4, 30, 60, 30, -60)]
    settings = PlanSettings(estimate=("boresight_pitch", "lever_arm_x"))
    pred = predict(lines, terrain, inst, settings)
    assert pred.poor and abs(pred.correlation[0, 1]) > 0.95
    pair = next(f for f in findings(pred) if f["parameter"] == "boresight_pitch and lever_arm_x")
    assert "cannot separate" in pair["why"]
    why = next(f for f in findings(pred) if f["parameter"] == "lever_arm_x")["why"]
    assert "80 m" in why and "pitch" in why
    best = suggest(lines, terrain, inst, settings, pred)[0]
    assert "second height" in best.kind and best.line.height_agl_m > 80.0
    assert np.all(best.prediction.reported < 0.75 * pred.reported)


def test_palmer_prediction_matches_the_calibrators_own_sigma():
    """Four Palmer lines over the scene simulated once and calibrated: the predicted σ (no point
    simulated) within 20 % of the σ the strip calibrator reports. Averaging both looks in every patch
    would miss the pitch that one-look patches beside buildings show (predicted 1.7× too wide)."""
    from calidar.planning.simulate import simulate_and_calibrate

    inst = rotating(PalmerScanner())
    lines = [line(1, -7, -60, -7, 60), line(2, -7, 60, -7, -60), line(3, 7, -60, 7, 60), line(4, 7, 60, 7, -60)]
    base = survey_config("uav", scene_seed=3)
    base = replace(base, scene=replace(base.scene, width_m=200.0, length_m=200.0))
    terrain = scene_terrain(base)
    settings = PlanSettings(estimate=("boresight",))
    pred = predict(lines, terrain, inst, settings)
    run = simulate_and_calibrate(fly_plan(lines, terrain), inst, settings, pred.names, 1, base)
    for name, sigma in zip(pred.names, pred.reported):
        assert sigma == pytest.approx(run["sigma"][name], rel=0.2), name
