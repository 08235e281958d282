"""Strip adjustment of delivered data without its trajectory (issue #30): ``calidar boresight`` with
the trajectory ``calidar trajectory`` reconstructs from the strips, against the same calibration with
the simulator's trajectory (sbet.out).

Per seed a survey is simulated with a random boresight error (σ 0.1° per axis), delivered as strips
georeferenced with the nominal sensor; the trajectory is reconstructed from the strips alone (the
scanner's origin and scan-plane attitude, so the sensor given with it has a zero lever arm); both
calibrations run with the default options (tie planes, boresight, trajectory model on); the true
trajectory's accuracy is its smrmsg.out, the reconstructed one's the survey's navigation grade given
as ``--trajectory-sigma`` (its σ columns are the reconstruction's σ, not the navigation error). Reported per run: the overlaps' mean |median dz|
and mean RMSDz after calibration (final quality stage), and the boresight error against the truth.

    PYTHONPATH=src nice -n 10 python benchmarks/trajectory_boresight.py [--preset uav] [--seeds 0-19]
        [--density 0.3] [--out /tmp/trajrec_boresight] [--json results.json]
"""

from __future__ import annotations

import argparse
import json
import tempfile
from pathlib import Path

import numpy as np

from calidar.pipelines.boresight import calibrate_strips
from calidar.pipelines.strip_config import StripConfig
from calidar.strips.config import CalibrationConfig, TrajectorySettings
from calidar.pipelines.trajectory import reconstruct_trajectory, write_outputs
from calidar.sensor import Sensor
from calidar.sim.survey import simulate_survey, survey_config

ANGLES = ("boresight_roll", "boresight_pitch", "boresight_yaw")


def _quality(run) -> dict:
    stages = run.quality["planes"]
    final = stages[-1].pairs
    med = [abs(q.median_dz_m) for q in final if q.median_dz_m is not None]
    rms = [q.rmsdz_m for q in final if q.rmsdz_m is not None]
    first = stages[0].pairs
    return {"stage": stages[-1].label, "mean_abs_median_dz_m": float(np.mean(med)), "mean_rmsdz_m": float(np.mean(rms)),
            "delivered_mean_abs_median_dz_m": float(np.mean([abs(q.median_dz_m) for q in first
                                                               if q.median_dz_m is not None])),
            "delivered_mean_rmsdz_m": float(np.mean([q.rmsdz_m for q in first if q.rmsdz_m is not None]))}


def _boresight_error_deg(run, truth: dict) -> list[float]:
    sol = run.results["planes"].solution
    return [float(np.degrees(sol.values[k]) - truth["parameters"][k]["value"]) for k in ANGLES]


def one(seed: int, preset: str, density: float, folder: Path) -> dict:
    rng = np.random.default_rng(1000 + seed)
    err = dict(zip(ANGLES, np.radians(rng.normal(0.0, 0.1, 3))))
    sim = folder / f"{preset}_{seed}"
    if not (sim / "truth.json").exists():
        simulate_survey(survey_config(preset, seed=seed, density=density, errors=err)).write(sim, force=True)
    strips = sorted((sim / "strips").glob("*.laz"))
    truth = json.loads((sim / "truth.json").read_text())
    rec = reconstruct_trajectory(strips)
    write_outputs(rec, sim / "rec" / "traj.csv", "text", sim / "rec" / "report.html", [], force=True)
    nominal = Sensor.read(sim / "sensor.toml")
    (sim / "rec" / "sensor.toml").unlink(missing_ok=True)
    nominal.with_parameters(lever_arm_x=0.0, lever_arm_y=0.0, lever_arm_z=0.0).write(sim / "rec" / "sensor.toml")
    out = {}
    # the reconstruction's σ columns say how well the points fix the path they were georeferenced with, not
    # that path's navigation error, which points cannot know: the reconstructed run is given the survey's
    # navigation grade (the simulator's GNSS σ and attitude σ), as a user would give their system's
    cfg = survey_config(preset)
    grade = StripConfig(CalibrationConfig(trajectory=TrajectorySettings(sigma=(cfg.gnss_noise_m, cfg.attitude_noise_rad))))
    for name, traj, sensor, opts in (
            ("true", sim / "sbet.out", sim / "sensor.toml", StripConfig()),
            ("reconstructed", sim / "rec" / "traj.csv", sim / "rec" / "sensor.toml",
             grade)):
        dest = Path(tempfile.mkdtemp(dir=folder)) / name
        run = calibrate_strips(strips, traj, sensor, opts)
        run.write(dest)
        out[name] = {**_quality(run), "boresight_error_deg": _boresight_error_deg(run, truth),
                     "verdict": run.verdicts["planes"].status}
    return {"seed": seed, "preset": preset, "density": density, **out,
            "ratio_median_dz": out["reconstructed"]["mean_abs_median_dz_m"] / max(out["true"]["mean_abs_median_dz_m"], 1e-9),
            "ratio_rmsdz": out["reconstructed"]["mean_rmsdz_m"] / out["true"]["mean_rmsdz_m"]}


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--preset", default="uav")
    ap.add_argument("--seeds", default="0-19")
    ap.add_argument("--density", type=float, default=0.3)
    ap.add_argument("--out", default=str(Path(tempfile.gettempdir()) / "calidar_trajrec_boresight"))
    ap.add_argument("--json", default=None)
    a = ap.parse_args()
    lo, _, hi = a.seeds.partition("-")
    seeds = range(int(lo), int(hi or lo) + 1)
    folder = Path(a.out)
    folder.mkdir(parents=True, exist_ok=True)
    results = []
    for seed in seeds:
        r = one(seed, a.preset, a.density, folder)
        results.append(r)
        print(json.dumps(r), flush=True)
        if a.json:
            Path(a.json).write_text(json.dumps(results, indent=2) + "\n", encoding="utf-8")
    rd = [r["ratio_median_dz"] for r in results]
    rr = [r["ratio_rmsdz"] for r in results]
    print(f"{len(results)} surveys: reconstructed / true trajectory, mean |median dz| ratio median {np.median(rd):.3f} "
          f"(max {np.max(rd):.3f}), mean RMSDz ratio median {np.median(rr):.3f} (max {np.max(rr):.3f})")


if __name__ == "__main__":
    main()
