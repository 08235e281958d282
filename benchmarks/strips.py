"""Benchmark: ``calidar boresight`` end to end on 8 simulated strips of about 1 million points each.

    NUMBA_NUM_THREADS=1 OMP_NUM_THREADS=1 PYTHONPATH=src python benchmarks/strips.py [--method planes]
        [--trajectory-model off]

The survey (airborne preset: 6 parallel lines flown in alternate directions + 2 cross
lines, boresight errors of a few hundredths of a degree, the preset's 3 cm / 0.002°
trajectory errors and the smrmsg.out that states them) is simulated once and cached as LAZ +
SBET + smrmsg under ``--cache`` (not timed). Then the boresight pipeline runs as the command
does (:func:`calidar.pipelines.boresight.calibrate_strips`, default options: the trajectory
model on with the smrmsg's σ as priors), timed per stage: read the LAZ strips (two passes:
footprints, then the overlap points thinned to the budget per strip, from what the first pass kept
on disk within ``HOLD_POINTS_BYTES``, else streamed again) and build them
(one inverse georeferencing of the kept points), calibrate (per outer iteration:
re-georeference the overlaps, match, solve), overlap quality of the whole strips (streamed
again) as delivered / new mounting / + trajectory corrections, report and outputs. Reading
the LAZ files alone (every field, one pass) is timed first for the ratio; the peak RSS of the
process is printed at the end.
"""

from __future__ import annotations

import argparse
import os
import resource
import platform
import tempfile
import time
from dataclasses import replace
from pathlib import Path

import numpy as np

from calidar.pipelines.boresight import calibrate_strips
from calidar.pipelines.strip_config import StripConfig
from calidar.strips.config import CalibrationConfig, matchers_named
from calidar.sim.survey import PRESETS, simulate_survey, survey_config

ERRORS = {"boresight_roll": np.radians(0.03), "boresight_pitch": np.radians(-0.04), "boresight_yaw": np.radians(0.05)}


def survey(density: float):
    """The 8-strip airborne survey at ``density`` (also benchmarks/strips_scale.py's)."""
    scene = replace(PRESETS["airborne"].scene, width_m=3300.0)
    return survey_config("airborne", seed=5, density=density, directions="cross", scene=scene, errors=ERRORS,
                         range_noise_m=0.03)


def simulate(cache: Path, density: float) -> Path:
    sim = cache / f"airborne_8_strips_d{density:g}_smrmsg"
    if (sim / "truth.json").exists():
        return sim
    cfg = survey(density)
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
    ap.add_argument("--trajectory-model", default="on", choices=["on", "off"])
    args = ap.parse_args()
    sim = simulate(args.cache, args.density)
    from calidar.io.las import iter_las_chunks

    clock = time.perf_counter()
    for path in sorted((sim / "strips").glob("*.laz")):
        for _ in iter_las_chunks(path):
            pass
    read_alone = time.perf_counter() - clock
    first: dict[str, float] = {}
    last: dict[str, float] = {}
    start = time.perf_counter()

    def progress(description, done, total):
        now = time.perf_counter() - start
        first.setdefault(description, now)
        last[description] = now

    cal = CalibrationConfig(matchers=matchers_named(args.method))
    config = StripConfig(cal if args.trajectory_model == "on" else replace(cal, trajectory=None))
    with tempfile.TemporaryDirectory() as out:
        run = calibrate_strips(sorted((sim / "strips").glob("*.laz")), sim / "sbet.out", sim / "sensor.toml", config,
                               truth=sim / "truth.json", progress=progress)
        run.write(Path(out))
    total = time.perf_counter() - start
    result = run.results[args.method]
    stages = {"read LAZ (2 passes), thin, build strips": last["reading strips"],
              "calibrate": last[f"calibrating ({args.method})"] - last["reading strips"]}
    for o in result.outer:
        for key in ("georeference_s", "match_s", "solve_s"):
            stages[f"  iteration {o['iteration']}: {key[:-2]}"
                   + (f" ({o['solver_iterations']} LM iterations)" if key == "solve_s" else "")] = o[key]
    stages["overlap quality (whole strips, every stage)"] = last["overlap quality"] - last[f"calibrating ({args.method})"]
    stages["verdict, report, outputs"] = total - last["overlap quality"]
    n = sum(run.inputs.source.counts.values())
    kept = sum(len(s) for s in run.inputs.strips)
    print(f"machine: {platform.machine()}, {os.cpu_count()} cores, python {platform.python_version()}; "
          f"NUMBA_NUM_THREADS={os.environ.get('NUMBA_NUM_THREADS')} OMP_NUM_THREADS={os.environ.get('OMP_NUM_THREADS')}; "
          f"load average {os.getloadavg()[0]:.2f}")
    print(f"{len(run.inputs.strips)} strips, {n / 1e6:.2f} M points ({kept / 1e6:.2f} M kept), {len(result.overlaps)} "
          "overlapping pairs, method "
          f"{args.method}, trajectory model {args.trajectory_model}"
          + (f" ({sum(p.name.startswith('trajectory_') for p in result.solution.parameters.free)} corrections)"
             if args.trajectory_model == "on" else ""))
    for k, v in stages.items():
        print(f"{k:55s} {v:7.2f} s")
    print(f"{'TOTAL end to end':55s} {total:7.2f} s")
    print(f"{'reading the LAZ alone (every field, one pass)':55s} {read_alone:7.2f} s  (end to end: "
          f"{total / read_alone:.1f}×; ingest + calibrate: {last[f'calibrating ({args.method})'] / read_alone:.1f}×)")
    print(f"peak RSS {resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 2**20:.2f} GiB")
    sol, truth = result.solution, run.inputs.truth
    for name in ERRORS:
        err = np.degrees(sol.values[name] - truth[name])
        print(f"{name:18s} error {err:+.5f}° σ {np.degrees(sol.sigma[name]):.5f}°")
    print(f"verdict: {run.verdicts[args.method].headline()}")


if __name__ == "__main__":
    main()
