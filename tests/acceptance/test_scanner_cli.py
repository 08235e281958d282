"""``calidar scanner analyze`` end to end (outputs, JSON, verdict, run record) and every bad option
giving exit code 1 with one line naming the option and its range, and no output left behind."""

import json

import numpy as np
import pytest

PALMER = ("scanner", "analyze", "--model", "palmer", "--range", "500")


def test_cli_json_outputs_verdict_and_record(cli, tmp_path):
    out = tmp_path / "a"
    code, stdout, err = cli(*PALMER, "--eccentricity", "2e-4", "--phase", "0", "--delta-l", "0.02", "--delta-r", "0.02",
                            "--spec-arcsec", "10", "--json", "--out", out)
    assert code == 3, err  # a FAIL verdict (below): exit 3, the exit-code contract of every command (issue 26)
    doc = json.loads(stdout)
    assert doc["pattern"]["extent_x_m"] == pytest.approx(258.8, rel=1e-3)
    assert set(doc["errors"]) == {"eccentricity", "delta_l", "delta_r"}
    assert doc["errors"]["eccentricity"]["max_abs_dx_m"] == pytest.approx(0.027, rel=0.1)
    for name in ("pattern.csv", "pattern.png", "displacement_delta_r.csv", "displacement_delta_r.png",
                 "displacement_combined.csv", "summary.json", "report.html"):
        assert (out / name).stat().st_size > 0, name
    rows = np.loadtxt(out / "displacement_eccentricity.csv", delimiter=",", skiprows=1)
    assert np.abs(rows[:, 1]).max() == pytest.approx(doc["errors"]["eccentricity"]["max_abs_dx_m"], rel=1e-6)
    # δ_R = 0.02° deflects the beam by 144″: 14.4× a 10″ spec, a fail; δ_L is a pitch of −2 δ_L: a warning
    v = doc["verdict"]
    assert v["status"] == "fail"
    delta_r = next(f for f in v["findings"] if "δ_R" in f["check"])
    assert delta_r["status"] == "fail" and "14.4×" in delta_r["detail"] and "0.001389°" in delta_r["action"]
    assert any(f["status"] == "warn" and "δ_L" in f["check"] and "pitch of −2.00" in f["detail"] for f in v["findings"])
    assert doc["run"]["options"]["errors"]["delta_r"] == 0.02 and doc["run"]["finished_utc"]
    html = (out / "report.html").read_text()
    assert "verdict v-fail" in html and "How this was made" in html and "−0.00" not in html


def test_cli_prints_the_verdict_and_refuses_to_overwrite(cli, tmp_path):
    out = tmp_path / "w"
    code, stdout, err = cli("scanner", "analyze", "--model", "wedge", "--range", "300", "--axis-tilt", "0.0005",
                            "--out", out)
    assert code == 0, err
    assert "PASS" in stdout and "wedge scanner at 300 m" in stdout, stdout
    assert json.loads((out / "summary.json").read_text())["verdict"]["status"] == "pass"
    code, _, err = cli("scanner", "analyze", "--model", "wedge", "--range", "300", "--out", out)
    assert code == 1 and "--force" in err


