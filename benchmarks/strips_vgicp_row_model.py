"""Benchmark: fit and check a rows' σ model for VGICP on dumped rows (issue 26, ninth session).

Reads the rows ``strips_vgicp_row_z.py --dump DIR`` wrote (each survey's rows at VGICP's solution:
residual r, σ, parallel or crossing pair, each side's raw and posterior scatter, a's count, b's
leverage) and, for the roughness model of :func:`calidar.strips.row_variance.row_sigma`

    σ² = s_a²/n_a + s_b²·h + κ·ρ² + f²,   ρ² = max(0, s̄² − s_q²)

(s̄² the mean of the two sides' posterior scatter, s_q² its ``quantile`` over the pair's rows),
estimates (κ, f²) by variance components (Förstner 1979; Koch 1999 §3.6: with diagonal cofactors
and redundancy numbers ≈ 1, θ = S⁻¹q, S_ij = Σ V_i V_j / σ⁴, q_i = Σ (r² − base) V_i / σ⁴,
iterated with σ² from the last θ; rows with |z| > 7 left out) from ``--fit`` surveys, then prints
the RMS z (|z| ≤ 7) per σ quintile and pair kind before (the dumped σ) and after (κ, f given by
``--kappa``/``--floor`` or the fitted ones) on ``--check`` surveys. The residuals are those of the
dumped solution: the after-column is the rows' model, not a new adjustment.

    PYTHONPATH=src python benchmarks/strips_vgicp_row_model.py --dump DIR \\
        [--fit 'uav_opposite_seed105*,uav_cross_seed112*'] [--check 'GLOB,…'] [--quantile 0.25] \\
        [--kappa K --floor F]
"""

from __future__ import annotations

import argparse
from pathlib import Path

import numpy as np

from calidar.strips.row_variance import roughness_excess, variance_components


def load(folder: Path, globs: str) -> list[dict]:
    files = sorted({f for g in globs.split(",") for f in folder.glob(g + ".npz")})
    out = []
    for f in files:
        d = dict(np.load(f))
        ok = np.isfinite(d["var_a_post"])
        out.append({k: v[ok] for k, v in d.items()} | {"name": f.stem})
    return out


def parts(d: dict, quantile: float) -> tuple[np.ndarray, np.ndarray]:
    """(the white-noise base σ² without a floor, ρ²) per row, m²."""
    base = d["var_a_post"] / d["count"] + d["var_b_post"] * d["leverage"]
    rho2 = np.concatenate([roughness_excess(d["var_a_post"][m], d["var_b_post"][m], quantile)
                           for m in (d["pair"] == p for p in np.unique(d["pair"]))])
    order = np.concatenate([np.flatnonzero(d["pair"] == p) for p in np.unique(d["pair"])])
    rho = np.empty_like(rho2)
    rho[order] = rho2
    return base, rho


def fit(rows: list[dict], quantile: float, fix_floor: float | None) -> tuple[float, float]:
    """(κ, f²) by iterated variance-component estimation (see the docstring)."""
    base, rho, r = (np.concatenate(v) for v in zip(*[(*parts(d, quantile), d["r"]) for d in rows]))
    if fix_floor is not None:
        return float(variance_components(r, base + fix_floor**2, rho[None])[0]), fix_floor**2
    kappa, floor2 = variance_components(r, base, np.stack([rho, np.ones_like(rho)]))
    return float(kappa), float(floor2)


def table(rows: list[dict], quantile: float, kappa: float, floor2: float) -> None:
    for d in rows:
        base, rho = parts(d, quantile)
        after = np.sqrt(base + kappa * rho + floor2)
        cols = []
        for sig in (d["sig"], after):
            z = d["r"] / sig
            q = np.quantile(sig, [0.2, 0.4, 0.6, 0.8, 0.9])
            edges = [0, *q, np.inf]
            groups = [(sig >= lo) & (sig < hi) for lo, hi in zip(edges[:-1], edges[1:])]
            groups += [d["parallel"].astype(bool), ~d["parallel"].astype(bool), np.ones(z.size, bool)]
            cols.append(["%.2f" % np.sqrt(np.mean(z[m & (np.abs(z) <= 7)] ** 2)) if m.any() else "–"
                         for m in groups])
        print(f"{d['name']:40s} {d['r'].size:6d} rows  before " + " ".join(cols[0])
              + "  after " + " ".join(cols[1]))


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--dump", type=Path, required=True)
    ap.add_argument("--fit", default="*")
    ap.add_argument("--check", default="*")
    ap.add_argument("--quantile", type=float, default=0.25)
    ap.add_argument("--kappa", type=float, default=None)
    ap.add_argument("--floor", type=float, default=None, help="m; with --kappa, or fixed in the fit")
    args = ap.parse_args()
    if args.kappa is None:
        kappa, floor2 = fit(load(args.dump, args.fit), args.quantile, args.floor)
        print(f"fitted on {args.fit}: κ = {kappa:.4f}, floor = {1000 * np.sqrt(floor2):.2f} mm")
    else:
        kappa, floor2 = args.kappa, (args.floor or 0.0) ** 2
    print("columns: RMS z in σ quintiles 1–5 (5th split 80–90 / 90–100 %), parallel, crossing, all")
    table(load(args.dump, args.check), args.quantile, kappa, floor2)


if __name__ == "__main__":
    main()
