"""Benchmark: what σ0 of a strip calibration is made of — the rows' and the priors' variance components
and their parts of the redundancy, and the rows' share of the angles' variance (issue 26, twelfth session).

    NUMBA_NUM_THREADS=1 OMP_NUM_THREADS=1 PYTHONPATH=src python benchmarks/strips_sigma0_parts.py \\
        --method vgicp SURVEY_FOLDER [SURVEY_FOLDER …]     # folders as strips_montecarlo.py --cache writes them

Each folder (strips/*.laz, sbet.out, smrmsg.out, sensor.toml, truth.json) is calibrated as
``strips_montecarlo.py`` does (default options, the trajectory model's priors from the smrmsg), and at the
solution x̂ of the last adjustment, with N = JᵀWJ + P (W = 1/σ², P the priors' precision):

- the redundancy split (Förstner 1979): the rows' r_rows = n − tr(N⁻¹JᵀWJ), the priors' r_P = n_P − tr(N⁻¹P);
- the variance components Σz² / r_rows (rows within 7 σ0) and (x̂ − c)ᵀP(x̂ − c) / r_P;
- σ0 as the global test reads it (``calidar.adjust.unit_weight.skipped_sigma0``) and the rows skipped;
- per boresight angle the rows' share of its variance, diag(N⁻¹JᵀWJN⁻¹) / diag(N⁻¹): how much the rows' σ
  can move the angle's σ (the rest is the trajectory priors').

One JSON line per folder.
"""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

import numpy as np
import scipy.sparse as sp

from calidar.adjust.unit_weight import GROSS_Z, skipped_sigma0
from calidar.pipelines.boresight import calibrate_inputs, load_inputs
from calidar.pipelines.strip_config import StripConfig
from calidar.strips import outer_loop
from calidar.strips.config import CalibrationConfig, matchers_named

ANGLES = ("boresight_roll", "boresight_pitch", "boresight_yaw")


def final_estimate(folder: Path, method: str):
    """(the last adjustment's Estimate, the solution) of the folder's survey, default options."""
    caught = {}
    solution = outer_loop.Run.solution

    def catch(run, est, problem):
        caught["est"] = est
        return solution(run, est, problem)

    outer_loop.Run.solution = catch
    try:
        config = StripConfig(CalibrationConfig(matchers=matchers_named(method)))
        inputs = load_inputs(sorted((folder / "strips").glob("*.laz")), folder / "sbet.out",
                             folder / "sensor.toml", config, truth=folder / "truth.json")
        sol = calibrate_inputs(inputs)[method].solution
    finally:
        outer_loop.Run.solution = solution
    return caught["est"], sol


def parts(est) -> dict:
    """The split of σ0 at the estimate (see the module docstring)."""
    fit, x, r = est.fit, est.x, est.r
    z = r / fit.sig
    J = est.normals[0]
    P = np.zeros((len(fit.free), len(fit.free)))
    prior_sq = 0.0
    for idx, centre, precision in fit.priors:
        P[np.ix_(idx, idx)] += precision
        d = x[idx] - centre
        prior_sq += float(d @ precision @ d)
    JW = sp.diags(1.0 / fit.sig**2) @ J
    Nd = np.asarray((J.T @ JW).todense()) if sp.issparse(J) else J.T @ JW
    Ni = np.linalg.inv(Nd + P)
    s0, skipped = skipped_sigma0(z, prior_sq, fit.n_prior, len(fit.free), GROSS_Z, fit.share)
    kept = np.abs(z) <= GROSS_Z * s0
    r_rows = float(np.sum(fit.share[kept]) - np.trace(Ni @ Nd))
    r_prior = float(fit.n_prior - np.trace(Ni @ P))
    names = [p.name for p in fit.free]
    rows_part = Ni @ Nd @ Ni
    return {"rows": int(z.size), "parameters": len(fit.free), "priors": fit.n_prior,
            "redundancy_rows": r_rows, "redundancy_priors": r_prior,
            "component_rows": float(np.sum(z[kept] ** 2) / r_rows),
            "component_priors": prior_sq / r_prior if r_prior > 0 else None,
            "sigma0_skipped": s0, "rows_skipped": skipped,
            "rows_share_of_angle_variance": {a: float(rows_part[i, i] / Ni[i, i])
                                             for a in ANGLES if a in names for i in [names.index(a)]}}


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("folders", nargs="+", type=Path)
    ap.add_argument("--method", default="vgicp", choices=("planes", "vgicp"))
    args = ap.parse_args()
    for folder in args.folders:
        est, sol = final_estimate(folder, args.method)
        print(json.dumps({"survey": folder.name, "method": args.method, **parts(est),
                          "sigma0_recorded": sol.extra.get("unit_weight", {}).get("sigma0")}), flush=True)


if __name__ == "__main__":
    sys.exit(main())
