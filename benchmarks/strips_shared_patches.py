"""Benchmark: how much the tie planes' rows share their patches across pairs, and what that does to
the angles' σ (issue 26, seventh session).

    NUMBA_NUM_THREADS=1 OMP_NUM_THREADS=1 PYTHONPATH=src \\
        python benchmarks/strips_shared_patches.py --preset uav --directions cross \\
        --seeds 1000-1003 --cache DIR [--exact] [--json out.jsonl]

Each cached survey (``strips_montecarlo.py``'s ``--cache``; ``--exact``: ``strips_roll.py``'s twin
without trajectory errors, the preset's priors) is adjusted once from the TRUE sensor with the tie
planes, twice: with the rows as matched (``independent``: each row its own noise) and with each
patch counted once (:mod:`calidar.strips.shared_patches`, ``counted``). At each solution the angles'
covariance from the rows is taken two ways:

- ``claimed``: N⁻¹(JᵀWJ)N⁻¹, what the rows' σ say (the rows' share of the reported σ);
- ``shared``: N⁻¹(JᵀW Σ W J)N⁻¹ with Σ the rows' covariance when each strip point's noise enters
  every row that uses it: Σ_ij = Σ_p s_i h_ip · s_j h_jp · (n_i · n_j), h the row's weights on the
  point (a's plane's hat weights, b's 1/m; signed a − b) and s² the side's per-point variance (its
  variance share over Σ h²). Its diagonal is each row's own σ², so the two differ only by the
  rows' sharing.

Also printed: how many rows use each strip point (k), the share of the rows whose sides have k ≥ 2,
and the pitch move. ``shared``/``claimed`` near 1 for ``counted`` says the rows' σ carry the
sharing.
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
from calidar.strips import outer_loop as cal  # noqa: E402
from calidar.strips import problem as problem_module  # noqa: E402
from calidar.strips import shared_patches  # noqa: E402
from calidar.strips.config import (CalibrationConfig, StripSettings,  # noqa: E402
                                   TrajectorySettings, matchers_named)
from calidar.strips.parameters import sensor_of  # noqa: E402

CAPTURED: list = []
MATCHED: list = []  # the correspondence sets each StripProblem was built from (before counting)


def _counting(on: bool):
    """StripProblem counts patches once (``on``) or takes the rows as matched; either way the
    matched sets are kept for the covariance."""
    def count(corrs):
        MATCHED[:] = [list(corrs)]
        if on:
            return shared_patches.counted_once(corrs)
        return list(corrs), [np.ones(c.n_obs * (3 if c.normal is None else 1)) for c in corrs]

    problem_module.counted_once = count


def _loading(matched, index) -> sp.csr_matrix:
    """(rows, points of all strips) the rows' loadings s·h on each strip point, signed a − b, in
    the problem's row order (tie-plane rows only; others get an empty row)."""
    offset, start = {}, 0
    for sid, idx in index.items():
        offset[sid] = start
        start += int(np.max(idx)) + 1 if idx.size else 0
    blocks = []
    for c in matched:
        if c.side_variance is None:
            blocks.append(sp.csr_matrix((c.n_obs * (3 if c.normal is None else 1), start)))
            continue
        sides = []
        for sign, sid, m, v in ((1.0, c.strip_a, c.A, c.side_variance[:, 0]),
                                (-1.0, c.strip_b, c.B, c.side_variance[:, 1])):
            m = m.tocsr()
            h2 = np.asarray(m.multiply(m).sum(axis=1)).ravel()
            s = np.sqrt(v / np.maximum(h2, 1e-300))  # the side's per-point σ along the normal
            rows = np.repeat(np.arange(m.shape[0]), np.diff(m.indptr))
            sides.append(sp.csr_matrix((sign * s[rows] * m.data, (rows, m.indices + offset[sid])),
                                       shape=(m.shape[0], start)))
        blocks.append(sides[0] + sides[1])
    return sp.vstack(blocks).tocsr()


def _uses(matched) -> tuple[float, float]:
    """The mean number of rows using a used strip point, and the share of row sides with k ≥ 2."""
    uses = shared_patches._uses(matched)
    ks = np.concatenate([u[u > 0] for u in uses.values()])
    sides = [shared_patches.side_factor(m, uses[sid]) for c in matched
             if c.side_variance is not None for sid, m in ((c.strip_a, c.A), (c.strip_b, c.B))]
    f = np.concatenate(sides)
    return float(ks.mean()), float(np.mean(f > 1.25))


