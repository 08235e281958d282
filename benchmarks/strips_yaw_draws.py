"""Benchmark: is a survey's boresight error its trajectory draw's, or its rows'? Per survey, and
the draw's size against the simulator's own spread (issue 26, seventh session: yaw on urban cross
lines).

    NUMBA_NUM_THREADS=1 OMP_NUM_THREADS=1 PYTHONPATH=src python benchmarks/strips_yaw_draws.py \\
        --preset uav --scene urban --directions cross --seeds 900-929 --cache DIR \\
        [--methods planes,vgicp] [--draws 80] [--save FN_DIR] [--json out.jsonl] \\
        [--trajectory-shape gm2,gm2] [--trajectory-correlation 17.7,3.5]
    ... --seeds 900-929,753-759 --transfer FN_DIR/911_planes.npz ... [--rows mc.jsonl ...]
    ... --summary --json out.jsonl      # several runs: cat their jsonl into one file first

Near its solution the adjustment is linear: the angles' error is N⁻¹JᵀWε − N⁻¹P·e, ε
the rows' noise and e the true trajectory errors at the knots
(``strips_trajectory_response.py``). Per survey (strips_montecarlo's cached folder, read only)
the default calibration is run once; at its solution

- ``traj``: the trajectory-caused part −[N⁻¹P·e] of THIS survey's draw, e from a replay of the
  simulator's navigation stream (``calidar.sim.survey.simulate_survey``'s streams up to
  ``measured_trajectory``: no points simulated, the same numbers as the survey's SBET);
- its expected spread for the simulator's process: in closed form (Gaussian-filtered white noise,
  kernel std 10 s position, 2 s attitude: ρ = exp(−Δt²/4k²); ``_circular``: as the generator
  was before main e8bc8b3, a circular convolution whose record's two ends were neighbours — the
  generator is linear since, so the plain closed form is its expectation), and over ``--draws``
  other draws of the generator itself;
- ``rows``: the rest of the actual error (actual − traj), against the rows' share
  √(N⁻¹N_dN⁻¹);
- the survey's draw as z: traj / its spread. Its RMS over seeds is 1 for ordinary draws.

The summary also gives the expected RMS z for the simulator (the closed form, the old circular
generator's closed form, and the ``--draws`` generator draws): on short flights the circular
generator's two record ends shared their errors, which moved the expectation (UAV opposite lines,
200 s: yaw 0.96 → 0.90; issue 26, ninth session); since e8bc8b3 the draws follow the plain
closed form. ``--scene`` defaults to the preset's scene, as strips_montecarlo's does.

Also per survey the replayed draw's summaries a yaw could follow (flight-mean heading error, the
lines' mean heading errors' spread, the along-track position errors' spread over the lines) and
the scene's wall facets, correlated with the yaw z.

``--save DIR`` keeps each survey's functional (G·P at the knots); ``--transfer`` applies saved
functionals to other seeds' replayed draws without calibrating them (the flight, hence the knots,
is the same for every seed of a preset and pattern; only the scene differs): the draw z per seed,
split by error kind and axis, against the Monte-Carlo rows' z (``--rows``).
"""

from __future__ import annotations

import argparse
import json
import sys
from dataclasses import replace
from pathlib import Path
from types import SimpleNamespace

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
from strips_montecarlo import ANGLES, ERRORS, URBAN, _simulated, seeds_of  # noqa: E402
from strips_prior_honesty import _CAPTURED, _capture, _knots  # noqa: E402
from strips_trajectory_response import true_corrections  # noqa: E402

from calidar.adjust import solver  # noqa: E402
from calidar.pipelines.boresight import calibrate_inputs, load_inputs  # noqa: E402
from calidar.pipelines.strip_config import StripConfig  # noqa: E402
from calidar.sim.motion import fly, measured_trajectory, trajectory_sigma  # noqa: E402
from calidar.sim.scene import build_scene, scene_seed  # noqa: E402
from calidar.sim.survey import (GPS_WEEK_START_S, STRIP_ERRORS, survey_config,  # noqa: E402
                                survey_lines)
from calidar.strips.config import CalibrationConfig, matchers_named  # noqa: E402


