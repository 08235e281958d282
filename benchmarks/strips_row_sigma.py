"""Benchmark: are the rows' σ right at the truth, and what does the global test read there? (issue 26)

    NUMBA_NUM_THREADS=1 PYTHONPATH=src python benchmarks/strips_row_sigma.py --seeds 7,8 [--preset airborne] \\
        [--directions cross] [--scene urban|flat|smooth] [--methods planes,vgicp] [--cache DIR] [--estimators] \\
        [--density 0.3 --range-noise 0.03]   # the airborne Monte-Carlo's survey (strips_montecarlo.py)

Each seed: ``calidar simulate survey --preset P --seed S --boresight-error 0.05,-0.03,0.1`` WITHOUT trajectory
errors (``--cache DIR`` keeps it), read as ``calidar boresight`` reads it, every overlap re-georeferenced with
the TRUE sensor and matched with each method's default rows: the residuals then hold nothing but the points'
noise. Per method: rows (walls |n_z| < 0.5 left out, as few as they are), RMS of residual/σ (1 when the σ are
right) over all, flat (|n_z| ≥ 0.97) and roofs, by quartile of σ (right row by row, quiet or rough), the
MAD-scale of residual/σ, and the global test's σ0 as the engine and the verdict compute it (Cauchy weights on
z / 1.4826·MAD, ÷ their consistency for Student-t residuals with the rows' degrees of freedom; also ÷ the
normal factor) against its χ² 95 % range; beside it the RMS of residual/σ with the rows beyond 7 σ0 skipped as
gross (``calidar.adjust.unit_weight.skipped_sigma0``, recorded in every robust solution; at the truth no parameter
is estimated, so no redundancy correction).

``--estimators`` (issue 26, fifth session): per method also the |z| quantiles against the normal's and the rows' t
mixture's, and what σ0 estimators read — the plain RMS, the old Cauchy-weighted one, an M-estimator of scale with
the Cauchy ρ made consistent for the rows' t mixture (δ = E[ρ(u)] under it, Maronna, Martin & Yohai 2006 §2.5), the
skipped RMS — each with the change 1 % of the rows given 10σ errors (of either sign) makes.
"""

from __future__ import annotations

import argparse
import sys
from dataclasses import replace
from pathlib import Path

import numpy as np
from scipy.special import chdtri, gammaln, stdtr

sys.path.insert(0, str(Path(__file__).resolve().parent))
from strips_montecarlo import URBAN, seeds_of  # noqa: E402

from calidar.adjust.solver import robust_weights  # noqa: E402
from calidar.adjust.unit_weight import skipped_sigma0  # noqa: E402
from calidar.pipelines.boresight import load_inputs  # noqa: E402
from calidar.sim.survey import simulate_survey, survey_config  # noqa: E402
from calidar.strips.outer_loop import Run  # noqa: E402
from calidar.strips.config import StripSettings  # noqa: E402
from calidar.strips.matchers import TiePlanes, Vgicp  # noqa: E402
from calidar.strips.parameters import sensor_of  # noqa: E402
from calidar.strips.problem import georeference  # noqa: E402
from calidar.strips.row_variance import consistency, dof_summary  # noqa: E402
from calidar.strips.verdict import robust_consistency  # noqa: E402

ERRORS_DEG = {"boresight_roll": 0.05, "boresight_pitch": -0.03, "boresight_yaw": 0.1}  #: issue 26's survey
MATCHERS = {"planes": TiePlanes, "vgicp": Vgicp}


#: ``--scene flat``: the preset's scene without relief, rough band or buildings (a plane and trees);
#: ``--scene smooth``: without its rough band
SCENES = {"urban": URBAN, "flat": {"relief_m": 0.0, "rough_sigma_m": 0.0, "building_density_per_km2": 0.0},
          "smooth": {"rough_sigma_m": 0.0}}


def survey_folder(preset: str, seed: int, directions: str, scene: str, cache: Path,
                  density: float | None = None, range_noise_m: float | None = None) -> Path:
    """The survey simulated without trajectory errors (once, into ``cache``); ``density``,
    ``range_noise_m``: other than the preset's (None: the preset's)."""
    other = {k: v for k, v in (("density", density), ("range_noise_m", range_noise_m)) if v is not None}
    tag = "".join(f"_{k}{v:g}" for k, v in other.items())
    folder = cache / f"{preset}_{directions}_seed{seed}_{scene}{tag}_exact"
    if not (folder / "truth.json").exists():
        cfg = survey_config(preset, seed=seed, directions=directions, gnss_noise_m=0.0, attitude_noise_rad=0.0,
                            errors={k: np.radians(v) for k, v in ERRORS_DEG.items()}, **other)
        if scene in SCENES:
            cfg = replace(cfg, scene=replace(cfg.scene, **SCENES[scene]))
        simulate_survey(cfg).write(folder, force=True)
    return folder