def _capture():
    original = cal.Run.solution

    def solution(self, est, problem):
        sol = original(self, est, problem)
        fit, x, w = est.fit, est.x, est.w
        J = fit.jacobian(x)
        N, _ = fit.normal_equations(J, w, x=x)
        names = [p.name for p in fit.free]
        R = np.linalg.inv(N)[[names.index(a) for a in ANGLES]]
        WJ = sp.diags(w) @ J
        claimed = np.einsum("ij,jk,ik->i", R, np.asarray((WJ.T @ J).todense()) if sp.issparse(J)
                            else WJ.T @ J, R)
        matched = MATCHED[0]
        L = _loading(matched, problem.index)
        normal = np.concatenate([c.normal if c.normal is not None else np.zeros((3 * c.n_obs, 3))
                                 for c in matched])
        G = np.asarray(WJ @ R.T).T  # (3, rows)
        shared = np.zeros(3)
        for ax in range(3):  # Σ = Σ_ax (L·n_ax)(L·n_ax)ᵀ: (n_i · n_j) s_i h_i s_j h_j
            Lax = sp.diags(normal[:, ax]) @ L
            t = (Lax.T @ G.T)  # (points, 3)
            shared += np.sum(np.asarray(t) ** 2, axis=0)
        mean_k, share_k = _uses(matched)
        CAPTURED.append({"claimed": np.sqrt(claimed).tolist(), "shared": np.sqrt(shared).tolist(),
                         "mean_k": mean_k, "sides_shared": share_k})
        return sol

    cal.Run.solution = solution


def run(folder: Path, exact: bool, counted: bool) -> dict:
    _counting(counted)
    traj = TrajectorySettings(sigma=SIGMA["uav"]) if exact else TrajectorySettings()
    config = StripConfig(CalibrationConfig(matchers=matchers_named("planes"), trajectory=traj,
                                           solver=StripSettings(max_outer=1), model_check=False),
                         IngestSettings())
    inputs = load_inputs(sorted((folder / "strips").glob("*.laz")), folder / "sbet.out",
                         folder / "sensor.toml", config, truth=folder / "truth.json")
    truth = sensor_of(inputs.nominal, inputs.truth)
    sol = calibrate_inputs(replace(inputs, nominal=truth))["planes"].solution
    return {"move_deg": [float(np.degrees(sol.values[a] - inputs.truth[a])) for a in ANGLES],
            "sigma_deg": [float(np.degrees(sol.sigma[a])) for a in ANGLES],
            **{k: (np.degrees(v).tolist() if k in ("claimed", "shared") else v)
               for k, v in CAPTURED.pop(0).items()}}


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--seeds", default="1000-1003")
    ap.add_argument("--preset", default="uav", choices=("airborne", "uav"))
    ap.add_argument("--directions", default="cross", choices=("cross", "opposite"))
    ap.add_argument("--vegetation", type=float, default=0.0)
    ap.add_argument("--cache", type=Path, required=True)
    ap.add_argument("--exact", action="store_true", help="the twins without trajectory errors")
    ap.add_argument("--json", type=Path, default=None)
    args = ap.parse_args()
    _capture()
    for seed in seeds_of(args.seeds):
        cfg = survey_config(args.preset, seed=seed, density=1.0, vegetation=args.vegetation,
                            directions=args.directions, errors=ERRORS)
        folder = _simulated(cfg, args.cache / "tmp", args.cache, (1.0,) * 6, 0.0, 1.0)
        if args.exact:
            folder = folder.with_name(folder.name + "_exact")
        for counted in (False, True):
            row = {"seed": seed, "exact": args.exact, "counted": counted,
                   **run(folder, args.exact, counted)}
            if args.json:
                with args.json.open("a") as f:
                    f.write(json.dumps(row) + "\n")
            c, s = np.array(row["claimed"]) * 1e3, np.array(row["shared"]) * 1e3
            print(f"seed {seed} {'counted' if counted else 'independent'}: pitch move "
                  f"{row['move_deg'][1] * 1e3:+.3f} mdeg, σ {row['sigma_deg'][1] * 1e3:.3f}; rows' "
                  f"share claimed r/p/y " + "/".join(f"{x:.3f}" for x in c) + ", with the sharing "
                  + "/".join(f"{x:.3f}" for x in s) + f" (ratio {s[1] / c[1]:.2f} pitch); mean k "
                  f"{row['mean_k']:.2f}, sides shared {100 * row['sides_shared']:.0f} %",
                  flush=True)


if __name__ == "__main__":
    main()
