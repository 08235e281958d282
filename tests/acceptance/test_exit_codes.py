"""The exit-code contract of every command (issues 26 and 27; README "Exit codes"), each case a
real subprocess on the bad-input corpus's files: 0 pass or warn, 3 a FAIL verdict, 1 input error
(missing and unreadable inputs alike), 2 usage error; 130/143 (interrupted) are tested in
test_signals_random.py and test_interrupted_runs.py. Every command's --help states the contract."""

from __future__ import annotations

import os
import subprocess
import sys

import pytest

from calidar.cli.common import EXIT_CODES_HELP, verdict_exit_code

ENV = {**os.environ, "NUMBA_NUM_THREADS": "1", "OMP_NUM_THREADS": "1", "COLUMNS": "200"}
S1, S2 = "{S}/strips/line_001.laz", "{S}/strips/line_002.laz"
TRAJ = ["--trajectory", "{S}/sbet.out"]

#: command → the arguments of a run that succeeds (None: too long for this test; its 0 is tested elsewhere)
COMMANDS = {
    "info": ["info", S1],
    "inverse": ["inverse", S1, *TRAJ, "--out", "{O}.csv"],
    "regeoref": ["regeoref", S1, *TRAJ, "--from", "{S}/sensor.toml", "--to", "{S}/sensor.toml", "--out", "{O}"],
    "georef": None,  # needs an Optech CSD file (real data): test_cli_georef_csd.py
    "range-cal": ["range-cal", "{T}/observations.csv", "--out", "{O}"],
    "simulate total-station": ["simulate", "total-station", "--out", "{O}"],
    "simulate photons": ["simulate", "photons", "--length", "200", "--out", "{O}"],
    "simulate survey": None,  # test_sim_cli.py
    "denoise": ["denoise", "{P}/ATL03_sim.h5", "--out", "{O}.csv"],
    "ccr": ["ccr", "{P}/ATL03_sim.h5", "--ccr", "{P}/ccr.csv", "--bootstrap", "5", "--out", "{O}"],
    "demo": None,  # a whole survey and every calibration (minutes): run by hand, see the final report
    "quality": ["quality", S1, S2, "--out", "{O}"],
    "boresight": None,  # test_output_runs.py, test_signals_random.py
    "scanner analyze": ["scanner", "analyze", "--model", "wedge", "--range", "300", "--axis-tilt", "0.0005",
                        "--out", "{O}"],
    "sensor import": ["sensor", "import", "{X}", "--from", "pdal-scan2imu", "--out", "{O}.toml"],
}
#: command → the arguments of a run with a missing input (exit 1)
MISSING = {
    "info": ["info", "{B}/missing.laz"],
    "inverse": ["inverse", "{B}/missing.laz", *TRAJ, "--out", "{O}.csv"],
    "regeoref": ["regeoref", S1, *TRAJ, "--from", "{B}/missing.toml", "--to", "{S}/sensor.toml", "--out", "{O}"],
    "georef": ["georef", "{B}/missing.csd", "--out", "{O}.laz"],
    "range-cal": ["range-cal", "{B}/missing.csv", "--out", "{O}"],
    "simulate total-station": ["simulate", "total-station", "--setups", "0", "--out", "{O}"],
    "simulate photons": ["simulate", "photons", "--n-ccr", "0", "--out", "{O}"],
    "simulate survey": ["simulate", "survey", "--preset", "satellite", "--out", "{O}"],
    "denoise": ["denoise", "{B}/missing.h5", "--out", "{O}.csv"],
    "ccr": ["ccr", "{P}/ATL03_sim.h5", "--ccr", "{B}/missing.csv", "--out", "{O}"],
    "demo": ["demo", "--out", "{S}/sensor.toml"],
    "quality": ["quality", S1, "{B}/missing.laz"],
    "boresight": ["boresight", S1, S2, *TRAJ, "--sensor", "{B}/missing.toml", "--out", "{O}"],
    "scanner analyze": ["scanner", "analyze", "--model", "spiral", "--range", "100", "--out", "{O}"],
    "sensor import": ["sensor", "import", "{B}/missing.toml", "--from", "leeward", "--out", "{O}.toml"],
}
FAIL = {  # a FAIL verdict: exit 3
    "range-cal": ["range-cal", "{T}/observations.csv", "--tolerance", "0.0001", "--out", "{O}"],
    "scanner analyze": ["scanner", "analyze", "--model", "linear", "--range", "100", "--out", "{O}"],
}


