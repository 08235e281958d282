"""Benchmark: the rows' share of VGICP's angles against the spread of its error over draws of the
points' noise alone — same hits, same trajectory errors (issue 26, twelfth session).

    NUMBA_NUM_THREADS=1 OMP_NUM_THREADS=1 PYTHONPATH=src python \\
        benchmarks/strips_vgicp_noise_draws.py --preset uav --directions opposite \\
        --seeds 1224-1229 --draws 0-3 --cache DIR [--exact] [--set noise_floor_m=0] \\
        [--json out.jsonl] [--summary]

Each seed's survey (``strips_montecarlo.py``'s cached folder; ``--exact``: its twin without
trajectory errors, ``strips_roll.py``'s) is simulated again with other draws of its range and angle
noise (draw 0: the cached survey itself; draw d > 0: folder ``…_drawd``, the same hits and the same
GNSS/INS errors, ``strips_roll._simulate_with_noise_draw``) and calibrated with the default options
(``--exact``: the preset's trajectory σ as priors), VGICP only. Within a seed the draws share the
trajectory's part of the error, so the spread of the error over the draws is the rows' noise part
alone: its variance (n − 1 degrees of freedom per seed, pooled over seeds) against the mean rows'
share [N⁻¹JᵀWJN⁻¹]_kk at the solutions. A ratio below 1: the share is wider than the rows' noise.
"""

from __future__ import annotations

import argparse
import json
import sys
from dataclasses import replace
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
from strips_montecarlo import ANGLES, ERRORS, _simulated, record, recorded, seeds_of  # noqa: E402
from strips_prior_honesty import _CAPTURED, _capture  # noqa: E402
from strips_roll import SIGMA, _simulate_with_noise_draw, folders  # noqa: E402
from strips_yaw_draws import functional  # noqa: E402

from calidar.adjust import solver  # noqa: E402
from calidar.pipelines.boresight import calibrate_inputs, load_inputs  # noqa: E402
from calidar.pipelines.strip_config import StripConfig  # noqa: E402
from calidar.sim.survey import survey_config  # noqa: E402
from calidar.strips.config import (CalibrationConfig, TrajectorySettings,  # noqa: E402
                                   matchers_named)


def folder(cache: Path, seed: int, directions: str, vegetation: float, draw: int,
           exact: bool) -> Path:
    if exact:
        return folders(cache, seed, "uav", directions, "scene", vegetation, noise_draw=draw)[1]
    cfg = survey_config("uav", seed=seed, density=1.0, vegetation=vegetation,
                        directions=directions, errors=ERRORS)
    base = _simulated(cfg, cache / "tmp", cache, (1.0,) * 6, 0.0, 1.0)
    if draw == 0:
        return base
    out = base.with_name(base.name + f"_draw{draw}")
    if not (out / "truth.json").exists():
        _simulate_with_noise_draw(cfg, draw).write(out, force=True)
    return out


def run(f: Path, exact: bool, vgicp_set: dict) -> dict:
    traj = TrajectorySettings(sigma=SIGMA["uav"]) if exact else TrajectorySettings()
    cal = CalibrationConfig(matchers=matchers_named("vgicp"), trajectory=traj, model_check=False)
    if vgicp_set:
        m = cal.matchers[0]
        cal = replace(cal, matchers=(replace(m, settings=replace(m.settings, **vgicp_set)),))
    inputs = load_inputs(sorted((f / "strips").glob("*.laz")), f / "sbet.out", f / "sensor.toml",
                         StripConfig(cal), truth=f / "truth.json")
    _CAPTURED.clear()
    res = calibrate_inputs(inputs)["vgicp"]
    _, sigma, share = functional(_CAPTURED[-1])
    sol = res.solution
    return {"error_deg": [float(np.degrees(sol.values[a] - inputs.truth[a])) for a in ANGLES],
            "sigma_deg": [float(np.degrees(sol.sigma[a])) for a in ANGLES],
            "model_deg": np.degrees(sigma).tolist(), "share_deg": np.degrees(share).tolist(),
            "sigma0": float(sol.extra.get("unit_weight", {}).get("sigma0", np.nan))}


def summary(rows: list[dict]) -> str:
    out = []
    for exact in sorted({r["exact"] for r in rows}):
        sel = [r for r in rows if r["exact"] == exact]
        seeds = sorted({r["seed"] for r in sel})
        ss, dof, sh2 = np.zeros(3), 0, []
        for s in seeds:
            e = np.array([r["error_deg"] for r in sel if r["seed"] == s])
            if len(e) < 2:
                continue
            ss += np.sum((e - e.mean(0)) ** 2, 0)
            dof += len(e) - 1
            sh2 += [r["share_deg"] for r in sel if r["seed"] == s]
        if not dof:
            continue
        spread = np.sqrt(ss / dof)
        share = np.sqrt(np.mean(np.square(sh2), 0))
        s0 = np.mean([r["sigma0"] for r in sel])
        out.append(f"{'exact' if exact else 'with trajectory errors'}: {len(seeds)} seeds, "
                   f"{len(sel)} runs, {dof} dof: spread over draws " + "/".join(
                       f"{1e3 * x:.2f}" for x in spread) + " mdeg, rows' share " + "/".join(
                       f"{1e3 * x:.2f}" for x in share) + " mdeg, ratio " + "/".join(
                       f"{x:.2f}" for x in spread / share) + f" (±{1 / np.sqrt(2 * dof):.2f}),"
                   f" mean σ0 {s0:.3f}")
    return "\n".join(out)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--seeds", default="1224-1229")
    ap.add_argument("--draws", default="0-3")
    ap.add_argument("--preset", default="uav", choices=("uav",))
    ap.add_argument("--directions", default="opposite", choices=("cross", "opposite"))
    ap.add_argument("--vegetation", type=float, default=0.0)
    ap.add_argument("--cache", type=Path, required=True)
    ap.add_argument("--exact", action="store_true")
    ap.add_argument("--set", nargs="*", default=[], help="[vgicp] key=value")
    ap.add_argument("--json", type=Path, default=None)
    ap.add_argument("--summary", action="store_true")
    args = ap.parse_args()
    if args.summary:
        print(summary(recorded(args.json)))
        return
    solver.Estimate.solution = _capture
    vset = {k: int(v) if v.isdigit() else float(v)
            for k, v in (s.split("=") for s in args.set)}
    rows = []
    for seed in seeds_of(args.seeds):
        for d in seeds_of(args.draws):
            f = folder(args.cache, seed, args.directions, args.vegetation, d, args.exact)
            row = {"seed": seed, "draw": d, "exact": args.exact, "directions": args.directions,
                   "set": args.set, **run(f, args.exact, vset)}
            rows.append(row)
            record(row, args.json)
            print(json.dumps(row), flush=True)
    print(summary(rows))


if __name__ == "__main__":
    main()
