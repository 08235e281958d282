"""Benchmark: are the boresight σ honest against the simulator's trajectory errors? Exact, no Monte-Carlo noise.

    NUMBA_NUM_THREADS=1 OMP_NUM_THREADS=1 PYTHONPATH=src python benchmarks/strips_prior_honesty.py \\
        --preset uav --directions opposite --seeds 700-709 --cache DIR [--scene urban] [--methods planes] \\
        [--parts]

The adjustment is linear near its solution: with N_d = JᵀWJ (the rows) and P the trajectory priors'
precision, the estimate's error is N⁻¹(JᵀWε − P·e) for row noise ε and true trajectory errors e at the
knots, so its covariance is C = N⁻¹(N_d + P Σ P)N⁻¹ with Σ the covariance of e; the adjustment reports
N⁻¹, which is C only when Σ = P⁻¹. Σ here is the simulator's own process
(:func:`calidar.sim.motion.measured_trajectory`: Gaussian-filtered white noise, kernel std 10 s for the
GNSS position and 2 s for the attitude, σ as the smrmsg states; ρ(Δt) = exp(−Δt²/4k²), the shifts one
process over the flight, the attitude's lines apart). Per survey the default calibration is run once
(strips_montecarlo's cached survey), N_d and the prior groups taken at its solution, and for each prior
shape the expected RMS of error/σ per angle printed: √(C_ii / (N⁻¹)_ii), the rows' ε taken as their σ say.

``--draws K``: also the same expectation with Σ taken from K draws of the simulator's own generator
(:func:`calidar.sim.motion.smooth_noise` on the survey's trajectory epochs, sampled at the knots): as
it is (``stationary=True``, the σ at every epoch the smrmsg's) and as it was before 27 Nov (each draw
scaled to σ about its own mean, the mean on top: 1.42–1.49 σ per axis on short flights).

Prior shapes: ``gm1`` — first-order Gauss–Markov, ρ = exp(−|Δt|/T) (the model before issue 26's fix);
``gm2`` — second-order, ρ = (1 + 2|Δt|/T)·exp(−2|Δt|/T), the same integral time T (20 s / 3.5 s);
``gm1/gm2`` — first order for the shifts, second for the rotations; ``… T=√πk`` — the integral times
matched to the simulator's at zero frequency (T = √π·kernel std: 17.72 s / 3.545 s) instead of 20 / 3.5 s
(:func:`calidar.strips.trajectory_errors.gauss_markov`; ``[trajectory_model] shape, correlation_s``);
``gm1 own 0`` — without the shifts' 5 % own share per strip (``OWN_STRIP_SHARE``); ``gm1 shifts T=10`` —
the shifts' integral time halved; ``gm3`` — third order (Matérn ν = 5/2, Rasmussen & Williams 2006, §4.2.1),
ρ = (1 + u + u²/3)·e^(−u), u = 8|Δt|/3T, the same T (``gm3/gm1``: the shifts only).

``--parts``: per prior shape, each trajectory-error kind and axis's share of the pitch and yaw variance: as the
prior states it (N⁻¹P·P⁻¹·PN⁻¹ over that group) against the simulator's process (N⁻¹P·Σ·PN⁻¹), pooled over
the surveys (issue 26, thirteenth session: which prior part makes the urban tie planes' pitch σ conservative).
"""

from __future__ import annotations

import argparse
import sys
from dataclasses import replace
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
from strips_montecarlo import ANGLES, ERRORS, URBAN, _simulated, seeds_of  # noqa: E402

from calidar.adjust import solver  # noqa: E402
from calidar.pipelines.boresight import calibrate_inputs, load_inputs  # noqa: E402
from calidar.pipelines.strip_config import StripConfig  # noqa: E402
from calidar.sim.survey import survey_config  # noqa: E402
from calidar.strips.config import CalibrationConfig, matchers_named  # noqa: E402
from calidar.strips.trajectory_errors import OWN_STRIP_SHARE  # noqa: E402

