"""The heading group's level from the overlaps on the airborne small-error survey (issue 26,
eleventh session): what the data say about it, and what the estimator reports.

    NUMBA_NUM_THREADS=1 OMP_NUM_THREADS=1 PYTHONPATH=src python benchmarks/strips_heading_level.py \\
        --seeds 3-6 [--dump /tmp/heading_dump] [--gnss 0.015 --attitude 0.001]

Each seed is the survey of ``tests/acceptance/test_trajectory_level.py`` (airborne, cross lines,
density 0.3, 1.5 cm / 0.001° smooth trajectory errors, no accuracy file: survey-grade priors,
their level estimated). The last adjustment's normal equations at the moment the level is
estimated are kept (``--dump``: pickled there, reused on later runs). Per group: the factor on
the survey-grade σ as the iterated estimator gives it with every group free (the estimate before
issue 26's eleventh session), its redundancy at the stated σ and at the estimate, its information
tr(R²) at the estimate, the restricted likelihood's 95 % interval (−2 log L within 3.84 of its
least, the other factors held), and what :func:`calidar.strips.trajectory_level.estimate_level`
reports now (estimated, or bounded and held at its upper end). The truth: the simulated σ over
the survey-grade default's (heading 0.001/0.008 = 0.125).
"""

from __future__ import annotations

import argparse
import pickle
import sys
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "tests" / "acceptance"))
from strips_montecarlo import seeds_of  # noqa: E402

import calidar.strips.calibrate as cal  # noqa: E402
import calidar.strips.trajectory_level as tl  # noqa: E402
from calidar.adjust.variance_components import (OBSERVATIONS, estimate_components,  # noqa: E402
                                                normal_terms, split_blocks)
from calidar.strips.trajectory_errors import Knot  # noqa: E402
from calidar.trajectory_accuracy import SURVEY_GRADE  # noqa: E402


def dumped(seed: int, gnss: float, attitude: float, out: Path) -> dict:
    """The level's inputs of the acceptance survey ``seed`` (kept in ``out``)."""
    if out.exists():
        return pickle.loads(out.read_bytes())
    import test_trajectory_level as acceptance

    box, orig = {}, cal._trajectory_level

    def hooked(run, est, corrs, say):
        box.update(terms=normal_terms(est), priors=est.fit.priors, free=[p.name for p in est.fit.free],
                   layout={k: tuple(v) for k, v in run.model.layout(run.spans).items()},
                   knot_times=run.model.knot_times(run.spans), base=run.model.accuracy)
        return orig(run, est, corrs, say)

    cal._trajectory_level = hooked
    try:
        acceptance._calibrate(gnss, attitude, seed=seed)
    finally:
        cal._trajectory_level = orig
    out.parent.mkdir(parents=True, exist_ok=True)
    out.write_bytes(pickle.dumps(box))
    return box


def deviance(terms, blocks, variance: dict) -> float:
    """−2 × the restricted log likelihood (Patterson & Thompson 1971), up to a constant: with the
    priors as pseudo-observations, n_obs log σ²_obs + Σ nₖ log σ²ₖ + log det N + min Φ."""
    JtWJ, JtWr, rWr, n_obs, x0 = terms
    s_obs = variance[OBSERVATIONS]
    N, b, logs = JtWJ / s_obs, -JtWr / s_obs, n_obs * np.log(s_obs)
    for blk in blocks:
        s = variance.get(blk.group, 1.0)
        N[np.ix_(blk.index, blk.index)] += blk.precision / s
        b[blk.index] -= blk.precision @ (x0[blk.index] - blk.center) / s
        logs += blk.index.size * np.log(s)
    L = np.linalg.cholesky(N)
    dx = np.linalg.solve(L.T, np.linalg.solve(L, b))
    phi = float(rWr + 2.0 * dx @ JtWr + dx @ JtWJ @ dx) / s_obs
    for blk in blocks:
        v = x0[blk.index] + dx[blk.index] - blk.center
        phi += float(v @ blk.precision @ v) / variance.get(blk.group, 1.0)
    return float(logs + 2.0 * np.sum(np.log(np.diag(L))) + phi)


def interval(terms, blocks, variance: dict, group: str, grid: np.ndarray) -> tuple[float, float]:
    """The 95 % interval of ``group``'s σ factor on ``grid`` (the others held at ``variance``)."""
    dev = np.array([deviance(terms, blocks, variance | {group: f * f}) for f in grid])
    inside = grid[dev - dev.min() <= 3.841]
    return float(inside.min()), float(inside.max())


class _Est:
    """What :func:`calidar.strips.trajectory_level.estimate_level` reads of an Estimate."""

    def __init__(self, d):
        self.fit = type("Fit", (), {"priors": d["priors"],
                                    "free": [type("P", (), {"name": n}) for n in d["free"]]})


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--seeds", default="3-6")
    ap.add_argument("--gnss", type=float, default=0.015)
    ap.add_argument("--attitude", type=float, default=0.001)
    ap.add_argument("--dump", type=Path, default=Path("/tmp/heading_dump"))
    a = ap.parse_args()
    stated = {"position_horizontal": 0.05, "position_vertical": 0.08,
              "attitude_horizontal": 0.003, "heading": 0.008}
    truth = {g: (a.gnss if g.startswith("position") else a.attitude) / s for g, s in stated.items()}
    grid = np.exp(np.linspace(np.log(tl.FLOOR_FACTOR), np.log(2.0), 80))
    for seed in seeds_of(a.seeds):
        d = dumped(seed, a.gnss, a.attitude, a.dump / f"seed{seed}_{a.gnss:g}_{a.attitude:g}.pkl")
        layout = {k: Knot(*v) for k, v in d["layout"].items()}
        groups = [tl.group_of(layout.get(n)) for n in d["free"]]
        blocks = split_blocks(d["priors"], groups)
        free = estimate_components(*d["terms"], blocks, fixed=["other"], floor=tl.FLOOR_FACTOR**2,
                                   marginal=True, tol=0.01)
        orig, tl.normal_terms = tl.normal_terms, lambda est: d["terms"]
        try:
            now = tl.estimate_level(_Est(d), SURVEY_GRADE, layout, d["knot_times"]).to_dict()
        finally:
            tl.normal_terms = orig
        print(f"seed {seed}")
        for g in tl.GROUPS:
            lo, hi = interval(d["terms"], blocks, free.variance, g, grid)
            v = now["groups"][g]
            state = ("bounded, held at" if v.get("bounded") else
                     "estimated" if v["estimated"] else "not estimated,")
            print(f"  {g:20s} truth {truth[g]:.3f}  all free {free.sigma_factor(g):.3f} "
                  f"(r {free.redundancy_start[g]:.1f} stated, {free.redundancy[g]:.1f} at it; "
                  f"tr R² {free.information[g]:.1f}; REML 95 % {lo:.3f}–{hi:.3f})  "
                  f"now: {state} {v['sigma_factor']:.3f}", flush=True)


if __name__ == "__main__":
    main()
