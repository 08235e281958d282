"""Monte-Carlo of ``calidar boresight`` with its DEFAULT options: are the σ honest?

    NUMBA_NUM_THREADS=1 OMP_NUM_THREADS=1 PYTHONPATH=src python benchmarks/strips_montecarlo.py \\
        --seeds 100-139 [--methods planes,vgicp] [--vegetation 0.3] [--no-source] [--density 0.3] \\
        [--preset uav] [--directions opposite] [--scene urban] [--only-hidden] \\
        [--sigma-scale 1,1,1.5,1,1,5 --sigma-variation 0.4] [--jobs 1] [--json out.jsonl] \\
        [--cache DIR [--simulate-only]] [--covariance sandwich] [--trajectory-shape gm2,gm2]

Each seed is one survey written to a folder as the simulator delivers it (airborne preset,
6 lines in alternate directions + 2 cross lines, density 0.3 (``--density``), boresight errors
0.03/−0.04/0.05°, 3 cm range noise, the preset's 3 cm / 0.002° smooth trajectory errors and
the smrmsg.out beside sbet.out that states them), then calibrated by the boresight pipeline
with default options (:func:`calidar.pipelines.boresight.load_inputs` and
:func:`calibrate_inputs`, what ``calidar boresight`` runs before its quality stages and
outputs: the trajectory model on, its priors from the smrmsg found beside the SBET).

``--sigma-scale N,E,D,ROLL,PITCH,HEADING`` and ``--sigma-variation V``: trajectory errors whose
σ differ per axis and change over the flight (σ(t) = σ · exp(V · g(t)), g smooth over 60 s),
the smrmsg stating them epoch by epoch. ``--no-source``: also calibrate each survey with the
smrmsg hidden: no accuracy file, so the trajectory's accuracy level is estimated from the
overlaps (:mod:`calidar.strips.trajectory_level`, starting from the survey-grade default 5/5/8 cm,
0.003° roll/pitch, 0.008° heading); ``--only-hidden``: only that calibration.

One line per survey, source and method (errors, σ, z = error/σ), then per source and method:
``--cache DIR``: each survey is simulated once into DIR and calibrated from there on later runs
(the same bytes: a seed always gives the same survey); ``--simulate-only`` only fills DIR.

``--covariance irls|sandwich``: the engine's covariance model (``[solver] covariance``,
:attr:`calidar.adjust.SolverOptions.covariance`; None: the default). ``--trajectory-shape P,A``:
the trajectory prior's correlation shape, position and attitude (``[trajectory_model] shape``,
:func:`calidar.strips.trajectory_errors.gauss_markov`; None: the default).

RMS of z per angle (1 for honest σ; its sampling spread is ±1/√(2n)), the mean z, the largest
|z|, the share of |z| > 2 (4.6 % for a normal z) and the count of |z| > 3.5.
"""

from __future__ import annotations

import argparse
import json
import shutil
import sys
import tempfile
import time
from dataclasses import replace
from concurrent.futures import ProcessPoolExecutor
from pathlib import Path

import numpy as np
from scipy.special import chdtri

sys.path.insert(0, str(Path(__file__).resolve().parent))
from strips import ERRORS  # noqa: E402  (the benchmarks' boresight errors)

from calidar.pipelines.boresight import calibrate_inputs, load_inputs  # noqa: E402
from calidar.pipelines.strip_config import StripConfig  # noqa: E402
from calidar.strips.config import CalibrationConfig, matchers_named  # noqa: E402
from calidar.strips.verdict import global_test_sigma0  # noqa: E402
from calidar.sim.survey import simulate_survey, survey_config  # noqa: E402

ANGLES = tuple(ERRORS)


def _hidden_accuracy(folder: Path) -> Path:
    """A copy of the survey folder without smrmsg.out (links, no data copied)."""
    bare = folder.with_name(folder.name + "_bare")
    bare.mkdir(exist_ok=True)  # (a cached survey's may be there already)
    for name in ("strips", "sbet.out", "sensor.toml", "truth.json"):
        if not (bare / name).is_symlink():
            (bare / name).symlink_to(folder / name)
    return bare


