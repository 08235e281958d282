"""Benchmark: one round of VGICP pair matching in this process against two worker processes.

    NUMBA_NUM_THREADS=1 OMP_NUM_THREADS=1 PYTHONPATH=src python benchmarks/pair_processes.py [--size 8.75] [--rounds 3]

The 8-strip survey of ``benchmarks/strips_scale.py`` (cached under ``--cache``, not timed), its strips built as
``calidar boresight`` builds them and georeferenced with the nominal sensor; every overlapping pair matched
as the calibrator matches one outer iteration's pairs (:func:`calidar.strips.outer_loop.match_or_error`),
interleaved: in this process (as before), then on :func:`calidar.strips.processes.pair_processes`' two
workers (the pool started once, its start timed on its own, as a calibration's first round pays it).
Printed per round the wall seconds of each, this process's CPU seconds and the workers' (summed over
the tasks, as each worker measured it), and whether the correspondences
are identical (A, B, normals, σ bit for bit). On a machine shared by other work, wall times measure the
queue as much as the code; the load average is printed with each round.
"""

from __future__ import annotations

import argparse
import os
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
from survey_pairs import survey_pairs  # noqa: E402  (the shared survey's pairs, as vgicp_pairs.py sets them up)


def same(x, y) -> bool:
    """Two correspondence sets (or the errors that skipped a pair) equal bit for bit."""
    if not hasattr(x, "A"):
        return str(x) == str(y)
    return ((x.A != y.A).nnz == 0 and (x.B != y.B).nnz == 0 and np.array_equal(x.normal, y.normal)
            and np.array_equal(np.asarray(x.sigma_m), np.asarray(y.sigma_m)))


def timed(func, *args):
    """(CPU seconds of the process that ran it, ``func(*args)``): what a worker spent on a task."""
    t = time.process_time()
    out = func(*args)
    return time.process_time() - t, out


def main() -> None:
    from calidar.strips.outer_loop import match_or_error
    from calidar.strips.matchers import Vgicp
    from calidar.strips.processes import map_in_processes, pair_processes

    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--size", type=float, default=8.75, help="survey size, million points")
    ap.add_argument("--cache", type=Path, default=Path(tempfile.gettempdir()) / "calidar_bench_strips_scale")
    ap.add_argument("--rounds", type=int, default=3)
    args = ap.parse_args()
    matcher = Vgicp()
    tasks = [(matcher, *pair) for pair in survey_pairs(args.cache, args.size)]
    print(f"{len(tasks)} pairs, {sum(len(t[2]) + len(t[4]) for t in tasks) / 1e6:.2f} M points; "
          f"{os.cpu_count()} cores", flush=True)
    ours, theirs = [], []
    with pair_processes(2) as pool:
        clock = time.perf_counter()
        map_in_processes(pool, abs, [(-1,), (-2,)])  # the workers started (imports)
        print(f"pool start {time.perf_counter() - clock:.2f} s wall", flush=True)
        for k in range(args.rounds):
            wall, cpu = time.perf_counter(), time.process_time()
            local = [match_or_error(*t) for t in tasks]
            ours.append((time.perf_counter() - wall, time.process_time() - cpu))
            load = os.getloadavg()[0]
            wall, cpu = time.perf_counter(), time.process_time()
            spent = map_in_processes(pool, timed, [(match_or_error, *t) for t in tasks])
            theirs.append((time.perf_counter() - wall, time.process_time() - cpu))
            remote = [r for _, r in spent]
            print(f"round {k + 1}: in process {ours[-1][0]:.2f} s wall ({ours[-1][1]:.2f} s CPU); two workers "
                  f"{theirs[-1][0]:.2f} s wall (this process {theirs[-1][1]:.2f} s CPU, the workers "
                  f"{sum(c for c, _ in spent):.2f} s CPU in the tasks); identical "
                  f"{all(same(x, y) for x, y in zip(local, remote))}; load {load:.1f} → {os.getloadavg()[0]:.1f}",
                  flush=True)
    a, b = np.median([t[0] for t in ours]), np.median([t[0] for t in theirs])
    print(f"median wall: in process {a:.2f} s, two workers {b:.2f} s ({a / b:.2f}× faster)")


if __name__ == "__main__":
    main()