BAD_OPTIONS = {
    "negative range": (["--range", "-500"], "--range"),
    "zero range": (["--range", "0"], "--range"),
    "NaN range": (["--range", "nan"], "--range"),
    "infinite range": (["--range", "inf"], "--range"),
    "range beyond 1000 km": (["--range", "2e6"], "--range"),
    "FOV over a full turn": (["--model", "linear", "--fov", "400"], "--fov"),
    "zero FOV": (["--model", "linear", "--fov", "0"], "--fov"),
    "a billion points": (["--points", "1000000000"], "--points"),
    "too few points": (["--points", "3"], "--points"),
    "zero mirror tilt": (["--mirror-tilt", "0"], "--mirror-tilt"),
    "negative mirror tilt": (["--mirror-tilt", "-3"], "--mirror-tilt"),
    "mirror tilt above the axis angle": (["--mirror-tilt", "50"], "--mirror-tilt"),
    "axis angle of 90°": (["--axis-angle", "90"], "--axis-angle"),
    "refractive index below 1": (["--model", "wedge", "--refractive-index", "0.9"], "--refractive-index"),
    "totally reflecting wedge": (["--model", "wedge", "--wedge-angle", "60"], "--wedge-angle"),
    "palmer error on a wedge": (["--model", "wedge", "--delta-l", "0.02"], "--delta-l"),
    "unknown model": (["--model", "conical"], "--model"),
    "zero spec": (["--spec-arcsec", "0"], "--spec-arcsec"),
    "NaN spec": (["--spec-arcsec", "nan"], "--spec-arcsec"),
    "negative eccentricity": (["--eccentricity", "-1e-4"], "--eccentricity"),
    "eccentricity of half the radius": (["--eccentricity", "0.5"], "--eccentricity"),
    "δ_R of 45°": (["--delta-r", "45"], "--delta-r"),
    "infinite phase": (["--phase", "inf"], "--phase"),
    "zero grating radius": (["--grating-radius-mm", "0"], "--grating-radius-mm"),
    "scan-angle scale of 10 000 %": (["--model", "linear", "--scan-angle-scale", "1e8"], "--scan-angle-scale"),
    "wedge axis tilt on a palmer": (["--axis-tilt", "0.1"], "--axis-tilt"),
}


@pytest.mark.parametrize("case", list(BAD_OPTIONS))
def test_bad_option_is_one_line_naming_it(cli, tmp_path, case):
    args, option = BAD_OPTIONS[case]
    argv = list(PALMER)
    for k in range(0, len(args), 2):  # override --model/--range when the case gives them
        if args[k] in argv:
            argv[argv.index(args[k]) + 1] = args[k + 1]
        else:
            argv += args[k: k + 2]
    code, _, err = cli(*argv, "--out", tmp_path / "bad")
    msg = err.strip()
    assert code == 1, msg
    assert "\n" not in msg and "Traceback" not in msg and "internal error" not in msg
    assert msg.startswith(f"error: {option}:"), msg
    assert "expected" in msg or "applies to" in msg, msg
    assert not (tmp_path / "bad").exists()


def test_points_that_are_not_an_integer_are_a_usage_error(cli, tmp_path):
    code, _, err = cli(*PALMER, "--points", "1e9", "--out", tmp_path / "bad")
    assert code == 2 and "--points" in err and "Traceback" not in err
    assert not (tmp_path / "bad").exists()


def test_out_that_is_a_file_is_refused(cli, tmp_path):
    f = tmp_path / "file.txt"
    f.write_text("keep me")
    code, _, err = cli(*PALMER, "--out", f, "--force")
    assert code == 1 and str(f) in err and "\n" not in err.strip()
    assert f.read_text() == "keep me"


@pytest.mark.parametrize("signum,code", [(15, 143), (2, 130)])
def test_interrupted_analysis_leaves_nothing(tmp_path, signum, code):
    """SIGTERM / SIGINT while the outputs are being written: exit 143 / 130, no folder, no temporary."""
    import os
    import signal
    import subprocess
    import sys
    import time

    out = tmp_path / "run"
    env = {**os.environ, "PYTHONPATH": os.pathsep.join(sys.path)}
    p = subprocess.Popen([sys.executable, "-m", "calidar", *PALMER, "--points", "100000", "--out", str(out)],
                         stdout=subprocess.PIPE, stderr=subprocess.PIPE, env=env, text=True)
    t0 = time.monotonic()
    while not any(tmp_path.glob(".run.calidar-*/*.csv")) and time.monotonic() - t0 < 60 and p.poll() is None:
        time.sleep(0.05)  # until the run is writing its files into its temporary folder
    p.send_signal(signal.Signals(signum))
    _, err = p.communicate(timeout=60)
    assert p.returncode == code, err
    assert "interrupted" in err and "Traceback" not in err
    assert list(tmp_path.iterdir()) == []
