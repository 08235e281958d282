"""The scanner's calibration terms in the trajectory fit (issue #30): a synthetic line (1000 m above
ground, 60 m/s, ±20° swath, 8 s, 20 000 points, scan angles with 0.003° noise) whose scan-angle
encoder has an offset and a scale error and whose scan plane is yawed and pitched in the body, each
drawn from calidar trajectory's default priors (0.1°, 0.3 %, 0.1°, 0.1°). Per channel the RMS of
error/σ over the draws (1 = honest σ) and the median σ, fitted with the default priors ("priors") and
with none ("priors 0", the fit before these terms), on lines with and without such errors.

    PYTHONPATH=src python benchmarks/trajectory_mounting.py [--draws 24] [--relief 40]
"""

from __future__ import annotations

import argparse

import numpy as np

from calidar.sim.mounted_line import fit_line, mounted_line
from calidar.trajrec import mounting


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--draws", type=int, default=24)
    ap.add_argument("--relief", type=float, default=40.0, help="σ of the ground heights, m")
    a = ap.parse_args()
    prior = np.asarray(mounting.DEFAULT_SIGMA)
    print("| line | fit | RMS(error/σ) E, N, U, roll, pitch, heading | median σ E, N, U [m] | median σ r, p, h [°] |")
    print("|---|---|---|---|---|")
    for errors in (True, False):
        for label, sigma in (("priors", prior), ("priors 0", np.zeros(4))):
            z, sig = [], []
            for seed in range(a.draws):
                rng = np.random.default_rng(seed)
                mount = rng.normal(0, prior) if errors else np.zeros(4)
                err, s = fit_line(*mounted_line(rng, mount, relief_m=a.relief), sigma)[:2]
                z.append(np.sqrt(np.mean((err / s) ** 2, axis=0)))
                sig.append(np.median(s, axis=0))
            rms, med = np.sqrt(np.mean(np.square(z), axis=0)), np.median(sig, axis=0)
            print(f"| {'encoder and scan plane drawn from the priors' if errors else 'exact scanner'} | {label} | "
                  f"{', '.join(f'{v:.2f}' for v in rms)} | {', '.join(f'{v:.3g}' for v in med[:3])} | "
                  f"{', '.join(f'{v:.3g}' for v in np.degrees(med[3:]))} |", flush=True)


if __name__ == "__main__":
    main()
