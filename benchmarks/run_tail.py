"""Benchmark: the serial tail of ``calidar boresight`` and ``calidar quality`` — from the end of
the last pass over the points to the process gone (report, outputs, the held points' removal,
atexit, the interpreter's exit), interleaved against another source tree.

    nice -n 10 env NUMBA_NUM_THREADS=1 OMP_NUM_THREADS=1 PYTHONPATH=src python benchmarks/run_tail.py \
        --sim DATA/flight_64M [--what quality,planes] [--runs 3] --baseline MAIN/src

Each run is a whole child process (``python -m calidar`` through a small wrapper) whose last pass
is stamped: ``boresight`` when its last overlap-quality stage returns
(``pipelines.boresight_outputs.quality_stages``), ``quality`` when its lines' precisions are
computed (``pipelines.quality.line_precisions``, after the swath differences). The child writes
the wall time and its CPU (every thread, ``getrusage``) at that moment; the parent takes the
process's end from ``os.wait4`` (wall, CPU, peak RSS). Printed per command and tree: the whole run and the
tail (wall, CPU), medians, and the load at each run.
"""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

WRAPPER = r"""
import json, os, resource, sys, time
def stamp():
    r = resource.getrusage(resource.RUSAGE_SELF)
    with open(os.environ["TAIL_STAMP"], "w") as f:
        json.dump({"wall": time.time(), "cpu": r.ru_utime + r.ru_stime}, f)
import calidar.pipelines.boresight_outputs as bo, calidar.pipelines.quality as pq
def wrap(module, name):
    real = getattr(module, name)
    def stamped(*a, **k):
        out = real(*a, **k)
        stamp()
        return out
    setattr(module, name, stamped)
wrap(bo, "quality_stages")
wrap(pq, "line_precisions")
sys.argv = ["calidar"] + sys.argv[1:]
from calidar.__main__ import main
main()
"""


def run_once(src: Path, args: list[str], stamp: Path) -> dict:
    env = {**os.environ, "PYTHONPATH": str(src), "TAIL_STAMP": str(stamp)}
    t0 = time.time()
    p = subprocess.Popen([sys.executable, "-c", WRAPPER, *args], env=env,
                         stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    _, status, usage = os.wait4(p.pid, 0)
    t1 = time.time()
    if os.waitstatus_to_exitcode(status) != 0:
        raise SystemExit(f"{args[0]} with {src} failed: {status}")
    s = json.loads(stamp.read_text())
    cpu = usage.ru_utime + usage.ru_stime
    return {"wall": t1 - t0, "cpu": cpu, "tail_wall": t1 - s["wall"], "tail_cpu": cpu - s["cpu"],
            "peak_gib": usage.ru_maxrss / 2**20, "load": os.getloadavg()[0]}


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--sim", type=Path, required=True, help="strips/*.laz, sbet.out, sensor.toml")
    ap.add_argument("--what", default="quality,planes")
    ap.add_argument("--runs", type=int, default=3)
    ap.add_argument("--baseline", type=Path, required=True, help="another calidar src tree")
    a = ap.parse_args()
    strips = [str(p) for p in sorted((a.sim / "strips").glob("*.laz"))]
    here = Path(__file__).resolve().parents[1] / "src"
    work = Path(tempfile.mkdtemp(prefix="run_tail-"))
    results: dict = {}
    for r in range(a.runs):
        for what in a.what.split(","):
            for tag, src in (("branch", here), ("base", a.baseline)):
                out = work / f"{what}_{tag}_{r}"
                cmd = (["quality", *strips, "--out", str(out)] if what == "quality" else
                       ["boresight", *strips, "--trajectory", str(a.sim / "sbet.out"), "--sensor",
                        str(a.sim / "sensor.toml"), "--method", what, "--out", str(out)])
                res = run_once(src, cmd, work / "stamp.json")
                results.setdefault((what, tag), []).append(res)
                print(f"run {r + 1}: {what:8s} {tag:6s} whole {res['wall']:6.2f} s wall, "
                      f"{res['cpu']:6.2f} s CPU; tail {res['tail_wall']:5.2f} s wall, "
                      f"{res['tail_cpu']:5.2f} s CPU; peak {res['peak_gib']:.2f} GiB; "
                      f"load {res['load']:.2f}", flush=True)
    print("medians:")
    for (what, tag), rs in results.items():
        med = {k: float(np.median([x[k] for x in rs])) for k in rs[0]}
        print(f"  {what:8s} {tag:6s} whole {med['wall']:6.2f} s wall, {med['cpu']:6.2f} s CPU; "
              f"tail {med['tail_wall']:5.2f} s wall, {med['tail_cpu']:5.2f} s CPU; "
              f"peak {med['peak_gib']:.2f} GiB")


if __name__ == "__main__":
    main()
