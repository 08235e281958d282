"""Trajectory corrections as nuisance parameters (calidar.strips.trajectory_errors)."""

from __future__ import annotations

import re

import numpy as np
import pytest

from calidar.errors import InputError
from calidar.strips.strip import georeference_pose
from calidar.strips.trajectory_errors import TrajectoryModel, corrections


def test_gauss_markov_prior_of_the_knots():
    m = TrajectoryModel(block_s=2.0, position_sigma_m=0.03, correlation_s=20.0)
    R = m.correlation(30)
    phi = np.exp(-2.0 / 20.0)
    assert np.allclose(np.diag(R), 1.0) and np.allclose(np.diag(R, 1), phi) and np.allclose(np.diag(R, 5), phi**5)
    P = np.linalg.inv(R)  # a first-order Gauss–Markov process: tridiagonal precision
    assert np.allclose(np.triu(P, 2), 0.0, atol=1e-9)
    spans = {1: (0.0, 7.0), 2: (10.0, 11.0)}
    groups = m.prior_correlation(spans)
    # knots every 2 s from each strip's start to past its end: 0…8 s (5) and 10, 12 s (2), the
    # shifts one process over the flight: one group per axis holding both strips' knots
    assert [names[0] for names, _ in groups] == [f"trajectory_bias_{ax}_1_0" for ax in ("east", "north", "up")]
    assert [len(names) for names, _ in groups] == [7, 7, 7]
    assert groups[2][0][5] == "trajectory_bias_up_2_0"
    assert TrajectoryModel(2.0, 0.03).prior_correlation(spans) == []  # no correlation time: independent


def test_the_shifts_are_one_process_across_the_lines():
    """The knots of two lines are correlated by their time apart, as one Gauss–Markov process
    (less a 5 % share of each line's own), so the flight's mean shift is as uncertain as that
    process makes it; two lines at the same time do not make the prior singular."""
    from calidar.strips.trajectory_errors import OWN_STRIP_SHARE

    m = TrajectoryModel(block_s=1.0, position_sigma_m=0.02, correlation_s=20.0)
    spans = {3: (0.0, 20.0), 5: (30.0, 50.0)}
    R = m.flight_correlation(spans)
    t = np.r_[np.arange(21.0), 30.0 + np.arange(21.0)]
    assert R.shape == (42, 42) and np.allclose(R[:21, :21], m.correlation(21))
    assert R[20, 21] == pytest.approx((1 - OWN_STRIP_SHARE) * np.exp(-10.0 / 20.0))
    # the flight's mean: σ² · mean(R), against independent lines' (each line's own block only)
    own = np.where((t[:, None] < 25) == (t[None, :] < 25), R, 0.0)
    assert np.sqrt(R.mean()) > 1.1 * np.sqrt(own.mean())  # 0.69 against 0.60
    same_time = m.flight_correlation({1: (0.0, 10.0), 2: (0.0, 10.0)})
    assert np.linalg.eigvalsh(same_time).min() > 1e-4


