"""Predicted σ of `calidar plan` against the RMS error of simulated, calibrated surveys of each plan.

    NUMBA_NUM_THREADS=1 OMP_NUM_THREADS=1 OPENBLAS_NUM_THREADS=1 PYTHONPATH=src \\
        nice -n 10 python benchmarks/plan_validation.py --runs 40 [--plans opposite,cross,...] [--json out.jsonl]

Every plan flies the UAV preset's scene (200 m × 200 m, scene seed 3: hills, a rough band, roofs,
10 % trees) at 2 kHz (2.2 points/m² at 80 m), 8 m/s, 1 cm range noise, a trajectory stated and
simulated at 2 cm / 0.002°. For each plan: the prediction (`calidar.planning.predict`, before any
simulation; whether it calls the plan poor), then ``--runs`` surveys (seeds 1…N; true mounting
errors drawn per survey, σ 0.03° and 3 cm) calibrated by the strip calibrator with the trajectory
model (`calidar.planning.simulate.simulate_and_calibrate`). Per parameter: predicted σ (the σ the
calibration will report, N⁻¹) and expected error σ, RMS error, their ratios (0.8–1.25 asked; the
sampling spread ≈ ±1/√(2N)), the calibration's mean σ. A poor plan's best suggested line
(`calidar.planning.suggest`) is added and validated as its own plan. ``--table rows.jsonl …``: the
table of earlier runs, each plan predicted again with today's code (simulations do not depend on it).
"""

from __future__ import annotations

import argparse
import json
import time
from dataclasses import replace
from pathlib import Path

import numpy as np

from calidar.io.flight_lines import PlanLine
from calidar.planning.geometry import Instrument, fly_plan
from calidar.planning.predict import PlanSettings, predict
from calidar.planning.simulate import FLAT_SCENE, confirm
from calidar.planning.suggest import suggest
from calidar.planning.terrain import scene_terrain
from calidar.sensor import Sensor
from calidar.sim.survey import survey_config


def L(n, x0, y0, x1, y1, h=80.0):  # noqa: N802 - a line of the plans below
    return PlanLine(n, np.array([x0, y0], float), np.array([x1, y1], float), h, 8.0)


#: name → (lines, estimated groups)
PLANS = {
    "opposite": ([L(1, -30, -60, -30, 60), L(2, -30, 60, -30, -60), L(3, 30, -60, 30, 60), L(4, 30, 60, 30, -60)],
                 ("boresight",)),
    "cross": ([L(1, -25, -60, -25, 60), L(2, 25, 60, 25, -60), L(3, -60, 0, 60, 0), L(4, 60, 10, -60, 10)],
              ("boresight",)),
    "three_alternate": ([L(1, -35, -60, -35, 60), L(2, 0, 60, 0, -60), L(3, 35, -60, 35, 60)], ("boresight",)),
    "pair_one_height": ([L(1, 0, -60, 0, 60), L(2, 0, 60, 0, -60)], ("boresight", "lever_arm_x", "lever_arm_y")),
    "poor_one_height": ([L(1, -30, -60, -30, 60), L(2, -30, 60, -30, -60), L(3, 30, -60, 30, 60),
                         L(4, 30, 60, 30, -60)], ("boresight", "lever_arm_x", "lever_arm_y")),
    "two_heights": ([L(1, -30, -60, -30, 60), L(2, -30, 60, -30, -60), L(3, 30, -60, 30, 60), L(4, 30, 60, 30, -60),
                     L(5, 0, -60, 0, 60, 130.0), L(6, 0, 60, 0, -60, 130.0)], ("boresight", "lever_arm_x", "lever_arm_y")),
    # gentle hills (2 m relief; no roof, tree or rough band) under a steady platform: every point of a line
    # moves along track by (height · pitch + lever_arm_x), the height the same ± 3 % (poor by design)
    "gentle_one_height": ([L(1, -30, -60, -30, 60), L(2, -30, 60, -30, -60), L(3, 30, -60, 30, 60),
                          L(4, 30, 60, 30, -60)], ("boresight_pitch", "lever_arm_x")),
    # a Palmer scanner (VQ-880-G-like oval, ±10.6° across at the swath's edge: a 30 m swath at 80 m) sees
    # every point twice, ahead and back; four lines 14 m apart
    "palmer_opposite": ([L(1, -7, -60, -7, 60), L(2, -7, 60, -7, -60), L(3, 7, -60, 7, 60), L(4, 7, 60, 7, -60)],
                        ("boresight",)),
}
#: plans whose sensor.toml names a rotating scanner (the plan's geometry and the simulation follow it)
SCANNERS = {"palmer_opposite": "palmer"}
#: plans flown over gentle hills only (no roof, tree or rough band) by a steady platform (a calm aircraft, a
#: stabilised mount): (relief m; σ of the attitude wobble, roll/pitch and heading, deg)
GENTLE = {"gentle_one_height": (2.0, (0.3, 0.3))}