def config(preset: str, scene: str, directions: str, vegetation: float, seed: int):
    """strips_montecarlo's survey configuration."""
    noise = {"range_noise_m": 0.03} if preset == "airborne" else {}
    density = 0.3 if preset == "airborne" else 1.0
    cfg = survey_config(preset, seed=seed, density=density, vegetation=vegetation,
                        directions=directions, errors=ERRORS, **noise)
    return replace(cfg, scene=replace(cfg.scene, **URBAN)) if scene == "urban" else cfg


def replay(cfg):
    """The simulator's streams up to the measured trajectory: (scene, lines, windows, true,
    measured, σ position, σ attitude) — the numbers the survey's SBET holds."""
    ss = np.random.SeedSequence(cfg.seed)
    rngs = [np.random.default_rng(s) for s in ss.spawn(6)]
    _, rng_motion, rng_nav, rng_strip, _, rng_sigma = rngs
    lat0, lon0, h0 = cfg.origin_deg
    sc = build_scene(cfg.scene, scene_seed(cfg.seed, cfg.scene_seed), np.radians(lat0),
                     np.radians(lon0), h0)
    lines = survey_lines(cfg, sc, cfg.nominal)
    true, windows = fly(sc, lines, cfg.motion, rng_motion, GPS_WEEK_START_S)
    strip_errors = [{k: rng_strip.normal(0.0, s, 3)
                     for k, s in zip(STRIP_ERRORS, cfg.strip_error_sigma)} for _ in lines]
    sig_pos, sig_att = trajectory_sigma(cfg, true.time, rng_sigma)
    per_strip = [(a, b, e) for (a, b), e in zip(windows, strip_errors)]
    measured = measured_trajectory(true, rng_nav, sig_pos, sig_att, per_strip)
    return sc, lines, windows, true, measured, sig_pos, sig_att


def draw_summaries(sc, lines, windows, true, measured) -> dict:
    """What of the draw a yaw could follow (mdeg, mm), and the scene's walls in the survey area."""
    t = true.time
    dh = np.degrees(np.angle(np.exp(1j * (measured.heading - true.heading)))) * 1e3
    shift, _ = true_corrections(measured, true, t)  # true − measured, ENU m
    heads, along = [], []
    for line, (a, b) in zip(lines, windows):
        w = (t >= a) & (t <= b)
        heads.append(dh[w].mean())
        along.append(-(shift[w, :2] @ line.direction).mean() * 1e3)
    inw = np.zeros(t.size, bool)
    for a, b in windows:
        inw |= (t >= a) & (t <= b)
    walls = int(np.sum(~sc.plane_is_roof & (np.abs(sc.plane_normal[:, 2]) < 0.3)))
    return {"flight_mean_heading_mdeg": float(dh[inw].mean()), "line_heading_mdeg": heads,
            "line_heading_spread_mdeg": float(np.std(heads)), "line_along_mm": along,
            "line_along_spread_mm": float(np.std(along)), "wall_facets": walls}


def functional(est):
    """The angles' linear response to the trajectory errors at the knots: [(G_idx·P, kind, axis,
    knot times)], the reported σ (rad) and the rows' share of it (rad)."""
    fit = est.fit
    N = fit.normal_equations(fit.jacobian(est.x), est.w)[0]
    N_d = N.copy()
    ang = [next(i for i, p in enumerate(fit.free) if p.name == a) for a in ANGLES]
    G = np.linalg.inv(N)[ang]
    groups = []
    for idx, _, P in fit.priors:
        N_d[np.ix_(idx, idx)] -= P
        if idx.size > 1 and fit.free[idx[0]].name.startswith("trajectory_"):
            knots = _knots(fit, idx)
            axis = ("east", "north", "up").index(fit.free[idx[0]].name.split("_")[2])
            groups.append((G[:, idx] @ P, knots[0][0], axis, np.array([k[2] for k in knots])))
    sigma = np.sqrt(np.diag(G[:, ang]))
    return groups, sigma, np.sqrt(np.diag(G @ N_d @ G.T))


def sampled(traj, times: np.ndarray) -> SimpleNamespace:
    """The trajectory at ``times`` (what :func:`true_corrections` reads of it): linear
    interpolation of its smooth fields, the headings unwrapped first."""
    at = lambda a: np.interp(times, traj.time, a)  # noqa: E731
    ecef = traj.ecef
    return SimpleNamespace(time=times, lat=at(traj.lat), lon=at(traj.lon), roll=at(traj.roll),
                           pitch=at(traj.pitch), heading=at(np.unwrap(traj.heading)),
                           ecef=np.column_stack([at(ecef[:, k]) for k in range(3)]))


