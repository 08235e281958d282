"""Monte-Carlo of `calidar ccr` on fresh 2-CCR passes, end to end (issue 26's acceptance).

Each seed: `calidar simulate photons --seed N --n-ccr 2 --ccr-dropout 0.33` (the same
configuration the CLI builds), written to a folder, then `calidar ccr ATL03_sim.h5 --ccr ccr.csv
--truth truth.json --out DIR` with the command's defaults (100 bootstrap replicates, profile
intervals, the 9 × 9 surface), through the same pipeline call (`calidar.pipelines.ccr.run_ccr`)
and the same error contract: a CalidarError is a refusal (exit 1, one line), anything else is
what the CLI would call an "internal error". solution.json is read back (so it must be valid
JSON) and compared with the truth.

Reported: passes solved / refused / internal errors; per geolocation parameter (along, cross,
diameter) the RMS and max of |error/σ|, the coverage of the reported 95 % profile-likelihood
intervals and of ±1.96 σ; and the same split by whether the verdict says no honest interval can be had
from the pass, and by whether a nuisance parameter was held at a bound.

Run (niced, one core): NUMBA_NUM_THREADS=1 OMP_NUM_THREADS=1 PYTHONPATH=src nice -n 10 \
    python benchmarks/photon_ccr_passes.py --seeds 2000:2100 [--bootstrap 100] [--surface 9] [--n-ccr 2] [--log FILE]
"""

from __future__ import annotations

import argparse
import json
import tempfile
import time
import traceback
from pathlib import Path

import numpy as np

from calidar.errors import CalidarError
from calidar.photon.parameters import GEOLOCATION
from calidar.photon.search import SearchSettings
from calidar.pipelines.ccr import run_ccr, simulate_photons
from calidar.pipelines.ccr_config import CCRConfig
from calidar.sim.photons import PhotonSimConfig


def one_pass(seed: int, bootstrap: int, surface: int = 9, n: int = 2) -> dict:
    """Simulate, calibrate and compare one pass with ``n`` lit CCRs; a dict with its status and figures."""
    cfg = PhotonSimConfig(seed=seed, n_ccr=n, ccr_dropout=0.33, ccr_spacing=min(60.0, 0.9 * 1200.0 / n))
    with tempfile.TemporaryDirectory(prefix="photon_ccr_") as tmp:
        sim_dir, out = Path(tmp) / "sim", Path(tmp) / "cal"
        sim_dir.mkdir()
        out.mkdir()
        paths = simulate_photons(cfg, sim_dir)
        t0 = time.perf_counter()
        try:
            run_ccr([paths["atl03"]], paths["ccr"], out,
                    CCRConfig(search=SearchSettings(bootstrap=bootstrap, surface_points=surface)), truth_path=paths["truth"])
        except CalidarError as e:
            return {"seed": seed, "status": "refused", "message": str(e)}
        except Exception as e:  # noqa: BLE001 - what the CLI reports as an internal error
            return {"seed": seed, "status": "internal", "message": f"{type(e).__name__}: {e}",
                    "traceback": traceback.format_exc()}
        seconds = time.perf_counter() - t0
        doc = json.loads((out / "solution.json").read_text())  # must parse: no NaN/Infinity tokens
        truth = json.loads(paths["truth"].read_text())
    prof = doc["uncertainty"]["profile_interval_95"]
    row = {"seed": seed, "status": "solved", "seconds": seconds, "held": doc["held_at_bound"],
           "verdict": doc["verdict"]["status"] if doc.get("verdict") else None}
    for k in GEOLOCATION:
        p = doc["parameters"][k]
        err, sig = p["value"] - truth[k], p["sigma"]
        row[k] = {"error": err, "sigma": sig, "z": err / sig if sig else float("nan"),
                  "profile_covers": prof[k]["low"] <= truth[k] <= prof[k]["high"],
                  "value": p["value"], "truth": truth[k], "profile": prof[k]}
    row["values"] = {n: p["value"] for n, p in doc["parameters"].items()}
    row["warnings"] = doc["verdict"]["findings"] if doc.get("verdict") and "findings" in doc["verdict"] else None
    return row


def summarise(rows: list[dict], label: str) -> list[str]:
    solved = [r for r in rows if r["status"] == "solved"]
    out = [f"{label}: {len(rows)} passes, {len(solved)} solved, "
           f"{sum(r['status'] == 'refused' for r in rows)} refused, {sum(r['status'] == 'internal' for r in rows)} "
           "internal errors"]
    if not solved:
        return out
    for k in GEOLOCATION:
        z = np.array([r[k]["z"] for r in solved])
        prof = np.mean([r[k]["profile_covers"] for r in solved])
        wald = np.mean(np.abs(z) <= 1.96)
        out.append(f"  {k:20s} RMS z {np.sqrt(np.nanmean(z ** 2)):.2f}  max |z| {np.nanmax(np.abs(z)):.2f}  "
                   f"95 % profile coverage {prof:.1%}  ±1.96σ coverage {wald:.1%}")
    return out


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--seeds", default="2000:2100", help="A:B, seeds A … B−1")
    ap.add_argument("--bootstrap", type=int, default=100, help="bootstrap replicates (calidar ccr's default: 100)")
    ap.add_argument("--surface", type=int, default=9, help="likelihood surface points per axis (the report's map; "
                    "no estimate, σ or interval depends on it; calidar ccr's default: 9)")
    ap.add_argument("--n-ccr", type=int, default=2, help="lit CCRs a pass (issue 26's acceptance: 2)")
    ap.add_argument("--log", type=Path, default=None, help="JSON lines, one per pass (appended)")
    args = ap.parse_args()
    a, b = map(int, args.seeds.split(":"))
    rows, t0 = [], time.perf_counter()
    for seed in range(a, b):
        row = one_pass(seed, args.bootstrap, args.surface, args.n_ccr)
        rows.append(row)
        if args.log:
            with open(args.log, "a", encoding="utf-8") as fh:
                fh.write(json.dumps(row) + "\n")
        brief = " ".join(f"{row[k]['z']:+.2f}" for k in GEOLOCATION) if row["status"] == "solved" else row["message"]
        print(f"seed {seed}: {row['status']} {brief} {row.get('held', '')}", flush=True)
    print(f"{time.perf_counter() - t0:.0f} s")
    for line in summarise(rows, "all"):
        print(line)
    warned = [r for r in rows if r["status"] == "solved" and any("no honest interval" in f["detail"]
                                                                 for f in r.get("warnings") or [])]
    if warned:
        for line in summarise(warned, "verdict: no honest interval"):
            print(line)
        for line in summarise([r for r in rows if r not in warned], "the others"):
            print(line)
    held = [r for r in rows if r["status"] == "solved" and r["held"]]
    if held:
        for line in summarise(held, "held at a bound"):
            print(line)


if __name__ == "__main__":
    main()
