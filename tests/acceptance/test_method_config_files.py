"""``calidar range-cal``, ``ccr`` and ``tpu`` with ``--config`` (issue 29): every run writes its
configuration beside its results (config.toml), and that file given back with --config repeats the
run exactly; options on the command line replace the file's settings."""

from __future__ import annotations

import json
import tomllib


def _doc(folder, name="solution.json"):
    doc = json.loads((folder / name).read_text())
    doc.pop("run", None)
    return doc


def _config(folder):
    return tomllib.loads((folder / "config.toml").read_text())


def test_range_cal_repeated_from_its_config_toml(cli, corpus, tmp_path):
    obs, truth = corpus.root / "total-station" / "observations.csv", corpus.root / "total-station" / "truth.json"
    code, _, err = cli("range-cal", obs, "--truth", truth, "--tolerance", "0.05", "--fix-scale", "--out", tmp_path / "a")
    assert code in (0, 3), err
    assert _config(tmp_path / "a") == {"tolerance_m": 0.05, "fix_scale": True}
    code, _, err = cli("range-cal", obs, "--truth", truth, "--config", tmp_path / "a" / "config.toml", "--out", tmp_path / "b")
    assert code in (0, 3), err
    a, b = _doc(tmp_path / "a"), _doc(tmp_path / "b")
    assert a["parameters"] == b["parameters"] and a["parameters"]["range_scale"]["free"] is False
    code, _, err = cli("range-cal", obs, "--config", tmp_path / "a" / "config.toml", "--tolerance", "0.02",
                       "--out", tmp_path / "c")
    assert _config(tmp_path / "c") == {"tolerance_m": 0.02, "fix_scale": True}, err


def test_ccr_repeated_from_its_config_toml(cli, corpus, tmp_path):
    p = corpus.root / "photons"
    common = [p / "ATL03_sim.h5", "--ccr", p / "ccr.csv"]
    code, _, err = cli("ccr", *common, "--bootstrap", "0", "--diameter-range", "9,14", "--out", tmp_path / "a")
    assert code in (0, 3), err
    written = _config(tmp_path / "a")
    assert written["beams"] == "all" and written["search"]["bootstrap"] == 0
    assert (written["search"]["diameter_min"], written["search"]["diameter_max"]) == (9.0, 14.0)
    code, _, err = cli("ccr", *common, "--config", tmp_path / "a" / "config.toml", "--out", tmp_path / "b")
    assert code in (0, 3), err
    a, b = _doc(tmp_path / "a"), _doc(tmp_path / "b")
    assert a["parameters"] == b["parameters"] and len(a["parameters"]) >= 3
    code, _, err = cli("ccr", *common, "--config", tmp_path / "a" / "config.toml", "--seed", "5", "--pulse-width-ns", "1.5",
                       "--out", tmp_path / "c")
    changed = _config(tmp_path / "c")
    assert changed["search"]["seed"] == 5 and changed["search"]["diameter_min"] == 9.0, err
    assert abs(changed["system"]["pulse_width_s"] - 1.5e-9) < 1e-21


def test_tpu_repeated_from_its_config_toml(cli, corpus, tmp_path):
    s = corpus.root / "survey"
    common = [s / "strips" / "line_001.laz", "-t", s / "sbet.out", "--sensor", s / "sensor.toml"]
    code, _, err = cli("tpu", *common, "--range-sigma", "0.02", "--trajectory-sigma", "0.05,0.005", "--out", tmp_path / "a")
    assert code == 0, err
    written = _config(tmp_path / "a")
    assert written["noise"]["range_sigma_m"] == 0.02 and written["trajectory_sigma"][0] == 0.05
    code, _, err = cli("tpu", *common, "--config", tmp_path / "a" / "config.toml", "--out", tmp_path / "b")
    assert code == 0, err
    assert _doc(tmp_path / "a", "tpu.json") == _doc(tmp_path / "b", "tpu.json")
    code, _, err = cli("tpu", *common, "--config", tmp_path / "a" / "config.toml", "--beam-divergence", "0",
                       "--out", tmp_path / "c")
    changed = _config(tmp_path / "c")
    assert changed["noise"]["beam_divergence_rad"] == 0.0 and changed["noise"]["range_sigma_m"] == 0.02, err
