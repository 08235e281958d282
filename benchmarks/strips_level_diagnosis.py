"""Which estimated trajectory level drives the mounting's σ? (issue 26, no accuracy file)

    NUMBA_NUM_THREADS=1 PYTHONPATH=src python benchmarks/strips_level_diagnosis.py \\
        --cache /tmp/level_cache --seeds 100-131 [--sigma-scale 1,1,1.5,1,1,10 --sigma-variation 0.4] \\
        [--dump DIR]

Each cached survey (``benchmarks/strips_montecarlo.py --cache DIR --simulate-only``) is calibrated
with the tie planes and its smrmsg hidden; the last adjustment's normal equations are kept at the
moment the level is estimated (``--dump``: pickled there, reused on later runs). Then, on those
linearised equations, the level is estimated as the code does and the boresight solved again with
the trajectory priors (a) as estimated, (b) as the hidden smrmsg states them (the truth), (c) as
estimated but one group's taken from the truth. Per survey: pitch's z and σ against (b); per group
the flight-wide factor against the truth (RMS of true/stated σ over its knots) and its stated
relative σ 1/√(2m). Summary: RMS z, mean σ/σ(truth), spread of log σ/σ(truth) per angle and swap,
and per group the RMS of log(estimated/true factor) / stated σ (1 if the stated σ is honest).
"""

from __future__ import annotations

import argparse
import pickle
import sys
from dataclasses import replace
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
from strips_montecarlo import _hidden_accuracy, seeds_of  # noqa: E402

import calidar.strips.calibrate as cal  # noqa: E402
import calidar.strips.trajectory_level as tl  # noqa: E402
from calidar.adjust.solution import cholesky_inverse  # noqa: E402
from calidar.adjust.variance_components import normal_terms  # noqa: E402
from calidar.io.smrmsg import read_smrmsg  # noqa: E402
from calidar.pipelines.boresight import calibrate_inputs, load_inputs  # noqa: E402
from calidar.pipelines.strip_config import StripConfig  # noqa: E402
from calidar.strips.config import CalibrationConfig, matchers_named  # noqa: E402
from calidar.strips.trajectory_errors import Knot  # noqa: E402

ANGLES = ("boresight_roll", "boresight_pitch", "boresight_yaw")


def dumped(folder: Path, out: Path) -> dict:
    """The level's inputs of one survey calibrated without its smrmsg (kept in ``out``)."""
    if out.exists():
        return pickle.loads(out.read_bytes())
    box, orig = {}, cal._trajectory_level

    def hooked(run, est, corrs, say):
        true_model = replace(run.model, accuracy=read_smrmsg(folder / "smrmsg.out"), estimate_level=False)
        box.update(terms=normal_terms(est), priors=est.fit.priors, free=[p.name for p in est.fit.free],
                   layout={k: tuple(v) for k, v in run.model.layout(run.spans).items()},
                   knot_times=run.model.knot_times(run.spans), model=run.model, spans=dict(run.spans),
                   headings=run.headings(), base_sigma={p.name: p.prior_sigma for p in est.fit.free},
                   true_sigma={p.name: p.prior_sigma for p in true_model.parameters(run.spans, run.headings())})
        return orig(run, est, corrs, say)

    cal._trajectory_level = hooked
    try:
        bare = _hidden_accuracy(folder)
        inputs = load_inputs(sorted((bare / "strips").glob("*.laz")), bare / "sbet.out", bare / "sensor.toml",
                             StripConfig(CalibrationConfig(matchers=matchers_named("planes"))), truth=bare / "truth.json")
        calibrate_inputs(inputs)
    finally:
        cal._trajectory_level = orig
    box["truth"] = {n: inputs.truth[n] for n in ANGLES}
    out.parent.mkdir(parents=True, exist_ok=True)
    out.write_bytes(pickle.dumps(box))
    return box


def solve_with(d: dict, sigma: dict) -> np.ndarray:
    """(error, σ) per angle of the linearised last adjustment with the trajectory priors' σ by name."""
    JtWJ, JtWr, _, _, x0 = d["terms"]
    f = np.array([sigma.get(n, d["base_sigma"][n]) / d["base_sigma"][n] if d["base_sigma"][n] else 1.0 for n in d["free"]])
    N, b = JtWJ.copy(), -JtWr.copy()
    for idx, c, P in d["priors"]:
        Pf = P / np.outer(f[idx], f[idx])
        N[np.ix_(idx, idx)] += Pf
        b[idx] -= Pf @ (x0[idx] - c)
    Q = cholesky_inverse(N)
    x = x0 + Q @ b
    i = [d["free"].index(a) for a in ANGLES]
    return np.array([[x[k] - d["truth"][a], np.sqrt(Q[k, k])] for k, a in zip(i, ANGLES)])


