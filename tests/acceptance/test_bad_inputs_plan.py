"""The bad-input corpus (issue 16), part 7: ``plan`` (see test_bad_inputs.py). Its flight-line files
are written here, beside the shared corpus."""

from __future__ import annotations

import json

import pytest

COMMANDS = {"plan"}  #: covered here
HEADER = "line,start_x,start_y,end_x,end_y,height_agl_m,speed_mps\n"
GOOD = ["--sensor", "{S}/sensor.toml"]
FILES = {
    "good.csv": HEADER + "1,-30,-60,-30,60,80,8\n2,30,60,30,-60,80,8\n",
    "columns.csv": "line,x0,y0,x1,y1,h,v\n1,-30,-60,-30,60,80,8\n",
    "negative_height.csv": HEADER + "1,-30,-60,-30,60,-80,8\n2,30,60,30,-60,80,8\n",
    "zero_speed.csv": HEADER + "1,-30,-60,-30,60,80,0\n2,30,60,30,-60,80,8\n",
    "text_value.csv": HEADER + "1,-30,-60,-30,sixty,80,8\n",
    "degrees.csv": HEADER + "1,8.001,47.001,8.002,47.003,80,8\n",
    "duplicate.csv": HEADER + "1,-30,-60,-30,60,80,8\n1,30,60,30,-60,80,8\n",
    "header_only.csv": HEADER,
    "apart.csv": HEADER + "1,-3000,-60,-3000,60,80,8\n2,3000,60,3000,-60,80,8\n",
    "not_json.geojson": "{ this is not json",
    "point.geojson": json.dumps({"type": "FeatureCollection", "features": [
        {"type": "Feature", "geometry": {"type": "Point", "coordinates": [0, 0]}, "properties": {}}]}),
    "no_height.geojson": json.dumps({"type": "FeatureCollection", "features": [
        {"type": "Feature", "geometry": {"type": "LineString", "coordinates": [[-30, -60], [-30, 60]]},
         "properties": {"speed_mps": 8}}]}),
    "not_a_dem.tif": "not a GeoTIFF\n" * 20,
}


@pytest.fixture(scope="module")
def lines_dir(tmp_path_factory):
    root = tmp_path_factory.mktemp("plan_lines")
    for name, text in FILES.items():
        (root / name).write_text(text)
    return root


def case(args, *messages: str, id: str):
    """One corpus case: its arguments ({L}: this module's files) and the substrings its message must hold."""
    return pytest.param(args, messages, id=id)


PLAN = [
    case(["{L}/missing.csv", *GOOD], "missing.csv", "not found", id="missing"),
    case(["{L}/columns.csv", *GOOD], "columns.csv", "height_agl_m", id="wrong-columns"),
    case(["{L}/negative_height.csv", *GOOD], "row 1 height_agl_m", "height above ground", id="negative-height"),
    case(["{L}/zero_speed.csv", *GOOD], "speed_mps", id="zero-speed"),
    case(["{L}/text_value.csv", *GOOD], "end_y", "number", id="text-value"),
    case(["{L}/degrees.csv", *GOOD], "metres", id="degrees-not-metres"),
    case(["{L}/duplicate.csv", *GOOD], "line", "twice", id="duplicate-line"),
    case(["{L}/header_only.csv", *GOOD], "no flight line", id="header-only"),
    case(["{L}/apart.csv", *GOOD], "overlap", id="no-overlap"),
    case(["{L}/not_json.geojson", *GOOD], "not_json.geojson", "JSON", id="geojson-invalid"),
    case(["{L}/point.geojson", *GOOD], "LineString", id="geojson-point"),
    case(["{L}/no_height.geojson", *GOOD], "height_agl_m", id="geojson-no-height"),
    case(["{L}/good.csv", "--sensor", "{B}/sensor_nan.toml"], "sensor_nan.toml", id="sensor-nan"),
    case(["{L}/good.csv", "--sensor", "{S}/truth.json"], "truth.json", id="sensor-not-toml"),
    case(["{L}/good.csv", *GOOD, "--terrain", "scene:moon"], "--terrain", id="terrain-unknown-scene"),
    case(["{L}/good.csv", *GOOD, "--terrain", "{L}/missing.tif"], "missing.tif", id="dem-missing"),
    case(["{L}/good.csv", *GOOD, "--terrain", "{L}/not_a_dem.tif"], "not_a_dem.tif", "GeoTIFF", id="dem-garbage"),
    case(["{L}/good.csv", *GOOD, "--terrain", "flat:abc"], "--terrain", id="flat-height-text"),
    case(["{L}/good.csv", *GOOD, "--estimate", "heading"], "--estimate", id="estimate-unknown"),
    case(["{L}/good.csv", *GOOD, "--estimate", "palmer"], "--estimate", id="estimate-palmer"),
    case(["{L}/good.csv", *GOOD, "--fov", "0"], "--fov", id="fov-zero"),
    case(["{L}/good.csv", *GOOD, "--pulse-rate", "-5"], "--pulse-rate", id="pulse-rate-negative"),
    case(["{L}/good.csv", *GOOD, "--range-sigma", "nan"], "--range-sigma", id="range-sigma-nan"),
    case(["{L}/good.csv", *GOOD, "--trajectory-sigma", "0.05"], "--trajectory-sigma", id="trajectory-sigma-one-number"),
    case(["{L}/good.csv", *GOOD, "--simulate", "-1"], "--simulate", id="simulate-negative"),
    case(["{L}/good.csv", *GOOD, "--platform-motion", "1.5"], "--platform-motion", id="platform-motion-one-number"),
    case(["{L}/good.csv", *GOOD, "--platform-motion", "1.5,-1"], "--platform-motion", id="platform-motion-negative"),
    case(["{L}/good.csv", *GOOD, "--config", "{B}/missing.toml"], "missing.toml", id="config-missing"),
    case(["{L}/good.csv", *GOOD, "--config", "{B}/plan_estimate.toml"], "plan_estimate.toml: estimate (--estimate)",
         id="config-estimate-unknown"),
    case(["{L}/good.csv", *GOOD, "--config", "{B}/plan_terrain.toml"], "plan_terrain.toml: terrain.kind (--terrain)",
         id="config-terrain-unknown"),
    case(["{L}/good.csv", *GOOD, "--simulate", "1", "--terrain", "{L}/not_a_dem.tif"], "not_a_dem.tif",
         id="simulate-bad-dem"),
]


@pytest.mark.parametrize("args, messages", PLAN)
def test_plan(bad_input, lines_dir, args, messages):
    bad_input(["plan", *[a.replace("{L}", str(lines_dir)) for a in args], "--out", "{O}"], 1, *messages)


def test_plan_never_writes_over_its_inputs(bad_input, lines_dir):
    bad_input(["plan", str(lines_dir / "good.csv"), *GOOD, "--out", "{S}", "--force"], 1, "input")


def test_plan_usage_errors(bad_input, lines_dir):
    bad_input(["plan", str(lines_dir / "good.csv"), "--out", "{O}"], 2, "--sensor")
    bad_input(["plan", str(lines_dir / "good.csv"), *GOOD, "--simulate", "many", "--out", "{O}"], 2, "--simulate")
