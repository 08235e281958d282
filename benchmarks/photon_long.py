"""Benchmark: a pass as long as a granule's — 2 000 km (about 10 M photons) — with 12 lit CCRs near
its middle, against the same CCR site on a 200 km pass (issue 19).

Each pass is simulated (not timed) and written as an ATL03 file; then the whole ``calidar ccr``
pipeline is timed on it (reading the file, the CCR sites, the maximum likelihood, 100 bootstrap
replicates, profile intervals, the surface, solution.json and report.html), on one thread.

Run: NUMBA_NUM_THREADS=1 OMP_NUM_THREADS=1 PYTHONPATH=src python benchmarks/photon_long.py [--seeds 1,2,3]
"""

from __future__ import annotations

import argparse
import os
import tempfile
import time
from pathlib import Path

from calidar.photon.parameters import GEOLOCATION
from calidar.pipelines.ccr import run_ccr
from calidar.pipelines.ccr_config import CCRConfig
from calidar.sim.photons import PhotonSimConfig, simulate_pass, write_pass


def run(length_m: float, seed: int, folder: Path) -> None:
    sim = simulate_pass(PhotonSimConfig(seed=seed, length=length_m, n_ccr=12, ccr_spacing=45.0))
    paths = write_pass(sim, folder)
    out = folder / "out"
    out.mkdir()
    c, w = time.process_time(), time.perf_counter()
    result = run_ccr([paths["atl03"]], paths["ccr"], out, CCRConfig(), truth_path=paths["truth"])
    cpu, wall = time.process_time() - c, time.perf_counter() - w
    errs = "  ".join(f"{k.split('_')[0]} {result.solution.values[k] - sim.truth[k]:+.3f}±{result.solution.sigma[k]:.3f}"
                     for k in GEOLOCATION)
    print(f"  {length_m / 1000:6.0f} km, {len(sim.beam):>10,} photons, seed {seed}: {cpu:5.1f} s CPU ({wall:5.1f} s wall); "
          f"error±σ (m) {errs}; verdict {result.verdict.status}", flush=True)


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--seeds", default="1")
    seeds = [int(s) for s in ap.parse_args().seeds.split(",")]
    print(f"load {os.getloadavg()[0]:.1f} on {os.cpu_count()} cores")
    with tempfile.TemporaryDirectory() as tmp:  # compile the numba kernels first
        run(1200.0, 99, Path(tmp))
    for seed in seeds:
        for length in (200_000.0, 2_000_000.0):
            with tempfile.TemporaryDirectory() as tmp:
                run(length, seed, Path(tmp))


if __name__ == "__main__":
    main()
