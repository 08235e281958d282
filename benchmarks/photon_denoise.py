"""Benchmark: `calidar denoise` on simulated daytime weak-beam land passes, against each photon's truth.

Each scenario is simulated (`calidar.sim.photons`, the model behind `calidar simulate photons`) on
--seeds; the photons are classified by `calidar.photon.denoise.denoise` (what `calidar denoise`
runs per beam) and by the earlier two-stage method (`denoise_stages`: histograms then DBSCAN),
and compared with the simulation's truth: the share of ground photons flagged signal, of the
solar background flagged signal (all of it, and the part more than 2 m from the ground and outside
the trees' crowns: the background inside the surface band cannot be told from the surface by any
classifier), of crown photons. Then the real sea-ice ATL03 subset ($CALIDAR_REAL_DATA/atl03_arctic)
against ATL03's own confidence.

Scenarios (weak beam: a quarter of the default strong beam's 3 ground photons a shot; window 60 m,
the telemetry band's height on the real granule; 3 km each; roughness 0.2 m, cross slope 0.05):
  hilly   4 MHz, slope 0.10 + hills of 10 m every 400 m (steepest 0.26, 15°)
  steep   4 MHz, slope 0.15 + hills of 15 m every 400 m (steepest 0.39, 21°)
  forest  4 MHz, slope 0.05 + hills of 8 m every 400 m, 30 % of 40 m stands wooded (9–15 m trees,
          half the signal from the crowns there)
  faint   (a limit) 0.5 photons a shot, 5 MHz, the forest's trees and hills

Run: NUMBA_NUM_THREADS=1 PYTHONPATH=src nice -n 10 python benchmarks/photon_denoise.py --seeds 0:10
"""

from __future__ import annotations

import argparse
import os
import time
from pathlib import Path

import numpy as np

from calidar.photon.denoise import denoise, denoise_stages
from calidar.sim.photons import PhotonSimConfig, _terrain, simulate_pass

BASE = dict(n_ccr=1, strength="weak", ground_photons=0.75, background_rate=4e6, window=60.0, length=3000.0,
            roughness=0.2, slope_cross=0.05, undulation_wavelength=400.0)
SCENARIOS = {
    "hilly": dict(slope_along=0.10, undulation=10.0),
    "steep": dict(slope_along=0.15, undulation=15.0),
    "forest": dict(slope_along=0.05, undulation=8.0, canopy_cover=0.3),
    "faint": dict(slope_along=0.05, undulation=8.0, canopy_cover=0.3, ground_photons=0.5, background_rate=5e6),
}


def shares(cfg: PhotonSimConfig, sim, signal: np.ndarray) -> dict[str, float]:
    c, x, h = sim.photon_class, sim.beam.x, sim.beam.h
    ground = _terrain(cfg, x, 0.0)
    away = (c == 0) & (np.abs(h - ground) > 2.0) & ((h - ground < 0) | (h - ground > cfg.canopy_height)
                                                    | (cfg.canopy_cover == 0))
    return {"ground": signal[c == 1].mean(), "background": signal[c == 0].mean(),
            "background_away": signal[away].mean(), "canopy": signal[c == 3].mean() if (c == 3).any() else np.nan}


def run(name: str, seeds: range) -> None:
    new, old, secs, n = [], [], 0.0, 0
    for seed in seeds:
        cfg = PhotonSimConfig(seed=seed, **{**BASE, **SCENARIOS[name]})
        sim = simulate_pass(cfg)
        t = time.process_time()
        sig = denoise(sim.beam.x, sim.beam.h)
        secs += time.process_time() - t
        n += len(sim.beam)
        new.append(shares(cfg, sim, sig))
        old.append(shares(cfg, sim, denoise_stages(sim.beam.x, sim.beam.h)[1]))
    for label, rows in (("denoise", new), ("two-stage (before)", old)):
        g = np.array([r["ground"] for r in rows])
        b = np.array([r["background"] for r in rows])
        line = (f"{name:7s} {label:19s} ground {g.mean():6.1%} (min {g.min():6.1%})  background {b.mean():5.1%} "
                f"(max {b.max():5.1%}), away from the surfaces {np.mean([r['background_away'] for r in rows]):5.2%}")
        if not np.isnan(rows[0]["canopy"]):
            line += f", crowns {np.nanmean([r['canopy'] for r in rows]):5.1%}"
        print(line, flush=True)
    print(f"{name:7s} {len(seeds)} passes, {n:,} photons, denoise {secs:.2f} s CPU")


def sea_ice() -> None:
    from calidar.io.atl03 import read_atl03

    path = Path(os.environ.get("CALIDAR_REAL_DATA", "../shared/data/real")) / "atl03_arctic" / "ATL03_gt1l.h5"
    if not path.exists():
        print(f"sea ice: {path} absent, skipped")
        return
    b = read_atl03(path, "gt1l")
    conf = b.signal_conf.max(axis=1)
    for label, sig in (("denoise", denoise(b.x, b.h)), ("two-stage (before)", denoise_stages(b.x, b.h)[1])):
        print(f"sea ice {label:19s} ATL03 medium/high {sig[conf >= 3].mean():6.1%} of {int((conf >= 3).sum())}, "
              f"ATL03 sea-ice high {sig[b.signal_conf[:, 2] == 4].mean():6.1%}, low/noise {sig[conf < 3].mean():5.1%} "
              f"of {int((conf < 3).sum())}")


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--seeds", default="0:10", help="A:B, seeds A … B−1")
    ap.add_argument("--scenarios", default=",".join(SCENARIOS), help="comma-separated: " + ", ".join(SCENARIOS))
    args = ap.parse_args()
    a, b = map(int, args.seeds.split(":"))
    denoise(np.arange(100.0), np.zeros(100))  # compile first
    for name in args.scenarios.split(","):
        run(name, range(a, b))
    sea_ice()


if __name__ == "__main__":
    main()
