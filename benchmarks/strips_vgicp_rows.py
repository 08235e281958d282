"""Benchmark: VGICP's point-to-plane rows at the truth, by how planar b's neighbourhood is (issue 26);
``--method planes``: the tie planes' rows at the truth, by surface, and the global test's σ0 there.

    NUMBA_NUM_THREADS=1 PYTHONPATH=src python benchmarks/strips_vgicp_rows.py --seed 7 [--preset uav] \\
        [--directions cross] [--exact-trajectory] [--method planes]

Simulates ``calidar simulate survey --preset uav --seed 7 --boresight-error 0.05,-0.03,0.1
--directions cross`` (``--exact-trajectory``: without trajectory errors, so that the strips agree
at the true sensor up to their noise), reads it as ``calidar boresight`` does, re-georeferences the
overlaps with the TRUE sensor and matches every pair with VGICP keeping every neighbourhood
(``min_spread`` 0, the code before issue 26). Each row's b neighbourhood (its 12 points) is
rated by √(λ_mid/λ_max) of its scatter (1: a disc, 0: a line); per bin: rows, share on walls
(|n_z| < 0.5), RMS residual at the truth and RMS of residual/σ. Rows below the default
``min_spread`` (0.3) are what the fix drops. One UAV survey: ≈ 40 s to simulate, ≈ 30 s to match.

``--method planes``: the default tie planes of every pair at the true sensor; per surface (walls
|n_z| < 0.5, roofs, flat |n_z| ≥ 0.97): rows, RMS residual, RMS σ, RMS and MAD-scale of
residual/σ; then the global test's σ0 over the non-wall rows as the verdict computes it (Cauchy
weights, ÷ their consistency for normal residuals) against its χ² 95 % range: what the test
would say if the calibration found the truth exactly.

``--by-surface`` (with ``--scene urban``: strips_montecarlo's URBAN scene): the DEFAULT VGICP rows at the
true sensor by surface (walls, roofs, flat ground) and by pair: RMS residual and σ, RMS and MAD-scale of
residual/σ, the scatter of a's ball and of b's neighbourhood along b's normal, rows sharing points (issue 26:
`--seed 309 --directions opposite --scene urban --exact-trajectory --by-surface`).
"""

from __future__ import annotations

import argparse
import sys
import tempfile
from dataclasses import replace
from pathlib import Path

import numpy as np
from scipy.special import chdtri

from calidar.adjust.solver import robust_weights
from calidar.pipelines.boresight import load_inputs
sys.path.insert(0, str(Path(__file__).resolve().parent))
from strips_montecarlo import URBAN  # noqa: E402
from calidar.sim.survey import simulate_survey, survey_config
from calidar.strips.outer_loop import Run
from calidar.strips.config import StripSettings
from calidar.strips.matchers import TiePlanes, Vgicp
from calidar.strips.parameters import sensor_of
from calidar.strips.pca import eigh3
from calidar.strips.planes import match_pair_planes
from calidar.strips.problem import georeference
from calidar.strips.verdict import robust_consistency
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
    ap.add_argument("--scene", default="preset", choices=("preset", "urban"), help="urban: strips_montecarlo's URBAN scene")
    ap.add_argument("--by-surface", action="store_true", help="vgicp: the default rows by surface and by pair")
    ap.add_argument("--method", default="vgicp", choices=("vgicp", "planes"))
    ap.add_argument("--out", type=Path, default=None, help="keep the survey here (default: a temporary folder)")
    args = ap.parse_args()
    exact = {"gnss_noise_m": 0.0, "attitude_noise_rad": 0.0} if args.exact_trajectory else {}
    cfg = survey_config(args.preset, seed=args.seed, directions=args.directions,
                        errors={k: np.radians(v) for k, v in ERRORS_DEG.items()}, **exact)
    if args.scene == "urban":
        cfg = replace(cfg, scene=replace(cfg.scene, **URBAN))
    folder = args.out or Path(tempfile.mkdtemp(prefix="calidar_vgicp_rows_")) / "sim"
    if not (folder / "truth.json").exists():
        simulate_survey(cfg).write(folder, force=True)
    inputs = load_inputs(sorted((folder / "strips").glob("*.laz")), folder / "sbet.out", folder / "sensor.toml",
                         truth=folder / "truth.json")
    truth = sensor_of(inputs.nominal, inputs.truth)
    run = Run.start(inputs.strips, truth, TiePlanes() if args.method == "planes" else Vgicp(), StripSettings())
    at_truth = {i: georeference(truth, None, run.poses[i], run.by_id[i].time[idx]) for i, idx in run.need.items()}
    print(f"{args.preset} seed {args.seed} {args.directions}{' exact trajectory' if exact else ''}, {args.method}: "
          f"{len(run.overlaps)} pairs")
    if args.by_surface:
        vgicp_by_surface(run, at_truth)
    else:
        (planes_at_truth if args.method == "planes" else vgicp_at_truth)(run, at_truth)


