"""Benchmark: tie planes and VGICP side by side on 8 simulated strips of about 1 million points.

    NUMBA_NUM_THREADS=1 OMP_NUM_THREADS=1 PYTHONPATH=src python benchmarks/strips_vgicp.py [--workers 2]
        [--trajectory-sigma 0.03,0.002]

Uses the survey of ``benchmarks/strips.py`` (airborne preset, 6 parallel lines in
alternate directions + 2 cross lines, cached under ``--cache``; simulation not timed).
Per method, timed: building the strips (read LAZ, one inverse georeferencing; shared),
then the calibration end to end with its stages summed over the outer iterations:
re-georeference, match (for VGICP split into preprocess = overlap crop, voxel
downsampling and covariances / register = VGICP alignment / correspond = nearest
neighbours, normals and selection, timed on the first iteration's pairs in-process) and
solve. The errors against the simulator's truth close each block.
"""

from __future__ import annotations

import argparse
import json
import os
import platform
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
from strips import ERRORS, simulate  # noqa: E402  (the shared 8-strip survey)

from calidar.pipelines.boresight import load_strips  # noqa: E402
from calidar.io.trajectory import read_trajectory  # noqa: E402
from calidar.sensor import Sensor  # noqa: E402
from calidar.strips.calibrate import calibrate  # noqa: E402
from calidar.strips.config import CalibrationConfig, StripSettings, TiePlanes, TrajectorySettings, Vgicp  # noqa: E402
from calidar.strips.parameters import truth_to_si  # noqa: E402
from calidar.strips.overlap import find_overlaps  # noqa: E402
from calidar.strips.vgicp import VgicpSettings, match_pair_vgicp  # noqa: E402

SETTINGS = {"planes": CalibrationConfig(matchers=(TiePlanes(),)), "vgicp": CalibrationConfig(matchers=(Vgicp(),))}


def vgicp_stages(strips, nominal: Sensor, settings: StripSettings = StripSettings(),
                 vgicp: VgicpSettings = VgicpSettings()) -> dict[str, float]:
    """Seconds per VGICP matching stage over every overlapping pair, nominal sensor."""
    by_id = {s.id: s for s in strips}
    overlaps, _ = find_overlaps({i: s.points for i, s in by_id.items()}, settings.overlap_cell_m,
                                settings.min_overlap_cells)
    timings: dict[str, float] = {}
    for o in overlaps:
        pa = by_id[o.a].georeference(nominal, o.index_a)
        pb = by_id[o.b].georeference(nominal, o.index_b)
        try:
            match_pair_vgicp(o.a, pa, o.b, pb, vgicp, timings)
        except Exception as e:  # a skipped pair still counts its time
            print(f"  pair {o.a}–{o.b}: {e}")
    return timings


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--density", type=float, default=1.7, help="simulator density (1.7 ≈ 8.6 M points)")
    ap.add_argument("--workers", type=int, default=None, help="Dask LocalCluster workers for the pair matching")
    ap.add_argument("--cache", type=Path, default=Path(tempfile.gettempdir()) / "calidar_bench_strips")
    ap.add_argument("--trajectory-sigma", default=None,
                    help="'POSITION_M,ATTITUDE_DEG': also estimate the trajectory errors (1 s blocks, 20 s / 3 s correlation)")
    args = ap.parse_args()
    sim = simulate(args.cache, args.density)

    t0 = time.perf_counter()
    nominal = Sensor.read(sim / "sensor.toml")
    strips, _ = load_strips(sorted((sim / "strips").glob("*.laz")), read_trajectory(sim / "sbet.out"), nominal)
    build = time.perf_counter() - t0
    truth_doc = json.loads((sim / "truth.json").read_text())

    n = sum(len(s) for s in strips)
    print(f"machine: {platform.machine()}, {os.cpu_count()} cores, python {platform.python_version()}; "
          f"NUMBA_NUM_THREADS={os.environ.get('NUMBA_NUM_THREADS')} OMP_NUM_THREADS={os.environ.get('OMP_NUM_THREADS')}; "
          f"workers={args.workers}")
    print(f"{len(strips)} strips, {n / 1e6:.2f} M points; read LAZ + build strips {build:.1f} s (shared)"
          + (f"; trajectory errors modelled ({args.trajectory_sigma})" if args.trajectory_sigma else ""))
    rows: dict[str, dict[str, float | str]] = {}
    model = None
    if args.trajectory_sigma:  # the benchmark's own option, read here
        pos, att_deg = (float(v) for v in args.trajectory_sigma.split(","))
        model = TrajectorySettings(sigma=(pos, float(np.radians(att_deg)))).model()
    for method, config in SETTINGS.items():
        t0 = time.perf_counter()
        result = calibrate(strips, nominal, config, trajectory=model, workers=args.workers)
        total = time.perf_counter() - t0
        row: dict[str, float | str] = {"outer iterations": len(result.outer), "pairs used": len(result.pairs),
                                       "observations (last)": result.outer[-1]["n_obs"]}
        for key in ("georeference_s", "match_s", "solve_s"):
            row[f"{key[:-2]} (all iterations) s"] = sum(o[key] for o in result.outer)
        row["calibrate end to end s"] = total
        row["build + calibrate s"] = total + build
        truth = truth_to_si(truth_doc, result.solution.parameters)
        for name in ERRORS:
            err = np.degrees(result.solution.values[name] - truth[name])
            row[f"{name} error / σ (deg)"] = f"{err:+.5f} / {np.degrees(result.solution.sigma[name]):.5f}"
        rows[method] = row
    stages = vgicp_stages(strips, nominal, SETTINGS["vgicp"])
    for stage in ("preprocess", "register", "correspond"):
        rows["vgicp"][f"  match: {stage} (iteration 1, in-process) s"] = stages.get(stage, 0.0)
        rows["planes"][f"  match: {stage} (iteration 1, in-process) s"] = "—"

    keys = list(dict.fromkeys(k for r in rows.values() for k in r))
    print(f"{'':48s} {'planes':>22s} {'vgicp':>22s}")
    for k in keys:
        cells = [rows[m].get(k, "—") for m in ("planes", "vgicp")]
        print(f"{k:48s} " + " ".join(f"{c:>22.2f}" if isinstance(c, float) else f"{c!s:>22s}" for c in cells))


if __name__ == "__main__":
    main()
