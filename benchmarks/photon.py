"""Benchmark: denoise + CCR-calibrate one simulated pass of about one million photons.

Run: NUMBA_NUM_THREADS=1 OMP_NUM_THREADS=1 PYTHONPATH=src python benchmarks/photon.py
"""

from __future__ import annotations

import time

from calidar.photon.ccr import PARAMETERS, CCRSurvey, SearchSettings, SystemParameters, calibrate, prepare_pass
from calidar.sim.photons import PhotonSimConfig, simulate_pass


def main() -> None:
    sim = simulate_pass(PhotonSimConfig(seed=1, length=210_000.0, n_ccr=12, ccr_spacing=45.0))
    survey = CCRSurvey(sim.ccr_id, sim.ccr_height, lat=sim.ccr_lat, lon=sim.ccr_lon)
    system = SystemParameters()
    t0 = time.perf_counter()
    p = prepare_pass(sim.beam, system, "bench")
    t1 = time.perf_counter()
    result = calibrate([p], survey, system, SearchSettings())
    t2 = time.perf_counter()
    print(f"{len(sim.beam):,} photons: denoise + ground {t1 - t0:.2f} s, CCR calibration {t2 - t1:.2f} s, "
          f"total {t2 - t0:.2f} s")
    for k in PARAMETERS:
        print(f"  {k:20s} error {result.solution.values[k] - sim.truth[k]:+.3f} m (σ {result.solution.sigma[k]:.3f})")


if __name__ == "__main__":
    main()
