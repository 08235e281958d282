"""Benchmark: end-to-end strip calibration on 8 simulated strips of about 1 million points each.

    NUMBA_NUM_THREADS=1 OMP_NUM_THREADS=1 PYTHONPATH=src python benchmarks/strips.py [--method planes]
        [--trajectory-sigma 0.03,0.002]

The survey (airborne preset: 6 parallel lines flown in alternate directions + 2 cross
lines, boresight errors of a few hundredths of a degree) is simulated once and cached as
LAZ + SBET under ``--cache`` (not timed). Then the same steps as ``calidar boresight``
are timed: read the LAZ strips, build the strips (one inverse georeferencing), calibrate
(per outer iteration: re-georeference overlaps, match pairs, solve), per-pair quality and
report, write the outputs.
"""

from __future__ import annotations

import argparse
import json
import os
import platform
import tempfile
import time
from dataclasses import replace
from pathlib import Path

import numpy as np

from calidar.pipelines.boresight import load_strips, trajectory_model
from calidar.io.trajectory import read_trajectory
from calidar.report import Report
from calidar.sensor import Sensor
from calidar.sim.survey import PRESETS, simulate_survey, survey_config
from calidar.strips.calibrate import StripSettings, calibrate, truth_to_si
from calidar.strips.report import add_report_section, pair_quality

ERRORS = {"boresight_roll": np.radians(0.03), "boresight_pitch": np.radians(-0.04), "boresight_yaw": np.radians(0.05)}


def simulate(cache: Path, density: float) -> Path:
    sim = cache / f"airborne_8_strips_d{density:g}"
    if (sim / "truth.json").exists():
        return sim
    scene = replace(PRESETS["airborne"].scene, width_m=3300.0)
    cfg = survey_config("airborne", seed=5, density=density, directions="cross", scene=scene, errors=ERRORS,
                        range_noise_m=0.03)
    t = time.perf_counter()
    res = simulate_survey(cfg)
    res.write(sim, force=True)
    print(f"simulated {len(res.strips)} strips, {res.n_points / 1e6:.2f} M points in {time.perf_counter() - t:.0f} s (not timed)")
    return sim


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--method", default="planes", choices=["planes", "vgicp"])
    ap.add_argument("--density", type=float, default=1.7, help="simulator density (1.7 ≈ 8 M points in 8 strips)")
    ap.add_argument("--cache", type=Path, default=Path(tempfile.gettempdir()) / "calidar_bench_strips")
    ap.add_argument("--trajectory-sigma", default=None,
                    help="'POSITION_M,ATTITUDE_DEG': also estimate the trajectory errors (1 s blocks, 20 s / 3 s correlation)")
    args = ap.parse_args()
    sim = simulate(args.cache, args.density)
    stages: dict[str, float] = {}

    def stage(name, t0):
        stages[name] = time.perf_counter() - t0

    start = t0 = time.perf_counter()
    nominal = Sensor.read(sim / "sensor.toml")
    traj = read_trajectory(sim / "sbet.out")
    paths = sorted((sim / "strips").glob("*.laz"))
    strips, crs = load_strips(paths, traj, nominal)
    stage("read LAZ + build strips (inverse georeferencing)", t0)
    t0 = time.perf_counter()
    if args.trajectory_sigma:
        settings = StripSettings(trajectory=trajectory_model(args.trajectory_sigma))
        result = calibrate(strips, nominal, method=args.method, estimate="boresight,trajectory_bias", settings=settings)
    else:
        result = calibrate(strips, nominal, method=args.method)
    stage("calibrate", t0)
    for o in result.outer:
        for key in ("georeference_s", "match_s", "solve_s"):
            stages[f"  iteration {o['iteration']}: {key[:-2]}"
                   + (f" ({o['solver_iterations']} LM iterations)" if key == "solve_s" else "")] = o[key]
    t0 = time.perf_counter()
    truth = truth_to_si(json.loads((sim / "truth.json").read_text()), result.solution.parameters)
    report = Report("benchmark")
    add_report_section(report, result, truth, pair_quality(result))
    stage("quality before/after + report section", t0)
    t0 = time.perf_counter()
    with tempfile.TemporaryDirectory() as out:
        result.solution.write_json(Path(out) / "solution.json", truth)
        result.sensor.write(Path(out) / "sensor.toml", force=True)
        report.write(Path(out) / "report.html")
    stage("write outputs", t0)
    total = time.perf_counter() - start

    n = sum(len(s) for s in strips)
    print(f"machine: {platform.machine()}, {os.cpu_count()} cores, python {platform.python_version()}; "
          f"NUMBA_NUM_THREADS={os.environ.get('NUMBA_NUM_THREADS')} OMP_NUM_THREADS={os.environ.get('OMP_NUM_THREADS')}")
    print(f"{len(strips)} strips, {n / 1e6:.2f} M points ({', '.join(f'{len(s) / 1e6:.2f}' for s in strips)} M), "
          f"{len(result.overlaps)} overlapping pairs, method {args.method}"
          + (f", trajectory errors modelled ({args.trajectory_sigma})" if args.trajectory_sigma else ""))
    for k, v in stages.items():
        print(f"{k:55s} {v:7.2f} s")
    print(f"{'TOTAL end to end':55s} {total:7.2f} s")
    sol = result.solution
    for name in ERRORS:
        err = np.degrees(sol.values[name] - truth[name])
        print(f"{name:18s} error {err:+.5f}° σ {np.degrees(sol.sigma[name]):.5f}°")


if __name__ == "__main__":
    main()
