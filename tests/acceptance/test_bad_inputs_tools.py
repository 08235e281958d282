"""The bad-input corpus (issue 16), part 4: ``range-cal``, ``simulate total-station``, ``simulate
survey``, ``scanner analyze``, ``demo`` (see test_bad_inputs.py)."""

from __future__ import annotations

import pytest

COMMANDS = {"range-cal", "simulate total-station", "simulate survey", "scanner analyze", "demo", "accuracy"}  #: covered here
OBS = "{T}/observations.csv"


def case(args, *messages: str, id: str):
    """One corpus case: its arguments and the substrings its message must hold."""
    return pytest.param(args, messages, id=id)


RANGECAL = [
    case(["{B}/obs_mm.csv"], "obs_mm.csv", "scanner_m", "mm", id="scanner-ranges-in-mm"),
    case(["{B}/obs_latin1.csv"], "obs_latin1.csv", "UTF-8", id="not-utf8"),
    case(["{B}/obs_nocol.csv"], "obs_nocol.csv", "scanner_m", id="missing-column"),
    case(["{B}/obs_nan.csv"], "obs_nan.csv", "slope_m", id="nan-distance"),
    case(["{B}/obs_negative.csv"], "obs_negative.csv", "slope_m", id="negative-distance"),
    case(["{B}/obs_zd400.csv"], "obs_zd400.csv", "zd_deg", id="zenith-distance-400"),
    case(["{B}/obs_header.csv"], "obs_header.csv", id="no-observations"),
    case(["{B}/missing.csv"], "missing.csv", id="missing"),
    case(["{B}/ccr_nan.csv"], "ccr_nan.csv", id="another-csv"),
    case([OBS, "--tolerance", "0"], "--tolerance", id="tolerance-0"),
    case([OBS, "--tolerance", "-0.01"], "--tolerance", id="tolerance-negative"),
    case([OBS, "--tolerance", "nan"], "--tolerance", id="tolerance-nan"),
    case([OBS, "--tolerance", "100"], "--tolerance", id="tolerance-huge"),
    case([OBS, "--truth", "{B}/truth_notjson.json"], "truth_notjson.json", id="truth-not-json"),
    case([OBS, "--truth", "{S}/truth.json"], "truth.json", id="truth-of-another-simulation"),
    case([OBS, "--config", "{B}/missing.toml"], "missing.toml", id="config-missing"),
    case([OBS, "--config", "{B}/config_not_toml.toml"], "config_not_toml.toml", "TOML", id="config-not-toml"),
    case([OBS, "--config", "{B}/rangecal_tolerance.toml"], "rangecal_tolerance.toml", "tolerance_m", "(0, 10] m",
         id="config-tolerance-negative"),
    case([OBS, "--config", "{B}/rangecal_unknown.toml"], "rangecal_unknown.toml", "tolerence_m", "unknown key",
         id="config-unknown-key"),
    case([OBS, "--config", "{B}/rangecal_fix_scale.toml"], "rangecal_fix_scale.toml", "fix_scale", "expected bool",
         id="config-fix-scale-text"),
]


@pytest.mark.parametrize("args, messages", RANGECAL)
def test_range_cal(bad_input, args, messages):
    bad_input(["range-cal", *args, "--out", "{O}"], 1, *messages)


def test_range_cal_never_writes_over_its_inputs(bad_input):
    bad_input(["range-cal", OBS, "--out", "{T}", "--force"], 1, "input")


TOTAL_STATION = [
    case(["--setups", "0"], "--setups", id="setups-0"),
    case(["--setups", "51"], "--setups", id="setups-51"),
    case(["--groups", "0"], "--groups", id="groups-0"),
    case(["--groups", "100000"], "--groups", id="groups-huge"),
    case(["--groups", "-2"], "--groups", id="groups-negative"),
    case(["--setups", "-1"], "--setups", id="setups-negative"),
    case(["--seed", "99999999999"], "--seed", id="seed-huge"),
    case(["--e-points", "-1"], "--e-points", id="e-points-negative"),
    case(["--e-points", "100000"], "--e-points", id="e-points-huge"),
    case(["--outliers", "-1"], "--outliers", id="outliers-negative"),
    case(["--outliers", "1000"], "--outliers", id="outliers-more-than-targets"),
    case(["--angle-unit", "rad"], "--angle-unit", id="angle-unit"),
    case(["--vertical", "elevation"], "--vertical", id="vertical"),
    case(["--seed", "-1"], "--seed", id="seed-negative"),
]


@pytest.mark.parametrize("extra, messages", TOTAL_STATION)
def test_simulate_total_station(bad_input, extra, messages):
    bad_input(["simulate", "total-station", *extra, "--out", "{O}"], 1, *messages)


