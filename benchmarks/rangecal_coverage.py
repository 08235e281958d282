"""Range calibration on many simulated data sets: accuracy, σ honesty, interval coverage, speed.

    NUMBA_NUM_THREADS=1 OMP_NUM_THREADS=1 PYTHONPATH=src python benchmarks/rangecal_coverage.py [runs]
"""

import sys
import time

import numpy as np

from calidar.rangecal import calibrate, truth_parameters
from calidar.sim.total_station import simulate_total_station


def main(runs: int = 200) -> None:
    hits = {"range_offset": 0, "range_scale": 0}
    err, sig, t_cal = [], [], 0.0
    for seed in range(runs):
        obs, truth = simulate_total_station(seed)
        t0 = time.perf_counter()
        res = calibrate(obs)
        t_cal += time.perf_counter() - t0
        t = truth_parameters(truth)
        for name in hits:
            lo, hi = res.fit.interval(name)
            hits[name] += lo <= t[name] <= hi
        err.append(res.solution.values["range_offset"] - t["range_offset"])
        sig.append(res.solution.sigma["range_offset"])
    err, sig = np.array(err), np.array(sig)
    print(f"{runs} runs, {len(obs)} targets each")
    for name, n in hits.items():
        print(f"95 % interval of {name} contains the truth in {100 * n / runs:.1f} % of runs")
    print(f"range_offset: RMS error {1e3 * np.sqrt(np.mean(err**2)):.3f} mm, mean σ {1e3 * sig.mean():.3f} mm, "
          f"std(error/σ) {np.std(err / sig):.3f}")
    print(f"calibrate(): {1e3 * t_cal / runs:.1f} ms per data set")


if __name__ == "__main__":
    main(int(sys.argv[1]) if len(sys.argv) > 1 else 200)
