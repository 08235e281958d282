"""CPU seconds of the kernels that share calidar.cells' cell equations and the LAS scaling
(issue "tidy", 28 Nov, ninth session), on N points (default 10 M), best of 3 after a warm-up.

Run once per source tree and compare:
    NUMBA_NUM_THREADS=1 OMP_NUM_THREADS=1 PYTHONPATH=/work/main/src \
        /work/main/.venv/bin/python benchmarks/one_equation_speed.py
    NUMBA_NUM_THREADS=1 OMP_NUM_THREADS=1 PYTHONPATH=$PWD/src \
        /work/main/.venv/bin/python benchmarks/one_equation_speed.py
"""

import sys
import time

import numpy as np


def _best(f, repeat=3):
    f()
    best = np.inf
    for _ in range(repeat):
        t0 = time.process_time()
        f()
        best = min(best, time.process_time() - t0)
    return best


def main(n: int = 10_000_000) -> None:
    from calidar.ingest.cell_counts import _seconds_cells
    from calidar.ingest.chunk_pass import selected_points
    from calidar.ingest.held import scaled_integers, stored_integers
    from calidar.strips.moments_kernel import dense_moments, point_cell_keys
    from calidar.strips.overlap import cell_keys
    from calidar.strips.vgicp_kernels import cell_keys as vgicp_keys

    rng = np.random.default_rng(0)
    scales, offsets = np.array([0.001, 0.001, 0.001]), np.array([5e5, 5.4e6, 0.0])
    ints = [rng.integers(0, 2_000_000, n).astype(np.int32) for _ in "xyz"]
    xyz = scaled_integers(*ints, scales, offsets)
    c = {"X": ints[0], "Y": ints[1], "Z": ints[2], "gps_time": rng.uniform(0, 1e3, n),
         "point_source_id": rng.integers(1, 5, n).astype(np.uint16),
         "bits": rng.integers(0, 4, n).astype(np.uint8)}
    local = xyz - xyz.min(axis=0)
    lo = xyz[:, :2].min(axis=0)
    cases = {
        "scaled_integers": lambda: scaled_integers(*ints, scales, offsets),
        "stored_integers": lambda: stored_integers(xyz, scales, offsets),
        "selected_points": lambda: selected_points(c, 1, scales, offsets),
        "point_cell_keys": lambda: point_cell_keys(xyz, 2.0),
        "cell_keys (origin)": lambda: cell_keys(xyz, 2.0, lo),
        "dense_moments": lambda: dense_moments(local, 2.0),
        "_seconds_cells": lambda: _seconds_cells(c["gps_time"], xyz, 2.0),
        "vgicp cell_keys": lambda: vgicp_keys(xyz, lo, 2.0, 1001),
    }
    print(f"{n:,} points, CPU s (best of 3)")
    for name, f in cases.items():
        print(f"{name:22s} {_best(f):.3f}", flush=True)


if __name__ == "__main__":
    main(int(float(sys.argv[1])) if len(sys.argv) > 1 else 10_000_000)
