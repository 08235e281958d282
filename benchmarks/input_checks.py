"""Cost of the input checks of issue 27 on a simulated UAV strip (LAZ 1.4, format 6).

Times ``calidar inverse`` (the pipeline, streamed in 2 M-point chunks) with and without the
geometry check (:class:`calidar.ingest.plausibility.GeometryCheck`: 1 000 points a chunk
against the trajectory), the LAZ point-count check (chunk table and the layered chunks' own
counts; uncached), the per-chunk bounds check (one min/max per axis) and boresight's ingest of
two strips with and without the geometry checks, as CPU time of this process, best of 3 (ingest: 1).

    NUMBA_NUM_THREADS=1 PYTHONPATH=src nice -n 10 python benchmarks/input_checks.py [density]
"""

from __future__ import annotations

import sys
import tempfile
import time
from pathlib import Path

import laspy
import numpy as np


def best_of(fn, repeats: int = 3) -> float:
    """Shortest CPU time (s) of this process over ``repeats`` calls."""
    out = []
    for _ in range(repeats):
        t0 = time.process_time()
        fn()
        out.append(time.process_time() - t0)
    return min(out)


def main(density: float = 2.0) -> None:
    from calidar.io import las_checks
    from calidar.pipelines import georef, plausibility
    from calidar.sim.survey import simulate_survey, survey_config

    root = Path(tempfile.mkdtemp(prefix="calidar-input-checks-"))
    simulate_survey(survey_config("uav", density=density)).write(root / "sim", force=True)
    strip, sbet, sensor = root / "sim" / "strips" / "line_001.laz", root / "sim" / "sbet.out", root / "sim" / "sensor.toml"
    header = laspy.open(strip).header
    n = header.point_count

    def inverse():
        georef.inverse_points(strip, sbet, root / "v.csv", sensor=sensor, force=True, notes=[])

    with_check = best_of(inverse)
    add = plausibility.GeometryCheck.add
    plausibility.GeometryCheck.add = lambda *a, **k: None
    try:
        without = best_of(inverse)
    finally:
        plausibility.GeometryCheck.add = add

    def count():
        las_checks._laz_count_problem.cache_clear()
        las_checks.check_laz_count(laspy.open(strip).header, strip)

    count_s = best_of(count)
    from calidar.pipelines.inputs import load_trajectory
    from calidar.ingest.strips import StripIngest
    from calidar.sensor import Sensor

    traj, model = load_trajectory(sbet), Sensor.read(sensor)
    pair = sorted((root / "sim" / "strips").glob("*.laz"))[:2]
    ingest = best_of(lambda: StripIngest().read(pair, traj, model), 1)
    plausibility.GeometryCheck.add = lambda *a, **k: None
    try:
        ingest_without = best_of(lambda: StripIngest().read(pair, traj, model), 1)
    finally:
        plausibility.GeometryCheck.add = add
    xyz = np.random.default_rng(0).uniform(header.mins, header.maxs, (2_000_000, 3))
    limits = las_checks.bounds_tolerance(header)
    bounds_s = best_of(lambda: las_checks.check_bounds(xyz, limits, header, strip, 0))
    print(f"strip {strip.name}: {n:,} points ({strip.stat().st_size / 1e6:.1f} MB LAZ)")
    print(f"inverse with the geometry check {with_check:.3f} s, without {without:.3f} s: "
          f"+{with_check - without:.3f} s ({(with_check - without) / without:+.1%})")
    print(f"LAZ point-count check (uncached): {count_s * 1e3:.2f} ms")
    print(f"boresight's ingest of 2 strips with the geometry checks {ingest:.2f} s, without {ingest_without:.2f} s "
          f"(+{ingest - ingest_without:.2f} s; the scan-angle layer is decompressed in both)")
    print(f"bounds check of a 2 M-point chunk: {bounds_s * 1e3:.1f} ms")


if __name__ == "__main__":
    main(float(sys.argv[1]) if len(sys.argv) > 1 else 2.0)
