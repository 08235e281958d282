"""Benchmark: calidar's VGICP matching of each strip pair against small_gicp's own registration of the same crop.

    NUMBA_NUM_THREADS=1 OMP_NUM_THREADS=1 PYTHONPATH=src python benchmarks/vgicp_pairs.py [--size 8.75] [--repeat 3]
        [--sim DATA/flight_8.75M]

The 8-strip survey of ``benchmarks/strips_scale.py`` (cached under ``--cache``, not timed), its strips
built as ``calidar boresight`` builds them (streamed ingest, 300 000 points per strip) and
georeferenced with the nominal sensor. For every overlapping pair, in one run and interleaved
(ours, theirs, ours, …, ``--repeat`` times each): :func:`calidar.strips.vgicp.match_pair_vgicp`
(crop to the overlap, coarse-to-fine VGICP registration, correspondences and their planes) and
``small_gicp.align(a, b, registration_type="VGICP")`` on the same overlap crop, at its defaults
(0.25 m downsampling, 1 m voxels) and at the downsampling and voxel of calidar's finest stage
(one registration; calidar then finds the correspondences), one
thread, timed in CPU seconds of this process
(``time.process_time``: on a shared machine the CPU a call takes, not the wall clock it waited).
Printed per pair the medians and the ratio, and over all pairs the sums and their ratio; the
calidar stages (preprocess / register / correspond, CPU seconds) summed over the pairs.
``--register-only``: calidar's :func:`calidar.strips.vgicp.register` alone on the crop (as
``match_pair_vgicp`` calls it), without the crop and the correspondences.
"""

from __future__ import annotations

import argparse
import os
import platform
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
from survey_pairs import survey_pairs  # noqa: E402  (the shared survey's pairs, as pair_processes.py sets them up)


def main() -> None:
    import small_gicp

    from calidar.strips.vgicp import VgicpSettings, match_pair_vgicp, overlap_masks, register

    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--size", type=float, default=8.75, help="survey size, million points")
    ap.add_argument("--cache", type=Path, default=Path(tempfile.gettempdir()) / "calidar_bench_strips_scale")
    ap.add_argument("--sim", type=Path, help="a survey simulated already (strips/*.laz, sbet.out, "
                    "sensor.toml), e.g. large_flight.py's flight_8.75M, instead of --size/--cache")
    ap.add_argument("--repeat", type=int, default=3)
    ap.add_argument("--register-only", action="store_true",
                    help="time calidar's registration alone")
    args = ap.parse_args()
    pairs = survey_pairs(args.cache, args.size, args.sim)
    settings = VgicpSettings()
    print(f"machine: {platform.machine()}, {os.cpu_count()} cores, python {platform.python_version()}; "
          f"NUMBA_NUM_THREADS={os.environ.get('NUMBA_NUM_THREADS')}; load average {os.getloadavg()[0]:.1f}; "
          f"{len(pairs)} pairs", flush=True)
    ours_all, theirs_all, same_all, stages = [], [], [], {}
    for a, pa, b, pb in pairs:
        in_a, in_b, area = overlap_masks(pa, pb, settings.overlap_cell_m)
        origin = pa[in_a].mean(axis=0)
        crop_a, crop_b = pa[in_a] - origin, pb[in_b] - origin
        # calidar's finest registration stage (strips.vgicp.register): its downsampling and voxel
        down = max(settings.downsampling_ratio * min(settings.voxel_m), np.sqrt(area / settings.max_registration_points))
        voxel = max(min(settings.voxel_m), 2.0 * down)
        ours, theirs, same = [], [], []
        for _ in range(args.repeat):
            t = time.process_time()
            try:
                if args.register_only:
                    register(crop_a, crop_b, settings, area)
                else:
                    match_pair_vgicp(a, pa, b, pb, settings, stages)
            except Exception as e:  # a skipped pair still counts its time
                print(f"  pair {a}–{b}: {e}")
            ours.append(time.process_time() - t)
            t = time.process_time()
            small_gicp.align(crop_a, crop_b, registration_type="VGICP", num_threads=1)
            theirs.append(time.process_time() - t)
            t = time.process_time()
            small_gicp.align(crop_a, crop_b, registration_type="VGICP", downsampling_resolution=down,
                             voxel_resolution=voxel, num_threads=1)
            same.append(time.process_time() - t)
        ours_all.append(np.median(ours))
        theirs_all.append(np.median(theirs))
        same_all.append(np.median(same))
        print(f"pair {a}–{b}: {len(crop_a):7d} + {len(crop_b):7d} points: calidar {ours_all[-1]:.3f} s; small_gicp "
              f"align, defaults {theirs_all[-1]:.3f} s ({ours_all[-1] / theirs_all[-1]:.2f}×), at calidar's finest "
              f"stage ({down:.2f} m, voxel {voxel:.2f} m) {same_all[-1]:.3f} s ({ours_all[-1] / same_all[-1]:.2f}×)",
              flush=True)
    for label, ref in (("defaults", theirs_all), ("calidar's finest stage", same_all)):
        print(f"all pairs: calidar {sum(ours_all):.2f} s, small_gicp align ({label}) {sum(ref):.2f} s: "
              f"{sum(ours_all) / sum(ref):.2f}× (median per pair {np.median(np.divide(ours_all, ref)):.2f}×)")
    print(f"load average {os.getloadavg()[0]:.1f}")
    print("calidar stages over the pairs and repeats (CPU): " + ", ".join(f"{k} {v:.2f} s" for k, v in stages.items()))


if __name__ == "__main__":
    main()