SURVEY = [
    case(["--seed", "-1"], "seed: expected an integer in [0, 4294967295]", id="seed-negative"),
    case(["--density", "nan"], "density", id="density-nan"),
    case(["--density", "1e9"], "density", id="density-huge"),
    case(["--density", "200"], "density", "pulses to simulate", id="density-beyond-memory"),
    case(["--range-offset", "nan"], "range", id="range-offset-nan"),
    case(["--range-offset", "1e9"], "range", id="range-offset-huge"),
    case(["--range-noise", "nan"], "range_noise", id="range-noise-nan"),
    case(["--range-noise", "1e6"], "range_noise", id="range-noise-huge"),
    case(["--beam-divergence", "nan"], "beam_divergence", id="beam-divergence-nan"),
    case(["--beam-divergence", "-1"], "beam_divergence", id="beam-divergence-negative"),
    case(["--vegetation", "nan"], "vegetation", id="vegetation-nan"),
    case(["--vegetation", "-0.1"], "vegetation", id="vegetation-negative"),
    case(["--seed", "99999999999"], "seed", id="seed-huge"),
    case(["--density", "-1"], "density", id="density-negative"),
    case(["--range-offset", "-1e9"], "range", id="range-offset-negative-huge"),
    case(["--boresight-error", "0,nan,0"], "--boresight-error", id="boresight-error-nan"),
    case(["--directions", "north"], "directions", id="directions"),
    case(["--boresight-error", "1e6,0,0"], "boresight", id="boresight-error-1e6"),
    case(["--lever-arm-error", "1e9,0,0"], "lever", id="lever-arm-error-1e9"),
    case(["--strip-errors", "nan,0,0,0"], "--strip-errors", id="strip-errors-nan"),
    case(["--strip-errors", "1e9,0,0,0"], "strip_errors", id="strip-errors-huge"),
    case(["--preset", "satellite"], "preset", id="preset"),
]


@pytest.mark.parametrize("extra, messages", SURVEY)
def test_simulate_survey(bad_input, extra, messages):
    bad_input(["simulate", "survey", *extra, "--out", "{O}"], 1, *messages)


SCANNER = [
    case(["--fov", "400"], "--fov", id="fov-400"),
    case(["--fov", "0"], "--fov", id="fov-0"),
    case(["--fov", "nan"], "--fov", id="fov-nan"),
    case(["--range", "0"], "--range", id="range-0"),
    case(["--range", "-5"], "--range", id="range-negative"),
    case(["--range", "inf"], "--range", id="range-inf"),
    case(["--points", "1000000000"], "--points", id="points-1e9"),
    case(["--points", "0"], "--points", id="points-0"),
    case(["--points", "7"], "--points", id="points-7"),
    case(["--range", "1e9"], "--range", id="range-1e9"),
    case(["--model", "wedge", "--eccentricity", "-0.1"], "--eccentricity", "expected", id="eccentricity-negative"),
    case(["--model", "palmer", "--delta-r", "nan"], "--delta-r", id="palmer-delta-r-nan"),
    case(["--model", "wedge", "--wedge-angle-error", "100"], "--wedge-angle-error", id="wedge-angle-error-100"),
    case(["--model", "palmer", "--eccentricity", "1"], "--eccentricity", "expected", id="eccentricity-1"),
    case(["--model", "palmer", "--eccentricity", "nan"], "--eccentricity", "expected", id="eccentricity-nan"),
    case(["--eccentricity", "0.01"], "--eccentricity", "not linear", id="eccentricity-on-linear"),
    case(["--scan-angle-offset", "100"], "--scan-angle-offset", id="scan-angle-offset-100"),
    case(["--scan-angle-scale", "1e9"], "--scan-angle-scale", id="scan-angle-scale-1e9"),
    case(["--phase", "nan"], "--phase", id="phase-nan"),
    case(["--grating-radius-mm", "-1"], "--grating-radius-mm", id="grating-negative"),
    case(["--grating-radius-mm", "1e9"], "--grating-radius-mm", id="grating-huge"),
    case(["--fov", "-30"], "--fov", id="fov-negative"),
    case(["--spec-arcsec", "1e9"], "--spec-arcsec", id="spec-huge"),
    case(["--points", "-5"], "--points", id="points-negative"),
    case(["--model", "palmer", "--axis-angle", "0"], "--axis-angle", id="palmer-axis-angle-0"),
    case(["--model", "palmer", "--mirror-tilt", "-1"], "--mirror-tilt", id="palmer-mirror-tilt-negative"),
    case(["--model", "wedge", "--refractive-index", "nan"], "--refractive-index", id="wedge-index-nan"),
    case(["--model", "wedge", "--wedge-angle", "0"], "--wedge-angle", id="wedge-angle-0"),
    case(["--model", "wedge", "--axis-tilt", "1e9"], "--axis-tilt", id="wedge-tilt-huge"),
    case(["--spec-arcsec", "0"], "--spec-arcsec", id="spec-0"),
    case(["--spec-arcsec", "nan"], "--spec-arcsec", id="spec-nan"),
    case(["--model", "spiral"], "--model", id="model"),
    case(["--model", "palmer", "--delta-l", "100"], "--delta-l", id="palmer-delta-l-100"),
    case(["--model", "palmer", "--axis-angle", "100"], "--axis-angle", id="palmer-axis-angle-100"),
    case(["--model", "palmer", "--mirror-tilt", "60"], "--mirror-tilt", id="palmer-mirror-tilt-above-axis"),
    case(["--model", "wedge", "--refractive-index", "0.5"], "--refractive-index", id="wedge-index-0.5"),
    case(["--model", "wedge", "--wedge-angle", "95"], "--wedge-angle", id="wedge-angle-95"),
    case(["--model", "wedge", "--axis-tilt", "-1"], "--axis-tilt", id="wedge-tilt-negative"),
    case(["--model", "wedge", "--axis-tilt-azimuth", "inf"], "--axis-tilt-azimuth", id="wedge-azimuth-inf"),
    case(["--config", "{B}/missing.toml"], "missing.toml", id="config-missing"),
    case(["--config", "{B}/scanner_model.toml", "--range", "100"], "scanner_model.toml: model (--model): expected",
         id="config-model-spiral"),
    case(["--config", "{B}/scanner_error.toml"], "scanner_error.toml: errors.scan_angle_offset_deg (--scan-angle-offset)",
         id="config-error-of-another-model"),
]