def test_corrections_are_linear_in_time_between_knots():
    m = TrajectoryModel(block_s=10.0, position_sigma_m=0.03, attitude_sigma_rad=1e-5, correlation_s=10.0,
                        attitude_correlation_s=10.0)
    spans = {7: (100.0, 125.0)}
    names = [p.name for p in m.parameters(spans)]
    assert len(names) == 4 * 6 and "trajectory_bias_up_7_3" in names and "trajectory_tilt_east_7_0" in names
    assert m.layout(spans)["trajectory_tilt_north_7_1"] == ("tilt", 1, 7, 1) and "boresight_roll" not in m.layout(spans)
    values = dict.fromkeys(names, 0.0) | {"trajectory_bias_up_7_0": 0.02, "trajectory_tilt_up_7_1": 1e-5}
    c = corrections(values, m, spans)[7]
    assert np.allclose(c.shift[:, 2], [0.02, 0.0, 0.0, 0.0]) and np.allclose(c.tilt[:, 2], [0.0, 1e-5, 0.0, 0.0])
    t = np.array([99.0, 100.0, 105.0, 110.0, 117.5, 130.0, 135.0])
    east = np.array([[1.0, 0.0, 0.0]])  # 1 m east of the origin: a rotation about up moves it north
    moved = c.apply(np.repeat(east, t.size, axis=0), np.zeros((1, 3)), t) - east
    # constant before the first knot and after the last, linear in between
    assert np.allclose(moved[:, 2], [0.02, 0.02, 0.01, 0.0, 0.0, 0.0, 0.0])
    assert np.allclose(moved[:, 1], [0.0, 0.0, 5e-6, 1e-5, 2.5e-6, 0.0, 0.0])
    p = c.apply(np.array([[10.0, 0.0, -1000.0]]), np.zeros((1, 3)), np.array([110.0]))
    # at knot 1: no shift, a rotation about up by 1e-5 rad: (10, 0) moves along +north by 10 m × 1e-5
    assert p[0, 2] == pytest.approx(-1000.0) and p[0, 1] == pytest.approx(1e-4)
    p0 = c.apply(np.array([[10.0, 0.0, -1000.0]]), np.zeros((1, 3)), np.array([105.0]))
    assert p0[0, 2] == pytest.approx(-1000.0 + 0.01) and p0[0, 1] == pytest.approx(5e-5)
    one = TrajectoryModel(position_sigma_m=0.03)  # no blocks: one constant correction per strip
    c1 = corrections({"trajectory_bias_up_7": 0.02}, one, spans)[7]
    assert np.allclose(c1.apply(np.zeros((t.size, 3)), np.zeros((1, 3)), t)[:, 2], 0.02)
    # weighted sums of points (correspondence rows): the shift counts once per unit of weight
    assert c.apply(np.zeros((1, 3)), np.zeros((1, 3)), np.array([105.0]), np.array([3.0]))[0, 2] == pytest.approx(0.03)


def test_blocks_without_a_prior_are_refused():
    with pytest.raises(InputError, match="need the trajectory's a-priori position σ"):
        TrajectoryModel(block_s=2.0)
    with pytest.raises(InputError, match="block_s: expected a number > 0"):
        TrajectoryModel(block_s=-1.0, position_sigma_m=0.03)


def test_priors_follow_the_trajectory_accuracy_per_axis_and_in_time():
    """Knots get the σ the accuracy states at their time: shifts east/north/up from east/north/down,
    the rotation about up heading's σ (10× roll's here), the horizontal rotations roll's or pitch's
    as the line's heading mixes them."""
    from calidar.trajectory_accuracy import TrajectoryAccuracy

    t = np.array([100.0, 110.0])
    pos = np.array([[0.02, 0.03, 0.05], [0.04, 0.06, 0.10]])  # north, east, down: doubling over 10 s
    att = np.radians([[0.002, 0.004, 0.02], [0.002, 0.004, 0.02]])  # roll, pitch, heading
    m = TrajectoryModel(block_s=5.0, correlation_s=20.0, attitude_correlation_s=3.5,
                        accuracy=TrajectoryAccuracy(t, pos, att, source="smrmsg.out"))
    assert m.has_priors and m.has_attitude
    spans = {1: (100.0, 110.0), 2: (100.0, 104.0)}
    params = {p.name: p.prior_sigma for p in m.parameters(spans, headings={1: 0.0, 2: np.pi / 2})}
    assert params["trajectory_bias_east_1_0"] == pytest.approx(0.03) and params["trajectory_bias_up_1_0"] == pytest.approx(0.05)
    assert params["trajectory_bias_north_1_1"] == pytest.approx(0.03)  # halfway: linear in time
    assert params["trajectory_bias_up_1_2"] == pytest.approx(0.10)
    assert np.degrees(params["trajectory_tilt_up_1_0"]) == pytest.approx(0.02)  # heading's σ
    # line 1 flies north: roll turns about north, pitch about east; line 2 flies east: the other way round
    assert np.degrees(params["trajectory_tilt_north_1_0"]) == pytest.approx(0.002)
    assert np.degrees(params["trajectory_tilt_east_1_0"]) == pytest.approx(0.004)
    assert np.degrees(params["trajectory_tilt_east_2_0"]) == pytest.approx(0.002)
    assert np.degrees(params["trajectory_tilt_north_2_0"]) == pytest.approx(0.004)
    groups = m.prior_correlation(spans)
    assert len(groups) == 3 + 2 * 3  # shifts per axis over both strips; rotations per strip and axis


