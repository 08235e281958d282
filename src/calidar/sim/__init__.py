"""Simulators with a known truth: lidar surveys (scene, flight plan, motion, ray casting).

>>> from calidar.sim import simulate_survey, survey_config
>>> cfg = survey_config("uav", seed=1, density=0.05, errors={"boresight_roll": 1e-3})
>>> res = simulate_survey(cfg)  # doctest: +SKIP
>>> res.truth.boresight_roll, len(res.strips), res.las_points()[0].xyz.shape   # doctest: +SKIP
"""

from calidar.sim.survey import SurveyConfig, SurveyResult, simulate_survey, survey_config

__all__ = ["SurveyConfig", "SurveyResult", "simulate_survey", "survey_config"]