SIM_KERNEL_S = {"bias": 10.0, "tilt": 2.0}  #: the simulator's kernel std (s): GNSS position, attitude
MODEL_T_S = {"bias": 20.0, "tilt": 3.5}  #: the model's default correlation times (s)
SHAPES = {"gm1": lambda d, T: np.exp(-d / T), "gm2": lambda d, T: (1.0 + 2.0 * d / T) * np.exp(-2.0 * d / T),
          "gm3": lambda d, T: (1.0 + 8 * d / (3 * T) + (8 * d / (3 * T)) ** 2 / 3) * np.exp(-8 * d / (3 * T)),
          "sim": lambda d, k: np.exp(-d**2 / (4.0 * k * k))}
MATCHED_T_S = {k: float(np.sqrt(np.pi) * v) for k, v in SIM_KERNEL_S.items()}  #: S(0) matched: T = √π·k
#: the priors compared: per kind (shift "bias", rotation "tilt") its shape and integral time (s)
VARIANTS = {"gm1": {k: ("gm1", MODEL_T_S[k]) for k in MODEL_T_S},
            "gm2": {k: ("gm2", MODEL_T_S[k]) for k in MODEL_T_S},
            "gm1/gm2": {"bias": ("gm1", MODEL_T_S["bias"]), "tilt": ("gm2", MODEL_T_S["tilt"])},
            "gm1 T=√πk": {k: ("gm1", MATCHED_T_S[k]) for k in MODEL_T_S},
            "gm2 T=√πk": {k: ("gm2", MATCHED_T_S[k]) for k in MODEL_T_S},
            "gm1 own 0": {**{k: ("gm1", MODEL_T_S[k]) for k in MODEL_T_S}, "own": 0.0},
            "gm1 shifts T=10": {"bias": ("gm1", 10.0), "tilt": ("gm1", MODEL_T_S["tilt"])},
            "gm3/gm1": {"bias": ("gm3", MODEL_T_S["bias"]), "tilt": ("gm1", MODEL_T_S["tilt"])},
            "gm3": {k: ("gm3", MODEL_T_S[k]) for k in MODEL_T_S}}

_CAPTURED: list = []
_solution = solver.Estimate.solution


def _capture(self, clusters=None):
    _CAPTURED.append(self)
    return _solution(self, clusters)


def _knots(fit, idx):
    """(kind, strip, time) of the prior group's parameters."""
    prob = fit.problem
    model, spans = prob.trajectory, prob.spans
    out = []
    for j in idx:
        _, kind, _, sid, k = fit.free[j].name.split("_")
        out.append((kind, int(sid), spans[int(sid)][0] + int(k) * (model.block_s or 0.0)))
    return out


def correlation(knots, shape: str, scale: dict, own: float = OWN_STRIP_SHARE) -> np.ndarray:
    kind = knots[0][0]
    t = np.array([k[2] for k in knots])
    s = np.array([k[1] for k in knots])
    R = SHAPES[shape](np.abs(t[:, None] - t[None, :]), scale[kind])
    same = s[:, None] == s[None, :]
    if shape == "sim":
        return np.where(same, R, R if kind == "bias" else 0.0)
    return np.where(same, R, (1.0 - own) * R)


