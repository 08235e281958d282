"""Benchmark: which ingredient makes the boresight angles' σ too small — the adjustment started at the truth
on the same surveys with and without trajectory errors, with the trajectory model changed (issue 26).

    NUMBA_NUM_THREADS=1 OMP_NUM_THREADS=1 PYTHONPATH=src python benchmarks/strips_roll.py \\
        --preset uav --directions opposite --seeds 700-709 --cache DIR \\
        [--scene urban] [--vegetation 0.3] [--methods planes,vgicp] [--variants default,exact,...] [--json out.jsonl]

Each seed is simulated twice into ``--cache`` (``strips_montecarlo.py``'s folder, shared with its
``--cache``, and the same survey with the trajectory errors set to 0: the simulator draws the points,
their noise and the trajectory's errors from separate streams, so the two folders hold the same hits
and the same range noise and differ only by the GNSS/INS errors). Each is read as ``calidar boresight``
reads it and adjusted once (one outer iteration) from the TRUE sensor, so that each variant's move is
the estimator's error and move/σ has RMS 1 when its σ is honest:

- ``default``: the default options (trajectory model from the smrmsg: 1 s knots, Gauss–Markov 20 / 3.5 s);
- ``exact``: the same priors (the preset's σ) on the survey WITHOUT trajectory errors: the rows' share;
- ``nomodel``: the survey without trajectory errors and no trajectory model (σ from the rows alone,
  scaled by σ0 as the engine does without priors; ``nomodel_apriori``: the same σ at variance factor 1);
- ``block05`` / ``block2``: knots every 0.5 / 2 s; ``tau``: correlation times 10 / 2 s;
- ``nocluster``: no cluster-robust sandwich; ``every``: every overlapping point (no thinning).

``--noise-scale S``: the twin without trajectory errors simulated with its range and angle noise
times S (the same random draws, scaled; folder ``…_exact_noiseS``): how the rows' share grows with
the points' noise (issue 26, sixth session). ``--noise-draws 1-8``: twins with the same hits and
other draws of that noise (folders ``…_exact_drawD``): the spread of the rows' share on one
geometry; the summary pools the draws of a seed as if they were seeds.

Per variant and method: RMS of move/σ per angle, RMS move and mean σ (mdeg); ``default − exact``, the
move the trajectory errors alone cause (same hits, same noise), against √(σ_default² − σ_exact_rows²).
"""

from __future__ import annotations

import argparse
import json
import sys
import time
from dataclasses import replace
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
from strips_montecarlo import ANGLES, ERRORS, URBAN, _simulated, seeds_of  # noqa: E402

from calidar.ingest.settings import IngestSettings  # noqa: E402
from calidar.pipelines.boresight import calibrate_inputs, load_inputs  # noqa: E402
from calidar.pipelines.strip_config import StripConfig  # noqa: E402
from calidar.sim.survey import simulate_survey, survey_config  # noqa: E402
from calidar.strips.config import CalibrationConfig, StripSettings, TrajectorySettings, matchers_named  # noqa: E402
from calidar.strips.parameters import sensor_of  # noqa: E402

SIGMA = {"airborne": (0.03, float(np.radians(0.002))), "uav": (0.02, float(np.radians(0.002)))}
#: variant → (exact-trajectory survey, trajectory settings or None, solver settings, every point)
VARIANTS = {
    "default": (False, "smrmsg", StripSettings(max_outer=1), False),
    "exact": (True, TrajectorySettings, StripSettings(max_outer=1), False),
    "nomodel": (True, None, StripSettings(max_outer=1), False),
    "block05": (False, dict(block_s=0.5), StripSettings(max_outer=1), False),
    "block2": (False, dict(block_s=2.0), StripSettings(max_outer=1), False),
    "tau": (False, dict(correlation_s=(10.0, 2.0)), StripSettings(max_outer=1), False),
    "nocluster": (False, "smrmsg", StripSettings(max_outer=1, cluster_s=None), False),
    "every": (False, "smrmsg", StripSettings(max_outer=1), True),
    "gauss": (False, "smrmsg", StripSettings(max_outer=1), False),
    "gm2": (False, "smrmsg", StripSettings(max_outer=1), False),
}
#: ``gauss``: the priors' correlation made the simulator's own (Gaussian-filtered white noise of kernel std
#: 10 s for the shifts and 2 s for the rotations, sim.motion.measured_trajectory: ρ = exp(−Δt²/4k²)), with
#: 1 % white so that the 1 s knots' matrix stays invertible
SIM_KERNEL_S = {"bias": 10.0, "tilt": 2.0}


