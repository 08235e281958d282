"""Benchmark: where the tie planes' pitch σ comes from, and whether their rows are correlated (issue 26, fifth session).

    NUMBA_NUM_THREADS=1 OMP_NUM_THREADS=1 PYTHONPATH=src python benchmarks/strips_pitch_sandwich.py \\
        --preset uav --directions cross --seeds 1000-1011 --cache DIR [--exact] [--methods planes] [--json out.jsonl]

Each cached survey (``strips_montecarlo.py``'s ``--cache`` folder; ``--exact``: its twin without trajectory
errors that ``strips_roll.py`` writes beside it) is adjusted once from the TRUE sensor with the default options
(so the move is the estimator's error), and at the solution the angles' covariance is split:

- ``model``: what the engine reports before the sandwich, max(σ0², 1)·N⁻¹, N = JᵀWJ + P;
- ``rows`` = N⁻¹(JᵀWJ)N⁻¹ and ``prior`` = N⁻¹PN⁻¹ (the two add up to N⁻¹): the rows' and the priors' shares;
- ``hc0``: N⁻¹(Σ_i s_i s_iᵀ)N⁻¹, s_i = w_i r_i J_i (each row its own cluster: the rows' σ, not their correlation);
- ``dyadic``: the engine's cluster-robust meat over the trajectory segments (strip, 10 s), as ``StripProblem.clusters``;
- ``pairs_cells``: clusters of rows sharing either side's (strip, patch neighbourhood of ``--cell`` m);
- ``sandwich_now``: what the engine reports today: max(dyadic, model) per angle;
- ``meat+prior``: N⁻¹(meat_dyadic + P)N⁻¹, the sandwich with the priors' share kept;
- ``hc0_r0`` / ``dyadic_r0`` / ``pair_seg_r0`` / ``cells_r0``: the same meats on the residuals at the START (the
  truth): on the twin without trajectory errors they hold the rows' own errors before the knots absorb any of
  them (``pair_seg``: clusters of one pair's rows in one a-side 10 s segment, no sharing across pairs);
  ``dyadic_r0_flat`` / ``dyadic_r0_sloped``: the dyadic meat at the truth from the rows with |n_z| ≥ 0.97 / < 0.97 alone.

It also prints each pair's and each slope class's share of the linear move −N⁻¹ Σ J_iᵀ w_i r0_i, and how much
the rows' residuals at the start hang together in time (variance inflation of time-bin means, lag-1 correlation).

Ratios meat/rows above 1 say the rows' residuals are correlated (or hold a misfit) beyond their stated σ.
"""

from __future__ import annotations

import argparse
import json
import sys
from dataclasses import replace
from pathlib import Path

import numpy as np
import scipy.sparse as sp

sys.path.insert(0, str(Path(__file__).resolve().parent))
from strips_montecarlo import ANGLES, ERRORS, _simulated, seeds_of  # noqa: E402
from strips_roll import SIGMA  # noqa: E402

from calidar.adjust import normals  # noqa: E402
from calidar.ingest.settings import IngestSettings  # noqa: E402
from calidar.pipelines.boresight import calibrate_inputs, load_inputs  # noqa: E402
from calidar.pipelines.strip_config import StripConfig  # noqa: E402
from calidar.sim.survey import survey_config  # noqa: E402
from calidar.strips import outer_loop as cal  # noqa: E402  (the run: outer_loop.Run)
from calidar.strips.config import CalibrationConfig, StripSettings, TrajectorySettings, matchers_named  # noqa: E402
from calidar.strips.parameters import sensor_of  # noqa: E402

CAPTURED: list = []


