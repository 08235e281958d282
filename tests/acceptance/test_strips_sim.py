"""Acceptance of the strip calibrator against the survey simulator's truth (issue 4)."""

from __future__ import annotations

import functools
import glob
import json
import shlex

import numpy as np
import pytest

from calidar.sim.survey import simulate_survey, survey_config
from calidar.strips.calibrate import calibrate
from calidar.strips.config import CalibrationConfig, Estimate, TiePlanes, Vgicp
from calidar.strips.trajectory_errors import TrajectoryModel

BORESIGHT_ERRORS = {"boresight_roll": np.radians(0.03), "boresight_pitch": np.radians(-0.04),
                    "boresight_yaw": np.radians(0.05)}
ANGLES = ("boresight_roll", "boresight_pitch", "boresight_yaw")


def _simulate(preset, directions, density, vegetation=0.0, seed=3, **errors):
    """One simulated survey per setting, shared by the tests that use it (this module, test_vgicp,
    test_distribute): the methods run on the same survey, not on a copy simulated again. The
    settings are normalised first: ``_simulate("airborne", "cross", 0.3)`` and ``seed=3`` are one survey."""
    return _simulated(preset, directions, float(density), float(vegetation), int(seed), tuple(sorted(errors.items())))


@functools.lru_cache(maxsize=6)  # ≈ 160 MB per airborne survey; 3 were evicted before their last use
def _simulated(preset, directions, density, vegetation, seed, errors):
    cfg = survey_config(preset, seed=seed, density=density, vegetation=vegetation, directions=directions,
                        errors={**BORESIGHT_ERRORS, **dict(errors)}, range_noise_m=0.03)
    return simulate_survey(cfg)


def _check_angles(sol, truth, tol_deg=0.002):
    for name in ANGLES:
        err = sol.values[name] - truth[name]
        assert abs(np.degrees(err)) < tol_deg, (name, np.degrees(err))
        assert abs(err) < 3 * sol.sigma[name], (name, err / sol.sigma[name])


@pytest.fixture(scope="module")
def airborne(tmp_path_factory):
    res = _simulate("airborne", "cross", 0.3)
    return res, res.write(tmp_path_factory.mktemp("airborne") / "sim")


def _args(sim):
    return [*sorted((sim / "strips").glob("*.laz")), "--trajectory", sim / "sbet.out", "--sensor", sim / "sensor.toml",
            "--truth", sim / "truth.json"]


def _run_shown(cli, command: str, folder) -> dict:
    """Run a report's "reproduced by" command line (glob expanded, its output folder in ``folder``);
    the per-pair results of its final ``calidar quality``."""
    out = None
    for part in command.split(" && "):
        args = [a.replace("MOUNTING", str(folder)).replace("CORRECTED", str(folder)) for a in shlex.split(part)]
        args = [x for a in args for x in (sorted(glob.glob(a)) if "*" in a else [a])]
        assert args[0] == "calidar"
        code, out, err = cli(*args[1:], *(["--json"] if args[1] == "quality" else []))
        assert code == 0, err
    return {(p["a"], p["b"]): p for p in json.loads(out)["pairs"]}


