"""CPU of ``calidar trajectory``'s reconstruction against reading the same file with laspy + lazrs (issue #30:
at most 2× the read), interleaved (read, reconstruct, read, …) ``--repeats`` times, per file: the medians of
each and of the pairs' ratios, CPU seconds of this process (all threads) and wall. One warm-up run first
(numba's compiled kernels are cached on disk, but the first call still loads them).

    PYTHONPATH=src nice -n 10 python benchmarks/trajectory_speed.py FILE... [--repeats 7]

e.g. one simulated airborne strip (``benchmarks/trajectory_reconstruction.py`` writes them under
/tmp/calidar_trajrec_bench/airborne_0_0.0/strips/) and the real files of $CALIDAR_REAL_DATA.
"""

from __future__ import annotations

import argparse
import time
from pathlib import Path

import numpy as np

from calidar.pipelines.trajectory import reconstruct_trajectory


def _cpu(fn) -> tuple[float, float]:
    c, w = time.process_time(), time.perf_counter()
    fn()
    return time.process_time() - c, time.perf_counter() - w


def measure(path: Path, repeats: int) -> dict:
    import laspy

    reconstruct_trajectory([path])  # warm-up
    pairs = []
    for _ in range(repeats):
        rc, rw = _cpu(lambda: laspy.read(path))
        fc, fw = _cpu(lambda: reconstruct_trajectory([path]))
        pairs.append((rc, rw, fc, fw))
    a = np.array(pairs)
    med = np.median(a, axis=0)
    return {"file": str(path), "points": int(laspy.open(path).header.point_count), "repeats": repeats,
            "read_cpu_s": med[0], "read_wall_s": med[1], "reconstruct_cpu_s": med[2], "reconstruct_wall_s": med[3],
            "ratio_cpu": float(np.median(a[:, 2] / a[:, 0])), "ratio_cpu_pairs": (a[:, 2] / a[:, 0]).round(2).tolist()}


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("files", nargs="+", type=Path)
    ap.add_argument("--repeats", type=int, default=7)
    a = ap.parse_args()
    print("| file | points | read CPU [s] | reconstruct CPU [s] | ratio (median of pairs) | pairs |\n|---|---|---|---|---|---|")
    for f in a.files:
        r = measure(f, a.repeats)
        print(f"| {f.name} | {r['points']:,} | {r['read_cpu_s']:.3f} | {r['reconstruct_cpu_s']:.3f} | "
              f"{r['ratio_cpu']:.2f}× | {' '.join(f'{v:.2f}' for v in r['ratio_cpu_pairs'])} |", flush=True)


if __name__ == "__main__":
    main()