def response(groups, measured, true, offset: float) -> np.ndarray:
    """−[N⁻¹P·e] (rad) for the trajectory errors measured − true (``offset``: SBET time −
    replay time)."""
    times = np.concatenate([g[3] for g in groups]) - offset
    shift, tilt = true_corrections(sampled(measured, times), sampled(true, times), times)
    out, k = np.zeros(len(ANGLES)), 0
    for GP, kind, axis, t in groups:
        out -= GP @ (shift if kind == "bias" else tilt)[k:k + t.size, axis]
        k += t.size
    return out


def analytic_spread(groups, sigma_m: float, sigma_rad: float,
                    period: float | None = None) -> np.ndarray:
    """The trajectory part's σ (rad) for the simulator's process in closed form: each axis
    Gaussian-filtered white noise (kernel std 10 s position, 2 s attitude), ρ = exp(−Δt²/4k²)
    between any two knots of that kind and axis, whatever their strips."""
    kernel = {"bias": 10.0, "tilt": 2.0}
    var = np.zeros(len(ANGLES))
    for kind, sig in (("bias", sigma_m), ("tilt", sigma_rad)):
        for axis in range(3):
            sel = [g for g in groups if g[1] == kind and g[2] == axis]
            if not sel:
                continue
            GP = np.concatenate([g[0] for g in sel], 1)
            t = np.concatenate([g[3] for g in sel])
            dt = np.abs(t[:, None] - t[None, :])
            if period:  # the generator's circular convolution: the record's ends are neighbours
                dt = np.minimum(dt, period - dt)
            S = sig**2 * np.exp(-(dt**2) / (4.0 * kernel[kind] ** 2))
            var += np.einsum("ij,jk,ik->i", GP, S, GP)
    return np.sqrt(var)


def other_draws(true, sig_pos, sig_att, draws: int):
    """Measured trajectories from other draws of the navigation stream (the same flight and σ)."""
    for k in range(draws):
        yield measured_trajectory(true, np.random.default_rng(20_000 + k), sig_pos, sig_att, [])


def survey(args, seed: int) -> list[dict]:
    """One survey: per method the actual error, its trajectory-caused part, that part's expected
    spread, the rows' share; and the draw's summaries."""
    from calidar.io.sbet import read_sbet

    cfg = config(args.preset, args.scene, args.directions, args.vegetation, seed)
    sc, lines, windows, true, measured, sig_pos, sig_att = replay(cfg)
    summ = draw_summaries(sc, lines, windows, true, measured)
    folder = _simulated(cfg, args.cache / "tmp", args.cache, (1.0,) * 6, 0.0, cfg.density)
    offset = float(read_sbet(folder / "sbet.out").time[0] - true.time[0])
    methods = args.methods.split(",")
    cal = CalibrationConfig(matchers=matchers_named(*methods), model_check=False)
    if args.trajectory_shape:  # the prior's shape, as [trajectory_model] shape sets it
        cal = replace(cal, trajectory=replace(cal.trajectory,
                                              shape=tuple(args.trajectory_shape.split(","))))
    if args.trajectory_correlation:  # its correlation times, as [trajectory_model] correlation_s
        times = tuple(float(v) for v in args.trajectory_correlation.split(","))
        cal = replace(cal, trajectory=replace(cal.trajectory, correlation_s=times))
    strip_config = StripConfig(cal)
    inputs = load_inputs(sorted((folder / "strips").glob("*.laz")), folder / "sbet.out",
                         folder / "sensor.toml", strip_config, truth=folder / "truth.json")
    _CAPTURED.clear()
    results = calibrate_inputs(inputs)
    rows, draws = [], list(other_draws(true, sig_pos, sig_att, args.draws))
    for m, est in zip(methods, _CAPTURED[-len(methods):]):
        sol = results[m].solution
        actual = np.array([sol.values[a] - inputs.truth[a] for a in ANGLES])
        groups, _, rows_sigma = functional(est)
        if args.save:
            args.save.mkdir(parents=True, exist_ok=True)
            np.savez(args.save / f"{seed}_{m}.npz", GP=np.concatenate([g[0] for g in groups], 1),
                     kind=np.concatenate([[g[1] == "tilt"] * g[3].size for g in groups]),
                     axis=np.concatenate([[g[2]] * g[3].size for g in groups]),
                     time=np.concatenate([g[3] for g in groups]) - offset - true.time[0])
        own = response(groups, measured, true, offset)
        others = np.array([response(groups, d, true, offset) for d in draws])
        others = others.reshape(-1, len(ANGLES))
        mdeg = lambda v: [float(x) for x in np.degrees(v) * 1e3]  # noqa: E731
        rows.append({"seed": seed, "method": m, "actual_mdeg": mdeg(actual),
                     "sigma_mdeg": mdeg([sol.sigma[a] for a in ANGLES]), "traj_mdeg": mdeg(own),
                     "traj_spread_mdeg": mdeg(np.sqrt(np.mean(others**2, 0))),
                     "traj_spread_analytic_mdeg": mdeg(analytic_spread(
                         groups, cfg.gnss_noise_m, cfg.attitude_noise_rad)),
                     "traj_spread_circular_mdeg": mdeg(analytic_spread(
                         groups, cfg.gnss_noise_m, cfg.attitude_noise_rad, period(true))),
                     "rows_sigma_mdeg": mdeg(rows_sigma),
                     "offset_s": offset, **summ})
    return rows


