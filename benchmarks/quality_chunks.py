"""Benchmark: the per-point CPU of ``calidar quality``'s two passes and of the boresight's
overlap-quality re-georeferencing, on chunks held in memory (no decompression), for one calidar
source tree — run it for two (e.g. main's and this checkout's) one after the other.

    nice -n 10 env NUMBA_NUM_THREADS=1 python benchmarks/quality_chunks.py --src src \\
        --laz DATA/flight_64M/strips/line_001.laz \
        --survey /tmp/calidar_bench_strips_scale/airborne_8_strips_d1.7

First pass: :func:`calidar.ingest.lines.index_flight_lines` with ``calidar quality``'s
:class:`~calidar.ingest.cell_counts.CellCounts` (counts, held rows written to a temporary folder,
the flight-line bookkeeping) over ``--chunks`` chunks of 500 000 points of ``--laz`` read once
beforehand; second pass: the held points of the first selection back and their 2 m cell moments.
Re-georeferencing: ``points_tile_linear`` + ``moved_versions`` of three stages (delivered, a new
mounting, a new mounting on another trajectory) over up to 4 chunks of a strip of ``--survey``
(a benchmarks/strips_scale.py survey). Printed: CPU ns a point, medians of ``--repeat`` rounds
after one unmeasured round.
"""

from __future__ import annotations

import argparse
import sys
import tempfile
import time
from dataclasses import replace
from pathlib import Path

import numpy as np


def quality_passes(laz: Path, n_chunks: int, repeat: int) -> tuple[float, float, int]:
    """(first pass, second pass) CPU s a point, medians, and the points."""
    import calidar.ingest.lines as lines
    from calidar.ingest.cell_counts import CellCounts, Metric, held_chunks
    from calidar.ingest.held import HeldPoints
    from calidar.io.las import iter_las_fields
    from calidar.strips.selection import FIELDS, PointSelection

    names = ("point_source_id", "classification", "gps_time", "x", "y", "z", "X", "Y", "Z",
             *FIELDS[1:])
    chunks = []
    for c in iter_las_fields(laz, names, 500_000):
        chunks.append(c)
        if len(chunks) == n_chunks:
            break
    lines.iter_las_fields = lambda path, names, chunk_points: iter(chunks)  # held in memory
    lines.prefetched = lambda items: items
    lines._check_alike = lambda paths, options: None
    lines.check_distinct = lambda paths: None
    rules = [PointSelection("ground", (2,)), PointSelection("last returns")]

    def one() -> tuple[float, float]:
        with tempfile.TemporaryDirectory() as d:
            counts = CellCounts({laz: rules}, Metric(), 5.0, HeldPoints(Path(d)))
            t0 = time.process_time()
            lines.index_flight_lines([laz], on_chunk=counts, fields=names[3:])
            t1 = time.process_time()
            for xyz, _, _ in held_chunks(counts.held, laz, 0, Metric()):
                from calidar.strips.cell_moments import CellMoments

                CellMoments.of_points(xyz, 2.0)
            return t1 - t0, time.process_time() - t1

    one()
    runs = [one() for _ in range(repeat)]
    n = sum(len(c["gps_time"]) for c in chunks)
    return float(np.median([r[0] for r in runs])) / n, float(np.median([r[1] for r in runs])) / n, n


def regeoref(survey: Path, repeat: int) -> tuple[float, int]:
    """tile_linear + moved_versions CPU s a point (median) and the points."""
    from calidar.ingest.regeoref import moved_versions
    from calidar.ingest.times import FileTimes, points_tile_linear
    from calidar.io.las import iter_las_chunks, las_time_system
    from calidar.io.trajectory import read_trajectory
    from calidar.sensor import Sensor

    traj, sensor = read_trajectory(survey / "sbet.out"), Sensor.read(survey / "sensor.toml")
    path = sorted((survey / "strips").glob("*.laz"))[2]
    times = FileTimes(path, traj, las_time_system(path))
    chunks = []
    for c in iter_las_chunks(path, 500_000):
        chunks.append((c, times.feed(c.gps_time)))
        if len(chunks) == 4:
            break
    moved = replace(sensor, boresight_roll=sensor.boresight_roll + 1e-3)
    models = [None, (moved, traj), (moved, replace(traj, height=traj.height + 0.01))]

    def one() -> float:
        t0 = time.process_time()
        for c, t in chunks:
            moved_versions(traj, sensor, models, t, points_tile_linear(c))
        return time.process_time() - t0

    one()
    n = sum(len(t) for _, t in chunks)
    return float(np.median([one() for _ in range(repeat)])) / n, n


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--src", type=Path, default=Path(__file__).resolve().parents[1] / "src")
    ap.add_argument("--laz", type=Path, required=True)
    ap.add_argument("--survey", type=Path)
    ap.add_argument("--chunks", type=int, default=8)
    ap.add_argument("--repeat", type=int, default=5)
    args = ap.parse_args()
    sys.path.insert(0, str(args.src.resolve()))
    first, second, n = quality_passes(args.laz, args.chunks, args.repeat)
    print(f"{args.src}: quality first pass {first * 1e9:.0f} ns a point, second pass "
          f"{second * 1e9:.0f} ns ({n / 1e6:.1f} M points, medians of {args.repeat})")
    if args.survey:
        per, n = regeoref(args.survey, args.repeat)
        print(f"{args.src}: stages' tile_linear + moved_versions {per * 1e9:.0f} ns a point "
              f"({n / 1e6:.2f} M points)")


if __name__ == "__main__":
    main()
