"""The profile deviance at the truth on 2-CCR passes: is χ²₁ its distribution? (issue 26, docs/validation.md
"σ and intervals from the profile likelihood").

Per seed a pass is simulated as `calidar simulate photons --seed N --n-ccr 2 --ccr-dropout 0.33` builds it;
its CCR windows are extracted and the estimate found as `calidar ccr` does (`photon.estimate.estimate`).
For each geolocation parameter the deviance 2·(−log L_profile(truth) − −log L_max) is computed, the other
parameters re-maximised from the estimate and from the truth (the better kept). The same is done on
``--draws`` sets of counts drawn from the model itself at the truth on the pass's own shots: if the model
is right, those and the simulator's follow one distribution, and a 95 % interval needs its 95 % point.

    NUMBA_NUM_THREADS=1 PYTHONPATH=src nice -n 10 python benchmarks/photon_ccr_deviance.py --seeds 2000:2075 \\
        [--draws 3] [--log FILE]
"""

from __future__ import annotations

import argparse
import json
import tempfile
from pathlib import Path

import numpy as np

from calidar.errors import CalibrationError
from calidar.photon.estimate import estimate, shots_of, windows_of
from calidar.photon.fit import Bounds, Layout, Problem, maximise
from calidar.photon.likelihood import count_distribution, simulate_counts
from calidar.photon.parameters import GEOLOCATION
from calidar.photon.passes import SystemParameters
from calidar.photon.search import SearchSettings
from calidar.pipelines.ccr import read_ccr_csv
from calidar.pipelines.ccr import load_passes, simulate_photons
from calidar.sim.photons import PhotonSimConfig

SETTINGS = SearchSettings(bootstrap=0, surface_points=0)
SYSTEM = SystemParameters()
BOUNDS = Bounds(SETTINGS.diameter_min, SETTINGS.diameter_max, SETTINGS.max_bias)


def deviances(problem: Problem, windows, counts, truth: dict) -> dict:
    """The estimate and, per geolocation parameter, the profile deviance at its true value."""
    fit = estimate(windows, problem, SETTINGS, SYSTEM.shot_spacing, counts).fit
    p = problem.with_counts(counts)
    row = {"estimate": fit.solution.values, "sigma": fit.solution.sigma}
    for k in GEOLOCATION:
        best = np.inf
        for start in (fit.solution.values, {**fit.solution.values, **truth}):
            try:
                best = min(best, maximise(p, {**start, k: truth[k]}, BOUNDS, fixed={k: truth[k]}, covariance=False).nll)
            except CalibrationError:
                pass
        row[k] = 2.0 * (best - fit.nll)
    return row


def one_seed(seed: int, draws: int, rng) -> dict:
    cfg = PhotonSimConfig(seed=seed, n_ccr=2, ccr_dropout=0.33, ccr_spacing=60.0)
    with tempfile.TemporaryDirectory() as tmp:
        paths = simulate_photons(cfg, Path(tmp))
        doc = json.loads(paths["truth"].read_text())
        survey = read_ccr_csv(paths["ccr"])
        passes = load_passes([paths["atl03"]], None, survey, SYSTEM)
    truth = {k: doc[k] for k in GEOLOCATION}
    full = {**truth, "ccr_peak_photons": cfg.ccr_photons, "shot_loss_rate": cfg.ccr_dropout}
    windows, _ = windows_of(passes, survey, SYSTEM, SETTINGS)
    for p in passes:
        p.group = 0
    for w in windows:
        w.group = 0
    problem = Problem(shots_of(windows), Layout((passes[0].group_key,)), SYSTEM.pointing_jitter)
    try:
        sim = deviances(problem, windows, [w.counts for w in windows], truth)
    except CalibrationError as e:
        return {"seed": seed, "refused": str(e)}
    table, _ = count_distribution(problem.layout.theta(full), problem.shots, problem.jitter)
    split = np.cumsum([w.shot_x.size for w in windows])[:-1]
    model = []
    for _ in range(draws):
        try:
            model.append(deviances(problem, windows, np.split(simulate_counts(table, rng), split), truth))
        except CalibrationError:
            pass
    return {"seed": seed, "truth": full, "simulator": sim, "model": model}


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--seeds", default="2000:2075", help="A:B, seeds A … B−1")
    ap.add_argument("--draws", type=int, default=3, help="model-drawn count sets per pass")
    ap.add_argument("--log", type=Path, default=None, help="JSON lines, one per pass (appended)")
    args = ap.parse_args()
    a, b = map(int, args.seeds.split(":"))
    rng = np.random.default_rng(a)
    rows = []
    for seed in range(a, b):
        row = one_seed(seed, args.draws, rng)
        rows.append(row)
        if args.log:
            with open(args.log, "a", encoding="utf-8") as fh:
                fh.write(json.dumps(row, default=float) + "\n")
    rows = [r for r in rows if "simulator" in r]
    print(f"{len(rows)} passes solved; deviance at the truth (χ²₁: mean 1, 95 % point 3.84)")
    for k in GEOLOCATION:
        for label, dev in (("simulator", [r["simulator"][k] for r in rows]),
                           ("model-drawn", [m[k] for r in rows for m in r["model"]])):
            d = np.array(dev)
            print(f"  {k:20s} {label:11s} n {d.size:4d}  mean {d.mean():.2f}  90/95/99 % points "
                  f"{' / '.join(f'{v:.2f}' for v in np.percentile(d, [90, 95, 99]))}  above 3.84: {np.mean(d > 3.84):.1%}")


if __name__ == "__main__":
    main()
