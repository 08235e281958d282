"""Benchmark: what a matching method alone does to the angles — the adjustment started at the truth.

    NUMBA_NUM_THREADS=1 OMP_NUM_THREADS=1 PYTHONPATH=src python benchmarks/strips_bias.py \\
        --seeds 100-105 --density 4.8 [--methods planes,vgicp] [--trajectory-errors] [--every-point] \\
        [--preset uav --scene urban --directions opposite] [--no-trajectory-model]

Each seed is the airborne survey of ``strips_montecarlo.py`` (6 lines in alternate directions + 2
cross lines, boresight errors 0.03/−0.04/0.05°, 3 cm range noise), simulated WITHOUT trajectory
errors unless ``--trajectory-errors``, and cached under ``--cache``. It is read as ``calidar
boresight`` reads it (thinned to the default budget; ``--every-point``: every overlapping point)
and calibrated with the default options except two: the TRUE sensor is the start, and there is one
outer iteration, so the correspondences are matched at the truth and the adjustment (trajectory
model on, priors 3 cm / 0.002°) moves the angles only by what their residuals at the truth imply.
Without trajectory errors that move is the method's bias plus its noise: the mean over the seeds
is printed in mdeg and in σ. (How VGICP's pitch bias on dense, thinned strips was found:
docs/validation.md.) One survey at density 4.8 takes ≈ 10 s to calibrate, ≈ 60 s to simulate.

``--preset uav`` (density 1, the preset's 1 cm range noise, priors 2 cm / 0.002°), ``--scene urban``
(strips_montecarlo's URBAN scene), ``--directions``: the UAV surveys of issue 26.
``--no-trajectory-model``: the adjustment without trajectory corrections, so that the angles' σ come
from the rows alone: over the seeds the move/σ then has RMS 1 if the rows' σ (and their independence)
are honest — the test of the matching's σ.
"""

from __future__ import annotations

import argparse
import sys
import time
from dataclasses import replace
from pathlib import Path
import tempfile

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
from strips_montecarlo import ANGLES, ERRORS, URBAN, seeds_of  # noqa: E402

from calidar.pipelines.boresight import calibrate_inputs, load_inputs  # noqa: E402
from calidar.pipelines.strip_config import StripConfig  # noqa: E402
from calidar.ingest.settings import IngestSettings  # noqa: E402
from calidar.sim.survey import simulate_survey, survey_config  # noqa: E402
from calidar.strips.config import CalibrationConfig, StripSettings, TrajectorySettings, matchers_named  # noqa: E402
from calidar.strips.parameters import sensor_of  # noqa: E402

TRAJECTORY_SIGMA = {"airborne": (0.03, float(np.radians(0.002))),  #: the presets' trajectory accuracy (m, rad), the priors
                    "uav": (0.02, float(np.radians(0.002)))}


def folder(cache: Path, seed: int, density: float, trajectory_errors: bool, preset: str = "airborne",
           scene: str = "preset", directions: str = "cross") -> Path:
    """The survey of ``seed``, simulated once."""
    f = cache / (f"seed{seed}_d{density:g}{'' if trajectory_errors else '_exact_trajectory'}"
                 + ("" if preset == "airborne" else f"_{preset}_{scene}_{directions}"))
    if not (f / "truth.json").exists():
        exact = {} if trajectory_errors else {"gnss_noise_m": 0.0, "attitude_noise_rad": 0.0}
        noise = {"range_noise_m": 0.03} if preset == "airborne" else {}
        cfg = survey_config(preset, seed=seed, density=density, vegetation=0.0, directions=directions,
                            errors=ERRORS, **noise, **exact)
        if scene == "urban":
            cfg = replace(cfg, scene=replace(cfg.scene, **URBAN))
        simulate_survey(cfg).write(f, force=True)
    return f


def from_truth(f: Path, methods: list[str], every_point: bool, preset: str = "airborne", trajectory_model: bool = True
               ) -> dict[str, tuple[np.ndarray, np.ndarray]]:
    """Per method: the angles' move from the truth (deg) and their σ (deg)."""
    trajectory = TrajectorySettings(sigma=TRAJECTORY_SIGMA[preset]) if trajectory_model else None
    config = StripConfig(CalibrationConfig(matchers=matchers_named(*methods), trajectory=trajectory,
                                           solver=StripSettings(max_outer=1)),
                         IngestSettings(budget_points=None if every_point else IngestSettings().budget_points))
    inputs = load_inputs(sorted((f / "strips").glob("*.laz")), f / "sbet.out", f / "sensor.toml", config,
                         truth=f / "truth.json")
    truth = sensor_of(inputs.nominal, inputs.truth)
    results = calibrate_inputs(replace(inputs, nominal=truth))
    return {m: (np.degrees([r.solution.values[a] - inputs.truth[a] for a in ANGLES]),
                np.degrees([r.solution.sigma[a] for a in ANGLES])) for m, r in results.items()}


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--seeds", default="100-105", help="e.g. 100-105 or 3,5,9-12")
    ap.add_argument("--methods", default="planes,vgicp")
    ap.add_argument("--density", type=float, default=None, help="simulator density (points grow with it; default "
                    "4.8 airborne, 1 uav)")
    ap.add_argument("--preset", default="airborne", choices=("airborne", "uav"))
    ap.add_argument("--scene", default="preset", choices=("preset", "urban"))
    ap.add_argument("--directions", default="cross", choices=("cross", "opposite"))
    ap.add_argument("--no-trajectory-model", action="store_true", help="adjust without trajectory corrections")
    ap.add_argument("--trajectory-errors", action="store_true", help="simulate the preset's trajectory errors too")
    ap.add_argument("--every-point", action="store_true", help="keep every overlapping point (no thinning)")
    ap.add_argument("--cache", type=Path, default=Path(tempfile.gettempdir()) / "calidar_bench_strips_bias")
    args = ap.parse_args()
    methods, moves = args.methods.split(","), {}
    density = args.density if args.density is not None else (4.8 if args.preset == "airborne" else 1.0)
    for seed in seeds_of(args.seeds):
        f = folder(args.cache, seed, density, args.trajectory_errors, args.preset, args.scene, args.directions)
        t = time.perf_counter()
        for m, (move, sigma) in from_truth(f, methods, args.every_point, args.preset,
                                           not args.no_trajectory_model).items():
            moves.setdefault(m, []).append((move, sigma))
            print(f"seed {seed} {m:6s} move from the truth (mdeg) " + " ".join(f"{v * 1e3:+.3f}" for v in move)
                  + "  σ " + " ".join(f"{v * 1e3:.3f}" for v in sigma) + "  z " + " ".join(f"{v:+.2f}" for v in move / sigma)
                  + f"  ({time.perf_counter() - t:.0f} s)",
                  flush=True)
    for m, rows in moves.items():
        move, sigma = (np.array([r[i] for r in rows]) for i in (0, 1))
        se = move.std(0, ddof=1) / np.sqrt(len(move)) if len(move) > 1 else np.full(3, np.nan)
        print(f"{m:6s} {len(move)} surveys, mean move roll/pitch/yaw "
              + " / ".join(f"{v * 1e3:+.3f} ± {e * 1e3:.3f}" for v, e in zip(move.mean(0), se))
              + " mdeg = " + " / ".join(f"{v:+.2f}" for v in (move / sigma).mean(0)) + " σ; RMS z "
              + " / ".join(f"{v:.2f}" for v in np.sqrt(np.mean((move / sigma) ** 2, 0))))


if __name__ == "__main__":
    main()
