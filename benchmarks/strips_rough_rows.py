"""Benchmark: what a VGICP row's residual variance is made of at the truth, on rough ground (issue 26,
thirteenth session).

    NUMBA_NUM_THREADS=1 OMP_NUM_THREADS=1 PYTHONPATH=src python benchmarks/strips_rough_rows.py \\
        --dump OUT.npz FOLDER...       # folders simulated without trajectory errors (strips_row_sigma.py's)
    PYTHONPATH=src python benchmarks/strips_rough_rows.py --table OUT.npz...

Each folder's overlaps are matched with VGICP's default rows at the TRUE sensor
(:func:`strips_row_sigma.rows_at_truth`'s way), so a row's residual holds nothing but the points' noise and
the surface's own unevenness as a's ball mean and b's plane sample it. Per row (walls |n_z| < 0.5 left out)
the dump keeps the residual r, its σ and, recomputed from the row's points: a's count n_a, a's raw scatter
variance along b's normal about a's mean (n_a − 1 dof), b's plane's (k − 3 dof), b's leverage h at a's mean,
a's tilt cofactor t, the ball's radius, a's spread against b's and along a line, and the sampling cofactors
Q, g_a, g_b of :func:`calidar.strips.row_sampling.sampling_cofactors` (ℓ ``--length``). Each folder's table
(and ``--table`` of saved dumps) prints the ratio of mean r² to mean σ² binned by quartile of each quantity
(σ: the row's σ as the calibration computes it).
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))

from calidar.pipelines.boresight import load_inputs  # noqa: E402
from calidar.strips.config import StripSettings  # noqa: E402
from calidar.strips.matchers import Vgicp  # noqa: E402
from calidar.strips.outer_loop import Run  # noqa: E402
from calidar.strips.parameters import sensor_of  # noqa: E402
from calidar.strips.problem import georeference  # noqa: E402
from calidar.strips.row_sampling import sampling_cofactors  # noqa: E402

LENGTH = [2.0]  #: ℓ of the recorded sampling cofactors (m; ``--length``)


def _row_ids(M) -> np.ndarray:
    return np.repeat(np.arange(M.shape[0]), np.diff(M.indptr))


def row_features(c, pa: np.ndarray, pb: np.ndarray) -> dict[str, np.ndarray]:
    """Per row of correspondences ``c`` (VGICP point-to-plane) on points ``pa``, ``pb`` (m)."""
    n = c.normal
    ra, k = _row_ids(c.A), int(np.diff(c.B.indptr)[0])
    mean_a, mean_b = c.A @ pa, c.B @ pb
    da = pa[c.A.indices] - mean_a[ra]
    count = np.diff(c.A.indptr).astype(float)
    var_a = np.bincount(ra, np.einsum("ij,ij->i", da, n[ra]) ** 2, c.n_obs) / np.maximum(count - 1, 1)
    db = (pb[c.B.indices] - mean_b[_row_ids(c.B)]).reshape(c.n_obs, k, 3)
    S = np.einsum("mki,mkj->mij", db, db)
    lam, vec = np.linalg.eigh(S)
    var_b = lam[:, 0] / (k - 3)
    off = mean_a - mean_b
    h = 1.0 / k + sum(np.einsum("ij,ij->i", off, vec[:, :, j]) ** 2 / lam[:, j] for j in (1, 2))
    t = sum(np.bincount(ra, np.einsum("ij,ij->i", da, vec[ra, :, j]) ** 2, c.n_obs) / lam[:, j]
            for j in (1, 2)) / np.maximum(count - 1, 1)
    radius_b = np.sqrt(np.max(np.einsum("mki,mki->mk", db, db), axis=1))
    # a's spread in b's plane against b's: each in-plane axis' variance, a's over b's
    spread_a = sum(np.bincount(ra, np.einsum("ij,ij->i", da, vec[ra, :, j]) ** 2, c.n_obs)
                   for j in (1, 2)) / np.maximum(count, 1)
    spread_b = (lam[:, 1] + lam[:, 2]) / k
    # a's linearity: its in-plane scatter's smaller over larger axis
    Ca = np.zeros((c.n_obs, 2, 2))
    for i, j in ((1, 1), (1, 2), (2, 2)):
        v = np.bincount(ra, np.einsum("ij,ij->i", da, vec[ra, :, i])
                        * np.einsum("ij,ij->i", da, vec[ra, :, j]), c.n_obs)
        Ca[:, i - 1, j - 1] = Ca[:, j - 1, i - 1] = v
    la = np.linalg.eigvalsh(Ca)
    q, g_a, g_b = sampling_cofactors(c.A, pa, pb[c.B.indices].reshape(c.n_obs, k, 3), mean_b,
                                     lam, vec, LENGTH[0])
    return {"Q": q, "g_a": g_a, "g_b": g_b, "nz": np.abs(n[:, 2]), "r": c.residuals(pa, pb), "sigma": np.broadcast_to(c.sigma_m, count.shape),
            "dof": np.broadcast_to(c.dof, count.shape), "count": count, "var_a": var_a, "var_b": var_b,
            "h": h, "t": t, "radius": radius_b, "spread_ratio": spread_a / spread_b,
            "a_line": np.sqrt(np.clip(la[:, 0], 0, None) / np.maximum(la[:, 1], 1e-300)),
            "offset": np.linalg.norm(off - np.einsum("ij,ij->i", off, n)[:, None] * n, axis=1)}


def rows_at_truth(folder: Path) -> dict[str, np.ndarray]:
    inputs = load_inputs(sorted((folder / "strips").glob("*.laz")), folder / "sbet.out", folder / "sensor.toml",
                         truth=folder / "truth.json")
    truth = sensor_of(inputs.nominal, inputs.truth)
    run = Run.start(inputs.strips, truth, Vgicp(), StripSettings())
    at = {i: georeference(truth, None, run.poses[i], run.by_id[i].time[idx]) for i, idx in run.need.items()}
    parts: dict[str, list] = {}
    for pair, o in enumerate(run.overlaps):
        pa, pb = (at[i][run.poses[i].rows_of(idx)] for i, idx in ((o.a, o.index_a), (o.b, o.index_b)))
        c = run.matcher.match(o.a, pa, o.b, pb)
        f = row_features(c, pa, pb)
        f["pair"] = np.full(c.n_obs, pair)
        for key, v in f.items():
            parts.setdefault(key, []).append(np.asarray(v, float))
    return {k: np.concatenate(v) for k, v in parts.items()}


def _bins(name: str, v: np.ndarray, r2: np.ndarray, s2: np.ndarray, n: int = 4) -> str:
    edges = np.quantile(v, np.linspace(0, 1, n + 1)[1:-1])
    q = np.digitize(v, edges)
    return f"  {name:12s} " + "  ".join(f"{np.median(v[q == i]):9.3g}: {np.mean(r2[q == i]) / np.mean(s2[q == i]):.2f}"
                                        for i in range(n))


def table(d: dict[str, np.ndarray], label: str) -> None:
    m = d["nz"] >= 0.5
    d = {k: v[m] for k, v in d.items()}
    r2, s2 = d["r"] ** 2, d["sigma"] ** 2
    z = d["r"] / d["sigma"]
    keep = np.abs(z) < 7
    d = {k: v[keep] for k, v in d.items()}
    r2, s2 = r2[keep], s2[keep]
    print(f"{label}: {r2.size} rows, RMS z {np.sqrt(np.mean(r2 / s2)):.3f}; mean r²/mean σ² by quartile of "
          "(median: ratio)")
    white = d["var_a"] / d["count"] + d["var_b"] * np.maximum(d["h"] - d["t"] / d["count"], 0)
    for name in ("sigma", "count", "var_a", "var_b", "h", "radius", "spread_ratio", "a_line", "offset"):
        print(_bins(name, d[name], r2, s2))
    print(_bins("white", white, r2, s2))
    dof_a, w2 = np.maximum(d["count"] - 1, 1), 1 / d["count"] + np.maximum(d["h"] - d["t"] / d["count"], 0)
    g = (dof_a * d["g_a"] + 9 * d["g_b"]) / (dof_a + 9)
    print(_bins("Q/g/Σw²", d["Q"] / np.maximum(g, 1e-12) / w2, r2, s2))


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("folders", nargs="*", type=Path)
    ap.add_argument("--dump", type=Path)
    ap.add_argument("--table", nargs="*", type=Path, default=[])
    ap.add_argument("--length", type=float, default=2.0,
                    help="ℓ of the sampling cofactors recorded (m)")
    args = ap.parse_args()
    LENGTH[0] = args.length
    for folder in args.folders:
        d = rows_at_truth(folder)
        out = args.dump.with_name(f"{args.dump.stem}_{folder.name}.npz")
        np.savez_compressed(out, **d)
        table(d, folder.name)
    for path in args.table:
        table(dict(np.load(path)), path.name)


if __name__ == "__main__":
    main()
