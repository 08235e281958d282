"""Benchmark: do the angles respond to the simulated trajectory errors as the adjustment's linear model says?

    NUMBA_NUM_THREADS=1 OMP_NUM_THREADS=1 PYTHONPATH=src python benchmarks/strips_trajectory_response.py \\
        --seeds 700-705 --cache DIR [--methods planes,vgicp]

For surveys simulated by ``strips_roll.py`` (each with and without the GNSS/INS errors: the same points),
the true trajectory errors are the two SBETs' difference; at the knots they are the corrections c_t the
adjustment should find (shift: true − measured position, local ENU; rotation: from the measured attitude
to the true one). Near the solution the angles' error from the trajectory is −[N⁻¹ P c_t]_angles (the
prior pulls the corrections toward 0 and the angles absorb what the overlaps cannot tell apart). Per
survey: that prediction against the default calibration's actual error (which adds the rows' noise, of
the σ the rows' share gives). A slope of actual on predicted above 1 means the angles respond to the
trajectory errors by more than the model's Jacobian says.
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
from strips_montecarlo import ANGLES, seeds_of  # noqa: E402
from strips_prior_honesty import _CAPTURED, _capture, _knots  # noqa: E402
from strips_roll import folders  # noqa: E402

from calidar import frames  # noqa: E402
from calidar.adjust import solver  # noqa: E402
from calidar.io.sbet import read_sbet  # noqa: E402
from calidar.pipelines.boresight import calibrate_inputs, load_inputs  # noqa: E402
from calidar.pipelines.strip_config import StripConfig  # noqa: E402
from calidar.strips.config import CalibrationConfig, matchers_named  # noqa: E402


def true_corrections(measured, exact, times: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(n, 3) shifts true − measured (local ENU m) and (n, 3) rotations measured → true (ENU rad) at ``times``."""
    r = frames.r_en(measured.lat[0], measured.lon[0])  # NED → ECEF at the start (a 300 m survey: one frame)
    d_ecef = exact.ecef - measured.ecef
    ned = d_ecef @ r  # ECEF → NED
    enu = ned[:, [1, 0]]
    shift = np.column_stack([enu, -ned[:, 2]])
    rm = frames.rpy_to_matrix(measured.roll, measured.pitch, measured.heading)
    rt = frames.rpy_to_matrix(exact.roll, exact.pitch, exact.heading)
    turn = rt @ np.swapaxes(rm, -1, -2)  # NED: measured → true
    w_ned = np.column_stack([turn[:, 2, 1], turn[:, 0, 2], turn[:, 1, 0]])
    tilt = np.column_stack([w_ned[:, 1], w_ned[:, 0], -w_ned[:, 2]])
    at = lambda a: np.column_stack([np.interp(times, measured.time, a[:, k]) for k in range(3)])  # noqa: E731
    return at(shift), at(tilt)


def predicted(est, measured, exact) -> np.ndarray:
    """−[N⁻¹ P c_t] for the angles (rad)."""
    fit = est.fit
    N = fit.normal_equations(fit.jacobian(est.x), est.w)[0]
    ang = [next(i for i, p in enumerate(fit.free) if p.name == a) for a in ANGLES]
    G = np.linalg.inv(N)[ang]
    out = np.zeros(len(ang))
    for idx, _, P in fit.priors:
        if idx.size > 1 and fit.free[idx[0]].name.startswith("trajectory_"):
            knots = _knots(fit, idx)
            axis = ("east", "north", "up").index(fit.free[idx[0]].name.split("_")[2])
            shift, tilt = true_corrections(measured, exact, np.array([k[2] for k in knots]))
            c = (shift if knots[0][0] == "bias" else tilt)[:, axis]
            out -= G[:, idx] @ (P @ c)
    return out


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--seeds", default="700-705")
    ap.add_argument("--methods", default="planes,vgicp")
    ap.add_argument("--directions", default="opposite", choices=("cross", "opposite"))
    ap.add_argument("--cache", type=Path, required=True)
    args = ap.parse_args()
    solver.Estimate.solution = _capture
    methods, res = args.methods.split(","), {}
    for seed in seeds_of(args.seeds):
        f, exact = folders(args.cache, seed, "uav", args.directions, "preset", 0.0)
        measured, true = read_sbet(f / "sbet.out"), read_sbet(exact / "sbet.out")
        for m in methods:
            config = StripConfig(CalibrationConfig(matchers=matchers_named(m), model_check=False))
            inputs = load_inputs(sorted((f / "strips").glob("*.laz")), f / "sbet.out", f / "sensor.toml", config,
                                 truth=f / "truth.json")
            _CAPTURED.clear()
            sol = calibrate_inputs(inputs)[m].solution
            actual = np.array([sol.values[a] - inputs.truth[a] for a in ANGLES])
            pred = predicted(_CAPTURED[-1], measured, true)
            sigma = np.array([sol.sigma[a] for a in ANGLES])
            res.setdefault(m, []).append((actual, pred, sigma))
            print(f"seed {seed} {m:6s} actual " + " ".join(f"{v:+.3f}" for v in np.degrees(actual) * 1e3)
                  + "  predicted from the true trajectory errors " + " ".join(f"{v:+.3f}" for v in np.degrees(pred) * 1e3)
                  + "  σ " + " ".join(f"{v:.3f}" for v in np.degrees(sigma) * 1e3) + " mdeg", flush=True)
    for m, rows in res.items():
        a, p, s = (np.array([r[i] for r in rows]) for i in range(3))
        slope = np.sum(a * p, 0) / np.sum(p * p, 0)
        print(f"{m:6s} {len(a)} surveys: slope actual on predicted roll/pitch/yaw " + " / ".join(f"{v:.2f}" for v in slope)
              + "; RMS (actual − predicted)/σ " + " / ".join(f"{v:.2f}" for v in np.sqrt(np.mean(((a - p) / s) ** 2, 0)))
              + "; RMS predicted/σ " + " / ".join(f"{v:.2f}" for v in np.sqrt(np.mean((p / s) ** 2, 0)))
              + "; RMS actual/σ " + " / ".join(f"{v:.2f}" for v in np.sqrt(np.mean((a / s) ** 2, 0))))


if __name__ == "__main__":
    main()