def test_corrected_trajectory_moves_points_as_the_corrections_do():
    """Georeferencing with the written corrected trajectory gives the adjustment's corrected points:
    exactly but for the trajectory's linear interpolation across a knot (here 100 Hz records,
    corrections of 5 cm and 0.005° changing slope every 2 s: < 0.5 mm there, < 0.01 mm elsewhere)."""
    from calidar import georef
    from calidar.sensor import Sensor
    from calidar.strips.trajectory_errors import StripCorrection, corrected_trajectory
    from strips_scene import frame, survey

    strip = survey(Sensor(), Sensor(), [((-250, -80, 0), 90, 500, 400)], n=5_000)[0]
    t0, t1 = float(strip.time.min()), float(strip.time.max())
    rng = np.random.default_rng(1)
    n = int(np.ceil((t1 - t0) / 2.0)) + 1
    fix = StripCorrection(t0, 2.0, rng.normal(0, 0.05, (n, 3)), rng.normal(0, np.radians(0.005), (n, 3)))
    sensor = Sensor(boresight_roll=1e-3, lever_arm_x=0.3)
    pose = strip.pose()
    expected = fix.apply(georeference_pose(sensor, pose), pose.position, strip.time)
    traj = corrected_trajectory(strip.trajectory, {strip.id: fix}, {strip.id: (t0, t1)}, frame())
    got = frame().to_local(georef.forward(traj, sensor, strip.time, strip.obs.range_m, strip.obs.angles))
    err = np.max(np.abs(got - expected), axis=1)
    assert np.max(err) < 5e-4 and np.median(err) < 1e-5
    # records away from the strip are untouched
    far = (traj.time < t0 - 0.015) | (traj.time > t1 + 0.015)  # beyond the bracketing records
    assert far.any() and np.array_equal(traj.lat[far], strip.trajectory.lat[far])


@pytest.mark.parametrize("model", [TrajectoryModel(), TrajectoryModel(None, 0.03), TrajectoryModel(2.0, 0.03),
                                   TrajectoryModel(1.0, 0.03, 1e-5, 20.0, 3.5)], ids=["free", "constant", "knots", "tilts"])
def test_the_layout_addresses_every_parameter_by_its_block(model):
    """TrajectoryModel.layout: each parameter :meth:`parameters` makes, by name → its typed Knot
    (kind, axis, strip, knot), the block the calibration addresses it by (issue 29: no name parsed)."""
    spans = {3: (100.0, 107.5), 1: (50.0, 52.0), 9: (0.0, 0.5)}
    names = [p.name for p in model.parameters(spans)]
    layout = model.layout(spans)
    assert sorted(layout) == sorted(names) and len(names) == len(set(names))
    assert all(_read(n) == tuple(k) for n, k in layout.items())  # the names say the same
    assert {k.strip for k in layout.values()} == ({3, 9} if not model.has_priors else {1, 3, 9})


def _read(name: str) -> tuple[str, int, int, int]:
    """What a trajectory parameter's name says (the test reads it; the library addresses knots by layout)."""
    m = re.match(r"trajectory_(bias|tilt)_(east|north|up)_(\d+)(?:_(\d+))?$", name)
    return m.group(1), ("east", "north", "up").index(m.group(2)), int(m.group(3)), int(m.group(4) or 0)