def period(true) -> float:
    """The record's length (s): the period of the generator's circular convolution."""
    return float(true.time.size / true.rate_hz)


def load_functional(path: Path, t0: float) -> list:
    """A saved functional as groups, its knot times moved to a flight starting at ``t0``."""
    f = np.load(path)
    return [(f["GP"][:, i:i + 1], "tilt" if f["kind"][i] else "bias", int(f["axis"][i]),
             f["time"][i:i + 1] + t0) for i in range(f["time"].size)]


def transfer(args) -> None:
    """The saved functional of one survey applied to other seeds' replayed draws (no calibration):
    their trajectory-caused part as z of its closed-form spread, against the Monte-Carlo rows'."""
    mc, err = {}, {}  # the Monte-Carlo rows' z and errors (mdeg)
    for path in args.rows:
        for line in path.read_text().splitlines():
            r = json.loads(line)
            mc[r["seed"], r["method"]] = np.divide(r["error_deg"], r["sigma_deg"])
            err[r["seed"], r["method"]] = np.multiply(r["error_deg"], 1e3)
    out = []
    for seed in seeds_of(args.seeds):
        cfg = config(args.preset, args.scene, args.directions, args.vegetation, seed)
        _, _, _, true, measured, sig_pos, sig_att = replay(cfg)
        if args.draws and not out:  # the closed form against the generator itself, on this flight
            draws = list(other_draws(true, sig_pos, sig_att, args.draws))
            for path in args.transfer:
                groups = load_functional(path, true.time[0])
                d = np.array([response(groups, m, true, 0.0) for m in draws])
                print(f"{path.stem}: trajectory part's spread over {args.draws} draws of the "
                      "generator " + " / ".join(f"{x:.3f}" for x in np.degrees(rms(d)) * 1e3)
                      + " mdeg, closed form "
                      + " / ".join(f"{x:.3f}" for x in np.degrees(analytic_spread(
                          groups, cfg.gnss_noise_m, cfg.attitude_noise_rad)) * 1e3)
                      + ", closed form of the circular convolution " + " / ".join(
                          f"{x:.3f}" for x in np.degrees(analytic_spread(
                              groups, cfg.gnss_noise_m, cfg.attitude_noise_rad,
                              period(true))) * 1e3),
                      flush=True)
        for path in args.transfer:
            groups = load_functional(path, true.time[0])
            spread = analytic_spread(groups, cfg.gnss_noise_m, cfg.attitude_noise_rad)
            z = response(groups, measured, true, 0.0) / spread
            m = path.stem.split("_")[1]
            parts = {}  # the angles' trajectory part by error kind and axis (mdeg), and its spread
            for kind, axis in [(k, a) for k in ("bias", "tilt") for a in range(3)]:
                sub = [g for g in groups if g[1] == kind and g[2] == axis]
                parts[f"{kind}_{'enu'[axis]}"] = (
                    np.degrees(response(sub, measured, true, 0.0)) * 1e3,
                    np.degrees(analytic_spread(sub, cfg.gnss_noise_m,
                                               cfg.attitude_noise_rad)) * 1e3)
            own = np.degrees(response(groups, measured, true, 0.0)) * 1e3  # mdeg
            out.append((seed, path.stem, z, mc.get((seed, m)), parts, own, err.get((seed, m))))
            own_mc = mc.get((seed, m))
            print(f"seed {seed} functional {path.stem}: trajectory part z "
                  + " ".join(f"{x:+.2f}" for x in z)
                  + ("" if own_mc is None else "  MC z " + " ".join(f"{x:+.2f}" for x in own_mc)),
                  flush=True)
    for name in sorted({o[1] for o in out}):
        sel = [o for o in out if o[1] == name]
        z = np.array([o[2] for o in sel])
        line = (f"{name}: {len(sel)} seeds, draw z RMS roll/pitch/yaw "
                + " / ".join(f"{x:.2f}" for x in rms(z)))
        both = [o for o in sel if o[3] is not None]
        if len(both) > 2:
            a, b = np.array([o[2] for o in both]), np.array([o[3] for o in both])
            line += (f"; with MC rows ({len(both)}): corr yaw "
                     f"{np.corrcoef(a[:, 2], b[:, 2])[0, 1]:+.2f}, MC RMS z "
                     + " / ".join(f"{x:.2f}" for x in rms(b)))
        print(line)
        if len(both) > 2:  # the lean: the draws' and the rest's means (the rest: MC − draw part)
            own = np.array([o[5] for o in both])
            rest = np.array([o[6] for o in both]) - own
            f = lambda v: " / ".join(f"{x:+.2f}" for x in v)  # noqa: E731
            print(f"    mean draw z {f(a.mean(0))} (± {1 / np.sqrt(len(both)):.2f}), mean MC z "
                  f"{f(b.mean(0))}; mean trajectory part {f(own.mean(0))} mdeg, mean rest "
                  f"(MC error − trajectory part) {f(rest.mean(0))} mdeg, RMS rest "
                  f"{f(rms(rest))} mdeg")
        for key in sel[0][4]:
            v = np.array([o[4][key][0] for o in sel])
            print(f"    roll/pitch/yaw's part from {key}: RMS "
                  + " / ".join(f"{x:.3f}" for x in rms(v)) + " mdeg, expected (closed form) "
                  + " / ".join(f"{x:.3f}" for x in sel[0][4][key][1]))


