"""The bad-input corpus (issue 16), part 3: ``denoise``, ``ccr``, ``simulate photons`` (see test_bad_inputs.py)."""

from __future__ import annotations

import pytest

COMMANDS = {"denoise", "ccr", "simulate photons"}  #: the commands this module's corpus covers
H5, CCR = "{P}/ATL03_sim.h5", "{P}/ccr.csv"


def case(args, *messages: str, id: str):
    """One corpus case: its arguments and the substrings its message must hold."""
    return pytest.param(args, messages, id=id)


ATL03 = [
    case(["{B}/atl03_zero.h5"], "atl03_zero.h5", id="zero-photons"),
    case(["{B}/atl03_badlat.h5"], "atl03_badlat.h5", "lat_ph", id="latitude-200"),
    case(["{B}/atl03_nan_h.h5"], "atl03_nan_h.h5", "h_ph", id="nan-height"),
    case(["{B}/atl03_nan_time.h5"], "atl03_nan_time.h5", "delta_time", id="nan-time"),
    case(["{B}/not_atl03.h5"], "not_atl03.h5", id="not-atl03"),
    case(["{B}/atl03_truncated.h5"], "atl03_truncated.h5", id="truncated"),
    case(["{B}/atl03_text.h5"], "atl03_text.h5", id="text"),
    case(["{B}/missing.h5"], "missing.h5", id="missing"),
]

DENOISE = [
    case([H5, "--out", H5, "--force"], "ATL03_sim.h5", "input", id="out-is-input"),
    case([H5, "--out", "{O}.csv", "--shot-spacing-m", "0"], "--shot-spacing-m", id="shot-spacing-0"),
    case([H5, "--out", "{O}.csv", "--shot-spacing-m", "-0.7"], "--shot-spacing-m", id="shot-spacing-negative"),
    case([H5, "--out", "{O}.csv", "--shot-spacing-m", "nan"], "--shot-spacing-m", id="shot-spacing-nan"),
    case([H5, "--out", "{O}.csv", "--shot-spacing-m", "1e9"], "--shot-spacing-m", id="shot-spacing-huge"),
    case([H5, "--out", "{O}.csv", "--beam", "gt9x"], "--beam", "gt9x", id="beam-bogus"),
    case([H5, "--out", "{O}.csv", "--beam", "gt2l"], "gt2l", id="beam-absent"),
    case([H5, "--out", "{P}", "--force"], "{P}", id="out-is-a-folder"),
    case([H5, "--out", "{B}/atl03_hardlink.csv", "--force"], "atl03_hardlink.csv", "input", id="out-is-a-hard-link"),
    case([H5, "--out", "{O}.csv", "--config", "{B}/missing.toml"], "missing.toml", id="config-missing"),
    case([H5, "--out", "{O}.csv", "--config", "{B}/denoise_beams.toml"], "denoise_beams.toml: beams (--beam): expected",
         id="config-beam-bogus"),
    case([H5, "--out", "{O}.csv", "--config", "{B}/denoise_spacing.toml"],
         "denoise_spacing.toml: shot_spacing_m: expected float", id="config-shot-spacing-text"),
    case([H5, "--out", "{O}.csv", "--config", H5], "ATL03_sim.h5", id="config-not-text"),
]


@pytest.mark.parametrize("args, messages", DENOISE)
def test_denoise(bad_input, corpus, args, messages):
    messages = [m.format(P=corpus.root / "photons") for m in messages]
    bad_input(["denoise", *args], 1, *messages)


@pytest.mark.parametrize("args, messages", ATL03)
def test_denoise_atl03(bad_input, args, messages):
    bad_input(["denoise", *args, "--out", "{O}.csv"], 1, *messages)


@pytest.mark.parametrize("args, messages", ATL03)
def test_ccr_atl03(bad_input, args, messages):
    bad_input(["ccr", *args, "--ccr", CCR, "--out", "{O}", "--bootstrap", "0"], 1, *messages)