def _meat(scores, labels: np.ndarray) -> np.ndarray:
    """Σ_g S_g S_gᵀ (dense p×p) for one or two (dyadic) group ids per row, CR1-scaled, shared pairs once."""
    c = labels.reshape(scores.shape[0], -1)
    _, g = np.unique(c, return_inverse=True)
    g = g.reshape(c.shape)
    G = int(g.max()) + 1

    def sums(lab, n):
        m = sp.csr_matrix((np.ones(lab.size), (lab, np.arange(lab.size))), shape=(n, lab.size))
        out = m @ scores
        return np.asarray(out.todense()) if sp.issparse(out) else out

    S = [sums(g[:, k], G) for k in range(c.shape[1])]
    M = sum(s.T @ s for s in S)
    if c.shape[1] == 2:
        M += S[0].T @ S[1] + S[1].T @ S[0]
        _, d = np.unique(np.sort(g, axis=1), axis=0, return_inverse=True)
        D = sums(d.ravel(), int(d.max()) + 1)
        M -= D.T @ D
    return M * G / max(G - 1, 1)


def _cells(problem, strips, cell_m: float) -> np.ndarray:
    """(n, 2) the (strip, cell) of each row's a-side and b-side centroid (tie planes: one row per plane)."""
    out = []
    for c in problem.corrs:
        sides = []
        for sid, m in ((c.strip_a, c.A), (c.strip_b, c.B)):
            st = strips[sid]
            idx = problem.index[sid]
            xy = np.column_stack([m @ st.points[idx, 0], m @ st.points[idx, 1]])  # the row's centroid, delivered
            key = np.floor(xy / cell_m).astype(np.int64)
            sides.append((np.int64(sid) << 48) + ((key[:, 0] & 0xFFFFFF) << 24) + (key[:, 1] & 0xFFFFFF))
        rep = 3 if c.normal is None else 1
        out.append(np.repeat(np.stack(sides, axis=1), rep, axis=0))
    return np.concatenate(out)


def _contributions(c: np.ndarray, problem, strips) -> None:
    """Print each pair's and each slope class's share of the angles' move (mdeg): N⁻¹ J_iᵀ w_i r_i summed."""
    sizes = [k.n_obs * (3 if k.normal is None else 1) for k in problem.corrs]
    parts = np.split(c, np.cumsum(sizes)[:-1], axis=1)
    total = np.degrees(c.sum(1)) * 1e3
    print("  move from the rows (mdeg) roll/pitch/yaw " + "/".join(f"{x:+.3f}" for x in total))
    nz_all = []
    for k, part in zip(problem.corrs, parts):
        nz = np.abs(k.normal[:, 2]) if k.normal is not None else np.ones(part.shape[1])
        nz_all.append(nz)
        print(f"  pair {k.strip_a}-{k.strip_b}: {part.shape[1]:5d} rows  " + "/".join(
            f"{x:+.3f}" for x in np.degrees(part.sum(1)) * 1e3))
    nz = np.concatenate(nz_all)
    for lo, hi in ((0.0, 0.9), (0.9, 0.97), (0.97, 0.995), (0.995, 1.01)):
        m = (nz >= lo) & (nz < hi)
        print(f"  |n_z| {lo:.3f}–{hi:.3f}: {m.sum():6d} rows " + "/".join(
            f"{x:+.3f}" for x in np.degrees(c[:, m].sum(1)) * 1e3))


def _neighbours(problem, strips, r0: np.ndarray, sig: np.ndarray) -> None:
    """Print how much the rows' residuals at the start (the truth) hang together along the strips: per time-bin
    width, the variance inflation n·mean(z)²/mean(z²) of the bins' means (1 for independent rows; pairs' rows by
    their a-side time), pooled over the pairs, and the lag-1 correlation of z in a-side time order."""
    sizes = [k.n_obs * (3 if k.normal is None else 1) for k in problem.corrs]
    z = np.split(r0 / sig, np.cumsum(sizes)[:-1])
    out = {w: [] for w in (0.1, 0.5, 1.0, 2.0, 5.0, 20.0)}
    lag = []
    for k, zk in zip(problem.corrs, z):
        if zk.size < 50 or k.normal is None:
            continue
        t = k.A @ strips[k.strip_a].time[problem.index[k.strip_a]]
        o = np.argsort(t)
        lag.append(np.corrcoef(zk[o][1:], zk[o][:-1])[0, 1])
        for w in out:
            b = np.floor((t - t.min()) / w).astype(np.int64)
            n = np.bincount(b)
            s = np.bincount(b, zk)
            ok = n > 0
            out[w].append((np.sum(s[ok] ** 2 / n[ok]) / ok.sum(), np.mean(zk**2)))
    print("  rows at the truth: lag-1 corr of z in a-side time order, median over pairs "
          f"{np.median(lag):+.3f}; variance inflation of time-bin means " + "  ".join(
              f"{w:g} s: {np.mean([a for a, _ in v]) / np.mean([b for _, b in v]):.2f}" for w, v in out.items()))


