"""An interrupted ``calidar boresight``, ``simulate survey`` or ``quality`` (SIGTERM, SIGINT; a real
subprocess) leaves no temporary file or folder and no partial result; a run failing on a bad input
found mid-way leaves nothing either, or, under --force, the previous result as it was (issue 16;
inverse and regeoref: test_georef_interrupted.py). Inputs: the bad-input corpus's simulated survey
(conftest.py)."""

from __future__ import annotations

import hashlib
import os
import shutil
import signal
import subprocess
import sys
import time

import pytest


def _args(corpus, out, *strips):
    s = corpus.root / "survey"
    strips = strips or tuple(sorted((s / "strips").glob("*.laz")))
    return ["boresight", *map(str, strips), "--trajectory", str(s / "sbet.out"), "--sensor", str(s / "sensor.toml"),
            "--write-strips", "--out", str(out)]


def _tree(folder):
    return {p.relative_to(folder).as_posix(): hashlib.sha256(p.read_bytes()).hexdigest()
            for p in sorted(folder.rglob("*")) if p.is_file()}


def _command(corpus, out, command):
    s = corpus.root / "survey"
    return {"boresight": _args(corpus, out),
            "simulate survey": ["simulate", "survey", "--density", "0.05", "--out", str(out)],
            "quality": ["quality", *map(str, sorted((s / "strips").glob("*.laz"))), "--out", str(out)]}[command]


#: what shows a run is writing its results into its temporary folder
WRITING = {"boresight": "*.json", "simulate survey": "strips/*.laz", "quality": "*.tif"}


def _interrupt(corpus, tmp_path, signum, writing: bool, command: str = "boresight", repeat: int = 1):
    """Start a run, signal it once its temporary folder exists (``writing``: once the first result
    is written into it) and return (exit code, stderr); None when the run finished first."""
    out = tmp_path / "out"
    system_tmp = tmp_path.parent / f"{tmp_path.name}_tmp"  # the run's TMPDIR: held points go there (issue 32)
    system_tmp.mkdir(exist_ok=True)
    env = {**os.environ, "NUMBA_NUM_THREADS": "1", "OMP_NUM_THREADS": "1", "TMPDIR": str(system_tmp)}
    proc = subprocess.Popen([sys.executable, "-m", "calidar", *_command(corpus, out, command)],
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, env=env)
    deadline = time.monotonic() + 120
    while True:
        tmp = [p for p in tmp_path.iterdir() if p.name.startswith(".out.")]  # the run's temporary folder
        if tmp and (not writing or any(tmp[0].glob(WRITING[command]))):
            break
        if proc.poll() is not None:
            break
        assert time.monotonic() < deadline, proc.communicate()
        time.sleep(0.005)
    if not writing:
        time.sleep(0.5)  # into the calibration: strips read, pairs being matched
    if proc.poll() is not None:
        assert proc.returncode == 0, proc.communicate()
        shutil.rmtree(out)
        return None
    for _ in range(repeat):  # a second signal (Ctrl-C pressed twice) must not cut the clean-up short
        proc.send_signal(signum)
        time.sleep(0.002)
    _, err = proc.communicate(timeout=120)
    return proc.returncode, err


@pytest.mark.parametrize("command, writing, repeat", [
    ("boresight", False, 1), ("boresight", True, 1), ("boresight", True, 3), ("simulate survey", True, 1),
    ("quality", True, 1)], ids=["boresight-calibrating", "boresight-writing", "boresight-writing-thrice",
                                "simulate-survey-writing", "quality-writing"])
@pytest.mark.parametrize("signum", [signal.SIGTERM, signal.SIGINT], ids=["SIGTERM", "SIGINT"])
def test_interrupted_run_leaves_nothing(corpus, tmp_path, signum, command, writing, repeat):
    for _ in range(20):  # a run may end between the first result written and the signal: run again (quality
        # writes its rasters within milliseconds of each other: under load 5 tries all ended first once)
        ended = _interrupt(corpus, tmp_path, signum, writing, command, repeat)
        if ended is not None:
            break
    assert ended is not None, "every run ended before it could be interrupted"
    code, err = ended
    assert code == 128 + signum, err
    assert err.strip() == "interrupted" + (" (SIGTERM)" if signum == signal.SIGTERM else "")
    assert list(tmp_path.iterdir()) == []  # no temporary folder, no partial result
    assert list(tmp_path.parent.glob(f"{tmp_path.name}_tmp/calidar-*")) == []  # nor in the system's temporary folder


def test_failed_boresight_leaves_nothing_or_the_previous_result(corpus, cli, tmp_path):
    """A strip with NaN GPS times is found only once the strips are read, inside the run's
    transaction: nothing is left behind; under --force the previous result stays intact."""
    s, bad = corpus.root / "survey", corpus.root / "bad"
    failing = sorted((s / "strips").glob("*.laz"))[1:] + [bad / "nan_time.las"]
    out = tmp_path / "out"
    code, _, err = cli(*_args(corpus, out, *failing))
    assert code == 1 and "nan_time.las: gps_time" in err
    assert list(tmp_path.iterdir()) == []

    code, _, err = cli(*_args(corpus, out))
    assert code == 0, err
    before = _tree(out)
    assert {"solution.json", "sensor.toml", "report.html", "sbet_corrected.out"} <= set(before)
    code, _, err = cli(*_args(corpus, out, *failing), "--force")
    assert code == 1 and "nan_time.las: gps_time" in err
    assert _tree(out) == before and [p.name for p in tmp_path.iterdir()] == ["out"]
