"""``calidar plan``'s options parsed once, at the CLI (issue 29): the pipeline takes a typed
PlanOptions (an Estimate, σ in SI) and checks ranges only; the run record shows them as a user gave them."""

from __future__ import annotations

import math

import pytest

from calidar.errors import InputError
from calidar.pipelines.plan import PlanOptions, plan_settings
from calidar.strips.config import Estimate


def test_the_cli_parses_into_typed_options():
    from calidar.cli.plan import _estimate, parse_platform_motion

    assert _estimate("boresight, lever_arm_z") == Estimate.of("boresight", "lever_arm_z")
    assert parse_platform_motion("0.8,1.5") == pytest.approx((math.radians(0.8), math.radians(1.5)))
    for bad, option in (("trajectory_bias", "--estimate"), ("heading", "--estimate")):
        with pytest.raises(InputError, match=option):
            _estimate(bad)
    with pytest.raises(InputError, match="--platform-motion"):
        parse_platform_motion("1.5")


def test_the_pipeline_takes_the_estimate_as_typed():
    options = PlanOptions(estimate=Estimate.of("lever_arm", "boresight"), trajectory_sigma=(0.05, math.radians(0.004)))
    settings = plan_settings(options)
    assert settings.estimate == ("boresight", "lever_arm")
    assert settings.trajectory.position_sigma_m == 0.05
    for what in (("height_bias",), ("palmer",), ("scan_angle_scale",), ("delta_l",)):
        with pytest.raises(InputError, match="--estimate"):
            plan_settings(PlanOptions(estimate=Estimate.of("boresight", *what)))


def test_the_record_shows_the_options_in_user_units():
    shown = PlanOptions(estimate=Estimate.of("boresight", "range_offset")).to_dict()
    assert shown["estimate"] == ["boresight", "range_offset"]
    assert shown["trajectory_sigma"] == "0.02,0.002" and shown["platform_motion"] == "1.5,1"


def test_the_terrain_is_parsed_at_the_cli_and_shown_back():
    from pathlib import Path

    from calidar.cli.plan import parse_terrain
    from calidar.pipelines.plan import TerrainChoice

    assert parse_terrain("flat") == TerrainChoice() and str(TerrainChoice()) == "flat"
    assert parse_terrain("flat:412.5") == TerrainChoice("flat", 412.5) and str(parse_terrain("flat:412.5")) == "flat:412.5"
    assert parse_terrain("scene") == TerrainChoice("scene", preset="uav", seed=0)
    assert str(parse_terrain("scene:airborne:3")) == "scene:airborne:3"
    assert parse_terrain("dem.tif") == TerrainChoice("dem", path=Path("dem.tif"))
    for bad in ("flat:abc", "scene:uav:x"):
        with pytest.raises(InputError, match="--terrain"):
            parse_terrain(bad)
