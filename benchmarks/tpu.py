"""Per-point TPU against the simulator's truth: RMS of error/σ per axis (east, north, up), by
|scan angle| and by terrain-slope bin, pooled over fresh surveys.

    python benchmarks/tpu.py --preset uav --seeds 0-19 [--exact-trajectory] [--boresight-sigma-deg 0.005]
    python benchmarks/tpu.py --seeds 0-4 --width 200 --exact-trajectory --beam-divergence-mrad 3

With --beam-divergence-mrad X the simulator draws each return's direction from the Gaussian beam
(σ = γ/4 per axis, `calidar.sim.shots`) and the TPU is given the same γ. The footprint's errors are
then also reported in the beam's frame, by incidence-angle bin, for two references: the actual hit
(`true_enu`: the error is across the beam) and where the nominal beam meets the hit's local plane
(the error is along the beam); and along the surface's normal, where both references agree.

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
INCIDENCE_BINS = [(0, 15), (15, 30), (30, 45), (45, 60), (60, 85)]
ANGLES = ("boresight_roll", "boresight_pitch", "boresight_yaw")


def beam_frame(res, s, cov, normal):
    """Error/σ in the beam's frame (N, 6) for one strip: against the actual hit along the beam,
    across it (horizontal, then the third axis), against the nominal beam's hit on the local plane
    along the beam; along the surface normal (either reference); and the incidence angle (deg)."""
    from calidar import georef

    enu = res.scene.r_e_enu
    _, dir_e = georef.beams(*georef.poses(res.trajectory, s.gps_time), res.nominal, s.angles)
    b = dir_e @ enu
    b /= np.linalg.norm(b, axis=1)[:, None]
    e1 = np.cross(b, [0.0, 0.0, 1.0])
    e1 /= np.linalg.norm(e1, axis=1)[:, None]
    e2 = np.cross(b, e1)
    err = res.scene.ecef_to_enu(s.ecef) - s.true_enu
    cos_a = np.clip(np.abs(np.einsum("ni,ni->n", normal, b)), 0.05, 1.0)
    along_nominal = np.einsum("ni,ni->n", err, normal) / np.einsum("ni,ni->n", b, normal)
    sig = lambda v: np.sqrt(np.einsum("ni,nij,nj->n", v, cov, v))  # noqa: E731
    z = np.stack([np.einsum("ni,ni->n", err, b) / sig(b), np.einsum("ni,ni->n", err, e1) / sig(e1),
                  np.einsum("ni,ni->n", err, e2) / sig(e2), along_nominal / sig(b),
                  np.einsum("ni,ni->n", err, normal) / sig(normal)], 1)
    return z, np.degrees(np.arccos(cos_a))


def one(preset: str, seed: int, exact: bool, boresight_sigma: float, width: float, divergence: float = 0.0):
    over = {"gnss_noise_m": 1e-4, "attitude_noise_rad": 1e-7} if exact else {}
    rng = np.random.default_rng(10_000 + seed)
    errors = {a: float(rng.normal(0, boresight_sigma)) for a in ANGLES} if boresight_sigma else {}
    cfg = calidar.survey_config(preset, seed=seed, density=0.3, directions="cross", errors=errors,
                                beam_divergence_rad=divergence, **over)
    if width:
        cfg = replace(cfg, scene=replace(cfg.scene, width_m=width, length_m=width))
    res = calidar.simulate_survey(cfg)
    cal = (CalibrationCovariance(ANGLES, np.eye(3) * boresight_sigma ** 2, ("rad",) * 3) if boresight_sigma else None)
    st = TpuSettings(cfg.range_noise_m, cfg.angle_noise_rad, beam_divergence_rad=divergence)
    z, scan, slope, zb, inc = [], [], [], [], []
    for s in res.strips:
        cov = point_covariance(res.trajectory, res.nominal, res.accuracy, s.gps_time, s.ecef, st, cal)
        err = res.scene.ecef_to_enu(s.ecef) - s.true_enu
        z.append(err / np.sqrt(np.diagonal(cov, axis1=1, axis2=2)))
        scan.append(np.abs(s.scan_angle_deg))
        normal = surface_normals(s.true_enu, 2.0)
        slope.append(np.degrees(np.arccos(normal[:, 2])))
        if divergence:
            zb_k, inc_k = beam_frame(res, s, cov, normal)
            zb.append(zb_k)
            inc.append(inc_k)
    beam = (np.concatenate(zb), np.concatenate(inc)) if divergence else None
    return np.concatenate(z), np.concatenate(scan), np.concatenate(slope), beam


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--preset", default="uav")
    ap.add_argument("--seeds", default="0-9")
    ap.add_argument("--exact-trajectory", action="store_true")
    ap.add_argument("--boresight-sigma-deg", type=float, default=0.0)
    ap.add_argument("--beam-divergence-mrad", type=float, default=0.0, help="beam divergence, full angle, mrad")
    ap.add_argument("--width", type=float, default=0.0, help="scene width and length, m (0: the preset's)")
    a = ap.parse_args()
    lo, hi = map(int, a.seeds.split("-"))
    ms = {"all": [], **{f"scan {b}": [] for b in SCAN_BINS}, **{f"slope {b}": [] for b in SLOPE_BINS}}
    mb = {f"incidence {b}": [] for b in INCIDENCE_BINS}
    t0 = time.perf_counter()
    for seed in range(lo, hi + 1):
        z, scan, slope, beam = one(a.preset, seed, a.exact_trajectory, np.radians(a.boresight_sigma_deg), a.width,
                                   a.beam_divergence_mrad * 1e-3)
        for b in INCIDENCE_BINS if beam is not None else ():
            m = (beam[1] >= b[0]) & (beam[1] < b[1])
            mb[f"incidence {b}"].append(np.mean(beam[0][m] ** 2, axis=0) if m.any() else np.full(5, np.nan))
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
    if a.beam_divergence_mrad:
        print("RMS of error/σ in the beam's frame: against the actual hit along the beam, across it (horizontal, "
              "third axis); against the nominal beam's hit along the beam; along the surface normal:")
        for k, v in mb.items():
            print(f"  {k:16s} {np.sqrt(np.nanmean(v, axis=0)).round(3).tolist()}")


if __name__ == "__main__":
    main()
