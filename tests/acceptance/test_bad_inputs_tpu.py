"""The bad-input corpus (issue 16), part 6: ``tpu`` (see test_bad_inputs.py)."""

from __future__ import annotations

import pytest

COMMANDS = {"tpu"}  #: covered here
S1 = "{S}/strips/line_001.laz"
GOOD = ["-t", "{S}/sbet.out", "--sensor", "{S}/sensor.toml"]


def case(args, *messages: str, id: str):
    """One corpus case: its arguments and the substrings its message must hold."""
    return pytest.param(args, messages, id=id)


TPU = [
    case([S1, *GOOD, "--range-sigma", "-0.01"], "--range-sigma", id="range-sigma-negative"),
    case([S1, *GOOD, "--angle-sigma", "nan"], "--angle-sigma", id="angle-sigma-nan"),
    case([S1, *GOOD, "--beam-divergence", "1e9"], "--beam-divergence", id="beam-divergence-huge"),
    case(["{B}/empty.laz", *GOOD], "empty.laz", id="empty"),
    case(["{B}/garbage.laz", *GOOD], "garbage.laz", id="garbage"),
    case(["{B}/missing.laz", *GOOD], "missing.laz", id="missing"),
    case([S1, "-t", "{B}/missing.out", "--sensor", "{S}/sensor.toml"], "missing.out", id="trajectory-missing"),
    case([S1, "-t", "{S}/sbet.out", "--sensor", "{S}/truth.json"], "truth.json", id="sensor-not-toml"),
    case([S1, *GOOD, "--calibration", "{S}/sensor.toml"], "sensor.toml", "JSON", id="calibration-not-json"),
    case([S1, *GOOD, "--calibration", "{S}/truth.json"], "truth.json", "solution.json", id="calibration-truth-json"),
    case([S1, *GOOD, "--trajectory-sigma", "0.05"], "--trajectory-sigma", id="trajectory-sigma-one-number"),
    case([S1, *GOOD, "--config", "{B}/missing.toml"], "missing.toml", id="config-missing"),
    case([S1, *GOOD, "--config", "{B}/tpu_noise.toml"], "tpu_noise.toml", "noise.range_sigma_m", "[0, 10] m",
         id="config-range-sigma-negative"),
    case([S1, *GOOD, "--config", "{B}/tpu_sigma.toml"], "tpu_sigma.toml", "trajectory_sigma", "list of 2",
         id="config-trajectory-sigma-one-number"),
    case([S1, *GOOD, "--config", "{B}/tpu_crs.toml"], "tpu_crs.toml", "inputs.crs", id="config-crs-unknown"),
    case([S1, *GOOD, "--config", "{B}/tpu_unknown.toml"], "tpu_unknown.toml", "noise.angle_sigma_deg", "unknown key",
         id="config-unknown-key"),
]


@pytest.mark.parametrize("args, messages", TPU)
def test_tpu(bad_input, args, messages):
    bad_input(["tpu", *args, "--out", "{O}"], 1, *messages)


def test_tpu_never_writes_over_its_inputs(bad_input):
    bad_input(["tpu", S1, *GOOD, "--out", "{S}/strips", "--force"], 1, "input")


def test_tpu_usage_errors(bad_input):
    bad_input(["tpu", S1, "--sensor", "{S}/sensor.toml", "--out", "{O}"], 2, "--trajectory")
