"""Benchmark: are VGICP's rows' σ right where the angles listen? The rows' residuals at the truth,
weighted by each row's share of an angle's variance (issue 26, twelfth session: VGICP's rows'
share too wide on UAV opposite lines).

    NUMBA_NUM_THREADS=1 OMP_NUM_THREADS=1 PYTHONPATH=src python \\
        benchmarks/strips_vgicp_row_influence.py --preset uav --directions opposite \\
        --seeds 1224-1229 --cache DIR [--set noise_floor_m=0] [--full] [--with-errors] \\
        [--json out.jsonl] [--summary [--against DRAWS.jsonl]]

Each survey's twin without trajectory errors (``strips_roll.py``'s ``…_exact`` folder in
``--cache``, simulated there when missing) is adjusted once from the TRUE sensor with the preset's
trajectory priors, VGICP only. At the solution, row i's share of angle k's rows' variance is
a_ik = (N⁻¹J_iᵀ)_k² w_i (Σ_i a_ik = the rows' share [N⁻¹JᵀWJN⁻¹]_kk, w_i the IRLS weight over
σ_i²), and z_i = r0_i/σ_i its residual at the truth (the rows' noise and the scene's model errors
only). The influence-weighted mean of z² (rows beyond 7σ left out), Σ a_ik z_i² / Σ a_ik, is 1
when the σ of the rows that carry angle k are right on average; below 1 they are too wide. Split
by the row's σ parts (the share of ``noise_floor_m``² in σ², and b's white noise) and its
normal's |n_z|; ``--set`` overrides ``[vgicp]`` settings (σ model variants). ``--with-errors``:
the survey itself (with its trajectory errors, the smrmsg's priors) instead of its twin.

``--full``: the twin calibrated as ``calidar boresight`` would (from the nominal sensor, every outer
iteration): its error is the rows' whole effect on the default estimate, RMS 1 against the share
when the rows' σ are right. ``--summary --against DRAWS.jsonl`` (``strips_yaw_draws.py --json``
rows of the same seeds WITH trajectory errors) sets the twins' errors beside that split: its rows'
part (actual − trajectory part) against the twin's error, and the actual error regressed on the
trajectory part and the twin's error together.
"""

from __future__ import annotations

import argparse
import json
import sys
from dataclasses import replace
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
from strips_montecarlo import ANGLES, record, recorded, seeds_of  # noqa: E402
from strips_roll import SIGMA, folders  # noqa: E402

from calidar.adjust import solver  # noqa: E402
from calidar.ingest.settings import IngestSettings  # noqa: E402
from calidar.pipelines.boresight import calibrate_inputs, load_inputs  # noqa: E402
from calidar.pipelines.strip_config import StripConfig  # noqa: E402
from calidar.strips import calibrate, vgicp_planes  # noqa: E402
from calidar.strips.config import CalibrationConfig, StripSettings, TrajectorySettings  # noqa: E402
from calidar.strips.config import matchers_named  # noqa: E402
from calidar.strips.parameters import sensor_of  # noqa: E402

CAPTURED: list = []
PARTS: list = []
_solution = solver.Estimate.solution
_row_sigma = vgicp_planes.row_sigma


def _capture(self, clusters=None):
    CAPTURED.append(self)
    return _solution(self, clusters)


def _parts(var_a, count_a, var_b, dof_b, leverage, settings):
    """row_sigma, recording each row's parts (m²): a's, b's, the floor."""
    from calidar.strips.row_variance import posterior
    sigma, dof = _row_sigma(var_a, count_a, var_b, dof_b, leverage, settings)
    pa = posterior(var_a, count_a - 1)[0] / count_a
    pb = posterior(var_b, dof_b)[0] * leverage
    PARTS.append(np.column_stack([pa, pb, np.full(pa.size, settings.noise_floor_m**2),
                                  count_a.astype(float)]))
    return sigma, dof


