"""Range calibration on many simulated data sets through ``calidar range-cal``'s pipeline (written
to a file and read back): accuracy, σ honesty, interval coverage, verdicts, speed.

    NUMBA_NUM_THREADS=1 OMP_NUM_THREADS=1 PYTHONPATH=src python benchmarks/rangecal_coverage.py [runs]
"""

import tempfile
import time
from collections import Counter
from pathlib import Path

import numpy as np

from calidar.pipelines.rangecal import calibrate_file, run_simulate_total_station, simulation_config


def main(runs: int = 200) -> None:
    hits = {"range_offset": 0, "range_scale": 0}
    err, sig, t_cal, status = [], [], 0.0, Counter()
    config = simulation_config()
    with tempfile.TemporaryDirectory() as tmp:
        for seed in range(runs):
            _, _, path = run_simulate_total_station(Path(tmp), seed, config)
            t0 = time.perf_counter()
            res, verdict, truth = calibrate_file(path, truth=Path(tmp) / "truth.json")
            t_cal += time.perf_counter() - t0
            status[verdict.status] += 1
            for name in hits:
                lo, hi = res.fit.interval(name)
                hits[name] += lo <= truth[name] <= hi
            err.append(res.solution.values["range_offset"] - truth["range_offset"])
            sig.append(res.solution.sigma["range_offset"])
    err, sig = np.array(err), np.array(sig)
    print(f"{runs} runs, {len(res.observations)} targets each")
    for name, n in hits.items():
        print(f"95 % interval of {name} contains the truth in {100 * n / runs:.1f} % of runs")
    print(f"range_offset: RMS error {1e3 * np.sqrt(np.mean(err**2)):.3f} mm, mean σ {1e3 * sig.mean():.3f} mm, "
          f"std(error/σ) {np.std(err / sig):.3f}")
    print(f"verdicts: {dict(status)}")
    print(f"read + calibrate + verdict: {1e3 * t_cal / runs:.1f} ms per data set")


if __name__ == "__main__":
    import argparse

    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("runs", nargs="?", type=int, default=200, help="simulated data sets (default 200)")
    main(parser.parse_args().runs)
