"""Trajectory reconstruction from delivered points (``calidar trajectory``) against the simulator's
trajectory, and its speed against reading the same files with laspy + lazrs.

Per case a survey is simulated and written as a real system delivers it (strips/*.laz, sbet.out,
sensor.toml), the trajectory is reconstructed from the strips alone (the same pipeline call as the
CLI) and compared, at the reconstructed epochs, with sbet.out — the trajectory the points were
georeferenced with — at the scanner's origin (sensor.toml's lever arm): median and 95th percentile
of the 3-D position, height and attitude errors, and RMS(error / σ) per channel (1 = honest σ).
Times: CPU seconds of this process (all threads) for ``laspy.read`` of every strip and for the
reconstruction, measured interleaved (read, reconstruct, read, reconstruct, …) ``--repeats`` times,
medians of each and the median of the per-pair ratios; wall seconds too. ``--mount known`` fits the
simulator's exact scanner with the encoder and scan-plane priors at 0 (default: calidar trajectory's
default priors, whose σ pass into the σ columns where the points do not determine them).

    PYTHONPATH=src nice -n 10 python benchmarks/trajectory_reconstruction.py [--cases airborne,uav,...]
        [--seeds 0] [--out /tmp/trajrec_bench] [--json results.json]

Cases: airborne (preset, 10 % of the area under trees: multi-return pulses), airborne_single (no trees:
one return a pulse), airborne_trees (40 % trees), airborne_rays (rays only, as PDAL's filters.trajectory:
no scan angles, no scan-plane geometry), uav, uav_single.
"""

from __future__ import annotations

import argparse
import json
import tempfile
import time
from dataclasses import replace
from pathlib import Path

import numpy as np

from calidar.io.sbet import read_sbet
from calidar.pipelines.trajectory import STANDING_NOTES, TrajectorySettings, reconstruct_trajectory
from calidar.sensor import Sensor
from calidar.sim.survey import simulate_survey, survey_config
from calidar.trajrec.result import compare, error_summary

CASES = {  # name: (preset, survey overrides, fit overrides)
    "airborne": ("airborne", {}, {}),
    "airborne_single": ("airborne", {"vegetation": 0.0}, {}),
    "airborne_trees": ("airborne", {"vegetation": 0.4}, {}),
    "airborne_rays": ("airborne", {}, {"use_scan_angles": False, "planar_scanner": False}),
    "uav": ("uav", {}, {}),
    "uav_single": ("uav", {"vegetation": 0.0}, {}),
    "uav_trees": ("uav", {"vegetation": 0.4}, {}),
}


def _once(fn):
    c, w = time.process_time(), time.perf_counter()
    out = fn()
    return out, time.process_time() - c, time.perf_counter() - w


def _interleaved(read, reconstruct, repeats: int):
    """(reconstruction, {read/reconstruct cpu/wall medians, median ratio}) of ``repeats`` interleaved pairs."""
    rows = []
    run = None
    for _ in range(repeats):
        _, rc, rw = _once(read)
        run, c, w = _once(reconstruct)
        rows.append((rc, rw, c, w))
    a = np.array(rows)
    med = np.median(a, axis=0)
    return run, {"read_cpu_s": med[0], "read_wall_s": med[1], "reconstruct_cpu_s": med[2], "reconstruct_wall_s": med[3],
                 "ratio_cpu": float(np.median(a[:, 2] / a[:, 0])), "ratio_wall": float(np.median(a[:, 3] / a[:, 1])),
                 "pairs": a.tolist()}


def _read_all(files):
    import laspy

    return sum(len(laspy.read(f).points) for f in files)


def run_case(name: str, seed: int, folder: Path, repeats: int, mount: str = "default") -> dict:
    preset, survey, fit = CASES[name]
    sim_dir = folder / f"{preset}_{seed}_{survey.get('vegetation', 'default')}"
    if not (sim_dir / "sbet.out").exists():
        simulate_survey(survey_config(preset, seed=seed, **survey)).write(sim_dir, force=True)
    files = sorted((sim_dir / "strips").glob("*.laz"))
    base = TrajectorySettings()
    if mount == "known":
        fit = {**fit, "mount_sigma": (0.0,) * 6}
    settings = replace(base, fit=replace(base.fit, **fit))
    n = _read_all(files)
    run, times = _interleaved(lambda: _read_all(files), lambda: reconstruct_trajectory(files, settings=settings), repeats)
    sensor = Sensor.read(sim_dir / "sensor.toml")
    truth = read_sbet(sim_dir / "sbet.out")
    c = compare(run.trajectory, truth, (sensor.lever_arm_x, sensor.lever_arm_y, sensor.lever_arm_z))
    per_line = []
    for ln in run.lines:
        from calidar.trajrec.result import to_trajectory

        one = compare(to_trajectory([ln]), truth, (sensor.lever_arm_x, sensor.lever_arm_y, sensor.lever_arm_z))
        per_line.append({"line": ln.label, "heading_median_deg": float(np.degrees(np.median(np.abs(one["d_att"][:, 2])))),
                         "position_median_m": float(np.median(np.linalg.norm(one["d_ned"], axis=1)))})
    return {"case": name, "seed": seed, "mount": mount, "points": n, "lines": len(run.lines), "errors": error_summary(c),
            "sigma_median": {k: float(np.median(v)) for k, v in run.trajectory.extra.items() if k.startswith("sigma_")},
            "per_line": per_line, "notes": run.notes[len(STANDING_NOTES):], **times}


def table(results: list[dict]) -> str:
    head = ("| case | seed | points | 3-D position median / p95 [m] | height median / p95 [m] | "
            "roll median / p95 [°] | pitch median / p95 [°] | heading median / p95 [°] | RMS(error/σ) N,E,D,r,p,h | "
            "read CPU [s] | reconstruct CPU [s] | ratio |\n|" + "---|" * 12)
    rows = []
    for r in results:
        e = r["errors"]
        z = e.get("rms_error_over_sigma", {})
        rows.append(f"| {r['case']} | {r['seed']} | {r['points']:,} | {e['position_3d_m']['median']:.4f} / "
                    f"{e['position_3d_m']['p95']:.4f} | {e['height_m']['median']:.4f} / {e['height_m']['p95']:.4f} | "
                    f"{e['roll_deg']['median']:.5f} / {e['roll_deg']['p95']:.5f} | {e['pitch_deg']['median']:.5f} / "
                    f"{e['pitch_deg']['p95']:.5f} | {e['heading_deg']['median']:.6f} / {e['heading_deg']['p95']:.6f} | "
                    f"{', '.join(f'{v:.2f}' for v in z.values())} | {r['read_cpu_s']:.2f} | {r['reconstruct_cpu_s']:.2f} | "
                    f"{r['ratio_cpu']:.2f} |")
    return head + "\n" + "\n".join(rows)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--cases", default=",".join(CASES))
    ap.add_argument("--seeds", default="0")
    ap.add_argument("--repeats", type=int, default=3)
    ap.add_argument("--mount", choices=("default", "known"), default="default")
    ap.add_argument("--out", default=str(Path(tempfile.gettempdir()) / "calidar_trajrec_bench"))
    ap.add_argument("--json", default=None)
    a = ap.parse_args()
    results = []
    for name in a.cases.split(","):
        for seed in (int(s) for s in a.seeds.split(",")):
            r = run_case(name, seed, Path(a.out), a.repeats, a.mount)
            results.append(r)
            print(json.dumps(r), flush=True)
    print(table(results))
    if a.json:
        Path(a.json).write_text(json.dumps(results, indent=2) + "\n", encoding="utf-8")


if __name__ == "__main__":
    main()