def _gauss_priors(second_order: bool = False):
    """Patch the trajectory model's prior correlation to the simulator's process (the ``gauss`` variant),
    or (``second_order``) to a second-order Gauss–Markov process of the model's correlation times as its
    integral scale: ρ = (1 + 2|Δt|/T)·exp(−2|Δt|/T)."""
    from calidar.strips import trajectory_errors as te

    def rho(dt, kind):
        if second_order:
            a = 2.0 * dt / (20.0 if kind == "bias" else 3.5)
            return (1.0 + a) * np.exp(-a)
        return 0.99 * np.exp(-dt**2 / (4.0 * SIM_KERNEL_S[kind] ** 2)) + 0.01 * (dt == 0)

    def correlation(self, n, kind="bias"):
        k = np.arange(n) * (self.block_s or 0.0)
        return rho(np.abs(k[:, None] - k[None, :]), kind)

    def flight_correlation(self, spans):
        times = self.knot_times(spans)
        t = np.concatenate(list(times.values()))
        strip = np.repeat(np.arange(len(times)), [v.size for v in times.values()])
        R = rho(np.abs(t[:, None] - t[None, :]), "bias")
        return np.where(strip[:, None] == strip[None, :], R, (1.0 - te.OWN_STRIP_SHARE) * R)

    te.TrajectoryModel.correlation, te.TrajectoryModel.flight_correlation = correlation, flight_correlation


class _OtherNoise:
    """The shots' generator with its normal draws (the range and angle noise) taken from another
    stream; the others (which surface a beam hits in a crown, intensities) are the survey's own."""

    def __init__(self, rng: np.random.Generator, other: np.random.Generator):
        self.rng, self.other = rng, other

    def normal(self, *args, **kwargs):
        self.rng.normal(*args, **kwargs)  # the survey's stream kept in step
        return self.other.normal(*args, **kwargs)

    def __getattr__(self, name):
        return getattr(self.rng, name)


def _simulate_with_noise_draw(cfg, draw: int):
    """The survey simulated with the range and angle noise of another draw (same hits otherwise)."""
    import calidar.sim.survey as survey_module

    record, other = survey_module.record, np.random.default_rng(10_000 + draw)
    survey_module.record = lambda *a: record(*a[:-1], _OtherNoise(a[-1], other))
    try:
        return simulate_survey(cfg)
    finally:
        survey_module.record = record


def folders(cache: Path, seed: int, preset: str, directions: str, scene: str, vegetation: float,
            noise_scale: float = 1.0, noise_draw: int = 0) -> tuple[Path, Path]:
    """The survey with trajectory errors (strips_montecarlo's cache folder) and without (with the
    range and angle noise times ``noise_scale``: the same draws, scaled; ``noise_draw`` > 0: other
    draws of that noise, the same hits)."""
    noise = {"range_noise_m": 0.03} if preset == "airborne" else {}
    density = 0.3 if preset == "airborne" else 1.0
    cfg = survey_config(preset, seed=seed, density=density, vegetation=vegetation, directions=directions,
                        errors=ERRORS, **noise)
    if scene == "urban":
        cfg = replace(cfg, scene=replace(cfg.scene, **URBAN))
    with_errors = _simulated(cfg, cache / "tmp", cache, (1.0,) * 6, 0.0, density)
    tag = "" if noise_scale == 1.0 else f"_noise{noise_scale:g}"
    tag += f"_draw{noise_draw}" if noise_draw else ""
    exact = with_errors.with_name(with_errors.name + "_exact" + tag)
    if not (exact / "truth.json").exists():
        twin = replace(cfg, gnss_noise_m=0.0, attitude_noise_rad=0.0,
                       range_noise_m=cfg.range_noise_m * noise_scale,
                       angle_noise_rad=cfg.angle_noise_rad * noise_scale)
        sim = _simulate_with_noise_draw(twin, noise_draw) if noise_draw else simulate_survey(twin)
        sim.write(exact, force=True)
    return with_errors, exact