def rows_at_truth(folder: Path, method: str) -> np.ndarray:
    """(|n_z|, residual m, σ m, degrees of freedom of σ²) of every row of every pair, matched at the true sensor."""
    inputs = load_inputs(sorted((folder / "strips").glob("*.laz")), folder / "sbet.out", folder / "sensor.toml",
                         truth=folder / "truth.json")
    truth = sensor_of(inputs.nominal, inputs.truth)
    run = Run.start(inputs.strips, truth, MATCHERS[method](), StripSettings())
    at = {i: georeference(truth, None, run.poses[i], run.by_id[i].time[idx]) for i, idx in run.need.items()}
    out = []
    for o in run.overlaps:
        pa, pb = (at[i][run.poses[i].rows_of(idx)] for i, idx in ((o.a, o.index_a), (o.b, o.index_b)))
        c = run.matcher.match(o.a, pa, o.b, pb)
        r = c.residuals(pa, pb)
        out.append(np.column_stack([np.abs(c.normal[:, 2]), r, np.broadcast_to(c.sigma_m, r.shape),
                                    np.broadcast_to(c.dof, r.shape)]))
    return np.concatenate(out)


def weighted_sigma0(z: np.ndarray, dof: np.ndarray | None = None) -> float:
    """The engine's σ0 (Cauchy weights on z over its MAD scale) ÷ the verdict's consistency factor: for Student-t
    rows with these degrees of freedom, or (None) for normal ones."""
    s = 1.4826 * np.median(np.abs(z - np.median(z)))
    w = robust_weights(z / s, "cauchy")
    factor = robust_consistency("cauchy") if dof is None else consistency("cauchy", dof_summary(dof))
    return float(np.sqrt(np.sum(w * z * z) / np.sum(w) / factor))


QUANTILES = (0.5, 0.9, 0.99, 0.999)


def _mixture(dof: np.ndarray):
    """(ν, unit) of the rows' t mixture (:func:`dof_summary`'s representative ν; t_ν · unit has variance 1)."""
    nu = np.clip(np.asarray(dof_summary(dof) or [1e9], float), 2.05, 1e9)
    return nu, np.sqrt((nu - 2.0) / nu)


def mixture_quantiles(dof: np.ndarray) -> list[float]:
    """The |z| quantiles :data:`QUANTILES` of the rows' t mixture (bisection on its CDF)."""
    nu, unit = _mixture(dof)
    out = []
    for q in QUANTILES:
        lo, hi = 0.0, 60.0
        for _ in range(60):
            mid = 0.5 * (lo + hi)
            lo, hi = (mid, hi) if np.mean(2.0 * stdtr(nu, mid / unit) - 1.0) < q else (lo, mid)
        out.append(0.5 * (lo + hi))
    return out


def m_scale(z: np.ndarray, dof: np.ndarray, k: float = 2.385) -> float:
    """The M-estimator of scale s with mean ρ(z/s) = E[ρ(u)] for u from the rows' t mixture, ρ(u) = log(1 + (u/k)²)
    (the Cauchy loss; trapezoid rule on a sinh grid, bisection on log s)."""
    nu, unit = _mixture(dof)
    rho = lambda u: np.log1p((u / k) ** 2)  # noqa: E731
    x = np.sinh(np.linspace(-9.0, 9.0, 6001))
    log_c = gammaln((nu + 1) / 2) - gammaln(nu / 2) - 0.5 * np.log(nu * np.pi)
    dens = np.exp(log_c[:, None] - (nu[:, None] + 1) / 2 * np.log1p(x[None, :] ** 2 / nu[:, None]))
    delta = float(np.mean(np.sum(dens * np.gradient(x) * rho(unit[:, None] * x[None, :]), axis=1)))
    lo, hi = 0.1, 10.0
    for _ in range(60):
        mid = np.sqrt(lo * hi)
        lo, hi = (mid, hi) if np.mean(rho(z / mid)) > delta else (lo, mid)
    return float(np.sqrt(lo * hi))


