"""Monte-Carlo of ``calidar boresight --control``: are the σ of the range offset honest with ground control?

    NUMBA_NUM_THREADS=1 OMP_NUM_THREADS=1 PYTHONPATH=src python benchmarks/control_montecarlo.py \\
        --seeds 100-139 [--estimate boresight,range_offset,height_bias] [--height-bias 0.04] [--control 10] \\
        [--kind points|planes|cloud] [--control-sigma 0.01] [--no-cluster] [--json out.jsonl]

Each seed is one UAV survey (200 m × 200 m, density 0.2, lines across each other, no trees, a
5 cm range offset, the preset's 2 cm / 0.002° trajectory errors and the smrmsg.out that states
them) written as the simulator delivers it, with ``--control`` surveyed points on open ground
(σ 1 cm, ``calidar.sim.checkpoints``) raised by ``--height-bias`` (a vertical trajectory bias:
trajectory and points that much low are, to the strips, control that much high), (``--kind planes``: as many roof facets, surveyed at their corners with σ 1 cm, 3-D, ``calidar.sim.control_planes``),
then calibrated by the boresight pipeline with its default
options and ``--control checkpoints.csv`` (:func:`calidar.pipelines.boresight.load_inputs` and
:func:`calibrate_inputs`). ``height_bias`` is compared with ``--height-bias``; "vertical", the
whole common height correction (height_bias + the trajectory knots' mean up shift, what the
verdict calls the vertical trajectory bias), with ``--height-bias`` minus the measured
trajectory's own mean height error at the points' times (its Gauss–Markov errors do not average
out over a few minutes of flight). The boresight angles are recorded too (truth 0). One line per survey (error, σ, z = error/σ), then
the RMS of z per parameter (1 for honest σ; its sampling spread ±1/√(2n)), the mean z, the largest
|z|, and the number of surveys that ran.
"""

from __future__ import annotations

import argparse
import json
import shutil
import sys
import tempfile
import time
from dataclasses import replace
from pathlib import Path

import numpy as np

from calidar.errors import InputError

RANGE_OFFSET = 0.05
NAMES = ("range_offset", "height_bias", "lever_arm_z", "boresight_roll", "boresight_pitch", "boresight_yaw")
SUMMARY = (*NAMES, "vertical")


def one(seed: int, estimate: str, n_control: int, height_bias: float, kind: str = "points", cluster: bool = True,
        control_sigma: float = 0.01) -> dict:
    from calidar.pipelines.boresight import calibrate_inputs, load_inputs
    from calidar.pipelines.strip_config import StripConfig
    from calidar.strips.config import CalibrationConfig, Estimate, StripSettings
    from calidar.sim.checkpoints import simulate_checkpoints
    from calidar.sim.survey import simulate_survey, survey_config
    from calidar.strips.control import vertical_shift

    clock = time.perf_counter()
    cfg = survey_config("uav", seed=seed, density=0.2, directions="cross", errors={"range_offset": RANGE_OFFSET})
    res = simulate_survey(replace(cfg, scene=replace(cfg.scene, width_m=200.0, length_m=200.0, vegetation_fraction=0.0)))
    folder = Path(tempfile.mkdtemp(prefix=f"control_mc_{seed}_"))
    try:
        sim = res.write(folder / "sim")
        if kind == "planes":  # roof facets surveyed at their corners (σ 1 cm, 3-D)
            from calidar.sim.control_planes import simulate_control_planes

            cp = simulate_control_planes(res, n_control, control_sigma, seed=seed)
        elif kind == "cloud":  # a dense scan of the open ground, its datum off by N(0, σ)
            from calidar.sim.reference_cloud import simulate_reference_cloud

            cp = simulate_reference_cloud(res, control_sigma, seed=seed)
        else:
            cp = simulate_checkpoints(res, n_control, control_sigma, seed=seed, vegetated_share=0.0)
        cp.xyz[:, 2] += height_bias
        control = cp.write(sim)
        solver = StripSettings() if cluster else StripSettings(cluster_s=None)
        config = StripConfig(CalibrationConfig(Estimate.of(*estimate.split(",")), solver=solver),
                             control_sigma_m=control_sigma if kind == "cloud" else None)
        inputs = load_inputs(sorted((sim / "strips").glob("*.laz")), sim / "sbet.out", sim / "sensor.toml", config,
                             truth=sim / "truth.json", control=control)
        result = calibrate_inputs(inputs)["planes"]
        sol = result.solution
    finally:
        shutil.rmtree(folder, ignore_errors=True)
    out = {"seed": seed, "seconds": time.perf_counter() - clock}
    truth = {**inputs.truth, "height_bias": height_bias}
    for name in NAMES:
        if name in sol.parameters.free_names:
            err = sol.values[name] - truth[name]
            out[name] = {"error_m": err, "sigma_m": sol.sigma[name], "z": err / sol.sigma[name]}
    shift = vertical_shift(result)
    if shift is not None:  # the whole common height correction (height_bias + the knots' mean)
        truth_v = height_bias - trajectory_height_error(res, inputs.strips[0].frame)
        err = shift[0] - truth_v
        out["vertical"] = {"error_m": err, "sigma_m": shift[1], "z": err / shift[1], "truth_m": truth_v}
    return out