def test_airborne_default_run_reproduces_its_report(cli, airborne, tmp_path):
    """``calidar boresight`` with its defaults on a simulated survey folder: the trajectory model on
    with the smrmsg beside the SBET as priors, every angle within 0.002° and 3σ, a verdict, the run's
    provenance — and the report's overlap quality reproduced by the commands it shows, within 2 mm."""
    res, sim = airborne
    strips = sorted((sim / "strips").glob("*.laz"))
    out = tmp_path / "cal"
    code, stdout, err = cli("boresight", *_args(sim), "--out", out, "--write-strips")
    assert code == 0, err
    doc = json.loads((out / "solution.json").read_text())
    for name in ANGLES:
        p = doc["parameters"][name]
        assert p["unit"] == "deg" and p["free"]
        assert abs(p["error"]) < 0.002 and abs(p["error"]) < 3 * p["sigma"], (name, p)
        assert p["truth"] == pytest.approx(np.degrees(res.truth.parameters()[name]))
    assert not doc["parameters"]["lever_arm_x"]["free"]
    assert len(doc["strips"]["pairs"]) >= 10
    assert doc["trajectory_accuracy"]["source"] == str(sim / "smrmsg.out")
    n_knots = sum(name.startswith("trajectory_tilt_up_") for name in doc["parameters"])
    assert n_knots > 50  # knots every second (the default) on every strip
    # nuisance parameters: value and σ listed, but not in the correlation matrix or the history
    assert doc["parameters"]["trajectory_tilt_up_1_0"]["sigma"] > 0
    assert doc["correlation"]["names"] == list(ANGLES) and len(doc["correlation"]["matrix"]) == 3
    assert set(doc["history"][-1]["values"]) == set(ANGLES)
    text = " ".join(stdout.split())
    assert f"{6 * n_knots} trajectory corrections estimated" in text
    assert doc["verdict"]["status"] == "pass" and text.startswith("PASS boresight_roll, boresight_pitch, boresight_yaw")
    assert {i["path"] for i in doc["run"]["inputs"]} == {str(p.resolve()) for p in
                                                         [*strips, sim / "sbet.out", sim / "smrmsg.out",
                                                          sim / "sensor.toml", sim / "truth.json"]}
    assert all(len(i["sha256"]) == 64 for i in doc["run"]["inputs"]) and doc["run"]["calidar_version"]
    from calidar.sensor import Sensor

    cal = Sensor.read(out / "sensor.toml")
    assert cal.boresight_roll == pytest.approx(np.radians(doc["parameters"]["boresight_roll"]["value"]))
    assert cal.lever_arm_x == res.nominal.lever_arm_x  # not estimated: unchanged
    # where it came from: σ of every estimated value as solution.json gives it, the solution, version
    assert cal.calibration.solution == "solution.json" and cal.calibration.method == "planes"
    assert cal.calibration.calidar_version == doc["run"]["calidar_version"]
    assert cal.calibration.sigma == {f"{n}_deg": pytest.approx(doc["parameters"][n]["sigma"], rel=1e-12)
                                     for n in ANGLES}
    html = (out / "report.html").read_text()
    assert "Strip calibration (planes)" in html and "RMSDz before" in html and 'class="verdict v-pass"' in html
    assert f"{6 * n_knots} trajectory_* parameters are estimated too" in html and "How this was made" in html
    stages = doc["overlap_quality"]
    assert [s["stage"] for s in stages] == ["as delivered", "new mounting", "new mounting + trajectory corrections"]
    for k, stage in enumerate(stages[1:]):
        got = _run_shown(cli, stage["reproduce"], tmp_path / f"stage{k}")
        assert set(got) == {(p["a"], p["b"]) for p in stage["pairs"]}
        for p in stage["pairs"]:
            q = got[p["a"], p["b"]]
            assert abs(q["median_dz_m"] - p["median_dz_m"]) < 0.002 and abs(q["rmsdz_m"] - p["rmsdz_m"]) < 0.002, (p, q)
    # the recalibrated strips (mounting + trajectory) agree better than the delivered ones
    rms = lambda pairs: np.median([p["rmsdz_m"] for p in pairs])  # noqa: E731
    written = _run_shown(cli, f"calidar quality {out}/strip_*.laz", tmp_path)
    assert rms(written.values()) < 0.6 * rms(stages[0]["pairs"])
    assert rms(written.values()) == pytest.approx(rms(stages[2]["pairs"]), abs=0.002)
    code, _, err = cli("boresight", *_args(sim), "--out", out)
    assert code == 1 and "pass --force" in err


def test_trajectory_model_off_and_bad_options(cli, airborne, tmp_path):
    """The old behaviour on request, with a warning in the verdict; unusable options say which and why."""
    res, sim = airborne
    code, _, err = cli("boresight", *_args(sim), "--trajectory-sigma", "0.03", "--out", tmp_path / "bad")
    assert code == 1 and "--trajectory-sigma" in err and "POSITION_M,ATTITUDE_DEG" in err and "Traceback" not in err
    code, _, err = cli("boresight", *_args(sim), "--trajectory-model", "maybe", "--out", tmp_path / "bad")
    assert code == 1 and "--trajectory-model: expected on or off" in err
    code, _, err = cli("boresight", *_args(sim), "--trajectory-model", "off", "--trajectory-sigma", "0.03,0.002",
                       "--out", tmp_path / "bad")
    assert code == 1 and "--trajectory-model: is off, so --trajectory-accuracy and --trajectory-sigma" in " ".join(err.split())
    assert not (tmp_path / "bad").exists()
    out = tmp_path / "off"
    code, stdout, err = cli("boresight", *_args(sim), "--trajectory-model", "off", "--out", out)
    assert code == 3, err  # a FAIL verdict (below): the outputs are written, the exit code says not to use them
    doc = json.loads((out / "solution.json").read_text())
    assert not any(n.startswith("trajectory_") for n in doc["parameters"]) and doc["trajectory_accuracy"] is None
    assert not (out / "sbet_corrected.out").exists() and len(doc["overlap_quality"]) == 2
    found = {f["check"]: f for f in doc["verdict"]["findings"]}
    # the 3 cm / 0.002° trajectory noise left in the residuals: σ0 ≈ 3, strips still offset by centimetres
    assert doc["verdict"]["status"] == "fail" and found["global test"]["status"] == "fail"
    assert "leave the trajectory model on" in found["global test"]["action"]
    assert found["overlaps"]["status"] == "warn" and found["trajectory model"]["status"] == "warn"
    assert "trajectory model off" in " ".join(err.split())


