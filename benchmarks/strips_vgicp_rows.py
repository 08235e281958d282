"""Benchmark: VGICP's point-to-plane rows at the truth, by how planar b's neighbourhood is (issue 26).

    NUMBA_NUM_THREADS=1 PYTHONPATH=src python benchmarks/strips_vgicp_rows.py --seed 7 [--preset uav] \\
        [--directions cross] [--exact-trajectory]

Simulates ``calidar simulate survey --preset uav --seed 7 --boresight-error 0.05,-0.03,0.1
--directions cross`` (``--exact-trajectory``: without trajectory errors, so that the strips agree
at the true sensor up to their noise), reads it as ``calidar boresight`` does, re-georeferences the
overlaps with the TRUE sensor and matches every pair with VGICP keeping every neighbourhood
(``min_spread`` 0, the code before issue 26). Each row's b neighbourhood (its 12 points) is
rated by √(λ_mid/λ_max) of its scatter (1: a disc, 0: a line); per bin: rows, share on walls
(|n_z| < 0.5), RMS residual at the truth and RMS of residual/σ. Rows below the default
``min_spread`` (0.3) are what the fix drops. One UAV survey: ≈ 40 s to simulate, ≈ 30 s to match.
"""

from __future__ import annotations

import argparse
import tempfile
from pathlib import Path

import numpy as np

from calidar.pipelines.boresight import load_inputs
from calidar.sim.survey import simulate_survey, survey_config
from calidar.strips.calibrate import _Run
from calidar.strips.config import StripSettings, Vgicp
from calidar.strips.parameters import sensor_of
from calidar.strips.pca import eigh3
from calidar.strips.problem import georeference
from calidar.strips.vgicp import VgicpSettings, match_pair_vgicp

ERRORS_DEG = {"boresight_roll": 0.05, "boresight_pitch": -0.03, "boresight_yaw": 0.1}  #: issue 26's survey
BINS = (0.0, 0.1, 0.2, 0.3, 0.4, 0.5, 0.7, 1.01)


def spread_of_rows(B, points_b: np.ndarray) -> np.ndarray:
    """√(λ_mid/λ_max) of each row's b points (the rows of the averaging matrix B)."""
    B = B.tocsr()
    k = np.diff(B.indptr)
    assert np.all(k == k[0])
    nb = points_b[B.indices].reshape(-1, k[0], 3)
    nb = nb - nb.mean(axis=1, keepdims=True)
    lam, _ = eigh3(np.einsum("mki,mkj->mij", nb, nb))
    return np.sqrt(np.clip(lam[:, 1], 0, None) / np.maximum(lam[:, 2], 1e-300))


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--seed", type=int, default=7)
    ap.add_argument("--preset", default="uav")
    ap.add_argument("--directions", default="cross")
    ap.add_argument("--exact-trajectory", action="store_true")
    ap.add_argument("--out", type=Path, default=None, help="keep the survey here (default: a temporary folder)")
    args = ap.parse_args()
    exact = {"gnss_noise_m": 0.0, "attitude_noise_rad": 0.0} if args.exact_trajectory else {}
    cfg = survey_config(args.preset, seed=args.seed, directions=args.directions,
                        errors={k: np.radians(v) for k, v in ERRORS_DEG.items()}, **exact)
    folder = args.out or Path(tempfile.mkdtemp(prefix="calidar_vgicp_rows_")) / "sim"
    if not (folder / "truth.json").exists():
        simulate_survey(cfg).write(folder, force=True)
    inputs = load_inputs(sorted((folder / "strips").glob("*.laz")), folder / "sbet.out", folder / "sensor.toml",
                         truth=folder / "truth.json")
    truth = sensor_of(inputs.nominal, inputs.truth)
    run = _Run.start(inputs.strips, truth, Vgicp(), StripSettings())
    at_truth = {i: georeference(truth, None, run.poses[i], run.by_id[i].time[idx]) for i, idx in run.need.items()}
    rows = []  # (spread, wall, residual m, σ m)
    for o in run.overlaps:
        pa, pb = (at_truth[i][run.poses[i].rows_of(idx)] for i, idx in ((o.a, o.index_a), (o.b, o.index_b)))
        c = match_pair_vgicp(o.a, pa, o.b, pb, VgicpSettings(min_spread=0.0))
        r = c.residuals(pa, pb)
        rows.append(np.column_stack([spread_of_rows(c.B, pb), np.abs(c.normal[:, 2]) < 0.5, r,
                                     np.broadcast_to(c.sigma_m, r.shape)]))
    rows = np.concatenate(rows)
    print(f"{args.preset} seed {args.seed} {args.directions}{' exact trajectory' if exact else ''}: {len(rows)} rows "
          f"in {len(run.overlaps)} pairs")
    for lo, hi in zip(BINS[:-1], BINS[1:]):
        m = (rows[:, 0] >= lo) & (rows[:, 0] < hi)
        if m.any():
            print(f"√(λ_mid/λ_max) {lo:.1f}–{min(hi, 1):.1f}: {m.sum():6d} rows ({m.mean():5.1%}), walls {rows[m, 1].mean():5.1%}, "
                  f"RMS {np.sqrt(np.mean(rows[m, 2] ** 2)) * 1e3:6.1f} mm, RMS z {np.sqrt(np.mean((rows[m, 2] / rows[m, 3]) ** 2)):6.2f}")


if __name__ == "__main__":
    main()
