"""Per-point TPU against the simulator's truth: RMS of error/σ per axis (east, north, up), by
|scan angle| and by terrain-slope bin, pooled over fresh surveys.

    python benchmarks/tpu.py --preset uav --seeds 0-19 [--exact-trajectory] [--boresight-sigma-deg 0.005]

Each survey's points are compared with their exact hits (`Strip.true_enu`); the σ come from
`calidar.tpu.propagate.point_covariance` with the simulator's own noise figures and its smrmsg.
With --boresight-sigma-deg S every survey draws a boresight error from N(0, S²) per angle and the
TPU is given that covariance (as a calibration's solution.json would give it).
"""

from __future__ import annotations

import argparse
import json
import time
from dataclasses import replace

import numpy as np

import calidar
from calidar.tpu.propagate import CalibrationCovariance, TpuSettings, point_covariance, surface_normals

SCAN_BINS = [(0, 10), (10, 20), (20, 30), (30, 45)]
SLOPE_BINS = [(0, 5), (5, 20), (20, 60), (60, 90)]
ANGLES = ("boresight_roll", "boresight_pitch", "boresight_yaw")


def one(preset: str, seed: int, exact: bool, boresight_sigma: float, width: float):
    over = {"gnss_noise_m": 1e-4, "attitude_noise_rad": 1e-7} if exact else {}
    rng = np.random.default_rng(10_000 + seed)
    errors = {a: float(rng.normal(0, boresight_sigma)) for a in ANGLES} if boresight_sigma else {}
    cfg = calidar.survey_config(preset, seed=seed, density=0.3, directions="cross", errors=errors, **over)
    if width:
        cfg = replace(cfg, scene=replace(cfg.scene, width_m=width, length_m=width))
    res = calidar.simulate_survey(cfg)
    cal = (CalibrationCovariance(ANGLES, np.eye(3) * boresight_sigma ** 2, ("rad",) * 3) if boresight_sigma else None)
    st = TpuSettings(cfg.range_noise_m, cfg.angle_noise_rad, beam_divergence_rad=0.0)
    z, scan, slope = [], [], []
    for s in res.strips:
        cov = point_covariance(res.trajectory, res.nominal, res.accuracy, s.gps_time, s.ecef, st, cal)
        err = res.scene.ecef_to_enu(s.ecef) - s.true_enu
        z.append(err / np.sqrt(np.diagonal(cov, axis1=1, axis2=2)))
        scan.append(np.abs(s.scan_angle_deg))
        slope.append(np.degrees(np.arccos(surface_normals(s.true_enu, 2.0)[:, 2])))
    return np.concatenate(z), np.concatenate(scan), np.concatenate(slope)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--preset", default="uav")
    ap.add_argument("--seeds", default="0-9")
    ap.add_argument("--exact-trajectory", action="store_true")
    ap.add_argument("--boresight-sigma-deg", type=float, default=0.0)
    ap.add_argument("--width", type=float, default=0.0, help="scene width and length, m (0: the preset's)")
    a = ap.parse_args()
    lo, hi = map(int, a.seeds.split("-"))
    ms = {"all": [], **{f"scan {b}": [] for b in SCAN_BINS}, **{f"slope {b}": [] for b in SLOPE_BINS}}
    t0 = time.perf_counter()
    for seed in range(lo, hi + 1):
        z, scan, slope = one(a.preset, seed, a.exact_trajectory, np.radians(a.boresight_sigma_deg), a.width)
        ms["all"].append(np.mean(z ** 2, axis=0))
        for b in SCAN_BINS:
            m = (scan >= b[0]) & (scan < b[1])
            ms[f"scan {b}"].append(np.mean(z[m] ** 2, axis=0) if m.any() else np.full(3, np.nan))
        for b in SLOPE_BINS:
            m = (slope >= b[0]) & (slope < b[1])
            ms[f"slope {b}"].append(np.mean(z[m] ** 2, axis=0) if m.any() else np.full(3, np.nan))
        print(json.dumps({"seed": seed, "rms": np.sqrt(ms["all"][-1]).round(3).tolist()}), flush=True)
    print(f"{hi - lo + 1} surveys in {time.perf_counter() - t0:.0f} s; RMS of error/σ (east, north, up), "
          "pooled as the root of the mean over surveys of each survey's mean square:")
    for k, v in ms.items():
        print(f"  {k:14s} {np.sqrt(np.nanmean(v, axis=0)).round(3).tolist()}  "
              f"per-survey max {np.sqrt(np.nanmax(v, axis=0)).round(2).tolist()}")


if __name__ == "__main__":
    main()