def _pairs(run, at_truth):
    for o in run.overlaps:
        yield o, *(at_truth[i][run.poses[i].rows_of(idx)] for i, idx in ((o.a, o.index_a), (o.b, o.index_b)))


def vgicp_at_truth(run, at_truth) -> None:
    rows = []  # (spread, wall, residual m, σ m)
    for o, pa, pb in _pairs(run, at_truth):
        c = match_pair_vgicp(o.a, pa, o.b, pb, VgicpSettings(min_spread=0.0))
        r = c.residuals(pa, pb)
        rows.append(np.column_stack([spread_of_rows(c.B, pb), np.abs(c.normal[:, 2]) < 0.5, r,
                                     np.broadcast_to(c.sigma_m, r.shape)]))
    rows = np.concatenate(rows)
    for lo, hi in zip(BINS[:-1], BINS[1:]):
        m = (rows[:, 0] >= lo) & (rows[:, 0] < hi)
        if m.any():
            print(f"√(λ_mid/λ_max) {lo:.1f}–{min(hi, 1):.1f}: {m.sum():6d} rows ({m.mean():5.1%}), walls {rows[m, 1].mean():5.1%}, "
                  f"RMS {np.sqrt(np.mean(rows[m, 2] ** 2)) * 1e3:6.1f} mm, RMS z {np.sqrt(np.mean((rows[m, 2] / rows[m, 3]) ** 2)):6.2f}")


def planes_at_truth(run, at_truth) -> None:
    rows = []  # (|n_z|, residual m, σ m)
    for o, pa, pb in _pairs(run, at_truth):
        c = match_pair_planes(o.a, pa, o.b, pb)
        rows.append(np.column_stack([np.abs(c.normal[:, 2]), c.residuals(pa, pb), c.sigma_m]))
    rows = np.concatenate(rows)
    z = rows[:, 1] / rows[:, 2]
    for lo, hi, name in ((0.0, 0.5, "walls"), (0.5, 0.97, "roofs"), (0.97, 1.01, "flat")):
        m = (rows[:, 0] >= lo) & (rows[:, 0] < hi)
        if m.any():
            print(f"{name:5s}: {m.sum():6d} rows, RMS {np.sqrt(np.mean(rows[m, 1] ** 2)) * 1e3:6.1f} mm, RMS σ "
                  f"{np.sqrt(np.mean(rows[m, 2] ** 2)) * 1e3:5.1f} mm, RMS z {np.sqrt(np.mean(z[m] ** 2)):5.3f}, "
                  f"MAD z {1.4826 * np.median(np.abs(z[m])):5.3f}")
    z = z[rows[:, 0] >= 0.5]
    w = robust_weights(z, "cauchy")
    s0 = np.sqrt(np.sum(w * z**2) / np.sum(w) / robust_consistency("cauchy"))
    lo, hi = (np.sqrt(chdtri(z.size, 1.0 - q) / z.size) for q in (0.025, 0.975))
    print(f"global test at the truth (non-wall rows): σ0 {s0:.3f} (plain RMS z {np.sqrt(np.mean(z ** 2)):.3f}); "
          f"its χ² 95 % range for {z.size} rows {lo:.3f}–{hi:.3f}")



