"""simulate_survey(on_strip=...): the strips handed over as simulated are those it would keep."""

from __future__ import annotations

import numpy as np

from calidar.sim.survey import simulate_survey, survey_config


def test_strips_handed_over_equal_the_kept_ones():
    cfg = survey_config("uav", seed=12, density=0.005)
    kept = simulate_survey(cfg)
    handed = []
    streamed = simulate_survey(cfg, on_strip=handed.append)
    assert streamed.strips == [] and streamed.n_points == kept.n_points > 0
    assert streamed.truth_dict()["simulation"]["points"] == kept.n_points
    assert len(handed) == len(kept.strips) >= 2
    for a, b in zip(handed, kept.strips):
        assert np.array_equal(a.xyz, b.xyz) and np.array_equal(a.gps_time, b.gps_time)


def test_the_pulse_bound_is_per_strip_when_strips_are_handed_over(monkeypatch):
    """Memory holds one strip at a time with on_strip: the bound then applies to the largest
    strip (the 64 M-point benchmark survey: 1.2e7 a strip, 6.0e7 in all), else to all of them."""
    import pytest

    import calidar.sim.survey as survey
    from calidar.errors import InputError

    cfg = survey_config("uav", seed=12, density=0.005)
    windows = []
    real_fly = survey.fly
    monkeypatch.setattr(survey, "fly", lambda *a: (lambda r: windows.append(r[1]) or r)(real_fly(*a)))
    simulate_survey(cfg, on_strip=lambda s: None)
    per_line = [cfg.pulse_rate_hz * cfg.density * (b - a) for a, b in windows[0]]
    assert len(per_line) >= 2
    monkeypatch.setattr(survey, "MAX_PULSES", (max(per_line) + sum(per_line)) / 2)  # between one strip and all
    assert simulate_survey(cfg, on_strip=lambda s: None).strips == []  # one strip at a time: within the bound
    with pytest.raises(InputError, match="pulses to simulate; expected"):
        simulate_survey(cfg)  # every strip held: beyond it
    monkeypatch.setattr(survey, "MAX_PULSES", 0.5 * max(per_line))
    with pytest.raises(InputError, match="in one strip"):
        simulate_survey(cfg, on_strip=lambda s: None)
