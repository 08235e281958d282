"""``calidar boresight --config`` (issue 29): every run writes its configuration beside its results,
and that file given back with --config repeats the run exactly; options on the command line replace
the file's settings."""

from __future__ import annotations

import json
import tomllib


def _parameters(folder):
    return json.loads((folder / "solution.json").read_text())["parameters"]


def test_a_run_repeated_from_its_config_toml_gives_the_same_solution(cli, corpus, tmp_path):
    s = corpus.root / "survey"
    common = [*sorted((s / "strips").glob("*.laz")), "--trajectory", s / "sbet.out", "--sensor", s / "sensor.toml"]
    code, _, err = cli("boresight", *common, "--estimate", "boresight,lever_arm_z", "--trajectory-sigma", "0.03,0.002",
                       "--trajectory-block", "2", "--trajectory-correlation", "10,2", "--out", tmp_path / "first")
    assert code in (0, 3), err
    written = tomllib.loads((tmp_path / "first" / "config.toml").read_text())
    assert written["estimate"] == ["boresight", "lever_arm_z"] and written["method"] == ["planes"]
    assert written["trajectory_model"] == {"on": True, "block_s": 2.0, "correlation_s": [10.0, 2.0], "shape": ["gm1", "gm1"],
                                          "sigma": [0.03, 0.002]}
    code, _, err = cli("boresight", *common, "--config", tmp_path / "first" / "config.toml", "--out", tmp_path / "again")
    assert code in (0, 3), err
    first, again = _parameters(tmp_path / "first"), _parameters(tmp_path / "again")
    assert first.keys() == again.keys() and len(first) > 10
    for name, p in first.items():
        for key in ("value", "sigma"):
            assert (p[key] is None and again[name][key] is None) or abs(p[key] - again[name][key]) <= 1e-9, (name, key)
    # an option given replaces the file's setting: the trajectory model off, the rest the file's
    code, _, err = cli("boresight", *common, "--config", tmp_path / "first" / "config.toml", "--trajectory-model", "off",
                       "--out", tmp_path / "off")
    off = tomllib.loads((tmp_path / "off" / "config.toml").read_text())
    assert off["trajectory_model"] == {"on": False} and off["estimate"] == ["boresight", "lever_arm_z"], err
    assert not any(n.startswith("trajectory_") for n in _parameters(tmp_path / "off"))