def run(folder: Path, variant: str, methods: list[str], preset: str) -> dict:
    """One adjustment from the truth: per method the move (deg), σ (deg) and σ0."""
    _, traj, solver, every = VARIANTS[variant]
    if traj == "smrmsg":
        traj = TrajectorySettings()
    elif traj is TrajectorySettings:
        traj = TrajectorySettings(sigma=SIGMA[preset])
    elif isinstance(traj, dict):
        traj = TrajectorySettings(**traj)
    config = StripConfig(CalibrationConfig(matchers=matchers_named(*methods), trajectory=traj, solver=solver,
                                           model_check=False),
                         IngestSettings(budget_points=None) if every else IngestSettings())
    inputs = load_inputs(sorted((folder / "strips").glob("*.laz")), folder / "sbet.out", folder / "sensor.toml",
                         config, truth=folder / "truth.json")
    truth = sensor_of(inputs.nominal, inputs.truth)
    out = {}
    for m, r in calibrate_inputs(replace(inputs, nominal=truth)).items():
        sol = r.solution
        out[m] = {"move_deg": [float(np.degrees(sol.values[a] - inputs.truth[a])) for a in ANGLES],
                  "sigma_deg": [float(np.degrees(sol.sigma[a])) for a in ANGLES], "sigma0": float(sol.sigma0)}
    return out


