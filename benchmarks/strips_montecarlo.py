"""Monte-Carlo of the boresight calibration with the trajectory errors modelled: are the σ honest?

    NUMBA_NUM_THREADS=1 OMP_NUM_THREADS=1 PYTHONPATH=src python benchmarks/strips_montecarlo.py \\
        --seeds 3-42 [--methods planes,vgicp] [--vegetation 0.3] [--jobs 2]

Each seed is one survey as the acceptance tests simulate it (airborne preset, 6 lines in
alternate directions + 2 cross lines, density 0.3, boresight errors 0.03/−0.04/0.05°, 3 cm
range noise, the preset's 3 cm / 0.002° smooth trajectory errors), calibrated by each method
with the trajectory corrections of the CLI's ``--trajectory-sigma 0.03,0.002``. One line per
survey and method (errors, σ, z = error/σ), then per method: RMS of z per angle (1 for honest
σ; its sampling spread is ±1/√(2n)), the mean z, the share of |z| > 2 (4.6 % for a normal z),
and the misses of the tests' bounds (0.002° and 3σ).
"""

from __future__ import annotations

import argparse
import sys
import time
from concurrent.futures import ProcessPoolExecutor
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
from strips import ERRORS  # noqa: E402  (the benchmarks' boresight errors)

from calidar.pipelines.boresight import trajectory_model  # noqa: E402
from calidar.sim.survey import simulate_survey, survey_config  # noqa: E402
from calidar.strips.calibrate import StripSettings, calibrate  # noqa: E402

ANGLES = tuple(ERRORS)
THRESHOLD_M = {"planes": 2e-4, "vgicp": 1e-3}  #: the tests' outer-loop thresholds


def survey(seed: int, methods: list[str], vegetation: float) -> list[tuple[str, int, np.ndarray, np.ndarray, float]]:
    """(method, seed, errors (3,) deg, σ (3,) deg, seconds) of one simulated survey per method."""
    cfg = survey_config("airborne", seed=seed, density=0.3, vegetation=vegetation, directions="cross",
                        errors=ERRORS, range_noise_m=0.03)
    res = simulate_survey(cfg)
    strips = res.calibration_strips()
    truth = res.truth.parameters()
    out = []
    for method in methods:
        t = time.perf_counter()
        settings = StripSettings(threshold_m=THRESHOLD_M[method], trajectory=trajectory_model("0.03,0.002"))
        sol = calibrate(strips, res.nominal, method=method, estimate="boresight,trajectory_bias",
                        settings=settings).solution
        err = np.degrees([sol.values[n] - truth[n] for n in ANGLES])
        out.append((method, seed, err, np.degrees([sol.sigma[n] for n in ANGLES]), time.perf_counter() - t))
    return out


def seeds_of(text: str) -> list[int]:
    """'3-42' or '3,5,9-12' → the seeds."""
    out = []
    for part in text.split(","):
        a, _, b = part.partition("-")
        out += list(range(int(a), int(b or a) + 1))
    return out


def summary(method: str, err: np.ndarray, sig: np.ndarray, seeds: list[int]) -> str:
    z = err / sig
    n = len(z)
    lines = [f"{method}: {n} surveys  RMS z (roll/pitch/yaw) " + "/".join(f"{v:.2f}" for v in np.sqrt(np.mean(z**2, 0)))
             + f" (±{1 / np.sqrt(2 * n):.2f})  mean z " + "/".join(f"{v:+.2f}" for v in z.mean(0))
             + f"  |z| > 2: {np.mean(np.abs(z) > 2):.1%}  mean σ " + "/".join(f"{v:.5f}" for v in sig.mean(0)) + "°"]
    miss = [(seeds[i], ANGLES[j].split("_")[1], err[i, j], z[i, j])
            for i, j in zip(*np.nonzero((np.abs(err) >= 0.002) | (np.abs(z) >= 3)))]
    lines.append(f"  misses of 0.002° or 3σ: {len(miss)} of {z.size}"
                 + "".join(f"; seed {s} {a} {e:+.5f}° ({v:+.1f}σ)" for s, a, e, v in miss))
    return "\n".join(lines)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--seeds", default="3-42", help="e.g. 3-42 or 3,5,9-12")
    ap.add_argument("--methods", default="planes,vgicp")
    ap.add_argument("--vegetation", type=float, default=0.0, help="tree cover fraction, e.g. 0.3")
    ap.add_argument("--jobs", type=int, default=1, help="surveys simulated and calibrated in parallel")
    args = ap.parse_args()
    methods, seeds = args.methods.split(","), seeds_of(args.seeds)
    results = {m: [] for m in methods}
    start = time.perf_counter()
    with ProcessPoolExecutor(args.jobs) as pool:
        for rows in pool.map(survey, seeds, [methods] * len(seeds), [args.vegetation] * len(seeds)):
            for method, seed, err, sig, sec in rows:
                results[method].append((seed, err, sig))
                print(f"{method:6s} seed {seed:4d}  error " + " ".join(f"{v:+.5f}" for v in err) + "°  σ "
                      + " ".join(f"{v:.5f}" for v in sig) + "°  z " + " ".join(f"{v:+.2f}" for v in err / sig)
                      + f"  {sec:.1f} s", flush=True)
    print(f"{len(seeds)} surveys in {time.perf_counter() - start:.0f} s, {args.jobs} job(s), vegetation {args.vegetation}")
    for method, rows in results.items():
        print(summary(method, np.array([r[1] for r in rows]), np.array([r[2] for r in rows]), [r[0] for r in rows]))


if __name__ == "__main__":
    main()
