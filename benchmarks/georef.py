"""Forward georeferencing speed: N points (default 10 million) with trajectory interpolation.

Times the full ``calidar.georef.forward`` call (range correction, scanner directions,
position interpolation, quaternion SLERP, the lidar equation) on a 200 Hz trajectory, and a
plain memory copy (np.copy) of the same input and output arrays for scale; and
``calidar.georef.inverse`` of the resulting points.

    NUMBA_NUM_THREADS=1 OMP_NUM_THREADS=1 PYTHONPATH=src python benchmarks/georef.py [N]
"""

from __future__ import annotations

import os
import platform
import time

import numpy as np

from calidar import georef
from calidar.sensor import Sensor
from calidar.trajectory import Trajectory


def machine() -> str:
    """CPU model (Linux) or architecture, logical core count, Python and numpy versions."""
    model = platform.machine()
    try:
        with open("/proc/cpuinfo", encoding="utf-8") as f:
            model = next(ln.split(":", 1)[1].strip() for ln in f if ln.startswith("model name"))
    except (OSError, StopIteration):
        pass
    return f"{model}, {os.cpu_count()} logical cores, Python {platform.python_version()}, numpy {np.__version__}"


def best_of(fn, repeats: int = 3) -> float:
    """Shortest CPU time of this (single-threaded) process over ``repeats`` calls, s.

    CPU time rather than wall time: on a shared machine wall time mostly measures the
    other processes. The wall time of the same calls is printed too.
    """
    cpu, wall = [], []
    for _ in range(repeats):
        w0, c0 = time.perf_counter(), time.process_time()
        fn()
        cpu.append(time.process_time() - c0)
        wall.append(time.perf_counter() - w0)
    print(f"  ({fn.__name__}: best wall time {min(wall):.3f} s, best CPU time {min(cpu):.3f} s)")
    return min(cpu)


def main(n: int = 10_000_000) -> None:
    duration = 600.0
    m = int(duration * 200) + 1
    tt = 300000.0 + np.linspace(0.0, duration, m)
    rng = np.random.default_rng(0)
    traj = Trajectory(
        tt, np.radians(45.0) + np.linspace(0, 6e-3, m), np.radians(7.0) + np.linspace(0, 6e-3, m), np.full(m, 1500.0),
        0.05 * np.sin(tt), 0.02 * np.cos(tt / 3), np.full(m, 0.7) + 0.01 * np.sin(tt / 7),
    )
    sensor = Sensor(boresight_roll=1e-3, boresight_pitch=-2e-3, boresight_yaw=5e-4, lever_arm_x=0.2, range_offset=0.01)
    t = np.sort(rng.uniform(tt[0], tt[-1], n))
    rng_m = rng.uniform(1000.0, 2000.0, n)
    ang = rng.uniform(-0.6, 0.6, n)
    traj.ecef, traj.q_eb  # build the per-trajectory caches once, as any real run does
    georef.forward(traj, sensor, t[:1000], rng_m[:1000], ang[:1000])  # JIT compile / load the cache
    out = np.empty((n, 3))

    def forward():
        return georef.forward(traj, sensor, t, rng_m, ang)

    def inverse():
        return georef.inverse(traj, sensor, t, points)

    def memory_copy():
        return np.copy(t), np.copy(rng_m), np.copy(ang), np.copy(out)

    t_fwd = best_of(forward)
    points = forward()
    t_inv = best_of(inverse)
    t_copy = best_of(memory_copy)
    moved = t.nbytes + rng_m.nbytes + ang.nbytes + out.nbytes
    print(f"machine: {machine()}; one thread")
    print(f"forward georeferencing of {n:,} points ({m:,} trajectory records, SLERP): {t_fwd:.3f} s "
          f"= {n / t_fwd / 1e6:.1f} M points/s")
    print(f"inverse georeferencing (vectors, ranges, scan angles) of the same points: {t_inv:.3f} s "
          f"= {n / t_inv / 1e6:.1f} M points/s")
    print(f"np.copy of the same arrays ({moved / 1e9:.2f} GB: t, range, angle, output): {t_copy:.3f} s "
          f"= {2 * moved / t_copy / 1e9:.1f} GB/s read+write")
    print(f"ratio georeferencing / memory copy: {t_fwd / t_copy:.1f}")


if __name__ == "__main__":
    import argparse

    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("n", nargs="?", type=float, default=10_000_000, help="points (default 1e7)")
    main(int(parser.parse_args().n))
