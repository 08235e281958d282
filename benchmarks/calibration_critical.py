"""Benchmark: the calibration stage's CPU, its main thread's and its critical path on two free
cores (issue 32, twelfth session) — a figure that holds on a loaded machine.

    nice -n 10 env NUMBA_NUM_THREADS=1 OMP_NUM_THREADS=1 PYTHONPATH=src python \
        benchmarks/calibration_critical.py --sim DATA/flight_8.75M [--runs 2] [--repeat 2] \
        [--baseline ../main/src]

Each run is a child process (this checkout's src, or ``--baseline``'s, alternately): it reads the
strips as ``calidar boresight`` does (not timed), calibrates once untimed (numba caches, imports)
and ``--repeat`` times timed (tie planes, default settings). Per timed calibration: the process
CPU seconds (every thread), the main thread's CPU seconds (``time.thread_time``), the CPU seconds
of every in-process pool thread (:class:`calidar.strips.distribute._DaemonPool`'s, each thread's
``thread_time`` over its life) and the critical path = main thread CPU + Σ over the pools of their
busiest thread's CPU: the wall the stage would take on two cores nobody else uses, were no
thread ever waiting for the GIL (a lower bound). Wall seconds are printed too (at a high load
they measure the queue).
"""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
import threading
import time
from pathlib import Path

import numpy as np

HERE = Path(__file__).resolve()


def child(sim: Path, repeat: int) -> None:
    import calidar.strips.distribute as distribute
    from calidar.pipelines.boresight import calibrate_inputs, load_inputs
    from calidar.pipelines.strip_config import StripConfig
    from calidar.strips.config import CalibrationConfig, matchers_named

    pools: list = []
    init, work = distribute._DaemonPool.__init__, distribute._DaemonPool._work

    def counted_init(self, threads):
        self.cpu = {}
        pools.append(self)
        init(self, threads)

    def counted_work(self):
        clock = time.thread_time()
        try:
            work(self)
        finally:
            self.cpu[threading.get_ident()] = time.thread_time() - clock

    distribute._DaemonPool.__init__, distribute._DaemonPool._work = counted_init, counted_work
    config = StripConfig(CalibrationConfig(matchers=matchers_named("planes")))
    strips = sorted((sim / "strips").glob("*.laz"))
    inputs = load_inputs(strips, sim / "sbet.out", sim / "sensor.toml", config)
    calibrate_inputs(inputs)
    for _ in range(repeat):
        pools.clear()
        cpu, main, wall = time.process_time(), time.thread_time(), time.perf_counter()
        calibrate_inputs(inputs)
        wall, main = time.perf_counter() - wall, time.thread_time() - main
        cpu = time.process_time() - cpu
        time.sleep(0.6)  # the last pool's threads end (JOIN_S)
        busiest = sum(max(p.cpu.values(), default=0.0) for p in pools)
        print(json.dumps({"cpu_s": cpu, "main_cpu_s": main,
                          "pool_cpu_s": sum(sum(p.cpu.values()) for p in pools),
                          "critical_s": main + busiest, "wall_s": wall, "pools": len(pools)}),
              flush=True)


def main() -> None:
    if len(sys.argv) > 1 and sys.argv[1] == "--child":
        return child(Path(sys.argv[2]), int(sys.argv[3]))
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--sim", type=Path, required=True)
    ap.add_argument("--runs", type=int, default=2)
    ap.add_argument("--repeat", type=int, default=2)
    ap.add_argument("--baseline", type=Path, help="another checkout's src, run alternately")
    args = ap.parse_args()
    sources = [("this", HERE.parents[1] / "src")]
    if args.baseline:
        sources.append(("baseline", args.baseline.resolve()))
    got: dict[str, list[dict]] = {name: [] for name, _ in sources}
    for k in range(args.runs):
        for name, src in sources:
            load = os.getloadavg()[0]
            out = subprocess.run([sys.executable, str(HERE), "--child", str(args.sim),
                                  str(args.repeat)], env={**os.environ, "PYTHONPATH": str(src)},
                                 capture_output=True, text=True, check=True).stdout
            for line in out.strip().splitlines():
                r = json.loads(line)
                got[name].append(r)
                print(f"run {k + 1} {name} (load {load:.1f}): CPU {r['cpu_s']:.2f} s, main thread "
                      f"{r['main_cpu_s']:.2f}, pool threads {r['pool_cpu_s']:.2f}, critical path "
                      f"{r['critical_s']:.2f}, wall {r['wall_s']:.2f}", flush=True)
    for name, rows in got.items():
        med = {k: float(np.median([r[k] for r in rows]))
               for k in ("cpu_s", "main_cpu_s", "critical_s", "wall_s")}
        print(f"{name}: medians " + ", ".join(f"{k} {v:.2f}" for k, v in med.items()))


if __name__ == "__main__":
    main()