def setup(name: str = ""):
    """The simulator's base configuration, the terrain and the instrument of plan ``name``."""
    base = survey_config("uav", scene_seed=3)
    base = replace(base, scene=replace(base.scene, width_m=200.0, length_m=200.0))
    inst = Instrument(Sensor(lever_arm_x=0.05, lever_arm_z=0.12), pulse_rate_hz=2000.0)
    key = name.split("+")[0]
    if key in SCANNERS:
        from calidar.planning.sweep import pattern_half_fov
        from calidar.scanners import SCANNERS as MODELS

        nominal = replace(inst.nominal, scanner=MODELS[SCANNERS[key]]())
        inst = replace(inst, nominal=nominal, half_fov_rad=pattern_half_fov(nominal))
    if key in GENTLE:
        relief, motion = GENTLE[key]
        scene = replace(base.scene, width_m=300.0, length_m=300.0, **{**FLAT_SCENE, "relief_m": relief})
        base = replace(base, scene=scene)
        return base, scene_terrain(base), replace(inst, motion_rad=tuple(np.radians(motion)))
    return base, scene_terrain(base), inst


def shown(name: str, unit: str, v: float) -> str:
    return f"{np.degrees(v):.5f}°" if unit == "rad" else f"{v * 100:.3f} cm"


def run_plan(name, lines, estimate, runs, base, terrain, inst, log) -> dict:
    settings = PlanSettings(estimate=estimate)
    t = time.perf_counter()
    pred = predict(lines, terrain, inst, settings)
    seconds = time.perf_counter() - t
    log(f"{name}: predicted in {seconds:.1f} s, poor={pred.poor}, " + ", ".join(
        f"{n} {shown(n, u, s)}" for n, u, s in zip(pred.names, pred.units, pred.sigma)))
    out = {"plan": name, "lines": [ln.to_dict() for ln in lines], "estimate": list(estimate), "poor": pred.poor,
           "predicted": dict(zip(pred.names, pred.sigma.tolist())), "units": dict(zip(pred.names, pred.units)),
           "reported": dict(zip(pred.names, pred.reported.tolist())),
           "predict_s": seconds, "correlated": pred.correlated_pairs(0.95)}
    if runs:
        flown = fly_plan(lines, terrain)
        t = time.perf_counter()
        res = confirm(flown, inst, settings, pred.names, runs, base,
                      progress=lambda text, done, total: log(f"  {name}: {done}/{total} surveys"))
        out.update(rms_error=res["rms_error"], mean_sigma=res["mean_sigma"], runs=len(res["runs"]),
                   seconds=time.perf_counter() - t, per_run=res["runs"])
        for n, u in zip(pred.names, pred.units):
            log(f"  {n}: predicted {shown(n, u, out['predicted'][n])}, RMS error {shown(n, u, res['rms_error'][n])}, "
                f"ratio {res['rms_error'][n] / out['predicted'][n]:.2f}; σ the calibration will report: predicted "
                f"{shown(n, u, out['reported'][n])}, its mean {shown(n, u, res['mean_sigma'][n])}")
    return out


def table(paths: list[Path]) -> None:
    """The validation table from the JSON rows of earlier runs, each plan predicted again with today's code
    (the simulations do not depend on the prediction)."""
    print("| plan | lines | named poor | parameter | predicted σ (reported) | expected error σ | RMS error | "
          "RMS / predicted σ | RMS / expected error σ | calibration's mean σ | runs |")
    print("|---|---|---|---|---|---|---|---|---|---|---|")
    for path in paths:
        for text in path.read_text().splitlines():
            row = json.loads(text)
            if "rms_error" not in row:
                continue
            lines = [PlanLine(d["line"], np.array(d["start"]), np.array(d["end"]), d["height_agl_m"], d["speed_mps"])
                     for d in row["lines"]]
            _, terrain, inst = setup(row["plan"])
            pred = predict(lines, terrain, inst, PlanSettings(estimate=tuple(row["estimate"])))
            for n, u, s, r in zip(pred.names, pred.units, pred.sigma, pred.reported):
                rms = row["rms_error"][n]
                print(f"| {row['plan']} | {len(lines)} | {'yes' if pred.poor else 'no'} | {n} | {shown(n, u, r)} | "
                      f"{shown(n, u, s)} | {shown(n, u, rms)} | {rms / r:.2f} | {rms / s:.2f} | "
                      f"{shown(n, u, row['mean_sigma'][n])} | {row['runs']} |")


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--runs", type=int, default=40)
    ap.add_argument("--plans", default=",".join(PLANS))
    ap.add_argument("--no-suggestion", action="store_true")
    ap.add_argument("--json", type=Path, default=None)
    ap.add_argument("--table", type=Path, nargs="*", default=None, help="JSON rows of earlier runs: print the table")
    args = ap.parse_args()
    if args.table:
        table(args.table)
        return
    start = time.perf_counter()

    def log(text):
        print(f"[{time.perf_counter() - start:7.0f} s] {text}", flush=True)

    def keep(row):
        if args.json:
            with open(args.json, "a", encoding="utf-8") as f:
                f.write(json.dumps(row) + "\n")

    for name in args.plans.split(","):
        lines, estimate = PLANS[name]
        base, terrain, inst = setup(name)
        row = run_plan(name, lines, estimate, args.runs, base, terrain, inst, log)
        keep(row)
        if row["poor"] and not args.no_suggestion:
            settings = PlanSettings(estimate=estimate)
            found = suggest(lines, terrain, inst, settings, predict(lines, terrain, inst, settings))
            best = found[0]
            log(f"{name}: best suggestion {best.kind} {best.line.to_dict()}: {best.parameter} "
                f"{best.sigma_before:.3g} → {best.sigma_after:.3g}")
            row = run_plan(f"{name}+suggested", [*lines, best.line], estimate, args.runs, base, terrain, inst, log)
            row["suggestion"] = best.to_dict()
            keep(row)
    log("done")


if __name__ == "__main__":
    main()