def classes(est, problem_parts) -> dict:
    fit = est.fit
    J = fit.jacobian(est.x)
    N = fit.normal_equations(J, est.w)[0]
    Ninv = np.linalg.inv(N)
    ang = [next(i for i, p in enumerate(fit.free) if p.name == a) for a in ANGLES]
    G = (J @ Ninv[:, ang]) if not hasattr(J, "tocsr") else np.asarray(J.tocsr() @ Ninv[:, ang])
    a = G**2 * est.w[:, None]  # (n, 3) each row's share of the angles' rows' variance
    z = fit.r0 / fit.sig
    rob = est.w * fit.sig**2  # the robust weights 0..1
    ok = np.abs(z) <= 7.0
    prob = fit.problem
    nz = np.concatenate([np.abs(c.normal[:, 2]) for c in prob.corrs])
    parts = problem_parts
    sig2 = fit.sig**2
    out = {"all": _stat(a, z, rob, ok), "share_deg": np.degrees(np.sqrt(a.sum(0))).tolist(),
           "model_deg": np.degrees(np.sqrt(np.diag(Ninv)[ang])).tolist()}
    if parts is not None and parts.shape[0] == z.size:
        fl = parts[:, 2] / sig2
        for lo, hi in ((0, 0.15), (0.15, 0.3), (0.3, 0.5), (0.5, 1.01)):
            out[f"floor {lo:g}-{hi:g}"] = _stat(a, z, rob, ok & (fl >= lo) & (fl < hi))
        share_b = parts[:, 1] / sig2
        for lo, hi in ((0, 0.25), (0.25, 0.5), (0.5, 1.01)):
            out[f"b's {lo:g}-{hi:g}"] = _stat(a, z, rob, ok & (share_b >= lo) & (share_b < hi))
        out["mean parts a/b/floor"] = [float(np.sum(a[:, 1] * parts[:, k] / sig2) / a[:, 1].sum())
                                       for k in range(3)]
        out["sigma_mm q25/50/75"] = (1e3 * np.quantile(fit.sig, [0.25, 0.5, 0.75])).tolist()
        out["count q25/50/75"] = np.quantile(parts[:, 3], [0.25, 0.5, 0.75]).tolist()
    for lo, hi in ((0, 0.9), (0.9, 0.97), (0.97, 0.995), (0.995, 1.01)):
        out[f"|nz| {lo:g}-{hi:g}"] = _stat(a, z, rob, ok & (nz >= lo) & (nz < hi))
    return out


def _stat(a, z, rob, sel) -> list:
    """[share of the rows' variance in the class (per angle), Σ a z²/Σ a (per angle), the same
    with the robust weights (Σ a·rob·z²/Σ a: the HC0 meat's reading), plain RMS z, rows]."""
    if not sel.any():
        return [[0.0] * 3, [np.nan] * 3, [np.nan] * 3, np.nan, 0]
    s = a[sel]
    return [(s.sum(0) / a.sum(0)).tolist(), (s.T @ z[sel] ** 2 / s.sum(0)).tolist(),
            (s.T @ (rob[sel] * z[sel] ** 2) / s.sum(0)).tolist(),
            float(np.sqrt(np.mean(z[sel] ** 2))), int(sel.sum())]


def run(folder: Path, vgicp_set: dict, full: bool = False, errors: bool = False
        ) -> tuple[dict, list]:
    traj = TrajectorySettings() if errors else TrajectorySettings(sigma=SIGMA["uav"])
    cal = CalibrationConfig(matchers=matchers_named("vgicp"), trajectory=traj,
                            model_check=False)
    if not full:
        cal = replace(cal, solver=StripSettings(max_outer=1))
    if vgicp_set:
        m = cal.matchers[0]
        cal = replace(cal, matchers=(replace(m, settings=replace(m.settings, **vgicp_set)),))
    config = StripConfig(cal, IngestSettings())
    inputs = load_inputs(sorted((folder / "strips").glob("*.laz")), folder / "sbet.out",
                         folder / "sensor.toml", config, truth=folder / "truth.json")
    truth = sensor_of(inputs.nominal, inputs.truth)
    CAPTURED.clear()
    PARTS.clear()
    res = calibrate_inputs(inputs if full else replace(inputs, nominal=truth))["vgicp"]
    est = CAPTURED[-1]
    parts = np.concatenate(PARTS) if PARTS else None
    n = est.fit.r0.size
    parts = parts[-n:] if parts is not None and parts.shape[0] >= n else None
    move = [float(np.degrees(res.solution.values[k] - inputs.truth[k])) for k in ANGLES]
    return classes(est, parts), move


def summary(rows: list[dict]) -> str:
    out = []
    for key in rows[0]["classes"]:
        vals = [r["classes"][key] for r in rows]
        if key.endswith("_deg"):
            continue
        if not isinstance(vals[0], list) or not isinstance(vals[0][0], list):
            out.append(f"  {key:22s} " + " ".join(f"{np.mean([v[i] for v in vals]):.3g}"
                                                  for i in range(len(vals[0]))))
            continue
        share = np.mean([v[0] for v in vals], 0)
        w = np.array([v[0] for v in vals])
        m = np.nansum(w * np.array([v[1] for v in vals]), 0) / np.sum(w, 0)
        mr = np.nansum(w * np.array([v[2] for v in vals]), 0) / np.sum(w, 0)
        out.append(f"  {key:22s} share " + "/".join(f"{x:.2f}" for x in share)
                   + "  Σaz²/Σa " + "/".join(f"{x:.2f}" for x in m)
                   + "  robust " + "/".join(f"{x:.2f}" for x in mr)
                   + f"  RMS z {np.nanmean([v[3] for v in vals]):.2f}"
                   + f"  rows {int(np.sum([v[4] for v in vals]))}")
    return "\n".join(out)


