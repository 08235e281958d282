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