def _run(corpus, tmp_path, args):
    r = corpus.root
    scan2imu = tmp_path / "scan2imu.txt"  # a PDAL scan2imu matrix: scanner axes = body axes
    scan2imu.write_text("1 0 0 0  0 1 0 0  0 0 1 0  0 0 0 1\n")
    argv = [a.format(S=r / "survey", T=r / "total-station", P=r / "photons", B=r / "bad", O=tmp_path / "out",
                     X=scan2imu) for a in args]
    p = subprocess.run([sys.executable, "-m", "calidar", *argv], capture_output=True, text=True, env=ENV, timeout=300)
    assert "Traceback" not in p.stdout + p.stderr and "internal error" not in p.stderr, p.stderr
    return p.returncode, p.stdout, p.stderr


def test_verdict_to_exit_code():
    assert [verdict_exit_code(*v) for v in (("pass",), ("warn", "pass"), ("pass", "fail"), ())] == [0, 0, 3, 0]


@pytest.mark.slow
@pytest.mark.parametrize("command", [c for c, a in COMMANDS.items() if a])
def test_exit_0_on_success(corpus, tmp_path, command):
    code, _, err = _run(corpus, tmp_path, COMMANDS[command])
    assert code == 0, err


@pytest.mark.slow
@pytest.mark.parametrize("command", list(FAIL))
def test_exit_3_on_a_fail_verdict(corpus, tmp_path, command):
    code, out, err = _run(corpus, tmp_path, FAIL[command])
    assert code == 3, err
    assert "FAIL" in out and (tmp_path / "out" / "report.html").exists()  # the results are written


@pytest.mark.slow
@pytest.mark.parametrize("command", list(MISSING))
def test_exit_1_on_bad_input(corpus, tmp_path, command):
    code, _, err = _run(corpus, tmp_path, MISSING[command])
    assert code == 1, err
    assert len([ln for ln in err.splitlines() if ln.startswith("error: ")]) == 1, err
    assert not (tmp_path / "out").exists()


@pytest.mark.slow
@pytest.mark.parametrize("command", list(MISSING))
def test_exit_2_on_usage_error_and_help_states_the_contract(corpus, tmp_path, command):
    words = command.split()
    code, _, err = _run(corpus, tmp_path, [*words, "--no-such-option"])
    assert code == 2 and "No such option" in err and "Usage: calidar" in err, err
    code, out, err = _run(corpus, tmp_path, [*words, "--help"])
    assert code == 0 and " ".join(EXIT_CODES_HELP.split()) in " ".join(out.split()), out


def test_unreadable_input_exits_1_like_a_missing_one(corpus):
    """click checks an argument's readability: "not readable" is an input error (1), not usage (2).
    Run as an unprivileged user (root reads everything); skipped where that is not possible."""
    import shutil
    import tempfile
    from pathlib import Path

    if os.geteuid() != 0 or not shutil.which("setpriv"):
        pytest.skip("needs root and setpriv to run as another user")
    work = Path(tempfile.mkdtemp(prefix="calidar-unreadable-", dir="/tmp"))  # reachable by that user
    try:
        work.chmod(0o777)
        f = work / "obs.csv"
        f.write_text((corpus.root / "total-station" / "observations.csv").read_text())
        f.chmod(0)
        env = {**ENV, "NUMBA_CACHE_DIR": str(work / "numba"), "HOME": str(work)}
        p = subprocess.run(["setpriv", "--reuid=65534", "--regid=65534", "--clear-groups", sys.executable, "-m",
                            "calidar", "range-cal", str(f), "--out", str(work / "out")], capture_output=True,
                           text=True, env=env, timeout=120)
        if "calidar" not in p.stderr and "obs.csv" not in p.stderr:
            pytest.skip(f"the unprivileged user cannot run calidar here: {p.stderr[-300:]}")
        assert p.returncode == 1, p.stderr
        assert p.stderr.startswith("error: ") and "obs.csv" in p.stderr and "not readable" in p.stderr, p.stderr
        assert "Traceback" not in p.stderr and not (work / "out").exists()
    finally:
        shutil.rmtree(work, ignore_errors=True)