def test_inputs_not_covering_the_strips_and_outputs_over_inputs_are_clear_errors(cli, airborne, tmp_path):
    import shutil

    from calidar.io.sbet import read_sbet, write_sbet
    from calidar.io.smrmsg import read_smrmsg, write_smrmsg
    from calidar.trajectory_accuracy import TrajectoryAccuracy

    res, sim = airborne
    strips = sorted((sim / "strips").glob("*.laz"))
    traj = read_sbet(sim / "sbet.out")
    short = write_sbet(tmp_path / "short.out", traj.subset(traj.time[0], traj.time[0] + 60.0))
    code, out, err = cli("boresight", *strips, "--trajectory", short, "--sensor", sim / "sensor.toml", "--out", tmp_path / "o")
    err = " ".join(err.split())  # the console wraps long lines
    assert code == 1
    assert "short.out: time:" in err and "outside the trajectory" in err and "Traceback" not in err
    # an smrmsg beside the SBET that stops before the last strip
    beside = tmp_path / "beside"
    beside.mkdir()
    shutil.copy(sim / "sbet.out", beside / "sbet.out")
    acc = read_smrmsg(sim / "smrmsg.out")
    keep = acc.time < acc.time[0] + 120.0
    write_smrmsg(beside / "smrmsg.out", TrajectoryAccuracy(acc.time[keep], acc.position_m[keep], acc.attitude_rad[keep]))
    code, _, err = cli("boresight", *strips, "--trajectory", beside / "sbet.out", "--sensor", sim / "sensor.toml",
                       "--out", tmp_path / "o")
    assert code == 1 and f"{beside / 'smrmsg.out'}: time: the accuracy file covers" in " ".join(err.split())
    assert not (tmp_path / "o").exists()
    # the recalibrated strips can never overwrite the delivered ones, --force or not
    code, _, err = cli("boresight", *strips, "--trajectory", sim / "sbet.out", "--sensor", sim / "sensor.toml",
                       "--out", sim / "strips", "--force", "--write-strips")
    assert code == 1 and "holds the input" in err and all(p.exists() for p in strips)


#: the simulator's trajectory errors as the adjustment models them: 3 cm and 0.002° at knots 1 s apart,
#: Gauss–Markov over 20 s (position) and 3.5 s (attitude), as the simulator smooths them over 10 s and 2 s
#: (the CLI's defaults; see docs/validation.md for the attitude's 3.5 s)
AIRBORNE_TRAJECTORY = TrajectoryModel(block_s=1.0, position_sigma_m=0.03, attitude_sigma_rad=np.radians(0.002),
                                      correlation_s=20.0, attitude_correlation_s=3.5)
METHODS = {"planes": TiePlanes(threshold_m=2e-4), "vgicp": Vgicp(threshold_m=1e-3)}  #: VGICP's re-matching moves ~0.1 mm


def _both_methods(res, estimate, model):
    """The calibration of one simulated survey by each method (the survey simulated once)."""
    strips = res.calibration_strips()
    return {m: calibrate(strips, res.nominal, _config(estimate), matcher=matcher, trajectory=model)
            for m, matcher in METHODS.items()}


def _config(estimate: str, **kw) -> CalibrationConfig:
    """The calibration of the groups ``estimate`` names ('boresight,lever_arm'; trajectory_bias: the model's)."""
    return CalibrationConfig(Estimate.of(*[n for n in estimate.split(",") if n != "trajectory_bias"]), **kw)