def summary(rows: list[dict]) -> str:
    """Per variant and method: RMS z, RMS move, mean σ; and the trajectory errors' own share."""
    lines = []
    by = {}
    for r in rows:
        by.setdefault((r["variant"], r["method"]), {})[r["seed"], r.get("noise_draw", 0)] = r
    for (v, m), sel in sorted(by.items()):
        mv = np.array([s["move_deg"] for s in sel.values()]) * 1e3
        sg = np.array([s["sigma_deg"] for s in sel.values()]) * 1e3
        s0 = np.array([s["sigma0"] for s in sel.values()])
        lines.append(f"{v:15s} {m:6s} n={len(mv):2d} RMS z " + "/".join(f"{x:.2f}" for x in np.sqrt(np.mean((mv / sg) ** 2, 0)))
                     + "  RMS move " + "/".join(f"{x:.3f}" for x in np.sqrt(np.mean(mv**2, 0)))
                     + "  mean σ " + "/".join(f"{x:.3f}" for x in sg.mean(0)) + f" mdeg  σ0 {s0.mean():.2f}")
        if v == "nomodel":  # the σ at variance factor 1 (the engine scales them by σ0 without priors)
            sa = sg / s0[:, None]
            lines.append(f"{'nomodel_apriori':15s} {m:6s} n={len(mv):2d} RMS z "
                         + "/".join(f"{x:.2f}" for x in np.sqrt(np.mean((mv / sa) ** 2, 0)))
                         + "  mean σ " + "/".join(f"{x:.3f}" for x in sa.mean(0)) + " mdeg")
    for m in sorted({r["method"] for r in rows}):
        d, e = by.get(("default", m), {}), by.get(("exact", m), {})
        seeds = sorted(set(d) & set(e))
        if not seeds:
            continue
        diff = np.array([np.subtract(d[s]["move_deg"], e[s]["move_deg"]) for s in seeds]) * 1e3
        sd = np.array([d[s]["sigma_deg"] for s in seeds]) * 1e3
        n_ = by.get(("nomodel", m), {})
        rows_sigma = np.array([np.divide(n_[s]["sigma_deg"], n_[s]["sigma0"]) for s in seeds if s in n_]) * 1e3
        if len(rows_sigma) == len(seeds):
            st = np.sqrt(np.maximum(sd**2 - rows_sigma**2, 0.0))
            lines.append(f"{'default-exact':15s} {m:6s} n={len(seeds):2d} RMS trajectory-caused move "
                         + "/".join(f"{x:.3f}" for x in np.sqrt(np.mean(diff**2, 0)))
                         + " mdeg against its σ √(σ_default² − σ_rows²) " + "/".join(f"{x:.3f}" for x in np.sqrt(np.mean(st**2, 0)))
                         + "  RMS ratio " + "/".join(f"{x:.2f}" for x in np.sqrt(np.mean(diff**2, 0) / np.mean(st**2, 0))))
        else:
            lines.append(f"{'default-exact':15s} {m:6s} n={len(seeds):2d} RMS trajectory-caused move "
                         + "/".join(f"{x:.3f}" for x in np.sqrt(np.mean(diff**2, 0))) + " mdeg")
    return "\n".join(lines)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--seeds", default="700-709")
    ap.add_argument("--methods", default="planes,vgicp")
    ap.add_argument("--preset", default="uav", choices=("airborne", "uav"))
    ap.add_argument("--scene", default="preset", choices=("preset", "urban"))
    ap.add_argument("--directions", default="opposite", choices=("cross", "opposite"))
    ap.add_argument("--vegetation", type=float, default=0.0)
    ap.add_argument("--variants", default="default,exact,nomodel")
    ap.add_argument("--noise-scale", type=float, default=1.0,
                    help="the twin without trajectory errors: its range and angle noise times this")
    ap.add_argument("--noise-draws", default="0",
                    help="e.g. 1-8: twins with other draws of the range and angle noise")
    ap.add_argument("--cache", type=Path, required=True)
    ap.add_argument("--json", type=Path, default=None, help="append every row; --summary reads it back")
    ap.add_argument("--summary", action="store_true", help="only print the summary of --json")
    args = ap.parse_args()
    if args.summary:
        print(summary([json.loads(x) for x in args.json.read_text().splitlines() if x.strip()]))
        return
    variants, methods, rows = args.variants.split(","), args.methods.split(","), []
    if {"gauss", "gm2"} & set(variants):
        if len(variants) != 1:
            ap.error("--variants gauss or gm2 runs alone (it patches the trajectory model)")
        _gauss_priors(variants == ["gm2"])
    for seed, draw in [(s, d) for s in seeds_of(args.seeds) for d in seeds_of(args.noise_draws)]:
        with_errors, exact = folders(args.cache, seed, args.preset, args.directions, args.scene,
                                     args.vegetation, args.noise_scale, draw)
        for v in variants:
            t = time.perf_counter()
            for m, res in run(exact if VARIANTS[v][0] else with_errors, v, methods, args.preset).items():
                row = {"seed": seed, "variant": v, "method": m, "noise_scale": args.noise_scale,
                       "noise_draw": draw, **res}
                rows.append(row)
                if args.json:
                    with args.json.open("a") as f:
                        f.write(json.dumps(row) + "\n")
                z = np.divide(res["move_deg"], res["sigma_deg"])
                print(f"seed {seed} {v:9s} {m:6s} move " + " ".join(f"{x * 1e3:+.3f}" for x in res["move_deg"])
                      + " σ " + " ".join(f"{x * 1e3:.3f}" for x in res["sigma_deg"]) + " mdeg z "
                      + " ".join(f"{x:+.2f}" for x in z) + f" σ0 {res['sigma0']:.2f} ({time.perf_counter() - t:.0f} s)",
                      flush=True)
    print(summary(rows))


if __name__ == "__main__":
    main()
