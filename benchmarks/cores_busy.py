"""Benchmark: how many cores a run keeps busy, stage by stage, on a shared machine (issue 32).

    nice -n 10 env NUMBA_NUM_THREADS=1 OMP_NUM_THREADS=1 PYTHONPATH=src python benchmarks/cores_busy.py \
        DIR/flight_64M [--method planes] [--src SRC] [--out stages.json]

Runs ``benchmarks/large_flight.py --child-stages DIR METHOD`` (``calidar boresight``'s pipeline in
one process, each stage's start stamped on stderr) and samples, every 0.2 s, every thread of
that process in ``/proc/PID/task/*/schedstat``: the nanoseconds each thread ran on a core and
those it waited runnable in the queue. Per stage (from one stamp's stage to the next):

- wall s, CPU s (ran, every thread: Python's, lazrs's rayon threads, numba's),
- cores busy = CPU / wall: what the run got — at a high load this measures the queue;
- cores wanted = (CPU + runnable wait) / wall: what the run would have used had the cores been
  free (a thread waiting for the GIL or for I/O sleeps, so it is not counted): what this
  change moves, and a figure that holds at any load.

``--src``: the sources to run (default: this checkout's ``src``), e.g. ``git archive`` of main.
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


def thread_times(pid: int) -> dict[int, tuple[int, int]]:
    """tid → (ns on a core, ns waiting runnable) of each live thread of ``pid``."""
    out = {}
    try:
        tids = os.listdir(f"/proc/{pid}/task")
    except OSError:
        return out
    for tid in tids:
        try:
            with open(f"/proc/{pid}/task/{tid}/schedstat") as f:
                run, wait, _ = f.read().split()
            out[int(tid)] = (int(run), int(wait))
        except (OSError, ValueError):
            continue
    return out


def sample(pid: int, done: threading.Event, samples: list, period: float = 0.2) -> None:
    """Append (monotonic s, total ns ran, total ns waited) of every thread ever seen until ``done``."""
    last: dict[int, tuple[int, int]] = {}
    while not done.is_set():
        last.update(thread_times(pid))
        samples.append((time.monotonic(), sum(r for r, _ in last.values()),
                        sum(w for _, w in last.values())))
        done.wait(period)


def run(sim: Path, method: str, src: Path) -> tuple[list, list, dict | None]:
    """The samples, the stages' starts and the run's result (boresight values and σ, degrees)."""
    env = {**os.environ, "PYTHONPATH": str(src)}
    cmd = [sys.executable, str(HERE.parent / "large_flight.py"), "--child-stages", str(sim), method]
    proc = subprocess.Popen(cmd, env=env, stderr=subprocess.PIPE, stdout=subprocess.PIPE, text=True)
    samples: list = []
    stamps: list = []  # (monotonic s, stage)
    done = threading.Event()
    sampler = threading.Thread(target=sample, args=(proc.pid, done, samples), daemon=True)
    sampler.start()
    stamps.append((time.monotonic(), "start"))
    for line in proc.stderr:
        if line.startswith("{"):
            stamp = json.loads(line)
            stage = stamp["stage"]
            if stage == "reading strips":  # its two passes: pass 1 counts to half the points
                n, total = map(int, stamp["done"].split("/"))
                stage += " (pass 1)" if 2 * n < total else " (pass 2, build)"
            if stage != stamps[-1][1]:
                stamps.append((time.monotonic(), stage))
    result = [ln for ln in proc.stdout.read().splitlines() if ln.startswith("{")]
    # the last sample before the process is reaped: its threads' times are still readable
    time.sleep(0.3)
    done.set()
    sampler.join()
    proc.wait()
    stamps.append((time.monotonic(), "end"))
    return samples, stamps, json.loads(result[-1]) if result else None


def at(samples: list, t: float) -> tuple[float, float]:
    """(ns ran, ns waited) of the last sample at or before ``t``."""
    best = samples[0]
    for s in samples:
        if s[0] > t:
            break
        best = s
    return best[1], best[2]


def per_stage(samples: list, stamps: list) -> list[dict]:
    rows = []
    for (t0, stage), (t1, _) in zip(stamps, stamps[1:]):
        r0, w0 = at(samples, t0)
        r1, w1 = at(samples, t1)
        wall = t1 - t0
        cpu, waited = (r1 - r0) / 1e9, (w1 - w0) / 1e9
        rows.append({"stage": stage, "wall_s": round(wall, 1), "cpu_s": round(cpu, 1),
                     "cores_busy": round(cpu / wall, 2) if wall > 0 else None,
                     "cores_wanted": round((cpu + waited) / wall, 2) if wall > 0 else None})
    return rows


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("sim", type=Path)
    ap.add_argument("--method", default="planes", choices=["planes", "vgicp"])
    ap.add_argument("--src", type=Path, default=HERE.parents[1] / "src")
    ap.add_argument("--out", type=Path)
    ap.add_argument("--timeline", type=float, default=0.0, metavar="S",
                    help="also print cores busy and wanted every S seconds")
    args = ap.parse_args()
    load = os.getloadavg()[0]
    samples, stamps, result = run(args.sim, args.method, args.src)
    rows = per_stage(samples, stamps)
    wall = stamps[-1][0] - stamps[0][0]
    r, w = samples[-1][1] / 1e9, samples[-1][2] / 1e9
    rows.append({"stage": "whole", "wall_s": round(wall, 1), "cpu_s": round(r, 1),
                 "cores_busy": round(r / wall, 2), "cores_wanted": round((r + w) / wall, 2)})
    if args.timeline:
        for t0 in np.arange(samples[0][0], samples[-1][0], args.timeline):
            (r0, w0), (r1, w1) = at(samples, t0), at(samples, t0 + args.timeline)
            stage = ([s for t, s in stamps if t <= t0] or ["start"])[-1]
            print(f"{t0 - samples[0][0]:6.0f} s {stage:28s} busy {(r1 - r0) / 1e9 / args.timeline:4.2f} "
                  f"wanted {(r1 - r0 + w1 - w0) / 1e9 / args.timeline:4.2f}")
    print(f"load at start {load:.1f}, at end {os.getloadavg()[0]:.1f}; src {args.src}")
    for row in rows:
        print(f"{row['stage']:28s} wall {row['wall_s']:7.1f} s  CPU {row['cpu_s']:7.1f} s  "
              f"busy {row['cores_busy']}  wanted {row['cores_wanted']}")
    if args.out:
        args.out.write_text(json.dumps({"load": load, "src": str(args.src), "stages": rows,
                                        "result": result}, indent=1))


if __name__ == "__main__":
    main()