CCR_CASES = [
    case(["--ccr", "{B}/ccr_latin1.csv"], "ccr_latin1.csv", "UTF-8", id="ccr-not-utf8"),
    case(["--ccr", "{B}/ccr_nocol.csv"], "ccr_nocol.csv", "height", id="ccr-missing-column"),
    case(["--ccr", "{B}/ccr_nan.csv"], "ccr_nan.csv", "lat", id="ccr-nan"),
    case(["--ccr", "{B}/ccr_lat100.csv"], "ccr_lat100.csv", "lat", id="ccr-latitude-100"),
    case(["--ccr", "{B}/ccr_empty.csv"], "ccr_empty.csv", id="ccr-empty"),
    case(["--ccr", "{B}/missing.csv"], "missing.csv", id="ccr-missing"),
    case(["--dead-time-ns", "-1"], "--dead-time-ns", id="dead-time-negative"),
    case(["--dead-time-ns", "nan"], "--dead-time-ns", id="dead-time-nan"),
    case(["--pulse-width-ns", "0"], "--pulse-width-ns", id="pulse-width-0"),
    case(["--pulse-width-ns", "1e9"], "--pulse-width-ns", id="pulse-width-huge"),
    case(["--shot-spacing-m", "0"], "--shot-spacing-m", id="shot-spacing-0"),
    case(["--channels", "0"], "--channels", id="channels-0"),
    case(["--channels", "100000"], "--channels", id="channels-huge"),
    case(["--pointing-jitter-m", "-1"], "--pointing-jitter-m", id="jitter-negative"),
    case(["--pointing-jitter-m", "inf"], "--pointing-jitter-m", id="jitter-inf"),
    case(["--diameter-range", "15,8"], "--diameter-range", id="diameter-range-reversed"),
    case(["--diameter-range", "a,b"], "--diameter-range", id="diameter-range-words"),
    case(["--diameter-range", "0,5"], "--diameter-range", id="diameter-range-0"),
    case(["--diameter-step", "0"], "--diameter-step", id="diameter-step-0"),
    case(["--diameter-step", "nan"], "--diameter-step", id="diameter-step-nan"),
    case(["--diameter-step", "1e9"], "--diameter-step", id="diameter-step-huge"),
    case(["--length-step", "1e9"], "--length-step", id="length-step-huge"),
    case(["--max-bias", "1e9"], "--max-bias", id="max-bias-huge"),
    case(["--dead-time-ns", "1e9"], "--dead-time-ns", id="dead-time-huge"),
    case(["--shot-spacing-m", "inf"], "--shot-spacing-m", id="shot-spacing-inf"),
    case(["--length-step", "0"], "--length-step", id="length-step-0"),
    case(["--length-step", "-0.1"], "--length-step", id="length-step-negative"),
    case(["--max-bias", "0"], "--max-bias", id="max-bias-0"),
    case(["--max-bias", "nan"], "--max-bias", id="max-bias-nan"),
    case(["--bootstrap", "-1"], "--bootstrap", id="bootstrap-negative"),
    case(["--bootstrap", "1000000000"], "--bootstrap", id="bootstrap-huge"),
    case(["--seed", "-1"], "--seed", id="seed-negative"),
    case(["--seed", "99999999999"], "--seed", id="seed-huge"),
    case(["--dead-time-ns", "0"], "--dead-time-ns", id="dead-time-0"),
    case(["--pulse-width-ns", "-1"], "--pulse-width-ns", id="pulse-width-negative"),
    case(["--pulse-width-ns", "nan"], "--pulse-width-ns", id="pulse-width-nan"),
    case(["--shot-spacing-m", "-0.7"], "--shot-spacing-m", id="shot-spacing-negative"),
    case(["--channels", "-4"], "--channels", id="channels-negative"),
    case(["--pointing-jitter-m", "nan"], "--pointing-jitter-m", id="jitter-nan"),
    case(["--pointing-jitter-m", "1e9"], "--pointing-jitter-m", id="jitter-huge"),
    case(["--diameter-step", "-0.1"], "--diameter-step", id="diameter-step-negative"),
    case(["--length-step", "nan"], "--length-step", id="length-step-nan"),
    case(["--max-bias", "-1"], "--max-bias", id="max-bias-negative"),
    case(["--diameter-range", "8,1e9"], "--diameter-range", id="diameter-range-huge"),
    case(["--beam", "gt9x"], "--beam", id="beam-bogus"),
    case(["--truth", "{B}/truth_notjson.json"], "truth_notjson.json", id="truth-not-json"),
    case(["--truth", "{B}/truth_latin1.json"], "truth_latin1.json", id="truth-not-utf8"),
    case(["--truth", "{S}/truth.json"], "truth.json", id="truth-of-another-simulation"),
    case(["--config", "{B}/missing.toml"], "missing.toml", id="config-missing"),
    case(["--config", "{B}/ccr_step.toml"], "ccr_step.toml", "search.diameter_step", "[0.01, 2] m",
         id="config-diameter-step-huge"),
    case(["--config", "{B}/ccr_range.toml"], "ccr_range.toml", "diameter_min", "MIN < MAX", id="config-range-reversed"),
    case(["--config", "{B}/ccr_beams.toml"], "ccr_beams.toml", "beams", "gt9x", id="config-beam-bogus"),
    case(["--config", "{B}/ccr_system.toml"], "ccr_system.toml", "system.dead_time_s", "expected float",
         id="config-dead-time-text"),
    case(["--config", "{B}/ccr_unknown.toml"], "ccr_unknown.toml", "system.dead_time_ns", "unknown key",
         id="config-unknown-key"),
]