def drawn(est, times: np.ndarray, draws: int, stationary: bool, seed: int = 0) -> np.ndarray:
    """The expected RMS z per angle with Σ from ``draws`` draws of the simulator's generator
    (``stationary`` as :func:`calidar.sim.motion.smooth_noise`) on the epochs ``times``."""
    from calidar.sim.motion import smooth_noise

    fit = est.fit
    N = fit.normal_equations(fit.jacobian(est.x), est.w)[0]
    N_d = N.copy()
    groups = []
    for idx, _, P in fit.priors:
        N_d[np.ix_(idx, idx)] -= P
        if idx.size > 1 and fit.free[idx[0]].name.startswith("trajectory_"):
            axis = ("east", "north", "up").index(fit.free[idx[0]].name.split("_")[2])
            t = np.array([k[2] for k in _knots(fit, idx)])
            groups.append((idx, P, fit.free[idx[0]].name.split("_")[1], axis, t, np.sqrt(np.diag(np.linalg.inv(P)))))
    ang = [next(i for i, p in enumerate(fit.free) if p.name == a) for a in ANGLES]
    Ninv = np.linalg.inv(N)
    G = Ninv[ang]
    rows = np.diag(G @ N_d @ G.T)
    rng = np.random.default_rng(seed)
    dt = float(np.median(np.diff(times)))
    acc = np.zeros(len(ang))
    for _ in range(draws):
        series = {"bias": smooth_noise(rng, times.size, dt, SIM_KERNEL_S["bias"], 1.0, 3, stationary=stationary),
                  "tilt": smooth_noise(rng, times.size, dt, SIM_KERNEL_S["tilt"], 1.0, 3, stationary=stationary)}
        u = np.zeros(len(ang))
        for idx, P, kind, axis, t, sigma in groups:
            e = np.interp(t, times, series[kind][:, axis]) * sigma
            u += G[:, idx] @ (P @ e)
        acc += u**2
    return np.sqrt((rows + acc / draws) / np.diag(Ninv)[ang])


