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

from calidar.frames import R_ENU_NED, rpy_to_matrix
from calidar.trajrec import mounting
from calidar.trajrec.fit import FitSettings, Observations, channel_sigma, solve_segment
from calidar.trajrec.spline import Spline


def truth_of(t):
    return np.c_[5 * np.sin(t / 3), 60 * t, 1000 + 2 * np.sin(t / 2), np.radians(1.0) * np.sin(t),
                 np.radians(2.0) + np.radians(0.5) * np.sin(t / 1.5), np.radians(3.0) + np.radians(0.3) * np.cos(t)]


def _rot(axis: int, a: float) -> np.ndarray:
    c, s = np.cos(a), np.sin(a)
    i, j = [(1, 2), (2, 0), (0, 1)][axis]
    r = np.eye(3)
    r[i, i], r[i, j], r[j, i], r[j, j] = c, -s, s, c
    return r


def line(rng, mount, relief: float, n: int = 20000):
    d, k, kappa, eps = mount
    t = np.sort(rng.uniform(0, 8, n))
    tr = truth_of(t)
    theta = np.radians(20.0) * np.sin(2 * np.pi * 20 * t)
    u_b = np.stack([np.zeros_like(theta), np.sin(theta), np.cos(theta)], 1) @ (_rot(2, kappa) @ _rot(1, eps)).T
    u_enu = np.einsum("ij,njk,nk->ni", R_ENU_NED, rpy_to_matrix(tr[:, 3], tr[:, 4], tr[:, 5]), u_b)
    pts = tr[:, :3] + ((tr[:, 2] - rng.normal(0, relief, n)) / -u_enu[:, 2])[:, None] * u_enu
    stored = (np.arctan2(u_b[:, 1], u_b[:, 2]) - d) / (1 + k) + rng.normal(0, np.radians(0.003), n)
    return t, pts, stored


def fit(t, pts, stored, sigma):
    obs = Observations(pts, t, stored, True, True, np.empty((0, 3)), np.empty((0, 3)), np.empty((0, 3)),
                       np.empty(0), np.empty(0))
    sp = Spline.covering(0, 8, 0.25)
    ts = np.linspace(0, 8, 200)
    start = truth_of(ts) * np.r_[1, 1, 1, 0, 0, 1] + np.r_[10.0, 20.0, -30.0, 0, 0, 0.01]
    f = solve_segment(obs, sp, sp.fit(ts, start), FitSettings(mount_sigma=tuple(sigma)))
    tt = np.linspace(0.5, 7.5, 50)
    return sp.evaluate(f.coef, tt) - truth_of(tt), channel_sigma(f, tt)


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
                err, s = fit(*line(rng, mount, a.relief), sigma)
                z.append(np.sqrt(np.mean((err / s) ** 2, axis=0)))
                sig.append(np.median(s, axis=0))
            rms, med = np.sqrt(np.mean(np.square(z), axis=0)), np.median(sig, axis=0)
            print(f"| {'encoder and scan plane drawn from the priors' if errors else 'exact scanner'} | {label} | "
                  f"{', '.join(f'{v:.2f}' for v in rms)} | {', '.join(f'{v:.3g}' for v in med[:3])} | "
                  f"{', '.join(f'{v:.3g}' for v in np.degrees(med[3:]))} |", flush=True)


if __name__ == "__main__":
    main()