def _capture(cell_m: float):
    original = cal.Run.solution

    def solution(self, est, problem):
        sol = original(self, est, problem)
        fit, x, r, w = est.fit, est.x, est.r, est.w
        J = fit.jacobian(x)
        D = normals.normal_matrix(J, w)
        N, _ = fit.normal_equations(J, w, x=x)
        Ninv = np.linalg.inv(N)
        names = list(fit.params.free_names) if hasattr(fit.params, "free_names") else [p.name for p in fit.free]
        k = [names.index(a) for a in ANGLES]
        _neighbours(problem, self.by_id, fit.r0, fit.sig)
        s0 = sp.diags(w * fit.r0) @ J  # at the start (the truth): the move is −N⁻¹ Σ_i J_iᵀ w_i r0_i (linear)
        scores = sp.diags(w * r) @ J
        scores = scores.tocsr() if sp.issparse(scores) else scores
        groupings = self.clusters(problem)
        factor = fit.variance_factor(r, w, x)
        R = Ninv[k]

        def var(M):
            return np.einsum("ij,jk,ik->i", R, M, R)

        hc0 = scores.T @ scores
        hc0 = np.asarray(hc0.todense()) if sp.issparse(hc0) else hc0
        dy = _meat(scores, groupings[0]) if groupings else hc0
        cells = _meat(scores, _cells(problem, self.by_id, cell_m))
        out = {"model": factor * np.diag(Ninv)[k], "rows": var(D), "prior": var(N - D), "hc0": var(hc0),
               "dyadic": var(dy), "pairs_cells": var(cells), "factor": np.full(3, factor)}
        s0c = s0.tocsr() if sp.issparse(s0) else s0
        h0 = s0c.T @ s0c
        out["hc0_r0"] = var(np.asarray(h0.todense()) if sp.issparse(h0) else h0)
        if groupings:
            out["dyadic_r0"] = var(_meat(s0c, groupings[0]))
            out["pair_seg_r0"] = var(_meat(s0c, groupings[1]))
        out["cells_r0"] = var(_meat(s0c, _cells(problem, self.by_id, cell_m)))
        if groupings:  # the dyadic meat at the truth from one class of rows alone (the others' scores set to 0)
            nz = np.concatenate([np.abs(k.normal[:, 2]) if k.normal is not None else np.ones(3 * k.n_obs)
                                 for k in problem.corrs])
            for name, keep in (("dyadic_r0_flat", nz >= 0.97), ("dyadic_r0_sloped", nz < 0.97)):
                out[name] = var(_meat(sp.diags(keep.astype(float)) @ s0c, groupings[0]))
        out["meat+prior"] = out["dyadic"] + out["prior"]
        out["sandwich_now"] = np.maximum(out["dyadic"], out["model"])
        out["reported"] = np.diag(sol.covariance)[k]
        _contributions(-(R @ (s0.T.toarray() if sp.issparse(s0) else s0.T)), problem, self.by_id)
        CAPTURED.append({key: np.sqrt(v).tolist() if key != "factor" else v.tolist() for key, v in out.items()})
        return sol

    cal.Run.solution = solution


