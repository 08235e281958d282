"""Benchmark (issue 26, eighth session): the outer loop's crawl on a survey folder — per outer
iteration the pitch's error/σ, the rows and the trajectory corrections; whether each iteration's
adjustment had converged on its own rows; and whether re-matched tie-plane rows follow the
adjustment's linear model when the state is moved on purpose.

    export NUMBA_NUM_THREADS=1 OMP_NUM_THREADS=1 PYTHONPATH=src
    nice -n 10 python benchmarks/crawl_response.py /work/bigsim_gpitch/cells_1000M [VARIANT [K,…]]

VARIANT: ``benchmarks/pitch_bisect.py``'s key=value settings (e.g. ``max_outer=6``,
``robust=none``). Printed:

- per outer iteration: pitch error/σ (the final σ), rows, the trajectory shifts along and across
  each line (RMS and largest over the knots, mm), the share of rows with robust weight < 0.5;
- ``refine``: each adjustment iterated further on its own rows (to 10⁻⁶ of each σ): how far the
  pitch moves (0: the inner solve had converged, the crawl is the re-matching's);
- ``move``: at the last iteration's state, four deliberate moves (boresight pitch +2·10⁻⁵ rad,
  the first line's knots +20 mm along its track, every knot's horizontal shift N(0, 10 mm), the
  last outer step K times over, K = 2 unless given: the crawl's own direction); the
  rows matched again at the moved state and paired with the unmoved rows by b's patch cell: β, the
  slope of (re-matched − model) on the model's change J·d (0: the rows follow the linear model;
  −1: they stay where the last matching put them), flat (tilt < 0.05) and sloped rows apart, and
  the rows' gradient along d, dᵀJᵀW r, before the move, after it by the model, after re-matching.
"""

from __future__ import annotations

import json
import sys
from dataclasses import replace
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
import pitch_bisect  # noqa: E402  (the variants' configurations)

import calidar.strips.outer_loop as loop  # noqa: E402
from calidar.strips.problem import StripProblem  # noqa: E402

PITCH = "boresight_pitch"
SOLVES: list = []  #: (run, parameters in, estimate, problem) of every outer iteration's solve


def recorded() -> None:
    """Keep every outer iteration's solve in SOLVES."""
    solve = loop.Run.solve

    def kept(self, corrs, params, step, scale):
        est, problem = solve(self, corrs, params, step, scale)
        SOLVES.append((self, params, est, problem))
        return est, problem

    loop.Run.solve = kept


def shifts_mm(run, values: dict) -> tuple[np.ndarray, np.ndarray]:
    """Every knot's trajectory shift along and across its line (mm)."""
    along, across = [], []
    for sid, h in run.headings().items():
        e, n, k = [], [], 0
        while f"trajectory_bias_east_{sid}_{k}" in values:
            e.append(values[f"trajectory_bias_east_{sid}_{k}"])
            n.append(values[f"trajectory_bias_north_{sid}_{k}"])
            k += 1
        e, n = np.array(e), np.array(n)
        along.append(e * np.sin(h) + n * np.cos(h))
        across.append(e * np.cos(h) - n * np.sin(h))
    return 1e3 * np.concatenate(along), 1e3 * np.concatenate(across)


def b_cells(problem: StripProblem, values: dict) -> list[np.ndarray]:
    """Per correspondence set the 0.5 m cell of each row's b-side centroid at ``values``."""
    sensor, fix = problem._read(values)
    out = []
    for k, (c, sides, times) in enumerate(zip(problem.corrs, problem.centroids,
                                              problem.row_time)):
        side, t, f = sides[1], times[1], fix.get(c.strip_b)
        q = side(sensor)
        if f is not None:
            q = f.apply(q, side.r, t, side.rowsum, problem._row_knots(k, 1, f, t))
        ij = np.floor(q[:, :2] / side.rowsum[:, None] / 0.5).astype(np.int64)
        out.append(ij[:, 0] * 1_000_003 + ij[:, 1])
    return out


def paired(p0: StripProblem, x0: dict, p1: StripProblem, x1: dict):
    """Row positions of the rows of p0 and p1 in the same pair and b-side cell."""
    k0, k1 = b_cells(p0, x0), b_cells(p1, x1)
    off0 = np.cumsum([0] + [c.n_obs for c in p0.corrs])
    off1 = np.cumsum([0] + [c.n_obs for c in p1.corrs])
    where = {(c.strip_a, c.strip_b): j for j, c in enumerate(p1.corrs)}
    i0, i1 = [], []
    for j, c in enumerate(p0.corrs):
        jj = where.get((c.strip_a, c.strip_b))
        if jj is not None:
            _, a, b = np.intersect1d(k0[j], k1[jj], return_indices=True)
            i0.append(off0[j] + a)
            i1.append(off1[jj] + b)
    return np.concatenate(i0), np.concatenate(i1)


def rows_at(run, params, values: dict) -> StripProblem:
    corrs, _, _ = run.match(values, 1, None, lambda *a: None)
    return StripProblem(run.nominal, run.poses, corrs, params, run._times(), run.model, run.spans)


