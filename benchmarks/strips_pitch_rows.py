"""Benchmark: which rows make a survey's pitch lean — the rows' contributions to the boresight
angles, split by class (issue 26, eighth session: UAV cross lines with 30 % trees).

    NUMBA_NUM_THREADS=1 OMP_NUM_THREADS=1 PYTHONPATH=src python benchmarks/strips_pitch_rows.py \\
        --preset uav --directions cross --vegetation 0.3 --seeds 1130-1139 --cache DIR \\
        [--methods planes,vgicp] [--json out.jsonl] [--summary]

Each survey's twin without trajectory errors (``strips_roll.py``'s ``…_exact`` folder in
``--cache``, simulated there when missing) is adjusted once from the TRUE sensor with the preset's
trajectory priors (``strips_roll.py --variants exact``). Near the truth the adjustment is linear:
the angles' move is −N⁻¹ Σ_i J_iᵀ w_i r_i, r_i the rows' residuals at the start (the truth: their
noise and the scene's model errors only), w_i the final weights (1/σ² × robust). Each row's
contribution c_i = −[N⁻¹J_iᵀ]_angle w_i r_i is summed by class, beside what the rows' σ claim for
that sum, √Σ ([N⁻¹J_iᵀ]_angle)² w_i (the class's share):

- ``pair``: the two strips' headings perpendicular (a long line and a cross line) or parallel;
- ``slope``: the row's normal, |n_z| ≥ 0.995 (flat), 0.97–0.995, < 0.97;
- ``trees``: b's patch centroid against the scene's tree crowns (horizontal distance to the
  nearest crown's edge): under a crown (< 0 m), 0–3 m, beyond 3 m.

``--drop-class 5``: the same twin with the points of that LAS class removed (copied to
``…_exact_no5``; the ground and its noise unchanged): does the lean need the crowns' returns?

A class whose summed contribution stands many of its shares off zero, the same sign over seeds, is
where the lean sits.
"""

from __future__ import annotations

import argparse
import json
import sys
from dataclasses import replace
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
from strips_montecarlo import ANGLES, ERRORS, seeds_of  # noqa: E402
from strips_roll import SIGMA, folders  # noqa: E402

from calidar.pipelines.boresight import calibrate_inputs, load_inputs  # noqa: E402
from calidar.pipelines.strip_config import StripConfig  # noqa: E402
from calidar.sim.scene import build_scene, scene_seed  # noqa: E402
from calidar.sim.survey import survey_config  # noqa: E402
from calidar.strips import outer_loop as cal  # noqa: E402
from calidar.strips import problem as problem_module  # noqa: E402
from calidar.strips.config import (CalibrationConfig, StripSettings,  # noqa: E402
                                   TrajectorySettings, matchers_named)
from calidar.strips.parameters import sensor_of  # noqa: E402

MATCHED: list = []  # per problem built: the correspondence sets, in the problem's row order
CAPTURED: list = []
SCENE: list = []  # the current survey's scene
CLASSES = {"pair": ("perpendicular", "parallel"), "slope": ("flat", "gentle", "steep"),
           "trees": ("under crown", "0-3 m", "beyond 3 m")}


def _keep_matched():
    original = problem_module.counted_once

    def count(corrs):
        out = original(corrs)
        MATCHED[:] = [out[0]]
        return out

    problem_module.counted_once = count


