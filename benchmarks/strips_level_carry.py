"""The estimated trajectory level's own uncertainty carried into the mounting's σ (issue 26).

    OMP_NUM_THREADS=1 PYTHONPATH=src python benchmarks/strips_level_carry.py /tmp/nofile_dump/v1*.pkl \\
        [--m-horizontal 3.5] [--json rows.jsonl]

Reads the pickled last-adjustment normal equations of surveys calibrated without their smrmsg
(``benchmarks/strips_level_diagnosis.py --dump``; the older dumps without a model, from the 27 Nov
diagnosis, are read too: the default trajectory model is rebuilt). Per survey: the level estimated
as the code does, then the boresight's error and σ (a) with the plug-in covariance at that level,
(b) with its uncertainty carried in (:func:`calidar.adjust.variance_carry.carried_covariance`,
what ``calidar boresight`` now reports), (c) with the smrmsg's (true) priors. ``--m-horizontal``
replaces the horizontal position group's effective number m (what-if: the level's honest spread).
Summary: RMS z per angle and mean σ / σ(true priors).
"""

from __future__ import annotations

import argparse
import json
import pickle
from dataclasses import replace

import numpy as np

import calidar.strips.trajectory_level as tl
from calidar.adjust.variance_carry import carried_covariance, solve_scaled
from calidar.strips.config import TrajectorySettings
from calidar.strips.trajectory_errors import Knot
from calidar.trajectory_accuracy import SURVEY_GRADE

ANGLES = ("boresight_roll", "boresight_pitch", "boresight_yaw")


class _Est:
    """What :func:`calidar.strips.trajectory_level.estimate_level` reads of an Estimate."""

    def __init__(self, d):
        self.fit = type("Fit", (), {"priors": d["priors"], "free": [type("P", (), {"name": n}) for n in d["free"]]})


def _factors(d: dict, sigma: dict) -> np.ndarray:
    return np.array([sigma.get(n, d["base_sigma"][n]) / d["base_sigma"][n] if d["base_sigma"][n] else 1.0 for n in d["free"]])


def survey(d: dict, m_horizontal: float | None) -> dict:
    """(a), (b), (c) of the module docstring for one dumped survey."""
    layout = {k: Knot(*v) for k, v in d["layout"].items()}
    model = d.get("model") or TrajectorySettings(block_s=d["block_s"]).model(SURVEY_GRADE, True)
    groups = [tl.group_of(layout.get(n)) for n in d["free"]]
    orig, tl.normal_terms = tl.normal_terms, lambda est: d["terms"]
    try:
        level = tl.estimate_level(_Est(d), model.accuracy, layout, model.knot_times(d["spans"]))
    finally:
        tl.normal_terms = orig
    est = {p.name: p.prior_sigma for p in replace(model, accuracy=level.accuracy, estimate_level=False).parameters(
        d["spans"], d["headings"])}
    true = {n: d["true_sigma"][n] for n, g in zip(d["free"], groups) if g}
    keep = np.array([d["free"].index(a) for a in ANGLES])
    truth = np.array([d["truth"][a] for a in ANGLES])
    JtWJ, JtWr, _, _, x0 = d["terms"]
    xt, Qt = solve_scaled(JtWJ, JtWr, x0, d["priors"], _factors(d, true), keep)
    f = _factors(d, est)
    priors = [(idx, c, P / np.outer(f[idx], f[idx])) for idx, c, P in d["priors"]]
    effective = {g: m for g, m in (level.effective or {}).items() if level.estimated.get(g)}
    if m_horizontal is not None and "position_horizontal" in effective:
        effective["position_horizontal"] = m_horizontal
    x, Q = solve_scaled(JtWJ, JtWr, x0, priors, np.ones(f.size), keep)
    _, delta = carried_covariance(JtWJ, JtWr, x0, priors, groups, effective, keep)
    return {"err": (x - truth).tolist(), "sig": np.sqrt(np.diag(Q)).tolist(),
            "sig_carried": np.sqrt(np.diag(Q + delta)).tolist(), "sig_true": np.sqrt(np.diag(Qt)).tolist(),
            "err_true": (xt - truth).tolist(), "m": effective}


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("dumps", nargs="+")
    ap.add_argument("--m-horizontal", type=float, default=None)
    ap.add_argument("--json", default=None, help="append one JSON line per survey here")
    a = ap.parse_args()
    rows = []
    for path in a.dumps:
        with open(path, "rb") as fh:
            row = {"file": path} | survey(pickle.load(fh), a.m_horizontal)
        rows.append(row)
        print(json.dumps(row), flush=True)
        if a.json:
            with open(a.json, "a") as fh:
                fh.write(json.dumps(row) + "\n")
    err, ref = np.array([r["err"] for r in rows]), np.array([r["sig_true"] for r in rows])
    for key, name in (("sig", "plug-in"), ("sig_carried", "carried"), ("sig_true", "true priors")):
        s = np.array([r[key] for r in rows])
        e = np.array([r["err_true"] for r in rows]) if key == "sig_true" else err
        print(f"{name:12s} {len(rows)} surveys: RMS z " + "/".join(f"{v:.2f}" for v in np.sqrt(np.mean((e / s) ** 2, 0)))
              + f", max |z| {np.max(np.abs(e / s)):.2f}, σ / σ(true priors) " + "/".join(f"{v:.3f}" for v in np.mean(s / ref, 0)))


if __name__ == "__main__":
    main()