def against(rows: list[dict], draws: list[dict]) -> str:
    """The twins' errors (no trajectory errors) beside the draws split of the same seeds."""
    tw = {r["seed"]: r for r in rows}
    mc = {r["seed"]: r for r in draws if r["method"] == "vgicp"}
    seeds = sorted(set(tw) & set(mc))
    sh = np.array([mc[s]["rows_sigma_mdeg"] for s in seeds])
    ex = np.array([tw[s]["move_deg"] for s in seeds]) * 1e3
    act = np.array([mc[s]["actual_mdeg"] for s in seeds])
    traj = np.array([mc[s]["traj_mdeg"] for s in seeds])
    f = lambda x: "/".join(f"{v:.2f}" for v in x)  # noqa: E731
    rms = lambda x: np.sqrt(np.mean((x / sh) ** 2, 0))  # noqa: E731
    out = [f"  {len(seeds)} surveys: RMS ÷ rows' share: twin {f(rms(ex))}, the split's rows' part "
           f"{f(rms(act - traj))} (±{1 / np.sqrt(2 * len(seeds)):.2f})"]
    for k, name in enumerate(ANGLES):
        X = np.column_stack([traj[:, k], ex[:, k]])
        coef = np.linalg.lstsq(X, act[:, k], rcond=None)[0]
        res = act[:, k] - X @ coef
        se = np.sqrt(np.diag(np.linalg.inv(X.T @ X)) * np.sum(res**2) / max(len(seeds) - 2, 1))
        out.append(f"  {name}: actual = {coef[0]:.2f} (±{se[0]:.2f}) · trajectory part + "
                   f"{coef[1]:.2f} (±{se[1]:.2f}) · twin's error, the rest's RMS ÷ share "
                   f"{np.sqrt(np.mean((res / sh[:, k]) ** 2)):.2f}; corr(trajectory part, twin) "
                   f"{np.corrcoef(traj[:, k], ex[:, k])[0, 1]:+.2f}")
    return "\n".join(out)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--seeds", default="1224-1229")
    ap.add_argument("--preset", default="uav", choices=("uav",))
    ap.add_argument("--directions", default="opposite", choices=("cross", "opposite"))
    ap.add_argument("--vegetation", type=float, default=0.0)
    ap.add_argument("--cache", type=Path, required=True)
    ap.add_argument("--set", nargs="*", default=[], help="[vgicp] key=value")
    ap.add_argument("--full", action="store_true",
                    help="the default run instead: from the nominal sensor, every outer iteration "
                    "(the classes then read the last adjustment's start, not the truth)")
    ap.add_argument("--with-errors", action="store_true",
                    help="the survey with its trajectory errors, not its twin")
    ap.add_argument("--json", type=Path, default=None)
    ap.add_argument("--summary", action="store_true")
    ap.add_argument("--against", type=Path, default=None, help="strips_yaw_draws.py rows")
    args = ap.parse_args()
    if args.summary:
        rows = recorded(args.json)
        print(summary(rows))
        print(moves(rows))
        if args.against:
            print(against(rows, recorded(args.against)))
        return
    vset = {k: int(v) if v.isdigit() else float(v)
            for k, v in (s.split("=") for s in args.set)}
    solver.Estimate.solution = _capture
    vgicp_planes.row_sigma = _parts
    calibrate.PROCESSES = 1  # the pairs in this process: the σ parts recorded here
    rows = []
    for seed in seeds_of(args.seeds):
        survey, exact = folders(args.cache, seed, args.preset, args.directions, "scene",
                                args.vegetation)
        cls, move = run(survey if args.with_errors else exact, vset, args.full, args.with_errors)
        row = {"seed": seed, "directions": args.directions, "set": args.set, "full": args.full,
               "with_errors": args.with_errors,
               "move_deg": move,
               "classes": cls}
        rows.append(row)
        record(row, args.json)
        print(f"seed {seed}: " + json.dumps(cls["all"]), flush=True)
    print(summary(rows))
    print(moves(rows))


def moves(rows: list[dict]) -> str:
    """RMS of the move (the rows' part: no trajectory errors) over the rows' share σ and over
    N⁻¹'s σ."""
    mv = np.array([r["move_deg"] for r in rows])
    sh = np.array([r["classes"]["share_deg"] for r in rows])
    md = np.array([r["classes"]["model_deg"] for r in rows])
    ratio = np.sqrt(np.mean((mv / sh) ** 2, 0))
    spread = 1 / np.sqrt(2 * len(rows))
    return (f"  {len(rows)} surveys: RMS move/share " + "/".join(f"{x:.2f}" for x in ratio)
            + f" (±{spread:.2f}); move/N⁻¹σ "
            + "/".join(f"{x:.2f}" for x in np.sqrt(np.mean((mv / md) ** 2, 0))))


if __name__ == "__main__":
    main()