#: ``--scene urban``: the preset's scene built up densely with taller buildings (walls in most overlaps)
URBAN = {"building_density_per_km2": 1200.0, "building_size_m": (10.0, 30.0), "building_height_m": (6.0, 25.0)}


def survey(seed: int, methods: list[str], vegetation: float, scale: tuple, variation: float, no_source: bool,
           density: float = 0.3, only_hidden: bool = False, preset: str = "airborne", directions: str = "cross",
           scene: str = "preset", cache: Path | None = None, simulate_only: bool = False,
           covariance: str | None = None, shape: tuple | None = None) -> list[dict]:
    """One simulated survey calibrated with default options (and, with ``no_source``, without its
    smrmsg; ``only_hidden``: only without it)."""
    noise = {"range_noise_m": 0.03} if preset == "airborne" else {}  # uav: the preset's 1 cm
    cfg = survey_config(preset, seed=seed, density=density, vegetation=vegetation, directions=directions, errors=ERRORS,
                        trajectory_sigma_scale=scale, trajectory_sigma_variation=variation, **noise)
    if scene == "urban":
        cfg = replace(cfg, scene=replace(cfg.scene, **URBAN))
    rows = []
    with tempfile.TemporaryDirectory(prefix="calidar_mc_") as tmp:
        folder = _simulated(cfg, Path(tmp) / f"seed{seed}", cache, scale, variation, density)
        if simulate_only:
            return rows
        for source in ("default",) if only_hidden else ("smrmsg", "default") if no_source else ("smrmsg",):
            f = folder if source == "smrmsg" else _hidden_accuracy(folder)
            cal = CalibrationConfig(matchers=matchers_named(*methods))
            if covariance is not None:  # the engine's covariance model, as [solver] covariance sets it
                cal = replace(cal, solver=replace(cal.solver, adjustment=replace(
                    cal.solver.adjustment, covariance=covariance)))
            if shape is not None:  # the trajectory prior's shape, as [trajectory_model] shape sets it
                cal = replace(cal, trajectory=replace(cal.trajectory, shape=shape))
            config = StripConfig(cal)
            t = time.perf_counter()
            inputs = load_inputs(sorted((f / "strips").glob("*.laz")), f / "sbet.out", f / "sensor.toml", config,
                                 truth=f / "truth.json")
            cpu = time.process_time()
            results = calibrate_inputs(inputs)
            cpu = time.process_time() - cpu  # every method's calibration, CPU s (all threads)
            seconds = time.perf_counter() - t  # reading and every method's calibration
            for method, result in results.items():
                sol = result.solution
                rows.append({"seed": seed, "source": source, "method": method,
                             "error_deg": [float(np.degrees(sol.values[n] - inputs.truth[n])) for n in ANGLES],
                             "sigma_deg": [float(np.degrees(sol.sigma[n])) for n in ANGLES],
                             "sigma0": sol.sigma0, "sigma0_range": sigma0_range(sol.dof), "seconds": seconds,
                             "sigma0_test": global_test_sigma0(sol),
                             "sigma0_skipped": sol.extra.get("unit_weight", {}).get("sigma0"),
                             "outer_iterations": len(result.outer), "calibration_cpu_s": cpu,
                             "level": sol.extra.get("trajectory_accuracy_estimate"),
                             "covariance": sol.extra.get("covariance"),
                             "trajectory_shape": list(cal.trajectory.shape),
                             "unevenness": [p["unevenness"] for p in sol.extra.get("strips", {})
                                            .get("pairs", []) if "unevenness" in p],
                             "unevenness_pooled": sol.extra.get("strips", {}).get("unevenness")})
        if cache is None:
            shutil.rmtree(folder, ignore_errors=True)
    return rows


