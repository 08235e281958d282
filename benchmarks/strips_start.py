"""Benchmark: does the calibrated boresight depend on where the adjustment starts? (issue 26,
eighth session: the pitch lean on UAV cross lines with trees.)

    NUMBA_NUM_THREADS=1 OMP_NUM_THREADS=1 PYTHONPATH=src python benchmarks/strips_start.py \\
        --preset uav --directions cross --vegetation 0.3 --seeds 1131-1135 --cache DIR \\
        [--methods planes] [--start mirror] [--json out.jsonl]

Each cached survey (``strips_montecarlo.py``'s folder, read only) is calibrated with the default
options (the whole outer loop) from a start other than the delivered nominal sensor: ``mirror``,
the truth minus the nominal's offset from it (the Monte-Carlo's boresight errors with the other
sign: a start as far from the truth on the other side); ``truth``, the true sensor. Printed: the
angles' error (mdeg), σ and outer iterations per start. A calibration that depends on its start
(stops short, or its matches pull toward the start) leans toward the start: with ``mirror`` its
error flips sign against the Monte-Carlo rows from the nominal. ``--exact-priors``: the preset's
trajectory σ instead of the smrmsg (for a ``--cache`` of twins without GNSS/INS errors, named as
the surveys: ``strips_roll.py``'s ``…_exact`` folders linked under the survey's name).
``--match-uncorrected``: the outer loop matches the strips with the current sensor but WITHOUT the
estimated trajectory corrections (the adjustment still applies them to the matched points): is the
loop's shift made by matching at the corrected positions?
``--max-outer 1`` with ``--start truth``: the rows matched once at the truth, as
``strips_roll.py --variants default``.
"""

from __future__ import annotations

import argparse
import json
import sys
from dataclasses import replace
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
from strips_montecarlo import ANGLES, ERRORS, _simulated, seeds_of  # noqa: E402
from strips_roll import SIGMA  # noqa: E402

from calidar.pipelines.boresight import calibrate_inputs, load_inputs  # noqa: E402
from calidar.pipelines.strip_config import StripConfig  # noqa: E402
from calidar.sim.survey import survey_config  # noqa: E402
from calidar.strips.config import (CalibrationConfig, StripSettings,  # noqa: E402
                                   TrajectorySettings, matchers_named)
from calidar.strips.parameters import sensor_of  # noqa: E402


def run(args, seed: int, start: str) -> list[dict]:
    cfg = survey_config(args.preset, seed=seed, density=1.0, vegetation=args.vegetation,
                        directions=args.directions, errors=ERRORS)
    folder = _simulated(cfg, args.cache / "tmp", args.cache, (1.0,) * 6, 0.0, 1.0)
    methods = args.methods.split(",")
    traj = (TrajectorySettings(sigma=SIGMA[args.preset]) if args.exact_priors
            else TrajectorySettings())
    solver = StripSettings() if args.max_outer is None else StripSettings(max_outer=args.max_outer)
    config = StripConfig(CalibrationConfig(matchers=matchers_named(*methods), trajectory=traj,
                                           solver=solver, model_check=False))
    inputs = load_inputs(sorted((folder / "strips").glob("*.laz")), folder / "sbet.out",
                         folder / "sensor.toml", config, truth=folder / "truth.json")
    truth = dict(inputs.truth)
    if start == "nominal":  # the delivered nominal (the Monte-Carlo's start)
        values = {a: inputs.nominal.parameters()[a] for a in ANGLES}
    elif start == "mirror":  # truth − (nominal − truth), per angle
        nominal = inputs.nominal.parameters()
        values = {a: 2.0 * truth[a] - nominal[a] for a in ANGLES}
    else:
        values = {a: truth[a] for a in ANGLES}
    sensor = sensor_of(inputs.nominal, values)
    out = []
    for m, r in calibrate_inputs(replace(inputs, nominal=sensor)).items():
        sol = r.solution
        out.append({"seed": seed, "method": m, "start": start,
                    "match_uncorrected": args.match_uncorrected,
                    "start_offset_mdeg": [float(np.degrees(values[a] - truth[a]) * 1e3)
                                          for a in ANGLES],
                    "error_mdeg": [float(np.degrees(sol.values[a] - truth[a]) * 1e3)
                                   for a in ANGLES],
                    "sigma_mdeg": [float(np.degrees(sol.sigma[a]) * 1e3) for a in ANGLES],
                    "outer_iterations": len(sol.extra["strips"]["outer_iterations"])})
    return out


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--seeds", default="1131-1135")
    ap.add_argument("--methods", default="planes")
    ap.add_argument("--preset", default="uav", choices=("airborne", "uav"))
    ap.add_argument("--directions", default="cross", choices=("cross", "opposite"))
    ap.add_argument("--vegetation", type=float, default=0.3)
    ap.add_argument("--start", default="mirror", choices=("mirror", "truth", "nominal"))
    ap.add_argument("--exact-priors", action="store_true",
                    help="the preset's trajectory σ (twins without GNSS/INS errors)")
    ap.add_argument("--max-outer", type=int, default=None,
                    help="at most this many outer iterations (1: the rows matched at the start)")
    ap.add_argument("--match-uncorrected", action="store_true",
                    help="match without the estimated trajectory corrections")
    ap.add_argument("--cache", type=Path, required=True)
    ap.add_argument("--json", type=Path, default=None)
    args = ap.parse_args()
    if args.match_uncorrected:
        from calidar.strips import outer_loop

        outer_loop.corrections = lambda values, model, spans: {}
    for seed in seeds_of(args.seeds):
        for r in run(args, seed, args.start):
            if args.json:
                with args.json.open("a") as f:
                    f.write(json.dumps(r) + "\n")
            print(f"seed {seed} {r['method']:6s} start {args.start} (offset "
                  + " ".join(f"{x:+.1f}" for x in r["start_offset_mdeg"]) + ") error "
                  + " ".join(f"{x:+.2f}" for x in r["error_mdeg"]) + " σ "
                  + " ".join(f"{x:.2f}" for x in r["sigma_mdeg"])
                  + f" mdeg, {r['outer_iterations']} outer", flush=True)


if __name__ == "__main__":
    main()
