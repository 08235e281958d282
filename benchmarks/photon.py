"""Benchmark: one simulated pass of about one million photons (210 km, 12 lit CCRs).

Times (CPU of this process and wall clock; one thread) of
  - denoising every photon of the pass (what ``calidar denoise`` does per beam), and
  - the CCR calibration as ``calidar ccr`` runs it by default: the CCR sites prepared, the
    maximum likelihood, 100 bootstrap replicates, profile intervals and the 9 × 9 surface.

Run: NUMBA_NUM_THREADS=1 OMP_NUM_THREADS=1 PYTHONPATH=src python benchmarks/photon.py
"""

from __future__ import annotations

import os
import time

from calidar.photon.ccr import calibrate
from calidar.photon.denoise import denoise
from calidar.photon.parameters import GEOLOCATION
from calidar.photon.passes import SystemParameters, prepare_pass
from calidar.photon.search import SearchSettings
from calidar.photon.survey import CCRSurvey
from calidar.sim.photons import PhotonSimConfig, simulate_pass


def timed(fn, *args):
    c, w = time.process_time(), time.perf_counter()
    out = fn(*args)
    return out, time.process_time() - c, time.perf_counter() - w


def main() -> None:
    sim = simulate_pass(PhotonSimConfig(seed=1, length=210_000.0, n_ccr=12, ccr_spacing=45.0))
    survey = survey_of(sim)
    system = SystemParameters()
    warm = simulate_pass(PhotonSimConfig(seed=2, n_ccr=3))  # compile the numba kernels first
    calibrate([prepare_pass(warm.beam, survey_of(warm), system)], survey_of(warm), system,
              SearchSettings(bootstrap=2, surface_points=3))
    denoise(warm.beam.x, warm.beam.h)
    _, c0, w0 = timed(denoise, sim.beam.x, sim.beam.h)
    p, c1, w1 = timed(prepare_pass, sim.beam, survey, system, "bench")
    result, c2, w2 = timed(calibrate, [p], survey, system, SearchSettings())
    print(f"{len(sim.beam):,} photons; load {os.getloadavg()[0]:.1f} on {os.cpu_count()} cores")
    print(f"  denoise every photon: {c0:.2f} s CPU ({w0:.2f} s wall)")
    print(f"  CCR calibration: sites {c1:.2f} s + calibration {c2:.2f} s = {c1 + c2:.2f} s CPU "
          f"({w1 + w2:.2f} s wall; {len(p.x):,} photons near the CCRs)")
    u = result.uncertainty
    for k in GEOLOCATION:
        print(f"  {k:20s} error {result.solution.values[k] - sim.truth[k]:+.3f} m  σ {result.solution.sigma[k]:.3f} "
              f"(bootstrap {u.bootstrap[k]:.3f}, Cramér–Rao {u.cramer_rao[k]:.3f})")


def survey_of(sim) -> CCRSurvey:
    return CCRSurvey(sim.ccr_id, sim.ccr_height, lat=sim.ccr_lat, lon=sim.ccr_lon)


if __name__ == "__main__":
    import argparse

    argparse.ArgumentParser(description=__doc__.split("\n")[0]).parse_args()  # no options; --help
    main()
