"""The bad-input corpus (issue 16), part 5: ``trajectory`` (see test_bad_inputs.py)."""

from __future__ import annotations

import pytest

COMMANDS = {"trajectory"}  #: covered here
S1 = "{S}/strips/line_001.laz"


def case(args, *messages: str, id: str):
    """One corpus case: its arguments and the substrings its message must hold."""
    return pytest.param(args, messages, id=id)


TRAJECTORY = [
    case([S1, "--rate", "0"], "--rate", id="rate-0"),
    case([S1, "--rate", "nan"], "--rate", id="rate-nan"),
    case([S1, "--points-per-second", "1"], "--points-per-second", id="points-per-second-1"),
    case([S1, "--knot-spacing", "0"], "--knot-spacing", id="knot-spacing-0"),
    case([S1, "--scan-plane-yaw", "100"], "--scan-plane-yaw", id="scan-plane-yaw-100"),
    case(["{B}/empty.laz"], "empty.laz", "no points", id="empty"),
    case(["{B}/garbage.laz"], "garbage.laz", id="garbage"),
    case(["{B}/truncated.laz"], "truncated.laz", id="truncated"),
    case(["{B}/missing.laz"], "missing.laz", id="missing"),
    case(["{B}/huge.las"], "huge.las", id="coordinates-1e300"),
    case(["{B}/no_gps_time.las"], "no_gps_time.las", "gps_time", "needs each point's GPS time", id="no-gps-time"),
    case(["{B}/no_scan_no_returns.laz"], "no_scan_no_returns.laz", "scan-angle field", "multi-return pulses", id="no-scan-angles-no-returns"),
    case(["{B}/one_pulse_per_line.laz"], "one_pulse_per_line.laz", "no flight line", id="one-pulse-per-line"),
    case(["{B}/short_line.laz"], "short_line.laz", "the method needs ≥ 0.5 s", id="single-short-line"),
    case([S1, "--encoder-sigma", "0.1"], "--encoder-sigma", "two or three numbers", id="encoder-sigma-one-number"),
    case([S1, "--encoder-sigma", "0.1,-1"], "--encoder-sigma", id="encoder-sigma-negative"),
    case([S1, "--scan-plane-sigma", "nan,0.1"], "--scan-plane-sigma", id="scan-plane-sigma-nan"),
    case([S1, "--scan-plane-sigma", "0.1,0.1,0.02,1"], "--scan-plane-sigma", "two or three numbers",
         id="scan-plane-sigma-four-numbers"),
    case([S1, "--config", "{B}/missing.toml"], "missing.toml", id="config-missing"),
    case([S1, "--config", "{B}/trajectory_rate.toml"], "trajectory_rate.toml: rate_hz (--rate): expected", id="config-rate-0"),
    case([S1, "--config", "{B}/trajectory_mount.toml"], "trajectory_mount.toml: mount_sigma.scan_scale (--encoder-sigma)",
         id="config-mount-sigma-negative"),
]


@pytest.mark.parametrize("args, messages", TRAJECTORY)
def test_trajectory(bad_input, args, messages):
    bad_input(["trajectory", *args, "--out", "{O}"], 1, *messages)


def test_trajectory_leaves_out_nan_times_and_says_so(cli, corpus, tmp_path):
    """NaN GPS times are damaged points, not a damaged file: left out, counted, the rest reconstructed."""
    code, out, err = cli(*corpus.args(["trajectory", "{B}/nan_time.las", "--out", "{O}"], tmp_path / "t.csv"))
    assert code == 0, err
    assert "10 points with a GPS time ≤ 0 or none were left out" in err and (tmp_path / "t.csv").exists()


def test_trajectory_never_writes_over_its_inputs(bad_input):
    bad_input(["trajectory", S1, "--out", S1, "--force"], 1, "input")


@pytest.mark.parametrize("option, value", [("--format", "las"), ("--scanner", "conical")])
def test_trajectory_usage_errors(bad_input, option, value):
    bad_input(["trajectory", S1, option, value, "--out", "{O}"], 2, option)