def response(run, params, label: str, move: dict) -> None:
    """The deliberate ``move`` (name → change, SI): β and the gradients (module docstring)."""
    x0 = params.values()
    names = params.free_names
    d = np.array([move.get(n, 0.0) for n in names])
    x1 = {n: v + move.get(n, 0.0) for n, v in x0.items()}
    p0, p1 = rows_at(run, params, x0), rows_at(run, params, x1)
    J = p0.jacobian(x0)
    jd = J @ d
    r_model, r_new = p0(x1), p1(x1)
    i0, i1 = paired(p0, x0, p1, x1)
    normal = np.concatenate([c.normal for c in p0.corrs])[i0]
    tilt = np.hypot(normal[:, 0], normal[:, 1])
    w, x, dr = 1.0 / p0.sigma[i0] ** 2, jd[i0], r_new[i1] - r_model[i0]
    print(f"move [{label}]: rows {p0.sigma.size} -> {p1.sigma.size}, {i0.size} in the same cell; "
          f"J·d RMS {1e3 * np.sqrt(np.mean(x ** 2)):.2f} mm", flush=True)
    for part, m in (("all", tilt >= 0), ("flat", tilt < 0.05), ("sloped", tilt >= 0.05)):
        info = np.sum(w[m] * x[m] ** 2)
        beta = np.sum(w[m] * x[m] * dr[m]) / info
        se = np.sqrt(np.sum((w[m] * x[m] * (dr[m] - beta * x[m])) ** 2)) / info
        print(f"  {part:6s} {m.sum():6d} rows  beta {beta:+.3f} ± {se:.3f}  dᵀJᵀWJd {info:.1f}")
    r0 = p0(x0)
    g0 = np.sum(jd * r0 / p0.sigma ** 2)
    g_model = np.sum(jd * r_model / p0.sigma ** 2)
    jd1 = p1.jacobian(x1) @ d
    g_new = np.sum(jd1 * r_new / p1.sigma ** 2)
    kept0, kept1 = np.zeros(jd.size, bool), np.zeros(jd1.size, bool)
    kept0[i0], kept1[i1] = True, True
    def change(m0, m1):  # the gradient's change of the rows m0 (before) / m1 (re-matched)
        model = np.sum(jd[m0] * (r_model[m0] - r0[m0]) / p0.sigma[m0] ** 2)
        return model, np.sum(jd1[m1] * r_new[m1] / p1.sigma[m1] ** 2) - np.sum(
            jd[m0] * r0[m0] / p0.sigma[m0] ** 2)
    big = np.abs(jd) >= np.quantile(np.abs(jd), 0.9)
    big1 = np.zeros(jd1.size, bool)
    big1[i1[big[i0]]] = True
    parts = (("kept", kept0, kept1), ("turned over", ~kept0, ~kept1),
             ("kept, largest tenth of |J·d|", kept0 & big, big1))
    print("  gradient change, model / re-matched: " + "; ".join(
        f"{name} {'{:+.0f} / {:+.0f}'.format(*change(m0, m1))}" for name, m0, m1 in parts))
    print(f"  dᵀJᵀWr: before {g0:+.1f}, moved (model) {g_model:+.1f}, re-matched {g_new:+.1f} "
          f"(share of the model's change kept {(g_new - g0) / (g_model - g0):.3f})", flush=True)


def main() -> None:
    from calidar.ingest.settings import IngestSettings
    from calidar.pipelines.boresight import calibrate_inputs, load_inputs
    from calidar.pipelines.strip_config import StripConfig

    sim, spec = Path(sys.argv[1]), (sys.argv[2] if len(sys.argv) > 2 else "")
    truth = json.loads((sim / "truth.json").read_text())["parameters"][PITCH]["value"]
    recorded()
    every = StripConfig(ingest=IngestSettings(budget_points=None))  # --strip-points 0
    inputs = load_inputs(sorted((sim / "strips").glob("*.laz")), sim / "sbet.out",
                         sim / "sensor.toml", every)
    run = replace(inputs, config=replace(inputs.config, calibration=pitch_bisect.config(spec)))
    sol = calibrate_inputs(run)["planes"].solution
    sigma = np.degrees(sol.sigma[PITCH])
    def z(values):
        return (np.degrees(values[PITCH]) - truth) / sigma

    for k, (r, params, est, problem) in enumerate(SOLVES):
        v = est.parameters.values()
        along, across = shifts_mm(r, v)
        low = np.mean(est.w * problem.sigma ** 2 < 0.5)
        print(f"iteration {k + 1}: pitch {z(params.values()):+.2f} -> {z(v):+.2f}σ, rows "
              f"{problem.sigma.size}, along RMS/max {np.sqrt(np.mean(along ** 2)):.0f}/"
              f"{np.abs(along).max():.0f} mm, across RMS {np.sqrt(np.mean(across ** 2)):.0f} mm, "
              f"robust weight < 0.5: {low:.3f}", flush=True)
    for k in range(1, len(SOLVES), 2):
        est = SOLVES[k][2]
        print(f"refine iteration {k + 1}: pitch {z(est.parameters.values()):+.3f} -> "
              f"{z(est.refine(1e-6).parameters.values()):+.3f}σ", flush=True)
    run_, _, est, _ = SOLVES[-1]
    params = est.parameters
    names = params.free_names
    first = sorted(run_.by_id)[0]
    h = run_.headings()[first]
    along = {n: 0.02 * (np.sin(h) if "_east_" in n else np.cos(h)) for n in names
             if n.startswith((f"trajectory_bias_east_{first}_", f"trajectory_bias_north_{first}_"))}
    rng = np.random.default_rng(1)
    knots = {n: rng.normal(0.0, 0.01) for n in names
             if n.startswith(("trajectory_bias_east", "trajectory_bias_north"))}
    before = SOLVES[-2][2].parameters.values()  # the last outer step: the crawl's direction
    moves = [(f"{PITCH} +2e-5 rad", {PITCH: 2e-5}), (f"line {first} +20 mm along", along),
             ("knots N(0, 10 mm)", knots)]
    for times in map(float, (sys.argv[3] if len(sys.argv) > 3 else "2").split(",")):
        step = {n: times * (v - before[n]) for n, v in params.values().items() if n in names}
        moves.append((f"the last outer step ×{times:g}", step))
    for label, move in moves:
        response(run_, params, label, move)


if __name__ == "__main__":
    main()