class _Est:
    """What :func:`calidar.strips.trajectory_level.estimate_level` reads of an Estimate."""

    def __init__(self, d):
        self.fit = type("Fit", (), {"priors": d["priors"], "free": [type("P", (), {"name": n}) for n in d["free"]]})


def analyse(d: dict) -> tuple[dict, dict]:
    """Per variant (estimated, truth, one group swapped) the (error, σ) per angle; per group the
    flight-wide factor's log(estimated/true) and its stated σ."""
    layout = {k: Knot(*v) for k, v in d["layout"].items()}
    groups = [tl.group_of(layout.get(n)) for n in d["free"]]
    orig, tl.normal_terms = tl.normal_terms, lambda est: d["terms"]
    try:
        level = tl.estimate_level(_Est(d), d["model"].accuracy, layout, d["knot_times"])
    finally:
        tl.normal_terms = orig
    model = replace(d["model"], accuracy=level.accuracy, estimate_level=False)
    est = {p.name: p.prior_sigma for p in model.parameters(d["spans"], d["headings"])}
    true = {n: d["true_sigma"][n] for n, g in zip(d["free"], groups) if g}
    out = {"estimated": solve_with(d, est), "truth": solve_with(d, true)}
    factors = {}
    for g in tl.GROUPS:
        names = [n for n, gg in zip(d["free"], groups) if gg == g]
        if not names:
            continue
        out[f"estimated, {g} true"] = solve_with(d, est | {n: true[n] for n in names})
        if level.estimated.get(g):
            tf = np.sqrt(np.mean([(true[n] / d["base_sigma"][n]) ** 2 for n in names]))
            factors[g] = (float(np.log(level.factor(g) / tf)), level.relative_sigma(g))
    return out, factors


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--cache", type=Path, required=True)
    ap.add_argument("--seeds", default="100-131")
    ap.add_argument("--sigma-scale", default="1,1,1.5,1,1,10")
    ap.add_argument("--sigma-variation", type=float, default=0.4)
    ap.add_argument("--dump", type=Path, default=Path("/tmp/calidar_level_dump"))
    a = ap.parse_args()
    scale = [float(v) for v in a.sigma_scale.split(",")]
    tag = "" if scale == [1.0] * 6 and a.sigma_variation == 0 else f"_s{'-'.join(f'{v:g}' for v in scale)}_v{a.sigma_variation:g}"
    Z, S, F = {}, {}, {}
    for seed in seeds_of(a.seeds):
        folder = a.cache / f"airborne_cross_seed{seed}_d0.3_veg0_scene{tag}"
        out, factors = analyse(dumped(folder, a.dump / f"{folder.name}.pkl"))
        ref = out["truth"][:, 1]
        print(f"seed {seed}: pitch z {out['estimated'][1, 0] / out['estimated'][1, 1]:+.2f} (true priors "
              f"{out['truth'][1, 0] / ref[1]:+.2f}), σ/σ(true priors) " + "/".join(f"{v:.2f}" for v in out["estimated"][:, 1] / ref)
              + "  level est/true " + ", ".join(f"{g} {np.exp(r):.2f} (±{s:.0%})" for g, (r, s) in factors.items()), flush=True)
        for k, v in out.items():
            Z.setdefault(k, []).append(v[:, 0] / v[:, 1])
            S.setdefault(k, []).append(v[:, 1] / ref)
        for g, v in factors.items():
            F.setdefault(g, []).append(v)
    for k in Z:
        print(f"{k:40s} RMS z " + "/".join(f"{v:.2f}" for v in np.sqrt(np.mean(np.square(Z[k]), 0)))
              + "  σ/σ(true priors) " + "/".join(f"{v:.3f}" for v in np.mean(S[k], 0))
              + "  spread of log σ/σ(true priors) " + "/".join(f"{v:.3f}" for v in np.std(np.log(S[k]), 0)))
    for g, v in F.items():
        v = np.array(v)
        print(f"{g:20s} flight-wide factor: sd of log(est/true) {np.sqrt(np.mean(v[:, 0] ** 2)):.2f}, "
              f"stated {np.sqrt(np.mean(v[:, 1] ** 2)):.2f}, RMS z {np.sqrt(np.mean((v[:, 0] / v[:, 1]) ** 2)):.2f}")


if __name__ == "__main__":
    main()