def _classes(run, matched, scene) -> dict[str, np.ndarray]:
    """Per row: its class index under each of :data:`CLASSES`."""
    head = run.headings()
    pair, slope, trees = [], [], []
    centre, radius = scene.tree_center[:, :2], scene.tree_radius
    for c in matched:
        n = c.n_obs
        per = 1 if c.normal is not None else 3  # point-to-point: three rows an observation
        d = abs(np.sin(head[c.strip_a] - head[c.strip_b]))
        pair.append(np.full(n, 0 if d > 0.5 else 1))
        nz = np.abs(c.normal[:, 2]) if c.normal is not None else np.ones(n)
        slope.append(np.where(nz >= 0.995, 0, np.where(nz >= 0.97, 1, 2)))
        st = run.by_id[c.strip_b]
        xy = scene.ecef_to_enu(st.frame.to_ecef(c.B @ st.points))[:, :2]
        if radius.size:
            dist = np.min(np.hypot(*(xy[:, None, :] - centre[None]).transpose(2, 0, 1))
                          - radius[None], axis=1)
        else:
            dist = np.full(n, np.inf)
        trees.append(np.where(dist < 0, 0, np.where(dist < 3, 1, 2)))
        for v in (pair, slope, trees):
            v[-1] = np.repeat(v[-1], per)
    return {"pair": np.concatenate(pair), "slope": np.concatenate(slope),
            "trees": np.concatenate(trees)}


def _capture(scene_of):
    """Wrap the final solution once; ``scene_of()`` gives the current survey's scene."""
    original = cal.Run.solution

    def solution(self, est, problem):
        sol = original(self, est, problem)
        fit = est.fit
        J = fit.jacobian(est.x)
        N, _ = fit.normal_equations(J, est.w, x=est.x)
        names = [p.name for p in fit.free]
        G = np.linalg.inv(N)[[names.index(a) for a in ANGLES]]
        GJ = np.asarray(J @ G.T)  # (rows, 3): [N⁻¹J_iᵀ]
        contrib = -GJ * (est.w * fit.r0)[:, None]
        share2 = GJ**2 * est.w[:, None]
        cls = _classes(self, MATCHED[0], scene_of())
        if cls["pair"].size != contrib.shape[0]:
            raise RuntimeError(f"{cls['pair'].size} classified rows, {contrib.shape[0]} in the fit")
        out = {"sum_mdeg": np.degrees(contrib.sum(0)) * 1e3, "rows": int(contrib.shape[0])}
        for key, labels in CLASSES.items():
            for k, label in enumerate(labels):
                sel = cls[key] == k
                out[f"{key}:{label}"] = {
                    "n": int(sel.sum()),
                    "sum_mdeg": (np.degrees(contrib[sel].sum(0)) * 1e3).tolist(),
                    "share_mdeg": (np.degrees(np.sqrt(share2[sel].sum(0))) * 1e3).tolist()}
        out["sum_mdeg"] = out["sum_mdeg"].tolist()
        CAPTURED.append(out)
        return sol

    cal.Run.solution = solution


def without_class(folder: Path, cls: int) -> Path:
    """A copy of a survey folder whose strips hold no points of LAS class ``cls``."""
    import shutil

    import laspy

    out = folder.with_name(f"{folder.name}_no{cls}")
    if (out / "truth.json").exists():
        return out
    (out / "strips").mkdir(parents=True, exist_ok=True)
    for f in sorted((folder / "strips").glob("*.laz")):
        las = laspy.read(f)
        las.points = las.points[np.asarray(las.classification) != cls]
        las.write(out / "strips" / f.name)
    for name in ("sbet.out", "smrmsg.out", "sensor.toml", "truth.json"):  # truth.json last
        if (folder / name).exists():
            shutil.copy(folder / name, out / name)
    return out


