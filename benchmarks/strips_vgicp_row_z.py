"""Benchmark: where VGICP's rows' σ are too large or too small at its solution (issue 26, eighth
session). Per survey (strips_montecarlo's cached folder, read only) VGICP calibrates with default
options; at its final adjustment, the standardised residuals z = r/σ are broken down by

- the pair's kind: parallel lines (their xy long axes within 30°, same or opposite direction) or
  crossing ones;
- the larger |scan angle| of the row's two sides (a's ball and b's k points, their mean);
- the row's σ (quartiles), a's point count, a's ball radius and the two centroids' distance in
  b's plane (terciles);

with RMS z over the rows within 7σ (the rest: the tail's share), and the σ0 the global test could
read: the engine's Cauchy-weighted σ0 ÷ its t-mixture factor, the RMS with rows beyond 7 σ0
skipped, and the plain RMS.

    NUMBA_NUM_THREADS=1 OMP_NUM_THREADS=1 PYTHONPATH=src python benchmarks/strips_vgicp_row_z.py \\
        --cache DIR --seeds 1112-1117 [--method vgicp] [--set max_scatter_ratio=2] \\
        [--json out.jsonl] [--dump DIR]

``--dump DIR``: each survey's rows as DIR/<folder>.npz (residual r and σ at the solution, the pair,
parallel or not, and each side's raw and posterior scatter variance, a's count and b's leverage,
captured from :func:`calidar.strips.vgicp_planes.plane_rows`) for fitting a rows' σ model offline
(issue 26, ninth session).
"""

from __future__ import annotations

import argparse
import json
import sys
from dataclasses import replace
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
from strips_montecarlo import seeds_of  # noqa: E402

from calidar.adjust import solver  # noqa: E402
from calidar.adjust.unit_weight import skipped_sigma0  # noqa: E402
from calidar.pipelines.boresight import calibrate_inputs, load_inputs  # noqa: E402
from calidar.pipelines.strip_config import StripConfig  # noqa: E402
from calidar.strips.config import CalibrationConfig, matchers_named  # noqa: E402
from calidar.strips import processes, row_variance, vgicp, vgicp_planes  # noqa: E402
from calidar.strips.row_variance import consistency  # noqa: E402

_PLANE_ROWS = vgicp_planes.plane_rows

_CAPTURED: list = []
_solution = solver.Estimate.solution
_ROWS: dict[bytes, dict] = {}  # per plane_rows call, keyed by its σ's bytes
_POSTERIOR: list = []


def _posterior(variance_m2, dof, sampled=True):
    out = row_variance.posterior(variance_m2, dof, sampled)
    _POSTERIOR.append((np.asarray(variance_m2, float), np.broadcast_to(dof, np.shape(variance_m2)),
                       out[0]))
    return out


def _plane_rows(*args):
    _POSTERIOR.clear()
    out = _PLANE_ROWS(*args)
    sigma = np.asarray(out[5], float)
    if len(_POSTERIOR) == 2 and sigma.ndim == 1:
        (va, dof_a, pa), (vb, _, pb) = _POSTERIOR
        s = args[-1]
        count = dof_a + 1
        rough = row_variance.rough_rows_variance(pa, np.maximum(dof_a, 1), pb, 9.0,
                                                 s.roughness_factor, s.roughness_quantile)[0]
        h = (sigma**2 - s.noise_floor_m**2 - pa / count - rough) / np.maximum(pb, 1e-300)
        _ROWS[sigma.tobytes()] = {"var_a_raw": va, "count": count, "var_b_raw": vb,
                                  "var_a_post": pa, "var_b_post": pb, "leverage": h}
    return out


def _capture(self, clusters=None):
    _CAPTURED.append(self)
    return _solution(self, clusters)


def _axis(points: np.ndarray) -> np.ndarray:
    """Unit xy long axis of a strip's points."""
    xy = points[:, :2] - points[:, :2].mean(axis=0)
    return np.linalg.eigh(xy.T @ xy)[1][:, -1]


def _groups(z: np.ndarray, masks: dict[str, np.ndarray]) -> dict[str, list[float]]:
    """Per named mask: rows, RMS z within 7σ, share of rows beyond 3σ (%), share of Σz² beyond
    7σ."""
    out = {}
    for name, m in masks.items():
        if m.sum():
            zm = z[m]
            core = np.abs(zm) <= 7
            out[name] = [int(m.sum()), float(np.sqrt(np.mean(zm[core] ** 2))),
                         float(100 * np.mean(np.abs(zm) > 3)),
                         float(np.sum(zm[~core] ** 2) / np.sum(zm**2))]
    return out


def _dump(path: Path, problem, est, parallel: np.ndarray) -> None:
    """The final adjustment's rows with what their σ were made of (see the docstring)."""
    keys = ("var_a_raw", "count", "var_b_raw", "var_a_post", "var_b_post", "leverage")
    parts = {k: [] for k in keys}
    pair = []
    for i, c in enumerate(problem.corrs):
        got = _ROWS.get(np.asarray(c.sigma_m, float).tobytes())
        for k in keys:
            parts[k].append(got[k] if got else np.full(c.n_obs, np.nan))
        pair.append(np.full(c.n_obs, i))
    n = sum(c.n_obs for c in problem.corrs)
    np.savez_compressed(path, r=est.r[:n], sig=est.fit.sig[:n], parallel=parallel,
                        pair=np.concatenate(pair), **{k: np.concatenate(v) for k, v in parts.items()})