@pytest.mark.parametrize("extra, messages", CCR_CASES)
def test_ccr(bad_input, extra, messages):
    args = ["ccr", H5, *extra, "--out", "{O}"]
    if "--ccr" not in extra:
        args += ["--ccr", CCR]
    if "--bootstrap" not in extra:
        args += ["--bootstrap", "0"]
    bad_input(args, 1, *messages)


def test_ccr_never_writes_over_its_inputs(bad_input):
    bad_input(["ccr", H5, "--ccr", CCR, "--out", "{P}", "--force", "--bootstrap", "0"], 1, "input")


SIMULATE = [
    case(["--n-ccr", "0"], "--n-ccr", id="n-ccr-0"),
    case(["--n-ccr", "100000"], "--n-ccr", id="n-ccr-huge"),
    case(["--n-ccr", "-3"], "--n-ccr", id="n-ccr-negative"),
    case(["--footprint-diameter", "0"], "--footprint-diameter", id="footprint-0"),
    case(["--footprint-diameter", "1e9"], "--footprint-diameter", id="footprint-huge"),
    case(["--length", "-100"], "--length", id="length-negative"),
    case(["--length", "nan"], "--length", id="length-nan"),
    case(["--ccr-photons", "1e9"], "--ccr-photons", id="ccr-photons-huge"),
    case(["--ccr-photons", "-1"], "--ccr-photons", id="ccr-photons-negative"),
    case(["--ccr-dropout", "nan"], "--ccr-dropout", id="dropout-nan"),
    case(["--seed", "99999999999"], "--seed", id="seed-huge"),
    case(["--n-unlit", "-1"], "--n-unlit", id="n-unlit-negative"),
    case(["--n-unlit", "100000"], "--n-unlit", id="n-unlit-huge"),
    case(["--footprint-diameter", "-5"], "--footprint-diameter", id="footprint-negative"),
    case(["--footprint-diameter", "nan"], "--footprint-diameter", id="footprint-nan"),
    case(["--seed", "-1"], "--seed", id="seed-negative"),
    case(["--along-bias", "nan"], "--along-bias", id="along-bias-nan"),
    case(["--along-bias", "1e9"], "--along-bias", id="along-bias-huge"),
    case(["--cross-bias", "inf"], "--cross-bias", id="cross-bias-inf"),
    case(["--ccr-dropout", "1.5"], "--ccr-dropout", id="dropout-1.5"),
    case(["--ccr-dropout", "-0.1"], "--ccr-dropout", id="dropout-negative"),
    case(["--length", "0"], "--length", id="length-0"),
    case(["--length", "1e12"], "--length", id="length-huge"),
    case(["--ccr-photons", "0"], "--ccr-photons", id="ccr-photons-0"),
    case(["--ccr-photons", "nan"], "--ccr-photons", id="ccr-photons-nan"),
    case(["--strength", "medium"], "--strength", id="strength"),
]


@pytest.mark.parametrize("extra, messages", SIMULATE)
def test_simulate_photons(bad_input, extra, messages):
    bad_input(["simulate", "photons", *extra, "--out", "{O}"], 1, *messages)
