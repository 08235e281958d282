"""Benchmark: a billion-point flight simulated to LAZ files on disk and calibrated from them, streamed.

    nice -n 10 env NUMBA_NUM_THREADS=1 OMP_NUM_THREADS=1 PYTHONPATH=src python benchmarks/billion.py \
        [--sizes 1000] [--method planes] [--cache DIR] [--max-load 4]

The survey of ``benchmarks/strips_scale.py`` (8 airborne strips, 6 parallel flown in alternate
directions + 2 cross lines, 3 cm / 0.002° trajectory errors and their smrmsg.out, boresight errors
of a few hundredths of a degree) simulated at the density that gives ≈ ``--sizes`` million points,
each strip written to LAZ as soon as it is simulated (one strip in memory at a time, ≈ 100 B a
point in the simulator: a billion points in 8 strips needs ≈ 13 GB while simulating), cached under
``--cache`` (not timed; the simulator makes ≈ 70 000 points a second on one core: a billion points
take hours). Then ``calidar boresight`` end to end in a child process (default options: the
streamed ingest, each point decompressed once, what later passes need kept on disk — 25 B a point,
25 GB for a billion; calibration; the three overlap-quality stages of the whole strips; report
and outputs): wall time, peak RSS (``os.wait4``), the boresight's error against the truth in
units of its σ, and the load average. With several sizes, time ∝ points^k is fitted and
extrapolated to 10⁹ points. A size is not started while the 1-minute load average exceeds
``--max-load`` (waits up to 10 minutes, then runs and says so): the machine is shared.
"""

from __future__ import annotations

import argparse
import os
import platform
import shutil
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
from strips import ERRORS  # noqa: E402  (the survey's mounting errors)
from strips_scale import exponent, run, simulate  # noqa: E402  (the 8-strip survey at a size, a child run)

HELD_BYTES_PER_POINT = 25  #: calidar.ingest.source.HELD_BYTES_PER_POINT


def wait_for_load(max_load: float, patience_s: float = 600.0) -> float:
    """The load average once it is below ``max_load`` (or after ``patience_s``)."""
    start = time.monotonic()
    while os.getloadavg()[0] > max_load and time.monotonic() - start < patience_s:
        time.sleep(10)
    return os.getloadavg()[0]


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--sizes", default="1000", help="survey sizes, million points (validate with 8.75,64)")
    ap.add_argument("--method", default="planes", choices=["planes", "vgicp"])
    ap.add_argument("--cache", type=Path, default=Path(tempfile.gettempdir()) / "calidar_bench_strips_scale")
    ap.add_argument("--max-load", type=float, default=4.0)
    args = ap.parse_args()
    sizes = [float(s) for s in args.sizes.split(",")]
    free = shutil.disk_usage(tempfile.gettempdir()).free
    need = HELD_BYTES_PER_POINT * max(sizes) * 1e6
    print(f"machine: {platform.machine()}, {os.cpu_count()} cores, python {platform.python_version()}; "
          f"NUMBA_NUM_THREADS={os.environ.get('NUMBA_NUM_THREADS')}; temp folder {free / 1e9:.0f} GB free "
          f"({need / 1e9:.1f} GB held points at the largest size)", flush=True)
    rows = []
    for m in sizes:
        sim = simulate(args.cache, m)
        load = wait_for_load(args.max_load)
        r = run(sim, args.method)
        rows.append(r)
        z = ", ".join(f"{(r['values'][k] - r['truth'][k]) / r['sigma'][k]:+.1f}" for k in ERRORS)
        err = ", ".join(f"{np.degrees(r['values'][k] - r['truth'][k]) * 3600:+.1f}″" for k in ERRORS)
        print(f"{r['points'] / 1e6:8.1f} M points: {r['wall_s']:7.1f} s wall ({r['wall_s'] / r['points'] * 1e6:.3f} s per "
              f"M points; ingest {r['ingest_s']:.1f} s, calibrate {r['calibrate_s']:.1f} s, quality {r['quality_s']:.1f} "
              f"s), peak {r['rss_gib']:.2f} GiB; boresight error {err} = {z} σ (roll, pitch, yaw); "
              f"load {load:.1f} → {os.getloadavg()[0]:.1f}", flush=True)
    if len(rows) > 1:
        points, walls = [r["points"] for r in rows], [r["wall_s"] for r in rows]
        k = exponent(points, walls)
        at = walls[-1] * (1e9 / points[-1]) ** k
        print(f"wall time ∝ points^{k:.2f} over {points[0] / 1e6:.0f}–{points[-1] / 1e6:.0f} M: 10⁹ points ≈ "
              f"{at / 60:.1f} min (from the largest size)", flush=True)


if __name__ == "__main__":
    main()