@pytest.mark.slow
@pytest.mark.parametrize("seed", [3, 4, 5, 6])
def test_airborne_boresight_with_the_trajectory_errors_modelled(seed):
    """The trajectory's errors (3 cm, 0.002°) estimated as Gauss–Markov nuisance parameters:
    every angle within 0.002° and 3σ on four surveys, by both methods (without them pitch and
    yaw reach 0.006° at 5σ). Closest: planes, seed 5, pitch 0.00131° = 1.9σ; VGICP, seed 5,
    pitch 0.00128° = 1.9σ (with piecewise-constant corrections 0.00150° = 2.2σ and yaw
    0.00169° = 2.4σ)."""
    res = _simulate("airborne", "cross", 0.3, seed=seed)
    for method, result in _both_methods(res, "boresight,trajectory_bias", AIRBORNE_TRAJECTORY).items():
        _check_angles(result.solution, res.truth.parameters())
        assert sum(n.startswith("trajectory_tilt_") for n in result.solution.parameters.free_names) > 200, method


@pytest.mark.slow
@pytest.mark.parametrize("seed", [3, 4, 5, 6])
def test_airborne_with_30_percent_vegetation_and_the_trajectory_errors_modelled(seed):
    """Tree crowns over 30 % of the area: the same accuracy as without them (every angle within
    0.002° and 3σ on four surveys; largest: tie planes seed 5, pitch 0.00127° = 1.8σ; VGICP seed 5,
    pitch 0.00130° = 1.9σ; with piecewise-constant corrections VGICP seed 5 yaw was 0.00184° = 2.5σ,
    0.00207° with single-point VGICP rows). Small tie
    planes (≈ 12 points) fit between the crowns and on roof facets; with 40-point patches only
    ~1 400 tie planes were left and yaw missed by 10 % on seed 4. Without the trajectory model:
    the next test."""
    res = _simulate("airborne", "cross", 0.3, vegetation=0.3, seed=seed)
    for result in _both_methods(res, "boresight,trajectory_bias", AIRBORNE_TRAJECTORY).values():
        _check_angles(result.solution, res.truth.parameters())
        assert result.solution.residuals_after["downweighted_fraction"] > 0.0


@pytest.mark.slow
def test_airborne_trees_are_clutter_without_the_trajectory_model():
    """The model off on an exact trajectory (nothing for it to estimate) with 30 % tree crowns:
    the crowns are down-weighted as clutter and every angle is within 0.002° and 3σ. (With the
    preset's trajectory errors and the model off, seed 3's roll reads +3.8σ and yaw 0.0037° off:
    the errors, not the crowns — the test above.)"""
    cfg = survey_config("airborne", seed=3, density=0.3, vegetation=0.3, directions="cross",
                        errors=BORESIGHT_ERRORS, range_noise_m=0.03, gnss_noise_m=0.0, attitude_noise_rad=0.0)
    res = simulate_survey(cfg)
    sol = calibrate(res.calibration_strips(), res.nominal).solution
    _check_angles(sol, res.truth.parameters())
    assert sol.residuals_after["downweighted_fraction"] > 0.0


@functools.lru_cache(maxsize=1)
def uav_lever_arm_survey():
    """The UAV survey with 5 cm lever-arm errors and 5 mm GNSS noise (see the test below)."""
    cfg = survey_config("uav", seed=3, density=0.2, vegetation=0.0, directions="cross", range_noise_m=0.03,
                        gnss_noise_m=0.005, errors={"lever_arm_x": 0.05, "lever_arm_y": -0.05})
    return simulate_survey(cfg)


@pytest.mark.slow
def test_uav_lever_arm_within_1_cm():
    """Lever-arm errors of 5 cm with the boresight known (calibrated beforehand): x, y within 1 cm.

    A smooth GNSS error shifts a whole line like a lever arm does in opposite lines, so the
    lever arm is only found to the GNSS error's level: this survey has 5 mm (the preset's 2 cm
    gives lever-arm errors of 1–3 cm). At one flying height a pitch error shifts points
    along-track nearly as lever_arm_x does: with the boresight free too the solution says so."""
    res = uav_lever_arm_survey()
    strips = res.calibration_strips()
    truth = res.truth.parameters()
    sol = calibrate(strips, res.nominal, _config("lever_arm_x,lever_arm_y")).solution
    for name in ("lever_arm_x", "lever_arm_y"):
        err = sol.values[name] - truth[name]
        assert abs(err) < 0.01 and abs(err) < 3 * sol.sigma[name], (name, err, sol.sigma[name])
    both = calibrate(strips, res.nominal, _config("boresight,lever_arm")).solution
    assert any(w.startswith("lever_arm_z is determined only through attitude changes") for w in both.warnings)
    assert any("boresight_pitch and lever_arm_x are strongly correlated" in w for w in both.warnings)
    for name in ("lever_arm_x", "lever_arm_y"):
        assert abs(both.values[name] - truth[name]) < 3 * both.sigma[name], name


