"""``calidar simulate survey --checkpoints N`` writes checkpoints that ``calidar accuracy`` reads, with
their truth; too few NVA checkpoints for the standard give a warning, not a failure."""

from __future__ import annotations

import json

import numpy as np

from calidar.io.checkpoints import read_checkpoints


def test_simulated_checkpoints_round_trip(cli, tmp_path):
    sim = tmp_path / "sim"
    code, out, err = cli("simulate", "survey", "--out", sim, "--density", "0.2", "--vegetation", "0.2",
                         "--checkpoints", "12", "--checkpoint-sigma", "0.03", "--seed", "2")
    assert code == 0, err
    cp = read_checkpoints(sim / "checkpoints.csv")
    truth = json.loads((sim / "truth.json").read_text())
    assert "parameters" in truth  # the survey's truth kept, the checkpoints' added
    pts = truth["checkpoints"]["points"]
    assert len(cp) == 12 and int(cp.vegetated.sum()) == 3 and truth["checkpoints"]["sigma_m"] == 0.03
    assert np.allclose(cp.sigma_m, 0.03)
    np.testing.assert_allclose([p["z_true"] + p["survey_error_m"] for p in pts], cp.xyz[:, 2], atol=6e-4)
    assert [p["id"] for p in pts] == list(cp.ids)
    code, out, err = cli("accuracy", *sorted((sim / "strips").glob("*.laz")), "--checkpoints", sim / "checkpoints.csv",
                         "--out", tmp_path / "acc")
    assert code == 0, err
    assert out.startswith("WARN") and "checkpoint count" in out
    doc = json.loads((tmp_path / "acc" / "accuracy.json").read_text())
    assert doc["accuracy"]["n_nva"] == 9 and doc["accuracy"]["rmse_survey_m"] == 0.03
    code, out, err = cli("simulate", "survey", "--out", tmp_path / "bad", "--checkpoints", "5", "--checkpoint-sigma", "-1")
    assert code == 1 and "--checkpoint-sigma" in err and not (tmp_path / "bad").exists()