def survey(args, seed: int) -> list[dict]:
    cfg = survey_config(args.preset, seed=seed, density=1.0, vegetation=args.vegetation,
                        directions=args.directions, errors=ERRORS)
    lat0, lon0, h0 = cfg.origin_deg
    scene = build_scene(cfg.scene, scene_seed(cfg.seed, cfg.scene_seed), np.radians(lat0),
                        np.radians(lon0), h0)
    SCENE[:] = [scene]
    _, exact = folders(args.cache, seed, args.preset, args.directions, "preset", args.vegetation)
    if args.drop_class is not None:
        exact = without_class(exact, args.drop_class)
    methods = args.methods.split(",")
    config = StripConfig(CalibrationConfig(
        matchers=matchers_named(*methods), trajectory=TrajectorySettings(sigma=SIGMA[args.preset]),
        solver=StripSettings(max_outer=1), model_check=False))
    inputs = load_inputs(sorted((exact / "strips").glob("*.laz")), exact / "sbet.out",
                         exact / "sensor.toml", config, truth=exact / "truth.json")
    truth = sensor_of(inputs.nominal, inputs.truth)
    CAPTURED.clear()
    results = calibrate_inputs(replace(inputs, nominal=truth))
    rows = []
    for m, cap in zip(methods, CAPTURED[-len(methods):]):
        sol = results[m].solution
        rows.append({"seed": seed, "method": m, "vegetation": args.vegetation,
                     "drop_class": args.drop_class,
                     "move_mdeg": [float(np.degrees(sol.values[a] - inputs.truth[a]) * 1e3)
                                   for a in ANGLES],
                     "sigma_mdeg": [float(np.degrees(sol.sigma[a]) * 1e3) for a in ANGLES], **cap})
    return rows


def summary(rows: list[dict], axis: int = 1) -> str:
    """Per method and class: over the seeds, the mean of each class's contribution to the angle
    (``axis``: 1 pitch) in its shares (z), its spread, and the mean in mdeg."""
    out = []
    for m in sorted({r["method"] for r in rows}):
        sel = [r for r in rows if r["method"] == m]
        mv = np.array([r["move_mdeg"][axis] for r in sel])
        sm = np.array([r["sum_mdeg"][axis] for r in sel])
        sg = np.array([r["sigma_mdeg"][axis] for r in sel])
        out.append(f"{m}: n={len(sel)} move mean {mv.mean():+.2f} mdeg (z {np.mean(mv / sg):+.2f},"
                   f" RMS z {np.sqrt(np.mean((mv / sg) ** 2)):.2f});"
                   f" the rows' sum {sm.mean():+.2f}")
        for key, labels in CLASSES.items():
            for label in labels:
                c = [r[f"{key}:{label}"] for r in sel]
                s = np.array([x["sum_mdeg"][axis] for x in c])
                sh = np.array([x["share_mdeg"][axis] for x in c])
                z = s / np.where(sh > 0, sh, np.inf)
                out.append(f"  {key:5s} {label:13s} rows {np.mean([x['n'] for x in c]):7.0f}"
                           f"  sum mean {s.mean():+.2f} mdeg  z mean {z.mean():+.2f}"
                           f" ± {1 / np.sqrt(len(z)):.2f}  RMS z {np.sqrt(np.mean(z**2)):.2f}")
    return "\n".join(out)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--seeds", default="1130-1139")
    ap.add_argument("--methods", default="planes,vgicp")
    ap.add_argument("--preset", default="uav", choices=("airborne", "uav"))
    ap.add_argument("--directions", default="cross", choices=("cross", "opposite"))
    ap.add_argument("--vegetation", type=float, default=0.3)
    ap.add_argument("--cache", type=Path, required=True)
    ap.add_argument("--drop-class", type=int, default=None,
                    help="remove this LAS class from the twin's strips first (5: the crowns)")
    ap.add_argument("--json", type=Path, default=None)
    ap.add_argument("--summary", action="store_true", help="only print the summary of --json")
    args = ap.parse_args()
    if args.summary:
        print(summary([json.loads(x) for x in args.json.read_text().splitlines() if x.strip()]))
        return
    _keep_matched()
    _capture(lambda: SCENE[0])
    rows = []
    for seed in seeds_of(args.seeds):
        for r in survey(args, seed):
            rows.append(r)
            if args.json:
                with args.json.open("a") as f:
                    f.write(json.dumps(r) + "\n")
            print(f"seed {seed} {r['method']:6s} move " + " ".join(
                f"{x:+.2f}" for x in r["move_mdeg"]) + "  rows' sum " + " ".join(
                f"{x:+.2f}" for x in r["sum_mdeg"]) + " mdeg", flush=True)
    print(summary(rows))


if __name__ == "__main__":
    main()
