"""The bad-input corpus, round two (issue 27): external resources bounded. Text inputs read with a
size limit and regular files only (a device never ends, a pipe can be read once): /dev/zero and a
named pipe as every kind of input; a text file past the limit; malformed scheduler addresses;
quality's cell advice; no Python warning printed before an error. Each case: exit 1, one error
line naming the file / option, no traceback, inputs unchanged, nothing left behind
(fixtures in conftest.py). The scheduler at an HTTP server or a proxy: test_scheduler_bounded.py."""

from __future__ import annotations

import os

import pytest


def case(args, *messages: str, id: str):
    return pytest.param(args, messages, id=id)


S1, S2 = "{S}/strips/line_001.laz", "{S}/strips/line_002.laz"
TRAJ, SENSOR = ["--trajectory", "{S}/sbet.out"], ["--sensor", "{S}/sensor.toml"]
DEV = "character device"

ZERO = [  # /dev/zero as each input: refused at once, not read (it never ends)
    case(["range-cal", "/dev/zero", "--out", "{O}"], "/dev/zero", DEV, "total-station", id="range-cal-obs"),
    case(["range-cal", "{T}/observations.csv", "--truth", "/dev/zero", "--out", "{O}"], "/dev/zero", DEV,
         id="range-cal-truth"),
    case(["boresight", S1, S2, *TRAJ, "--sensor", "/dev/zero", "--out", "{O}"], "/dev/zero", DEV, "sensor.toml",
         id="boresight-sensor"),
    case(["boresight", S1, S2, "--trajectory", "/dev/zero", *SENSOR, "--out", "{O}"], "/dev/zero", DEV, "trajectory",
         id="boresight-trajectory"),
    case(["boresight", S1, S2, *TRAJ, *SENSOR, "--trajectory-accuracy", "/dev/zero", "--out", "{O}"], "/dev/zero",
         DEV, "accuracy", id="boresight-trajectory-accuracy"),
    case(["boresight", S1, S2, *TRAJ, *SENSOR, "--truth", "/dev/zero", "--out", "{O}"], "/dev/zero", DEV,
         id="boresight-truth"),
    case(["boresight", "/dev/zero", S2, *TRAJ, *SENSOR, "--out", "{O}"], "/dev/zero", DEV, "LAS", id="boresight-strip"),
    case(["ccr", "{P}/ATL03_sim.h5", "--ccr", "/dev/zero", "--out", "{O}"], "/dev/zero", DEV, "CCR", id="ccr-csv"),
    case(["ccr", "{P}/ATL03_sim.h5", "--ccr", "{P}/ccr.csv", "--truth", "/dev/zero", "--out", "{O}"], "/dev/zero", DEV,
         id="ccr-truth"),
    case(["ccr", "/dev/zero", "--ccr", "{P}/ccr.csv", "--out", "{O}"], "/dev/zero", DEV, id="ccr-atl03"),
    case(["denoise", "/dev/zero", "--out", "{O}.csv"], "/dev/zero", DEV, id="denoise-atl03"),
    case(["inverse", S1, "--trajectory", "/dev/zero", "--out", "{O}.csv"], "/dev/zero", DEV, id="inverse-trajectory"),
    case(["inverse", S1, *TRAJ, "--sensor", "/dev/zero", "--out", "{O}.csv"], "/dev/zero", DEV, id="inverse-sensor"),
    case(["regeoref", S1, *TRAJ, "--from", "{S}/sensor.toml", "--to", "/dev/zero", "--out", "{O}"], "/dev/zero", DEV,
         id="regeoref-to"),
    case(["quality", S1, "/dev/zero"], "/dev/zero", DEV, id="quality-strip"),
    case(["info", "/dev/zero"], "/dev/zero", DEV, id="info"),
    case(["sensor", "import", "/dev/zero", "--from", "leeward", "--out", "{O}.toml"], "/dev/zero", DEV,
         id="sensor-import-leeward"),
    case(["sensor", "import", "/dev/zero", "--from", "pdal-scan2imu", "--out", "{O}.toml"], "/dev/zero", DEV,
         id="sensor-import-pdal"),
    case(["sensor", "import", "/dev/zero", "--from", "optech-csd", "--out", "{O}.toml"], "/dev/zero", DEV,
         id="sensor-import-csd"),
    case(["georef", "/dev/zero", "--out", "{O}.laz"], "/dev/zero", DEV, id="georef-csd"),
]


@pytest.mark.parametrize("args, messages", ZERO)
def test_dev_zero(bad_input, args, messages):
    bad_input(args, 1, *messages)


@pytest.fixture
def fifo(corpus, tmp_path):
    """A named pipe nobody writes to (a reader would wait for ever)."""
    path = tmp_path / "pipe.csv"
    os.mkfifo(path)
    return path


@pytest.mark.parametrize("args", [
    pytest.param(["range-cal", "{F}", "--out", "{O}"], id="range-cal"),
    pytest.param(["info", "{F}"], id="info"),
    pytest.param(["boresight", S1, S2, "--trajectory", "{F}", *SENSOR, "--out", "{O}"], id="boresight-trajectory"),
    pytest.param(["ccr", "{P}/ATL03_sim.h5", "--ccr", "{F}", "--out", "{O}"], id="ccr-csv"),
    pytest.param(["quality", S1, "{F}"], id="quality-strip"),
])
def test_named_pipe(bad_input, fifo, args):
    args = [a.replace("{F}", str(fifo)) for a in args]
    bad_input(args, 1, str(fifo), "is a pipe, not a regular file", "save the stream to a file first")


def test_text_input_beyond_the_size_limit(bad_input, tmp_path):
    """A sensor.toml of 65 MiB (sparse): refused from its size, never read into memory."""
    big = tmp_path / "sensor_huge.toml"
    with open(big, "wb") as f:
        f.truncate(65 << 20)
    bad_input(["boresight", S1, S2, *TRAJ, "--sensor", str(big), "--out", "{O}"], 1, str(big), "size",
              "at most 64 MiB", "got 65 MiB")


@pytest.mark.parametrize("address", ["not an address", "tcp://127.0.0.1:99999", "tcp://:8786", "http://host:80",
                                     "tcp://host name:8786"])
def test_malformed_scheduler_address(bad_input, address):
    bad_input(["boresight", S1, S2, *TRAJ, *SENSOR, "--method", "vgicp", "--scheduler", address, "--out", "{O}"], 1,
              "--scheduler", "expected a Dask scheduler address such as tcp://host:8786", repr(address))


def test_no_python_warning_before_an_error(corpus, cli, tmp_path):
    """A strip with NaN GPS times makes numpy / laspy warn while it is read; the run fails on it with
    one line, and the warnings of a failed run are not printed (they used to come first)."""
    argv = corpus.args(["boresight", *(f"{{S}}/strips/line_00{i}.laz" for i in (2, 3, 4)), "{B}/nan_time.las",
                        *TRAJ, *SENSOR, "--out", "{O}"], tmp_path / "out")
    code, _, err = cli(*argv)
    assert code == 1 and "nan_time.las" in err and "gps_time" in err, err
    assert [ln for ln in err.splitlines() if ln.strip()] == [err.strip()] and err.strip().startswith("error: "), err
    assert "Warning" not in err and "warning" not in err


def test_quality_cell_too_small_advises_a_larger_cell(bad_input):
    message = bad_input(["quality", S1, S2, "--cell", "0.2"], 1, "--cell", "larger cell")
    assert "smaller" not in message
