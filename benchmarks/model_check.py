"""Monte-Carlo of the strip calibration's model check: its false alarms and its detections.

    NUMBA_NUM_THREADS=1 OMP_NUM_THREADS=1 PYTHONPATH=src python benchmarks/model_check.py \\
        --seeds 1000-1029 [--preset uav] [--range-offset 0.0] [--directions cross,opposite] \\
        [--json out.jsonl]
    python benchmarks/model_check.py --summary out.jsonl [more.jsonl ...]

Each seed is one fresh survey of the preset (UAV: 300 m × 300 m at density 0.2, the preset's trees,
2 cm / 0.002° trajectory errors and the smrmsg.out that states them), lines ``--directions`` (one
per seed, in turn), written as the simulator delivers it with a true range offset of
``--range-offset`` m that the calibration does NOT estimate, then calibrated by the boresight
pipeline with its default options (boresight, tie planes, trajectory model on;
:func:`calidar.pipelines.boresight.load_inputs`, :func:`calibrate_inputs`). One JSON line per survey:
each candidate's freed value, σ and z, the shifts of the angles in their own σ, the angles' errors
against the truth in their σ, the check's seconds and the calibration's, and the verdict's model-check
finding. ``--summary``: per (preset, range offset) the surveys, the largest |z| per candidate, the
fraction with |z| above 2, 3, 4, 5, the warn / fail rates, the median seconds added.
"""

from __future__ import annotations

import argparse
import json
import shutil
import sys
import tempfile
import time
from dataclasses import replace
from pathlib import Path

import numpy as np

ANGLES = ("boresight_roll", "boresight_pitch", "boresight_yaw")


def one(seed: int, preset: str, range_offset: float, directions: str) -> dict:
    from calidar.pipelines.boresight import calibrate_inputs, load_inputs
    from calidar.pipelines.strip_config import StripConfig
    from calidar.sim.survey import simulate_survey, survey_config
    from calidar.strips.model_check_verdict import model_check_finding

    clock = time.perf_counter()
    density = 0.2 if preset == "uav" else 1.0
    cfg = survey_config(preset, seed=seed, density=density, directions=directions, errors={"range_offset": range_offset})
    res = simulate_survey(cfg)
    folder = Path(tempfile.mkdtemp(prefix=f"model_check_{seed}_"))
    try:
        sim = res.write(folder / "sim")
        simulated = time.perf_counter() - clock
        inputs = load_inputs(sorted((sim / "strips").glob("*.laz")), sim / "sbet.out", sim / "sensor.toml",
                             StripConfig(), truth=sim / "truth.json")
        start = time.perf_counter()
        result = calibrate_inputs(inputs)["planes"]
        calibrated = time.perf_counter() - start
    finally:
        shutil.rmtree(folder, ignore_errors=True)
    sol = result.solution
    check = sol.extra["model_check"]
    finding = model_check_finding(check, sol)
    out = {"seed": seed, "preset": preset, "range_offset_m": range_offset, "directions": directions,
           "simulate_s": simulated, "calibrate_s": calibrated, "check_s": check["seconds"],
           "status": finding.status, "finding": finding.detail, "sigma0": sol.sigma0}
    out["angles"] = {a: {"error": sol.values[a] - inputs.truth.get(a, 0.0), "sigma": sol.sigma[a],
                         "z": (sol.values[a] - inputs.truth.get(a, 0.0)) / sol.sigma[a]} for a in ANGLES}
    out["candidates"] = {}
    for name, c in check["candidates"].items():
        row = {"separable": c["separable"], "information_share": c["information_share"]}
        if c["separable"]:
            row.update(value=c["value"], sigma=c["sigma"], sigma_model=c["sigma_model"],
                       sigma_cluster=c["sigma_cluster"], z=c["z"],
                       shift_in_own_sigma={a: s["in_own_sigma"] for a, s in c["shifts"].items()})
        out["candidates"][name] = row
    return out


def summary(paths: list[Path]) -> None:
    rows = [json.loads(line) for p in paths for line in p.read_text().splitlines() if line.strip()]
    groups: dict[tuple, list] = {}
    for r in rows:
        groups.setdefault((r["preset"], r["range_offset_m"]), []).append(r)
    for (preset, ro), rs in sorted(groups.items()):
        n = len(rs)
        status = {s: sum(r["status"] == s for r in rs) for s in ("pass", "note", "warn", "fail")}
        print(f"{preset} range offset {ro * 100:g} cm: {n} surveys, verdict {status}, check "
              f"{np.median([r['check_s'] for r in rs]):.2f} s median (calibration {np.median([r['calibrate_s'] for r in rs]):.1f} s)")
        names = sorted({c for r in rs for c in r["candidates"]})
        for c in names:
            z = np.array([r["candidates"][c]["z"] for r in rs if r["candidates"].get(c, {}).get("separable")])
            if not z.size:
                print(f"  {c}: not separable")
                continue
            shift = np.array([max(abs(v) for v in r["candidates"][c]["shift_in_own_sigma"].values())
                              for r in rs if r["candidates"].get(c, {}).get("separable")])
            above = ", ".join(f">{t}: {np.mean(np.abs(z) > t):.0%}" for t in (2, 3, 4, 5))
            print(f"  {c}: RMS z {np.sqrt(np.mean(z * z)):.2f}, max |z| {np.max(np.abs(z)):.1f} ({above}); "
                  f"largest angle shift {np.median(shift):.1f} σ median, {np.max(shift):.1f} σ max")
        za = np.array([r["angles"][a]["z"] for r in rs for a in ANGLES])
        print(f"  angles' error/σ: RMS {np.sqrt(np.mean(za * za)):.2f}, max |z| {np.max(np.abs(za)):.1f}")


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--seeds", default="1000-1001")
    ap.add_argument("--preset", default="uav")
    ap.add_argument("--range-offset", type=float, default=0.0)
    ap.add_argument("--directions", default="cross,opposite")
    ap.add_argument("--json", type=Path)
    ap.add_argument("--summary", type=Path, nargs="+")
    args = ap.parse_args()
    if args.summary:
        summary(args.summary)
        return
    lo, _, hi = args.seeds.partition("-")
    seeds = range(int(lo), int(hi or lo) + 1)
    directions = args.directions.split(",")
    for k, seed in enumerate(seeds):
        row = one(seed, args.preset, args.range_offset, directions[k % len(directions)])
        line = json.dumps(row)
        if args.json:
            with args.json.open("a") as f:
                f.write(line + "\n")
        print(f"seed {seed} {row['directions']}: {row['status']} {row['finding']}", file=sys.stderr, flush=True)


if __name__ == "__main__":
    main()