#: the UAV preset's trajectory errors (2 cm, 0.002°) as the adjustment models them
UAV_TRAJECTORY = TrajectoryModel(block_s=2.0, position_sigma_m=0.02, attitude_sigma_rad=np.radians(0.002),
                                 correlation_s=20.0, attitude_correlation_s=20.0)


@pytest.mark.slow
@pytest.mark.parametrize("seed", [3, 4, 5])
def test_uav_preset_lever_arm_within_1_cm_with_the_trajectory_errors_modelled(seed):
    """The UAV preset as it is (2 cm GNSS noise), 5 cm lever-arm errors, boresight known: with the
    trajectory errors modelled x and y come within 1 cm and 3σ by both methods (without: up to
    1.9 cm, 3σ+). Largest: VGICP seed 5, x 8.5 mm = 1.6σ; tie planes seed 5, x 5.0 mm = 1.0σ
    (seeds 3–11: one miss, VGICP seed 9 y 10.3 mm = 1.8σ). The σ are ≈ 5 mm, so 1 cm is a 2σ
    goal here: the GNSS noise, not the matching, sets the limit."""
    cfg = survey_config("uav", seed=seed, density=0.2, vegetation=0.0, directions="cross", range_noise_m=0.03,
                        errors={"lever_arm_x": 0.05, "lever_arm_y": -0.05})
    res = simulate_survey(cfg)
    truth = res.truth.parameters()
    for method, result in _both_methods(res, "lever_arm_x,lever_arm_y,trajectory_bias", UAV_TRAJECTORY).items():
        sol = result.solution
        for name in ("lever_arm_x", "lever_arm_y"):
            err = sol.values[name] - truth[name]
            assert abs(err) < 0.01 and abs(err) < 3 * sol.sigma[name], (method, name, err, sol.sigma[name])


@pytest.mark.slow
def test_same_direction_strips_warn_and_report_correlations():
    """Lines flown the same way: pitch is named poorly determined, roll is right (the trajectory's
    errors modelled, as `calidar boresight` does by default; without the model roll reads 3.4σ off)."""
    res = _simulate("airborne", "same", 0.3)
    sol = calibrate(res.calibration_strips(), res.nominal, trajectory=AIRBORNE_TRAJECTORY).solution
    assert any("boresight_pitch poorly determined: all overlapping strips are parallel and flown the same way" in w
               for w in sol.warnings)
    doc = sol.to_dict()
    assert doc["correlation"]["names"] == list(ANGLES)
    assert len(doc["correlation"]["matrix"]) == 3
    # pitch is the undetermined one: its σ dwarfs roll's (its error may exceed even that σ:
    # with nothing to determine it, systematic effects set its value)
    assert sol.sigma["boresight_pitch"] > 5 * sol.sigma["boresight_roll"]
    truth = res.truth.parameters()
    assert abs(sol.values["boresight_roll"] - truth["boresight_roll"]) < 3 * sol.sigma["boresight_roll"]


@pytest.mark.slow
def test_demo_shows_a_pass_and_a_warning(tmp_path):
    """The demo's boresight step: the calibration as it should be run passes, every estimated
    parameter within 2σ of the truth; the contrast case (the lever arm too, from one flying
    height) warns that lever_arm_z is not determined and says what to do."""
    from calidar.demo.boresight import CASES, boresight_step
    from calidar.demo.survey import simulation_step
    from calidar.report import Report

    report = Report("demo")
    simulation_step(report, tmp_path, 0)
    boresight_step(report, tmp_path, 0)
    (good_title, good), (warn_title, warn) = report.verdicts
    assert good.status == "pass" and good_title == CASES[0][0].split(" (")[0]
    doc = json.loads((tmp_path / "boresight" / "solution.json").read_text())
    free = [n for n, p in doc["parameters"].items() if p["free"] and not n.startswith("trajectory_")]
    assert free == list(ANGLES)
    for name in free:
        p = doc["parameters"][name]
        assert abs(p["error"]) < 2 * p["sigma"], (name, p)
    assert doc["trajectory_accuracy"]["source"].endswith("smrmsg.out")
    assert warn.status == "warn" and warn_title == CASES[1][0].split(" (")[0]
    z = next(f for f in warn.findings if f.check == "lever_arm_z")
    assert z.status == "warn" and z.action.startswith("hold it at the measured value or add a flight line at a second "
                                                      "height") and "calidar boresight --control FILE" in z.action
    html = report.sections[-1].html("s1")
    assert "lever_arm_z" in html and "truth" in html and "RMSDz before" in html
    assert [s.title for s in report.sections[-2:]] == [title for title, _, _ in CASES]