def estimators(label: str, rows: np.ndarray) -> str:
    """The |z| quantiles and what each σ0 estimator reads, with 1 % of the rows given 10σ errors (see the docstring)."""
    rows = rows[rows[:, 0] >= 0.5]
    z, dof = rows[:, 1] / rows[:, 2], rows[:, 3]
    rng = np.random.default_rng(1)
    bad = z.copy()
    i = rng.choice(z.size, z.size // 100, replace=False)
    bad[i] += 10.0 * rng.choice([-1.0, 1.0], i.size)
    reads = {"RMS": lambda v: float(np.sqrt(np.mean(v * v))), "Cauchy-weighted": lambda v: weighted_sigma0(v, dof),
             "M-scale": lambda v: m_scale(v, dof), "skipped": lambda v: skipped_sigma0(v)[0]}
    text = "; ".join(f"{k} {f(z):.3f} ({100 * (f(bad) / f(z) - 1):+.1f} %)" for k, f in reads.items())
    return (f"{label}: |z| quantiles {'/'.join(f'{q:.2f}' for q in np.quantile(np.abs(z), QUANTILES))} (t mixture "
            + "/".join(f"{q:.2f}" for q in mixture_quantiles(dof)) + f"); σ0 {text} (1 % of 10σ errors)")


def line(label: str, rows: np.ndarray) -> str:
    rows = rows[rows[:, 0] >= 0.5]
    nz, r, s, dof = rows.T
    z = r / s
    rms = lambda m: np.sqrt(np.mean(z[m] ** 2))  # noqa: E731
    q = np.digitize(s, np.quantile(s, [0.25, 0.5, 0.75]))
    lo, hi = (np.sqrt(chdtri(z.size, 1.0 - p) / z.size) for p in (0.025, 0.975))
    return (f"{label}: {z.size:6d} rows, RMS σ {np.sqrt(np.mean(s**2)) * 1e3:5.2f} mm, RMS z {rms(slice(None)):.3f} "
            f"(flat {rms(nz >= 0.97):.3f}, roofs {rms(nz < 0.97):.3f}; by σ quartile "
            + "/".join(f"{rms(q == k):.2f}" for k in range(4))
            + f"), MAD-scale z {1.4826 * np.median(np.abs(z)):.3f}, global test σ0 {weighted_sigma0(z, dof):.3f} "
            f"(÷ the normal factor: {weighted_sigma0(z):.3f}; median ν {np.median(dof):.0f}; χ² 95 % range "
            f"{lo:.3f}–{hi:.3f}); skipped RMS {skipped_sigma0(z)[0]:.3f} ({skipped_sigma0(z)[1]} rows beyond 7 σ0)")


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--seeds", default="7")
    ap.add_argument("--preset", default="uav", choices=("uav", "airborne"))
    ap.add_argument("--directions", default="cross", choices=("cross", "opposite"))
    ap.add_argument("--scene", default="preset", choices=("preset", *SCENES))
    ap.add_argument("--methods", default="planes,vgicp")
    ap.add_argument("--cache", type=Path, default=Path("/tmp/calidar_row_sigma"))
    ap.add_argument("--estimators", action="store_true", help="also what each σ0 estimator reads (issue 26)")
    ap.add_argument("--density", type=float, help="the simulator's density (default: the preset's)")
    ap.add_argument("--range-noise", type=float, help="range noise, m (default: the preset's; the "
                    "airborne Monte-Carlo's: --density 0.3 --range-noise 0.03)")
    args = ap.parse_args()
    pooled: dict[str, list] = {}
    for seed in seeds_of(args.seeds):
        folder = survey_folder(args.preset, seed, args.directions, args.scene, args.cache, args.density,
                               args.range_noise)
        for method in args.methods.split(","):
            rows = rows_at_truth(folder, method)
            pooled.setdefault(method, []).append(rows)
            print(line(f"{args.preset} {args.directions} {args.scene} seed {seed} {method:6s}", rows), flush=True)
            if args.estimators:
                print(estimators(f"{args.preset} {args.directions} {args.scene} seed {seed} {method:6s}", rows),
                      flush=True)
    for method, parts in pooled.items():
        if len(parts) > 1:
            print(line(f"{args.preset} {args.directions} {args.scene} pooled  {method:6s}", np.concatenate(parts)))
        if args.estimators:
            print(estimators(f"{args.preset} {args.directions} {args.scene} pooled  {method:6s}",
                             np.concatenate(parts)))


if __name__ == "__main__":
    main()