def rms(x) -> np.ndarray:
    return np.sqrt(np.mean(np.square(x), 0))


def summary(rows: list[dict]) -> str:
    """Per method: the decomposition, pooled over the surveys (the last row of a seed kept)."""
    last = {(r["seed"], r["method"]): r for r in rows}
    f = lambda v: " / ".join(f"{x:.2f}" for x in v)  # noqa: E731
    out = []
    for m in sorted({k[1] for k in last}):
        sel = [r for k, r in sorted(last.items()) if k[1] == m]
        a, s, t, ts, rs, tc, tg = (np.array([r[k] for r in sel]) for k in (
            "actual_mdeg", "sigma_mdeg", "traj_mdeg", "traj_spread_analytic_mdeg",
            "rows_sigma_mdeg", "traj_spread_circular_mdeg", "traj_spread_mdeg"))
        out += [f"{m:6s} n={len(sel)} RMS z (actual/σ) roll/pitch/yaw {f(rms(a / s))}",
                f"{m:6s}   trajectory part: RMS {f(rms(t))} mdeg, expected (closed form) "
                f"{f(rms(ts))} mdeg; draw z RMS {f(rms(t / ts))}",
                f"{m:6s}   rows part (actual − trajectory): RMS {f(rms(a - t))} mdeg, "
                "rows' share "
                f"{f(rms(rs))} mdeg; RMS ratio {f(rms(a - t) / rms(rs))}",
                f"{m:6s}   expected RMS z √(spread² + share²)/σ "
                f"{f(rms(np.sqrt(ts**2 + rs**2) / s))};"
                f" given these draws √(part² + share²)/σ {f(rms(np.sqrt(t**2 + rs**2) / s))}",
                f"{m:6s}   the simulator's wrap: spread (closed form) {f(rms(tc))} mdeg, expected"
                f" RMS z {f(rms(np.sqrt(tc**2 + rs**2) / s))}, draw z RMS {f(rms(t / tc))}; "
                f"the generator's --draws: spread {f(rms(tg))} mdeg, expected RMS z "
                f"{f(rms(np.sqrt(tg**2 + rs**2) / s))}"]
        if len(sel) > 2:  # the error follows its draw as N⁻¹P says: slope 1, parts uncorrelated
            slope = np.sum(a * t, 0) / np.sum(t**2, 0)
            spread = np.sqrt(np.sum(rs**2 * t**2, 0)) / np.sum(t**2, 0)  # rows' share as noise
            corr = [np.corrcoef(a[:, i] - t[:, i], t[:, i])[0, 1] for i in range(3)]
            out.append(f"{m:6s}   response: slope of actual on trajectory part {f(slope)} "
                       f"(± {f(spread)}); corr(rows part, trajectory part) {f(corr)}")
        if len(sel) > 2:
            out.append(f"{m:6s}   yaw: corr(actual, trajectory part) "
                       f"{np.corrcoef(a[:, 2], t[:, 2])[0, 1]:+.2f}")
            for key in ("flight_mean_heading_mdeg", "line_heading_spread_mdeg",
                        "line_along_spread_mm", "wall_facets"):
                v = np.array([r[key] for r in sel], float)
                out.append(f"{m:6s}   corr(yaw z, {key}) "
                           f"{np.corrcoef(a[:, 2] / s[:, 2], v)[0, 1]:+.2f}, corr(|yaw z|, ·) "
                           f"{np.corrcoef(np.abs(a[:, 2] / s[:, 2]), v)[0, 1]:+.2f}")
    return "\n".join(out)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--seeds", default="900-905")
    ap.add_argument("--methods", default="planes,vgicp")
    ap.add_argument("--preset", default="uav", choices=("airborne", "uav"))
    ap.add_argument("--scene", default="preset", choices=("preset", "urban"),
                    help="as strips_montecarlo's (urban: dense, taller buildings)")
    ap.add_argument("--directions", default="cross", choices=("cross", "opposite"))
    ap.add_argument("--vegetation", type=float, default=0.0)
    ap.add_argument("--draws", type=int, default=80)
    ap.add_argument("--trajectory-shape", default=None,
                    help="POSITION,ATTITUDE gm1|gm2: the prior's shape (default: the config's)")
    ap.add_argument("--trajectory-correlation", default=None,
                    help="POSITION,ATTITUDE s: the prior's correlation times (default: the config's)")
    ap.add_argument("--cache", type=Path, required=True)
    ap.add_argument("--json", type=Path, default=None,
                    help="append every row; --summary reads it back")
    ap.add_argument("--summary", action="store_true", help="only print the summary of --json")
    ap.add_argument("--save", type=Path, default=None,
                    help="save each survey's functional here (npz)")
    ap.add_argument("--transfer", type=Path, nargs="*", default=None,
                    help="saved functionals to apply to the seeds' replayed draws (no calibration)")
    ap.add_argument("--rows", type=Path, nargs="*", default=[],
                    help="Monte-Carlo rows (jsonl) of the seeds")
    args = ap.parse_args()
    if args.transfer:
        transfer(args)
        return
    rows = []
    if args.summary:
        rows = [json.loads(x) for x in args.json.read_text().splitlines() if x.strip()]
        print(summary(rows))
        return
    solver.Estimate.solution = _capture
    for seed in seeds_of(args.seeds):
        for r in survey(args, seed):
            rows.append(r)
            if args.json:
                with args.json.open("a") as f:
                    f.write(json.dumps(r) + "\n")
            print(f"seed {seed} {r['method']:6s} actual "
                  + " ".join(f"{x:+.2f}" for x in r["actual_mdeg"])
                  + " trajectory part " + " ".join(f"{x:+.2f}" for x in r["traj_mdeg"])
                  + " (expected ±" + " ".join(f"{x:.2f}" for x in r["traj_spread_mdeg"])
                  + ") rows' share ±" + " ".join(f"{x:.2f}" for x in r["rows_sigma_mdeg"])
                  + " σ " + " ".join(f"{x:.2f}" for x in r["sigma_mdeg"]) + " mdeg", flush=True)
    print(summary(rows))


if __name__ == "__main__":
    main()
