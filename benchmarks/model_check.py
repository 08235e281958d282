"""Monte-Carlo of the strip calibration's model check: its false alarms and its detections.

    NUMBA_NUM_THREADS=1 OMP_NUM_THREADS=1 PYTHONPATH=src python benchmarks/model_check.py \\
        --seeds 1000-1029 [--preset uav] [--range-offset 0.0] [--directions cross,opposite] \\
        [--vegetation 0.3] [--json out.jsonl]
    python benchmarks/model_check.py --summary out.jsonl [more.jsonl ...]

Each seed is one fresh survey of the preset (UAV: 300 m × 300 m at density 0.2, the preset's trees,
2 cm / 0.002° trajectory errors and the smrmsg.out that states them; ``--vegetation``: another
fraction under trees), lines ``--directions`` (one
per seed, in turn), written as the simulator delivers it with a true range offset of
``--range-offset`` m that the calibration does NOT estimate, then calibrated by the boresight
pipeline with its default options (boresight, tie planes, trajectory model on;
:func:`calidar.pipelines.boresight.load_inputs`, :func:`calibrate_inputs`). One JSON line per survey:
each candidate's freed value, σ and z, the shifts of the angles in their own σ, the angles' errors
against the truth in their σ, the check's seconds and the calibration's, and the verdict's model-check
finding. ``--summary``: per (preset, range offset) the surveys, the model check's FAIL / WARN counts
re-derived from the raw z and shifts with today's candidates and thresholds (and at other z
thresholds), per candidate its σ, mean and RMS of z, the surveys with |z| above 2, 3, 4, 5 and the
angles' shifts, the median seconds the check added and the calibration took.
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


def one(seed: int, preset: str, range_offset: float, directions: str, vegetation: float | None = None) -> dict:
    from calidar.pipelines.boresight import calibrate_inputs, load_inputs
    from calidar.pipelines.strip_config import StripConfig
    from calidar.sim.survey import simulate_survey, survey_config
    from calidar.strips.model_check_verdict import model_check_finding

    clock = time.perf_counter()
    density = 0.2 if preset == "uav" else 1.0
    cfg = survey_config(preset, seed=seed, density=density, directions=directions, errors={"range_offset": range_offset})
    if vegetation is not None:
        cfg = replace(cfg, scene=replace(cfg.scene, vegetation_fraction=vegetation))
    res = simulate_survey(cfg)
    folder = Path(tempfile.mkdtemp(prefix=f"model_check_{seed}_"))
    try:
        sim = res.write(folder / "sim")
        simulated = time.perf_counter() - clock
        inputs = load_inputs(sorted((sim / "strips").glob("*.laz")), sim / "sbet.out", sim / "sensor.toml",
                             StripConfig(), truth=sim / "truth.json")
        start, cpu = time.perf_counter(), time.process_time()
        result = calibrate_inputs(inputs)["planes"]
        calibrated, calibrated_cpu = time.perf_counter() - start, time.process_time() - cpu
    finally:
        shutil.rmtree(folder, ignore_errors=True)
    sol = result.solution
    check = sol.extra["model_check"]
    finding = model_check_finding(check, sol)
    out = {"seed": seed, "preset": preset, "range_offset_m": range_offset, "directions": directions,
           "vegetation": cfg.scene.vegetation_fraction,
           "simulate_s": simulated, "calibrate_s": calibrated, "check_s": check["seconds"], "check_parts": check.get("parts"),
           "calibrate_cpu_s": calibrated_cpu, "check_cpu_s": check.get("cpu_seconds"),
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


def flagged(row: dict, z_limit: float, shift_limit: float) -> bool:
    """Would a candidate of today's list (calidar.strips.model_check.CANDIDATES) in this survey's
    record pass |z| > z_limit with an angle moved by more than shift_limit of its σ?"""
    from calidar.strips.model_check import CANDIDATES

    return any(c["separable"] and abs(c["z"]) > z_limit
               and max(abs(v) for v in c["shift_in_own_sigma"].values()) > shift_limit
               for name, c in row["candidates"].items() if name in CANDIDATES)


def summary(paths: list[Path]) -> None:
    """Per (preset, range offset): the surveys, the verdict's model-check status re-derived from the
    raw z and shifts with today's candidates and thresholds, each candidate's z statistics, and the
    warn / fail rates at other thresholds."""
    from calidar.strips.model_check import CANDIDATES
    from calidar.strips.model_check_verdict import SHIFT_LIMIT, Z_FAIL, Z_WARN

    rows = [json.loads(line) for p in paths for line in p.read_text().splitlines() if line.strip()]
    groups: dict[tuple, list] = {}
    for r in rows:
        groups.setdefault((r["preset"], r.get("vegetation", 0.1), r["range_offset_m"]), []).append(r)
    for (preset, trees, ro), rs in sorted(groups.items()):
        n = len(rs)
        fail = sum(flagged(r, Z_FAIL, SHIFT_LIMIT) for r in rs)
        warn = sum(flagged(r, Z_WARN, SHIFT_LIMIT) for r in rs) - fail
        dirs = {d: sum(r["directions"] == d for r in rs) for d in sorted({r["directions"] for r in rs})}
        print(f"{preset} ({trees:.0%} trees) range offset {ro * 100:g} cm: {n} surveys {dirs}; model check FAIL {fail}, WARN {warn} "
              f"(|z| > {Z_FAIL:g} / {Z_WARN:g}, shift > {SHIFT_LIMIT:g} σ); check {np.median([r['check_s'] for r in rs]):.2f} s "
              f"median, calibration {np.median([r['calibrate_s'] for r in rs]):.1f} s median")
        sweep = ", ".join(f"|z|>{t:g}: {sum(flagged(r, t, SHIFT_LIMIT) for r in rs)}" for t in (2, 3, 3.5, 4, 5))
        cpu = [(r["check_cpu_s"], r["calibrate_cpu_s"]) for r in rs if r.get("check_cpu_s") is not None]
        if cpu:
            print(f"  CPU: check {np.median([c for c, _ in cpu]):.2f} s median of calibration {np.median([k for _, k in cpu]):.1f} s "
                  f"({np.median([c / k for c, k in cpu]):.1%} median, {max(c / k for c, k in cpu):.1%} max; {len(cpu)} surveys)")
        print(f"  surveys flagged at other z thresholds (shift > {SHIFT_LIMIT:g} σ): {sweep}")
        for c in [c for c in CANDIDATES if any(c in r["candidates"] for r in rs)] + sorted(
                {c for r in rs for c in r["candidates"]} - set(CANDIDATES)):
            sep = [r["candidates"][c] for r in rs if r["candidates"].get(c, {}).get("separable")]
            tag = "" if c in CANDIDATES else " [no longer a candidate]"
            if not sep:
                print(f"  {c}: not separable / not freed{tag}")
                continue
            z = np.array([x["z"] for x in sep])
            shift = np.array([max(abs(v) for v in x["shift_in_own_sigma"].values()) for x in sep])
            sig = np.median([x["sigma"] for x in sep])
            above = ", ".join(f">{t}: {np.sum(np.abs(z) > t)}" for t in (2, 3, 4, 5))
            print(f"  {c}{tag}: σ {sig:.3g} (median), mean z {np.mean(z):+.2f}, RMS z {np.sqrt(np.mean(z * z)):.2f}, "
                  f"|z| min {np.min(np.abs(z)):.1f} max {np.max(np.abs(z)):.1f} (surveys with |z| {above}); "
                  f"largest angle shift {np.median(shift):.1f} σ median, {np.max(shift):.1f} σ max")
        za = np.array([r["angles"][a]["z"] for r in rs for a in ANGLES])
        print(f"  angles' error/σ: RMS {np.sqrt(np.mean(za * za)):.2f}, max |z| {np.max(np.abs(za)):.1f}")
        freed = [r for r in rs if r["candidates"].get("range_offset", {}).get("separable")]
        zf = np.array([r["angles"][a]["z"] + r["candidates"]["range_offset"]["shift_in_own_sigma"][a]
                       for r in freed for a in ANGLES])  # error/σ (restricted σ) with the offset freed
        if zf.size:
            print(f"  with range_offset freed (error + shift, in the restricted σ): RMS {np.sqrt(np.mean(zf * zf)):.2f}, "
                  f"max |z| {np.max(np.abs(zf)):.1f}")


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--seeds", default="1000-1001")
    ap.add_argument("--preset", default="uav")
    ap.add_argument("--range-offset", type=float, default=0.0)
    ap.add_argument("--directions", default="cross,opposite")
    ap.add_argument("--vegetation", type=float, help="fraction under trees (default: the preset's)")
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
        row = one(seed, args.preset, args.range_offset, directions[k % len(directions)], args.vegetation)
        line = json.dumps(row)
        if args.json:
            with args.json.open("a") as f:
                f.write(line + "\n")
        print(f"seed {seed} {row['directions']}: {row['status']} {row['finding']}", file=sys.stderr, flush=True)


if __name__ == "__main__":
    main()