def run(folder: Path, methods: list[str], exact: bool) -> dict:
    """The adjustment from the truth; the twin without errors takes the preset's σ as its priors (its smrmsg says 0)."""
    traj = TrajectorySettings(sigma=SIGMA["uav"]) if exact else TrajectorySettings()
    config = StripConfig(CalibrationConfig(matchers=matchers_named(*methods), trajectory=traj,
                                           solver=StripSettings(max_outer=1), model_check=False), IngestSettings())
    inputs = load_inputs(sorted((folder / "strips").glob("*.laz")), folder / "sbet.out", folder / "sensor.toml",
                         config, truth=folder / "truth.json")
    truth = sensor_of(inputs.nominal, inputs.truth)
    out = {}
    for m, r in calibrate_inputs(replace(inputs, nominal=truth)).items():
        sol = r.solution
        out[m] = {"move_deg": [float(np.degrees(sol.values[a] - inputs.truth[a])) for a in ANGLES],
                  "sigma_deg": {key: np.degrees(v).tolist() for key, v in CAPTURED.pop(0).items() if key != "factor"}}
    return out


def summary(rows: list[dict]) -> str:
    lines = []
    for (exact, m) in sorted({(r["exact"], r["method"]) for r in rows}):
        sel = [r for r in rows if r["exact"] == exact and r["method"] == m]
        mv = np.array([r["move_deg"] for r in sel])
        lines.append(f"{'exact' if exact else 'default'} {m} n={len(sel)}  RMS move (mdeg) "
                     + "/".join(f"{x:.3f}" for x in 1e3 * np.sqrt(np.mean(mv**2, 0))))
        for key in sel[0]["sigma_deg"]:
            sg = np.array([r["sigma_deg"][key] for r in sel])
            lines.append(f"   {key:13s} mean σ " + "/".join(f"{x:.3f}" for x in 1e3 * sg.mean(0))
                         + "  RMS z " + "/".join(f"{x:.2f}" for x in np.sqrt(np.mean((mv / sg) ** 2, 0)))
                         + "  σ/σ_rows " + "/".join(f"{x:.2f}" for x in np.sqrt(np.mean(sg**2, 0) / np.mean(
                             np.array([r["sigma_deg"]["rows"] for r in sel]) ** 2, 0))))
    return "\n".join(lines)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--seeds", default="1000-1011")
    ap.add_argument("--methods", default="planes")
    ap.add_argument("--preset", default="uav", choices=("airborne", "uav"))
    ap.add_argument("--directions", default="cross", choices=("cross", "opposite"))
    ap.add_argument("--vegetation", type=float, default=0.0)
    ap.add_argument("--cache", type=Path, required=True)
    ap.add_argument("--exact", action="store_true", help="the twins without trajectory errors")
    ap.add_argument("--cell", type=float, default=5.0, help="m, the patch neighbourhoods of pairs_cells")
    ap.add_argument("--json", type=Path, default=None)
    ap.add_argument("--summary", action="store_true")
    args = ap.parse_args()
    if args.summary:
        print(summary([json.loads(x) for x in args.json.read_text().splitlines() if x.strip()]))
        return
    _capture(args.cell)
    rows = []
    for seed in seeds_of(args.seeds):
        cfg = survey_config(args.preset, seed=seed, density=1.0, vegetation=args.vegetation, directions=args.directions,
                            errors=ERRORS)
        folder = _simulated(cfg, args.cache / "tmp", args.cache, (1.0,) * 6, 0.0, 1.0)  # cached: read, not written
        if args.exact:
            folder = folder.with_name(folder.name + "_exact")
            if not (folder / "truth.json").exists():
                print(f"seed {seed}: no {folder} yet (strips_roll.py writes it)", flush=True)
                continue
        for m, res in run(folder, args.methods.split(","), args.exact).items():
            row = {"seed": seed, "exact": args.exact, "method": m, **res}
            rows.append(row)
            if args.json:
                with args.json.open("a") as f:
                    f.write(json.dumps(row) + "\n")
            print(json.dumps(row), flush=True)
    print(summary(rows))


if __name__ == "__main__":
    main()