def honesty(est) -> dict[str, tuple]:
    """Per prior (:data:`VARIANTS`): the expected RMS z per angle, the reported σ (deg), the rows'
    share (deg) and per kind and axis its (stated, simulated) variance per angle (rad²)."""
    fit = est.fit
    J = fit.jacobian(est.x)
    N_full = fit.normal_equations(J, est.w)[0]
    N_d = N_full.copy()
    groups = []
    for idx, _, P in fit.priors:
        N_d[np.ix_(idx, idx)] -= P
        if idx.size > 1 and fit.free[idx[0]].name.startswith("trajectory_"):
            knots = _knots(fit, idx)
            sigma = np.sqrt(np.diag(np.linalg.inv(P)))
            groups.append((idx, P, knots, sigma))
    ang = [next(i for i, p in enumerate(fit.free) if p.name == a) for a in ANGLES]
    out = {}
    for name, variant in VARIANTS.items():
        N = N_d.copy()
        Ps = []
        for idx, P, knots, sigma in groups:
            shape, T = variant[knots[0][0]]
            R = correlation(knots, shape, {knots[0][0]: T}, variant.get("own", OWN_STRIP_SHARE))
            Pn = np.linalg.inv(sigma[:, None] * R * sigma[None, :])
            N[np.ix_(idx, idx)] += Pn
            Ps.append(Pn)
        Ninv = np.linalg.inv(N)
        meat = N_d.copy()
        parts: dict[str, np.ndarray] = {}
        for (idx, _, knots, sigma), Pn in zip(groups, Ps):
            S = sigma[:, None] * correlation(knots, "sim", SIM_KERNEL_S) * sigma[None, :]
            meat[np.ix_(idx, idx)] += Pn @ S @ Pn
            GP = Ninv[np.ix_(ang, idx)] @ Pn
            key = f"{knots[0][0]}_{fit.free[idx[0]].name.split('_')[2]}"
            both = np.array([np.einsum("ij,jk,ik->i", GP, M, GP) for M in (np.linalg.inv(Pn), S)])
            parts[key] = parts.get(key, 0.0) + both
        C = Ninv[ang] @ meat @ Ninv[:, ang]
        rows = np.degrees(np.sqrt(np.diag(Ninv[ang] @ N_d @ Ninv[:, ang])))
        out[name] = (np.sqrt(np.diag(C) / np.diag(Ninv)[ang]), np.degrees(np.sqrt(np.diag(Ninv)[ang])), rows,
                     parts, np.diag(Ninv)[ang])
    return out


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--seeds", default="700-709")
    ap.add_argument("--methods", default="planes")
    ap.add_argument("--preset", default="uav", choices=("airborne", "uav"))
    ap.add_argument("--scene", default="preset", choices=("preset", "urban"))
    ap.add_argument("--directions", default="opposite", choices=("cross", "opposite"))
    ap.add_argument("--vegetation", type=float, default=0.0)
    ap.add_argument("--cache", type=Path, required=True)
    ap.add_argument("--draws", type=int, default=0, help="also Σ from this many draws of the simulator's generator")
    ap.add_argument("--parts", action="store_true", help="each kind and axis's share of the variance")
    args = ap.parse_args()
    solver.Estimate.solution = _capture
    ratios: dict[str, list] = {}
    shares: dict[tuple, list] = {}
    for seed in seeds_of(args.seeds):
        noise = {"range_noise_m": 0.03} if args.preset == "airborne" else {}
        density = 0.3 if args.preset == "airborne" else 1.0
        cfg = survey_config(args.preset, seed=seed, density=density, vegetation=args.vegetation,
                            directions=args.directions, errors=ERRORS, **noise)
        if args.scene == "urban":
            cfg = replace(cfg, scene=replace(cfg.scene, **URBAN))
        f = _simulated(cfg, args.cache / "tmp", args.cache, (1.0,) * 6, 0.0, density)
        config = StripConfig(CalibrationConfig(matchers=matchers_named(*args.methods.split(",")), model_check=False))
        inputs = load_inputs(sorted((f / "strips").glob("*.laz")), f / "sbet.out", f / "sensor.toml", config,
                             truth=f / "truth.json")
        _CAPTURED.clear()
        calibrate_inputs(inputs)
        for m, est in zip(args.methods.split(","), _CAPTURED[-len(args.methods.split(",")):]):
            for shape, (r, s, rows, parts, var) in honesty(est).items():
                ratios.setdefault((m, shape), []).append(r)
                shares.setdefault((m, shape), []).append((parts, var))
                print(f"seed {seed} {m:6s} prior {shape}: expected RMS z roll/pitch/yaw "
                      + " / ".join(f"{v:.2f}" for v in r) + "  σ " + " / ".join(f"{v * 1e3:.3f}" for v in s)
                      + " mdeg, the rows' share of it " + " / ".join(f"{v * 1e3:.3f}" for v in rows) + " mdeg",
                      flush=True)
            if args.draws:
                from calidar.io.sbet import read_sbet
                times = read_sbet(f / "sbet.out").time
                for stationary, name in ((True, "drawn, today"), (False, "drawn, before 27 Nov")):
                    r = drawn(est, times, args.draws, stationary)
                    ratios.setdefault((m, name), []).append(r)
                    print(f"seed {seed} {m:6s} {name}: expected RMS z roll/pitch/yaw " + " / ".join(f"{v:.2f}" for v in r),
                          flush=True)
    for (m, shape), rs in sorted(ratios.items()):
        rs = np.array(rs)
        print(f"{m:6s} {shape}: {len(rs)} surveys, expected RMS z roll/pitch/yaw "
              + " / ".join(f"{v:.2f}" for v in np.sqrt(np.mean(rs**2, 0))))
        if args.parts and (m, shape) in shares:
            print(parts_table(shares[m, shape]))


def parts_table(surveys: list) -> str:
    """Per kind and axis: its share of the pitch and yaw variance as stated and as simulated (pooled:
    each survey's part over its stated variance, averaged) and their ratio."""
    out = []
    for key in sorted(surveys[0][0]):
        st = np.mean([p[key][0] / v for p, v in surveys], 0)
        sim = np.mean([p[key][1] / v for p, v in surveys], 0)
        out.append(f"    {key:7s} share of σ² stated / simulated: pitch {st[1]:.3f} / {sim[1]:.3f}, yaw "
                   f"{st[2]:.3f} / {sim[2]:.3f}  (roll {st[0]:.3f} / {sim[0]:.3f})")
    return "\n".join(out)


if __name__ == "__main__":
    main()