def survey(folder: Path, method: str, settings: dict, dump: Path | None = None) -> dict:
    matcher = matchers_named(method)[0]
    if settings:
        matcher = replace(matcher, settings=replace(matcher.settings, **settings))
    config = StripConfig(CalibrationConfig(matchers=(matcher,), model_check=False))
    inputs = load_inputs(sorted((folder / "strips").glob("*.laz")), folder / "sbet.out",
                         folder / "sensor.toml", config, truth=folder / "truth.json")
    _CAPTURED.clear()
    result = calibrate_inputs(inputs)[method]
    est = _CAPTURED[-1]
    fit, problem = est.fit, est.fit.problem
    z = est.r / fit.sig
    strips = {s.id: s for s in inputs.strips}
    kind, angle, count, radius, offset = [], [], [], [], []
    for c in problem.corrs:
        pa = strips[c.strip_a].points[problem.index[c.strip_a]]
        pb = strips[c.strip_b].points[problem.index[c.strip_b]]
        mean_a, mean_b = c.A @ pa, c.B @ pb
        count.append(np.diff(c.A.indptr))
        rows_a = np.repeat(np.arange(c.n_obs), np.diff(c.A.indptr))
        far = np.linalg.norm(pa[c.A.indices] - mean_a[rows_a], axis=1)
        radius.append(np.maximum.reduceat(far, c.A.indptr[:-1]) if far.size else far)
        d = mean_a - mean_b
        offset.append(np.linalg.norm(d - np.einsum("ij,ij->i", d, c.normal)[:, None] * c.normal,
                                     axis=1))
        cos = abs(_axis(strips[c.strip_a].points) @ _axis(strips[c.strip_b].points))
        kind.append(np.full(c.n_obs, cos > np.cos(np.radians(30))))
        sides = [m @ np.abs(strips[i].obs.angles[problem.index[i], 0])
                 for i, m in ((c.strip_a, c.A), (c.strip_b, c.B))]
        angle.append(np.degrees(np.maximum(*sides)))
    parallel, angle = np.concatenate(kind), np.concatenate(angle)
    if dump is not None:
        dump.mkdir(parents=True, exist_ok=True)
        _dump(dump / f"{folder.name}.npz", problem, est, parallel)
    count, radius, offset = (np.concatenate(v) for v in (count, radius, offset))
    q = np.quantile(fit.sig, [0.25, 0.5, 0.75, 0.9])
    masks = {"parallel": parallel, "crossing": ~parallel}
    masks.update({f"|scan| {lo}-{hi}°": (angle >= lo) & (angle < hi)
                  for lo, hi in ((0, 10), (10, 20), (20, 30), (30, 90))})
    for name, v in (("a's points", count), ("a's ball radius", radius),
                    ("centroids apart", offset)):
        t = np.quantile(v, [1 / 3, 2 / 3])
        masks.update({f"{name} {k + 1}/3": (v >= lo) & (v < hi)
                      for k, (lo, hi) in enumerate(zip([-np.inf, *t], [*t, np.inf]))})
    edges = [0.0, *q, np.inf]
    names = ["σ 0-25 %", "σ 25-50 %", "σ 50-75 %", "σ 75-90 %", "σ 90-100 %"]
    masks.update({name: (fit.sig >= edges[k]) & (fit.sig < edges[k + 1])
                  for k, name in enumerate(names)})
    sol = result.solution
    strip_extra = sol.extra.get("strips", {})
    truth = inputs.truth
    angles = ("boresight_roll", "boresight_pitch", "boresight_yaw")
    return {"folder": folder.name, "method": method, "settings": settings, "rows": int(z.size),
            "z": [float((sol.values[a] - truth[a]) / sol.sigma[a]) for a in angles],
            "sigma0_t_model": float(sol.sigma0 / np.sqrt(consistency(
                strip_extra.get("robust"), strip_extra.get("row_dof")))),
            "sigma0_skipped": float(skipped_sigma0(z, share=fit.share)[0]),
            "rms": float(np.sqrt(np.mean(z**2))), "groups": _groups(z, masks)}


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--cache", type=Path, required=True)
    ap.add_argument("--seeds", required=True)
    ap.add_argument("--method", default="vgicp")
    ap.add_argument("--json", type=Path, default=None)
    ap.add_argument("--set", nargs="*", default=[], metavar="KEY=VALUE",
                    help="matcher settings (numbers), e.g. max_scatter_ratio=2")
    ap.add_argument("--dump", type=Path, default=None, help="write each survey's rows here")
    args = ap.parse_args()
    solver.Estimate.solution = _capture
    vgicp_planes.posterior = _posterior
    vgicp.plane_rows = _plane_rows
    processes.MIN_POINTS = 1 << 62  # every pair in this process, where plane_rows is wrapped
    for seed in seeds_of(args.seeds):
        folder = next(p for p in sorted(args.cache.iterdir()) if f"_seed{seed}_" in p.name)
        row = survey(folder, args.method,
                     {k: float(v) for k, v in (kv.split("=", 1) for kv in args.set)}, args.dump)
        if args.json:
            with args.json.open("a") as f:
                f.write(json.dumps(row) + "\n")
        print(f"{row['folder']} {args.method}: z " + " / ".join(f"{v:+.2f}" for v in row["z"])
              + f"; σ0 t-model {row['sigma0_t_model']:.3f}, skipped {row['sigma0_skipped']:.3f}, "
              f"RMS {row['rms']:.3f} ({row['rows']} rows)", flush=True)
        for name, (n, rms, tail, gross) in row["groups"].items():
            print(f"    {name:20s} {n:6d} rows  RMS z (|z| ≤ 7) {rms:.2f}  beyond 3σ {tail:.2f} %  "
                  f"Σz² beyond 7σ {100 * gross:.0f} %", flush=True)


if __name__ == "__main__":
    main()
