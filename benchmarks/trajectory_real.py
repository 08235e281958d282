"""``calidar trajectory`` on the real files of ``$CALIDAR_REAL_DATA`` (docs/validation.md): per line
the plausibility figures (ellipsoidal height, speed, heading and its steadiness, roll, pitch, σ), and
for ``leeward_sierra`` (the one file with its true SBET) the errors against that SBET.

    CALIDAR_REAL_DATA=/work/shared/data/real PYTHONPATH=src python benchmarks/trajectory_real.py
"""

from __future__ import annotations

import json
import os
import time
from dataclasses import replace
from pathlib import Path

import numpy as np

from calidar.io.sbet import read_sbet
from calidar.pipelines.trajectory import STANDING_NOTES, TrajectorySettings, reconstruct_trajectory
from calidar.trajrec.result import compare, error_summary
from calidar.trajrec.summary import line_summary

FILES = {"lidr_topography": "Topography.laz", "pdal_autzen": "autzen_trim.laz", "leeward_sierra": "points.las"}
#: the scan plane's known yaw in the body (docs/conventions.md), run as well as the default
SCAN_PLANE_YAW_DEG = {"leeward_sierra": 13.96}


def main() -> None:
    root = Path(os.environ.get("CALIDAR_REAL_DATA", "../shared/data/real"))
    d = np.degrees
    for name, file in FILES.items():
        path = root / name / file
        c0 = time.process_time()
        run = reconstruct_trajectory([path])
        cpu = time.process_time() - c0
        print(f"## {name} ({run.counts['points_read']} points, {cpu:.2f} s CPU; lines from {run.lines_from})")
        for ln in run.lines:
            s = line_summary(ln)
            g = s["sigma_median"]
            print(f"line {s['line']}: {s['duration_s']:.2f} s, height {s['height_m']:.1f} m (range "
                  f"{s['height_range_m']:.1f}), speed {s['speed_mps']:.1f} m/s, heading {d(s['heading_rad']):.2f}° "
                  f"(RMS about trend {d(s['heading_rms_about_trend_rad']):.3f}°), roll {d(s['roll_mean_rad']):+.2f} ± "
                  f"{d(s['roll_std_rad']):.2f}°, pitch {d(s['pitch_mean_rad']):+.2f} ± {d(s['pitch_std_rad']):.2f}°, "
                  f"σ E/N/U {g['east_m']:.3f}/{g['north_m']:.3f}/{g['up_m']:.3f} m, σ r/p/h {d(g['roll_rad']):.3f}/"
                  f"{d(g['pitch_rad']):.3f}/{d(g['heading_rad']):.3f}°; scan-angle misfit "
                  f"{d(s['misfit_rad'].get('across', np.nan)):.3f}°, scan-plane misfit "
                  f"{d(s['misfit_rad'].get('along', np.nan)):.4f}°, rays {s['rays']}")
        for n in run.notes[len(STANDING_NOTES):]:
            print("note:", n)
        sbet = root / name / "sbet.out"
        if name in SCAN_PLANE_YAW_DEG and sbet.exists():
            for mount, label in ((None, "default priors"), ((0.0, 0.0, 0.0, 0.0), "priors 0")):
                base = TrajectorySettings()
                fit = replace(base.fit, scan_plane_yaw=np.radians(SCAN_PLANE_YAW_DEG[name]),
                              **({} if mount is None else {"mount_sigma": mount}))
                told = reconstruct_trajectory([path], settings=replace(base, fit=fit))
                print(f"--scan-plane-yaw {SCAN_PLANE_YAW_DEG[name]}, {label}: against the true SBET:",
                      json.dumps(error_summary(compare(told.trajectory, read_sbet(sbet)))))
                for n in told.notes[len(STANDING_NOTES):]:
                    print("  note:", n)
        if sbet.exists():
            truth = read_sbet(sbet)
            print("against the true SBET:", json.dumps(error_summary(compare(run.trajectory, truth))))
            t = run.trajectory.time
            inside = truth.covers(t)
            print(f"  true SBET: height {np.mean(truth.height):.1f} m, heading {d(np.mean(truth.heading)):.2f}°, "
                  f"pitch {d(np.mean(truth.pitch)):.2f}°, roll {d(np.mean(truth.roll)):.3f}°; reconstructed epochs "
                  f"inside it {inside.sum()} of {t.size}")


if __name__ == "__main__":
    main()