def _simulated(cfg, tmp: Path, cache: Path | None, scale: tuple, variation: float, density: float) -> Path:
    """The survey's folder: simulated into ``tmp``, or once into ``cache`` and read from there after."""
    if cache is None:
        return simulate_survey(cfg).write(tmp)
    tag = "" if scale == (1.0,) * 6 and variation == 0.0 else f"_s{'-'.join(f'{v:g}' for v in scale)}_v{variation:g}"
    folder = cache / (f"{cfg.preset}_{cfg.directions}_seed{cfg.seed}_d{density:g}_veg{cfg.scene.vegetation_fraction:g}"
                      f"_{'urban' if cfg.scene.building_height_m == URBAN['building_height_m'] else 'scene'}{tag}")
    if not (folder / "truth.json").exists():  # written last
        simulate_survey(cfg).write(folder, force=True)
    return folder


def sigma0_range(dof: float) -> list[float]:
    """The χ² test's 95 % range of σ0 for ``dof`` degrees of freedom (as the verdict states it)."""
    return [float(np.sqrt(chdtri(dof, 1.0 - q) / dof)) for q in (0.025, 0.975)]


def record(row: dict, path: Path | None) -> None:
    """Append ``row`` as one line to the JSON-lines file ``path`` (None: nowhere): how the
    Monte-Carlo benchmarks keep their rows, one survey at a time."""
    if path:
        with path.open("a") as f:
            f.write(json.dumps(row) + "\n")


def recorded(path: Path) -> list[dict]:
    """The rows :func:`record` appended to ``path`` (blank lines skipped)."""
    return [json.loads(x) for x in path.read_text().splitlines() if x.strip()]


def seeds_of(text: str) -> list[int]:
    """'3-42' or '3,5,9-12' → the seeds."""
    out = []
    for part in text.split(","):
        a, _, b = part.partition("-")
        out += list(range(int(a), int(b or a) + 1))
    return out