def trajectory_height_error(res, frame) -> float:
    """The measured trajectory's mean height error (m, up) at the strips' points' times: what the
    delivered points carry besides the sensor's errors, to be corrected with the height bias."""
    t = np.concatenate([s.gps_time[::50] for s in res.strips])
    d = res.trajectory.interpolate(t)[0] - res.trajectory_true.interpolate(t)[0]
    return float(np.mean(d @ frame.r_le[2]))


def main(argv=None) -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--seeds", default="100-109")
    ap.add_argument("--estimate", default="boresight,range_offset,height_bias")
    ap.add_argument("--height-bias", type=float, default=0.04)
    ap.add_argument("--control", type=int, default=10)
    ap.add_argument("--kind", choices=("points", "planes", "cloud"), default="points",
                    help="control points on open ground, roof facets (control planes) surveyed at their corners, or "
                         "a reference cloud of the open ground")
    ap.add_argument("--control-sigma", type=float, default=0.01,
                    help="the control's survey σ, m (a reference cloud's: the σ of its datum)")
    ap.add_argument("--no-cluster", action="store_true",
                    help="σ from the model alone (StripSettings.cluster_s None), not raised by the cluster-robust sandwich")
    ap.add_argument("--json", type=Path)
    a = ap.parse_args(argv)
    lo, hi = (int(x) for x in a.seeds.split("-"))
    rows = []
    skipped = []
    for seed in range(lo, hi + 1):
        try:
            r = one(seed, a.estimate, a.control, a.height_bias, a.kind, not a.no_cluster, a.control_sigma)
        except InputError as e:  # e.g. a scene without room for the control points: told, not counted
            skipped.append(seed)
            print(f"seed {seed} skipped: {e}", file=sys.stderr)
            continue
        rows.append(r)
        print(json.dumps(r), flush=True)
        if a.json:
            with a.json.open("a") as f:
                f.write(json.dumps(r) + "\n")
    for name in SUMMARY:
        z = np.array([r[name]["z"] for r in rows if name in r])
        if z.size:
            print(f"{name}: {z.size} surveys, RMS z {np.sqrt(np.mean(z**2)):.2f} (±{1 / np.sqrt(2 * z.size):.2f}), "
                  f"mean z {z.mean():+.2f}, max |z| {np.abs(z).max():.2f}, "
                  f"RMS error {1e3 * np.sqrt(np.mean([r[name]['error_m'] ** 2 for r in rows if name in r])):.1f} mm, "
                  f"median σ {1e3 * np.median([r[name]['sigma_m'] for r in rows if name in r]):.1f} mm")
    print(f"{len(rows)} surveys ran" + (f"; seeds skipped: {skipped}" if skipped else ""), file=sys.stderr)


if __name__ == "__main__":
    main()