@pytest.mark.parametrize("extra, messages", SCANNER)
def test_scanner_analyze(bad_input, extra, messages):
    args = ["scanner", "analyze", *extra, "--out", "{O}"]
    if "--model" not in extra and "--config" not in extra:
        args += ["--model", "linear"]
    if "--range" not in extra and "--config" not in extra:
        args += ["--range", "100"]
    bad_input(args, 1, *messages)


def test_demo_seed_beyond_32_bits(bad_input):
    bad_input(["demo", "--seed", "99999999999", "--out", "{O}"], 1, "seed")


def test_demo_refuses_a_file_as_its_folder(bad_input):
    bad_input(["demo", "--out", "{S}/sensor.toml", "--force"], 1, "sensor.toml", "not a folder")


STRIP = "{S}/strips/line_001.laz"
ACCURACY = [
    case(["--checkpoints", "{T}/observations.csv"], "observations.csv", "id", "column", id="not-a-checkpoint-file"),
    case(["--checkpoints", "{B}/ccr_nan.csv"], "ccr_nan.csv", "x", "column", id="lat-lon-columns"),
    case(["--checkpoints", "{B}/ccr_latin1.csv"], "ccr_latin1.csv", "UTF-8", id="not-utf8"),
    case(["--checkpoints", "{B}/missing.csv"], "missing.csv", id="missing"),
    case(["--checkpoints", "{S}/truth.json"], "truth.json", id="json-not-csv"),
    case(["--checkpoints", "{T}/observations.csv", "--radius", "0"], "--radius", id="radius-0"),
    case(["--checkpoints", "{T}/observations.csv", "--max-edge", "nan"], "--max-edge", id="max-edge-nan"),
    case(["--checkpoints", "{T}/observations.csv", "--survey-sigma", "-0.01"], "--survey-sigma", id="survey-sigma-negative"),
    case(["--checkpoints", "{T}/observations.csv", "--class", "0"], "--class", id="class-0"),
    case(["--checkpoints", "{T}/observations.csv", "--checkpoints-crs", "EPSG:0"], "--checkpoints-crs", id="crs-unknown"),
    case(["--checkpoints", "{T}/observations.csv", "--classes", "ground"], "--classes", id="classes-not-numbers"),
    case(["--checkpoints", "{T}/observations.csv", "--config", "{B}/missing.toml"], "missing.toml", id="config-missing"),
    case(["--checkpoints", "{T}/observations.csv", "--config", "{B}/accuracy_radius.toml"],
         "accuracy_radius.toml: radius_m (--radius): expected", id="config-radius-negative"),
    case(["--checkpoints", "{T}/observations.csv", "--config", "{B}/accuracy_crs.toml"],
         "accuracy_crs.toml: checkpoints_crs (--checkpoints-crs): expected a CRS", id="config-crs-unknown"),
]


@pytest.mark.parametrize("args, messages", ACCURACY)
def test_accuracy(bad_input, args, messages):
    bad_input(["accuracy", STRIP, *args, "--out", "{O}"], 1, *messages)