def summary(rows: list[dict]) -> str:
    """One line per source and method: RMS z, mean z, max |z|, |z| > 2 share, |z| > 3.5 count, mean σ."""
    out = []
    for key in sorted({(r["source"], r["method"]) for r in rows}):
        sel = [r for r in rows if (r["source"], r["method"]) == key]
        err, sig = np.array([r["error_deg"] for r in sel]), np.array([r["sigma_deg"] for r in sel])
        z = err / sig
        n = len(z)
        test = [r.get("sigma0_test", r["sigma0"]) for r in sel]  # the verdict's σ0 (older rows: the engine's)
        below = sum(t < r["sigma0_range"][0] for t, r in zip(test, sel) if "sigma0_range" in r)
        inside = sum(r["sigma0_range"][0] <= t <= r["sigma0_range"][1] for t, r in zip(test, sel) if "sigma0_range" in r)
        out.append(f"{key[0]:7s} {key[1]:6s} {n:3d} surveys  RMS z (roll/pitch/yaw) "
                   + "/".join(f"{v:.2f}" for v in np.sqrt(np.mean(z**2, 0))) + f" (±{1 / np.sqrt(2 * n):.2f})"
                   + "  mean z " + "/".join(f"{v:+.2f}" for v in z.mean(0))
                   + "  max |z| " + "/".join(f"{v:.1f}" for v in np.abs(z).max(0))
                   + f"  |z|>2 {np.mean(np.abs(z) > 2):.1%}  |z|>3.5 {int(np.sum(np.abs(z) > 3.5))}"
                   + "  mean σ " + "/".join(f"{v:.5f}" for v in sig.mean(0)) + "°"
                   + f"  σ0 {np.mean([r['sigma0'] for r in sel]):.2f} (test {np.mean(test):.3f})"
                   + (f" (below / inside / above its 95 % range: {below} / {inside} / {n - below - inside})"
                      if "sigma0_range" in sel[0] else ""))
    return "\n".join(out)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--seeds", default="100-139", help="e.g. 100-139 or 3,5,9-12")
    ap.add_argument("--methods", default="planes,vgicp")
    ap.add_argument("--vegetation", type=float, default=0.0, help="tree cover fraction, e.g. 0.3")
    ap.add_argument("--preset", default="airborne", choices=("airborne", "uav"), help="the simulator's preset")
    ap.add_argument("--scene", default="preset", choices=("preset", "urban"), help="urban: dense, taller buildings")
    ap.add_argument("--directions", default="cross", choices=("cross", "opposite"), help="the flight lines' directions")
    ap.add_argument("--density", type=float, default=None, help="simulator density (points grow with it; default "
                    "0.3 airborne, 1 uav)")
    ap.add_argument("--sigma-scale", default="1,1,1,1,1,1", help="trajectory σ factors N,E,D,roll,pitch,heading")
    ap.add_argument("--sigma-variation", type=float, default=0.0, help="slow change of the trajectory σ in time")
    ap.add_argument("--no-source", action="store_true", help="also run each survey without its smrmsg (the default accuracy)")
    ap.add_argument("--only-hidden", action="store_true", help="calibrate each survey only with its smrmsg hidden")
    ap.add_argument("--jobs", type=int, default=1, help="surveys simulated and calibrated in parallel")
    ap.add_argument("--json", type=Path, default=None, help="append every row to this JSON-lines file")
    ap.add_argument("--cache", type=Path, default=None, help="keep the simulated surveys here and reuse them")
    ap.add_argument("--simulate-only", action="store_true", help="only simulate the surveys into --cache")
    ap.add_argument("--covariance", default=None, choices=("irls", "sandwich"),
                    help="the engine's covariance model ([solver] covariance; default: the configuration's)")
    ap.add_argument("--trajectory-shape", default=None, help="POSITION,ATTITUDE: gm1 or gm2 each "
                    "([trajectory_model] shape; default: the configuration's)")
    args = ap.parse_args()
    methods, seeds = args.methods.split(","), seeds_of(args.seeds)
    scale = tuple(float(v) for v in args.sigma_scale.split(","))
    shape = None if args.trajectory_shape is None else tuple(args.trajectory_shape.split(","))
    density = args.density if args.density is not None else (0.3 if args.preset == "airborne" else 1.0)
    rows, start = [], time.perf_counter()
    with ProcessPoolExecutor(args.jobs) as pool:
        n = len(seeds)
        for found in pool.map(survey, seeds, [methods] * n, [args.vegetation] * n, [scale] * n,
                              [args.sigma_variation] * n, [args.no_source] * n, [density] * n,
                              [args.only_hidden] * n, [args.preset] * n, [args.directions] * n, [args.scene] * n,
                              [args.cache] * n, [args.simulate_only] * n, [args.covariance] * n,
                              [shape] * n):
            for r in found:
                r.update(vegetation=args.vegetation, sigma_scale=scale, sigma_variation=args.sigma_variation,
                         density=density, preset=args.preset, directions=args.directions, scene=args.scene,
                         covariance_model=args.covariance or "default")
                rows.append(r)
                z = np.array(r["error_deg"]) / np.array(r["sigma_deg"])
                print(f"{r['source']:7s} {r['method']:6s} seed {r['seed']:4d}  error "
                      + " ".join(f"{v:+.5f}" for v in r["error_deg"]) + "°  σ "
                      + " ".join(f"{v:.5f}" for v in r["sigma_deg"]) + "°  z " + " ".join(f"{v:+.2f}" for v in z)
                      + f"  σ0 {r['sigma0']:.2f}  {r['seconds']:.1f} s"
                      + (f"  level {r['level']['headline']}" if r.get("level") else ""), flush=True)
                if args.json:
                    with open(args.json, "a", encoding="utf-8") as f:
                        f.write(json.dumps(r) + "\n")
    print(f"{len(seeds)} surveys in {time.perf_counter() - start:.0f} s, {args.jobs} job(s), vegetation "
          f"{args.vegetation}, σ scale {scale}, σ variation {args.sigma_variation}, density {density}, preset "
          f"{args.preset}, directions {args.directions}, scene {args.scene}")
    print(summary(rows))


if __name__ == "__main__":
    main()