def _row_moments(M, points: np.ndarray, normal: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:  # noqa: E501
    """Per row of the averaging matrix M: point count, variance of the points along ``normal``
    about their mean (m², ddof 1), and their own PCA plane's scatter variance (m², ddof 3)."""
    M = M.tocsr()
    count = np.diff(M.indptr)
    row = np.repeat(np.arange(M.shape[0]), count)
    p = points[M.indices]
    mean = np.add.reduceat(p, M.indptr[:-1], axis=0) / count[:, None]
    d = p - mean[row]
    along = np.einsum("ij,ij->i", d, normal[row])
    var_n = np.bincount(row, along**2, M.shape[0]) / np.maximum(count - 1, 1)
    cov = np.zeros((M.shape[0], 3, 3))
    np.add.at(cov, row, d[:, :, None] * d[:, None, :])
    lam, _ = eigh3(cov)
    return count, var_n, np.clip(lam[:, 0], 0, None) / np.maximum(count - 3, 1)


def vgicp_by_surface(run, at_truth) -> None:
    """The default VGICP rows at the truth by surface (walls |n_z| < 0.5, roofs, flat |n_z| ≥ 0.97) and per pair:
    RMS residual, RMS σ, RMS and MAD-scale of residual/σ, the RMS scatter of a's ball and of b's neighbourhood
    along b's normal, and the share of rows sharing a point with another row."""
    rows = []  # |n_z|, r, σ, var_a along n, var_b along n, shares a point, pair
    for o, pa, pb in _pairs(run, at_truth):
        c = match_pair_vgicp(o.a, pa, o.b, pb)
        r = c.residuals(pa, pb)
        _, va, _ = _row_moments(c.A, pa, c.normal)
        _, vb, _ = _row_moments(c.B, pb, c.normal)
        share = ((c.B @ c.B.T).astype(bool).sum(axis=1).A1 > 1) | ((c.A @ c.A.T).astype(bool).sum(axis=1).A1 > 1)
        rows.append(np.column_stack([np.abs(c.normal[:, 2]), r, np.broadcast_to(c.sigma_m, r.shape), va, vb, share,
                                     np.full(r.shape, 1000 * o.a + o.b)]))
    rows = np.concatenate(rows)
    groups = [(name, (rows[:, 0] >= lo) & (rows[:, 0] < hi)) for lo, hi, name in
              ((0.0, 0.5, "walls"), (0.5, 0.97, "roofs"), (0.97, 1.01, "flat"), (0.0, 1.01, "all"))]
    groups += [(f"pair {int(p) // 1000}–{int(p) % 1000}", rows[:, 6] == p) for p in np.unique(rows[:, 6])]
    for name, m in groups:
        if m.any():
            nz, r, s, va, vb, share, _ = rows[m].T
            print(f"{name:11s}: {m.sum():6d} rows, RMS r {np.sqrt(np.mean(r ** 2)) * 1e3:5.1f} mm, RMS σ "
                  f"{np.sqrt(np.mean(s ** 2)) * 1e3:5.1f} mm, RMS z {np.sqrt(np.mean((r / s) ** 2)):5.2f}, MAD z "
                  f"{1.4826 * np.median(np.abs(r / s)):5.2f}, mean z {np.mean(r / s):+5.2f} | scatter along n: a "
                  f"{np.sqrt(np.mean(va)) * 1e3:5.1f} mm, b {np.sqrt(np.mean(vb)) * 1e3:5.1f} mm; rows sharing points "
                  f"{share.mean():5.1%}")

if __name__ == "__main__":
    main()
