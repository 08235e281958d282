"""Benchmark: the tie-plane calibration stage by itself (issue 32) — `calidar boresight`'s
``calibrate_with_client`` on the strips of a simulated flight, read once, timed in CPU seconds.

    nice -n 10 env NUMBA_NUM_THREADS=1 OMP_NUM_THREADS=1 PYTHONPATH=src python \
        benchmarks/calibration_stage.py --sim DATA/flight_8.75M [--runs 3] [--repeat 3] \
        [--baseline ../main/src]

``--sim``: a flight of ``benchmarks/large_flight.py simulate``. Each run is a child process
(importing calidar from this checkout's src, or ``--baseline``'s, alternately): it reads the
strips as ``calidar boresight`` does (default settings, not timed), calibrates once to warm
numba's caches and the imports (not timed) and then ``--repeat`` times timed: the process CPU
seconds of ``calibrate_inputs`` (every thread; the least of the repeats, which a shared machine's
load inflates least, and their median), its wall, the outer iterations with their solver
iterations and each stage's wall, and the peak RSS. The calibrated values and σ of the two
sources are compared (max |Δ|): the timed change must leave them identical.
"""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
import time
from pathlib import Path

import numpy as np

HERE = Path(__file__).resolve()


def child(sim: Path, method: str, repeat: int = 1) -> None:
    """One source's run: read, calibrate once untimed, ``repeat`` times timed; a JSON line on
    stdout."""
    from calidar.pipelines.boresight import calibrate_inputs, load_inputs
    from calidar.pipelines.strip_config import StripConfig
    from calidar.strips.config import CalibrationConfig, matchers_named

    config = StripConfig(CalibrationConfig(matchers=matchers_named(method)))
    strips = sorted((sim / "strips").glob("*.laz"))
    inputs = load_inputs(strips, sim / "sbet.out", sim / "sensor.toml", config)
    calibrate_inputs(inputs)  # warm: numba caches loaded, imports done
    cpus, walls = [], []
    for _ in range(repeat):
        cpu, wall = time.process_time(), time.perf_counter()
        result = calibrate_inputs(inputs)[method]
        cpus.append(time.process_time() - cpu)
        walls.append(time.perf_counter() - wall)
    cpu, wall = min(cpus), float(np.median(walls))
    sol = result.solution
    hwm = next(int(ln.split()[1]) for ln in open("/proc/self/status") if ln.startswith("VmHWM"))
    keep = ("solver_iterations", "georeference_s", "match_s", "solve_s")
    print(json.dumps({
        "cpu_s": cpu, "cpu_median_s": float(np.median(cpus)), "wall_s": wall,
        "peak_gib": hwm / 2**20,
        "outer": [{k: o[k] for k in keep if k in o} for o in result.outer],
        "values": {k: float(v) for k, v in sol.values.items()},
        "sigma": {k: float(v) for k, v in sol.sigma.items()}}))


def run(sim: Path, method: str, src: Path, repeat: int) -> dict:
    env = {**os.environ, "PYTHONPATH": str(src)}
    load = os.getloadavg()[0]
    out = subprocess.run([sys.executable, str(HERE), "--child", str(sim), method, str(repeat)],
                         env=env,
                         capture_output=True, text=True, check=True).stdout
    return {**json.loads(out.strip().splitlines()[-1]), "load": load}


def main() -> None:
    if len(sys.argv) > 1 and sys.argv[1] == "--child":
        return child(Path(sys.argv[2]), sys.argv[3], int(sys.argv[4]))
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--sim", type=Path, required=True)
    ap.add_argument("--method", default="planes")
    ap.add_argument("--runs", type=int, default=1)
    ap.add_argument("--repeat", type=int, default=1, help="timed calibrations in each run")
    ap.add_argument("--baseline", type=Path, help="another checkout's src, run alternately")
    args = ap.parse_args()
    sources = [("this", HERE.parents[1] / "src")]
    if args.baseline:
        sources.append(("baseline", args.baseline.resolve()))
    done: dict[str, list[dict]] = {name: [] for name, _ in sources}
    for k in range(args.runs):
        for name, src in sources:
            r = run(args.sim, args.method, src, args.repeat)
            done[name].append(r)
            its = " ".join(f"{o['solver_iterations']}" for o in r["outer"])
            print(f"run {k + 1} {name}: {r['cpu_s']:.2f} CPU s (median {r['cpu_median_s']:.2f}), "
                  f"{r['wall_s']:.2f} s wall, peak "
                  f"{r['peak_gib']:.3f} GiB, load {r['load']:.1f}; outer {len(r['outer'])}, "
                  f"solver iterations {its}; "
                  f"match {sum(o['match_s'] for o in r['outer']):.2f} s, solve "
                  f"{sum(o['solve_s'] for o in r['outer']):.2f} s wall", flush=True)
    if args.baseline:
        a, b = done["this"][0], done["baseline"][0]
        dv = max(abs(a["values"][k] - b["values"][k]) for k in a["values"])
        ds = max(abs(a["sigma"][k] - b["sigma"][k]) for k in a["sigma"])
        print(f"values max |Δ| {dv:.3g}, σ max |Δ| {ds:.3g} (SI)")


if __name__ == "__main__":
    main()
