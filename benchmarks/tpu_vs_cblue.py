"""`calidar tpu` against cBLUE's subaerial TPU, side by side on the same simulated points (issue 31).

    python benchmarks/tpu_vs_cblue.py --cblue /tmp/cblue_src --cblue-python /tmp/cblue_venv/bin/python \
        [--scanner palmer|linear] [--seed 0] [--width 200] [--density 0.3]

(or CBLUE_DIR / CBLUE_PYTHON in the environment). cBLUE (NOAA RSD / Oregon State, LGPL; Parrish et al.,
https://github.com/noaa-rsd/cBLUE) is not part of calidar and is never imported into it: this script
writes the per-point inputs to a temporary .npz and runs a short driver under cBLUE's own python that
calls cBLUE's ``Subaerial.SensorModel``, ``Jacobian`` and ``Subaerial`` classes on them, one flight
line at a time as cBLUE's ``Tpu.calc_tpu`` does. Without a cBLUE checkout (``Subaerial.py``) or a
python that imports its dependencies (sympy, numexpr, numpy) the script says so and exits 0.

The inputs both tools get, per point: the delivered point and the SBET pose at its time (position,
roll, pitch, heading, from the simulator's measured trajectory), in the scene's local east/north/up
frame (cBLUE takes projected easting/northing and ellipsoidal height; at 200 m the two differ by a
rotation and a scale of < 1e-3), and the same σ: the smrmsg's per-epoch position and attitude σ, a
range σ and a scan-angle σ. The sensor's lever arm is zero (cBLUE measures ρ from the SBET position)
and its beam divergence 0 (cBLUE's subaerial part has no footprint term). cBLUE has no calibration
covariance; calidar is run without one.

Each configuration isolates one term, or combines them, and gives its per-point ratio cBLUE/calidar
of THU (√(σ_e² + σ_n²)) and TVU: median and 5th/95th percentiles, by |scan angle| bin. "vs truth" is
each tool's RMS of (actual error / its σ) against the simulator's exact hits (horizontal:
RMS(|e_h| / THU); vertical: RMS(e_u / TVU); 1 is honest), for the configuration whose σ are the
simulator's own noise figures.
"""

from __future__ import annotations

import argparse
import json
import os
import shutil
import subprocess
import sys
import tempfile
import time
from dataclasses import replace
from pathlib import Path

import numpy as np

#: run under cBLUE's python: argv = cBLUE checkout, inputs .npz, outputs .npz. Calls cBLUE's classes only.
DRIVER = r"""
import sys, numpy as np
sys.path.insert(0, sys.argv[1])
from Subaerial import SensorModel, Jacobian, Subaerial
d = np.load(sys.argv[2])
jacobian = Jacobian(SensorModel("Riegl VQ-880-G"))
out = {}
for line in np.unique(d["line"]):
    m = d["line"] == line
    merged = np.vstack([d["t"][m], d["t"][m], *d["las"][m].T, *d["sbet"][m].T, *d["rph"][m].T])
    j_eval = jacobian.eval_jacobian(merged)
    sm = jacobian.sensor_model  # how well cBLUE's own model re-locates the points, before/after its polynomial
    miss = sm.calc_aer_pos_err(sm.calc_cblue_aer_pos(), merged[2:5])
    out.setdefault("miss", []).append([np.sqrt(np.mean(sm.dx ** 2 + sm.dy ** 2 + sm.dz ** 2)),
                                       np.sqrt(np.mean(sum(c ** 2 for c in miss)))])
    for k, sig in enumerate(d["sigma"]):  # per configuration: a, b (rad), range (m); smrmsg σ per point
        n = int(m.sum())  # stddev rows as cBLUE's Merge.merge builds them: a, b, r, p, h, x, y, z, rho
        stddev = np.vstack([np.full(n, sig[0]), np.full(n, sig[1]), *(d["att"][m].T * sig[4:7, None]),
                            *(d["pos"][m].T * sig[3]), np.full(n, sig[2])])
        sub = Subaerial(jacobian, merged, stddev)
        sub.propogate_uncertainty(j_eval)
        out.setdefault(f"thu{k}", []).append(sub.thu)
        out.setdefault(f"tvu{k}", []).append(sub.tvu)
np.savez(sys.argv[3], miss=np.array(out.pop("miss")), **{k: np.concatenate(v) for k, v in out.items()})
"""

SCAN_BINS = [(0, 5), (5, 10), (10, 15), (15, 20), (20, 30), (30, 45)]


def cblue_available(cblue_dir: str | None, python: str) -> str | None:
    """None when cBLUE can run, else why not."""
    if not cblue_dir:
        return "no cBLUE checkout given (--cblue DIR or CBLUE_DIR)"
    if not (Path(cblue_dir) / "Subaerial.py").is_file():
        return f"{cblue_dir} holds no Subaerial.py (not a cBLUE checkout)"
    if shutil.which(python) is None and not Path(python).is_file():
        return f"python {python!r} for cBLUE not found (--cblue-python or CBLUE_PYTHON)"
    probe = subprocess.run([python, "-c", "import sympy, numexpr, numpy"], capture_output=True, text=True)
    if probe.returncode:
        last = (probe.stderr.strip().splitlines() or ["?"])[-1]
        return f"{python} cannot import cBLUE's dependencies (sympy, numexpr, numpy): {last}"
    return None


def configurations(cfg):
    """(name, calidar settings, factors on the smrmsg σ (position; roll, pitch, heading; 0 leaves the term
    out), cBLUE's σ_a, σ_b (rad) and σ_ρ (m)). The angle σ is calidar's encoder σ and cBLUE's a, b σ."""
    from calidar.tpu.propagate import TpuSettings

    enc, rng, deg = cfg.angle_noise_rad, cfg.range_noise_m, np.radians(0.02)
    off = TpuSettings(0.0, 0.0, 0.0)
    return [
        ("position (smrmsg)", off, (1, 0, 0, 0), (0, 0, 0)),
        ("attitude (smrmsg)", off, (0, 1, 1, 1), (0, 0, 0)),
        ("roll only", off, (0, 1, 0, 0), (0, 0, 0)),
        ("heading only", off, (0, 0, 0, 1), (0, 0, 0)),
        (f"range {rng * 100:g} cm", TpuSettings(rng, 0.0, 0.0), (0, 0, 0, 0), (0, 0, rng)),
        ("angle 0.02° (a = b)", TpuSettings(0.0, deg, 0.0), (0, 0, 0, 0), (deg, deg, 0)),
        ("angle 0.02° (b only)", TpuSettings(0.0, deg, 0.0), (0, 0, 0, 0), (0, deg, 0)),
        ("simulator's noise (all)", TpuSettings(rng, enc, 0.0), (1, 1, 1, 1), (enc, enc, rng)),
        ("each tool's defaults", TpuSettings(), (1, 1, 1, 1), (deg, deg, 0.025)),
    ]


def simulate(a, seed: int):
    import calidar
    from calidar.scanners import LinearScanner, PalmerScanner

    scanner = PalmerScanner(palmer_mirror_tilt=np.radians(a.mirror_tilt_deg)) if a.scanner == "palmer" \
        else LinearScanner()
    nominal = calidar.Sensor(scanner=scanner)  # lever arm 0: cBLUE's ρ starts at the SBET position
    over = {"gnss_noise_m": 1e-4, "attitude_noise_rad": 1e-7} if a.exact_trajectory else {}
    if a.angle_noise_deg is not None:
        over["angle_noise_rad"] = float(np.radians(a.angle_noise_deg))
    cfg = calidar.survey_config("uav", seed=seed, density=a.density, directions="cross", nominal=nominal, **over)
    cfg = replace(cfg, scene=replace(cfg.scene, width_m=a.width, length_m=a.width))
    return calidar.simulate_survey(cfg)


def inputs(res):
    """Per point, both tools' inputs in the scene's ENU frame: line, time, point, SBET position and
    roll/pitch/heading (rad) at the point's time, the smrmsg σ (east, north, up; roll, pitch, heading)."""
    from calidar import georef

    cols = {k: [] for k in ("line", "t", "las", "sbet", "rph", "pos", "att", "true", "scan")}
    for s in res.strips:
        position, _ = georef.poses(res.trajectory, s.gps_time)
        sig_pos, sig_att = res.accuracy.at(s.gps_time)
        cols["line"].append(np.full(len(s), s.point_source_id))
        cols["t"].append(s.gps_time)
        cols["las"].append(res.scene.ecef_to_enu(s.ecef))
        cols["sbet"].append(res.scene.ecef_to_enu(position))
        cols["rph"].append(np.stack(res.trajectory.interpolate_rpy(s.gps_time), 1))
        cols["pos"].append(sig_pos[:, [1, 0, 2]])
        cols["att"].append(sig_att)
        cols["true"].append(s.true_enu)
        cols["scan"].append(np.abs(s.scan_angle_deg))
    return {k: np.concatenate(v) for k, v in cols.items()}


def calidar_tpu(res, configs):
    from calidar.tpu.propagate import point_covariance, thu_tvu
    from calidar.trajectory_accuracy import TrajectoryAccuracy

    acc, out = res.accuracy, []
    for _, settings, factors, _ in configs:
        f = np.maximum(factors, 1e-9)  # σ must be > 0: 1e-9 of it leaves the term out
        scaled = TrajectoryAccuracy(acc.time, acc.position_m * f[0], acc.attitude_rad * f[1:])
        parts = [thu_tvu(point_covariance(res.trajectory, res.nominal, scaled, s.gps_time, s.ecef, settings))
                 for s in res.strips]
        out.append(tuple(np.concatenate(p) for p in zip(*parts)))
    return out


def run_cblue(cblue_dir: str, python: str, data: dict, configs):
    """cBLUE's (THU, TVU) per configuration, and per line the RMS 3D distance (m) between the points and
    cBLUE's re-location of them from its estimated ρ, a, b: before and after its polynomial correction."""
    sigma = np.array([[*c[3], *c[2]] for c in configs], float)  # a, b, ρ; position, roll, pitch, heading
    with tempfile.TemporaryDirectory() as tmp:
        src, dst = Path(tmp) / "in.npz", Path(tmp) / "out.npz"
        np.savez(src, sigma=sigma, **{k: data[k] for k in ("line", "t", "las", "sbet", "rph", "pos", "att")})
        done = subprocess.run([python, "-c", DRIVER, str(Path(cblue_dir).resolve()), str(src), str(dst)],
                              capture_output=True, text=True)
        if done.returncode:
            sys.exit(f"cBLUE driver failed:\n{done.stderr[-2000:]}")
        got = np.load(dst)
        return [(got[f"thu{k}"], got[f"tvu{k}"]) for k in range(len(configs))], got["miss"]


def ratio(num: np.ndarray, den: np.ndarray) -> np.ndarray:
    """num / den per point; NaN where both are below 1 µm (a term that gives nothing on that axis)."""
    with np.errstate(divide="ignore", invalid="ignore"):
        return np.where((num < 1e-6) & (den < 1e-6), np.nan, num / den)


def ratio_stats(r: np.ndarray) -> str:
    r = r[~np.isnan(r)]
    if r.size == 0:
        return "both 0"
    p5, p50, p95 = np.percentile(r, [5, 50, 95])
    return f"{p50:.3f} ({p5:.3f}–{p95:.3f})"


def one_survey(a, seed: int):
    """Both tools on one simulated survey: (inputs, configurations, calidar's and cBLUE's (THU, TVU) per
    configuration, seconds simulating, in calidar, in cBLUE)."""
    t0 = time.perf_counter()
    res = simulate(a, seed)
    data = inputs(res)
    configs = configurations(res.config)
    t1 = time.perf_counter()
    ours = calidar_tpu(res, configs)
    t2 = time.perf_counter()
    theirs, miss = run_cblue(a.cblue, a.cblue_python, data, configs)
    return data, configs, ours, theirs, (t1 - t0, t2 - t1, time.perf_counter() - t2), miss


def pooled(a, seeds):
    """one_survey over the seeds, per-point arrays concatenated."""
    runs = [one_survey(a, s) for s in seeds]
    data = {k: np.concatenate([r[0][k] for r in runs]) for k in runs[0][0]}
    cat = lambda i: [tuple(np.concatenate([r[i][k][j] for r in runs]) for j in range(2))  # noqa: E731
                     for k in range(len(runs[0][1]))]
    miss = np.concatenate([r[5] for r in runs])
    return data, runs[0][1], cat(2), cat(3), np.sum([r[4] for r in runs], axis=0), len(runs), miss


def print_truth(data, configs, ours, theirs) -> None:
    """Each tool's RMS of actual error / σ for the simulator's own noise figures, overall and by bin."""
    k = [c[0] for c in configs].index("simulator's noise (all)")
    err = data["las"] - data["true"]
    print("\nvs truth (σ = the simulator's noise): RMS of |e_h|/THU and e_u/TVU (1 = honest σ)")
    print("| |scan angle| | points | calidar horizontal | calidar vertical | cBLUE horizontal | cBLUE vertical |")
    print("|---|---|---|---|---|---|")
    for lo, hi in [(0, 90), *SCAN_BINS]:
        m = (data["scan"] >= lo) & (data["scan"] < hi)
        if m.sum() < 100:
            continue
        cells = []
        for thu, tvu in (ours[k], theirs[k]):
            cells += [np.sqrt(np.mean((err[m, 0] ** 2 + err[m, 1] ** 2) / thu[m] ** 2)),
                      np.sqrt(np.mean(err[m, 2] ** 2 / tvu[m] ** 2))]
        label = "all" if hi == 90 else f"{lo}–{hi}°"
        print(f"| {label} | {m.sum():,} | " + " | ".join(f"{c:.3f}" for c in cells) + " |")


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--cblue", default=os.environ.get("CBLUE_DIR"), help="cBLUE checkout (holds Subaerial.py)")
    ap.add_argument("--cblue-python", default=os.environ.get("CBLUE_PYTHON", "python3"),
                    help="python with cBLUE's dependencies (sympy, numexpr, numpy)")
    ap.add_argument("--scanner", choices=("palmer", "linear"), default="palmer")
    ap.add_argument("--mirror-tilt-deg", type=float, default=10.0,
                    help="Palmer mirror tilt B, deg (10: the beam 14–20° off nadir, an oval like the VQ-880-G's)")
    ap.add_argument("--seeds", default="0-0", help="surveys FIRST-LAST, pooled")
    ap.add_argument("--width", type=float, default=200.0, help="scene width and length, m")
    ap.add_argument("--density", type=float, default=0.3)
    ap.add_argument("--exact-trajectory", action="store_true", help="no trajectory errors (smrmsg σ ≈ 0)")
    ap.add_argument("--angle-noise-deg", type=float, default=None,
                    help="the simulator's encoder noise σ, deg (default: the preset's 0.002°)")
    a = ap.parse_args()
    why = cblue_available(a.cblue, a.cblue_python)
    if why:
        print(f"skipped: {why}")
        return
    lo, hi = map(int, a.seeds.split("-"))
    data, configs, ours, theirs, seconds, n_surveys, miss = pooled(a, range(lo, hi + 1))
    print(f"{a.scanner} scanner, UAV {a.width:.0f} m, seeds {a.seeds}: {data['t'].size:,} points in {n_surveys} "
          f"surveys; simulated in {seconds[0]:.0f} s, calidar {seconds[1]:.0f} s, cBLUE {seconds[2]:.0f} s "
          f"({len(configs)} configurations each)")
    print(f"cBLUE's re-location of the points from its ρ, a, b (RMS 3D, per line): {miss[:, 0].min() * 100:.3g}–"
          f"{miss[:, 0].max() * 100:.3g} cm before its polynomial correction, {miss[:, 1].min() * 100:.3g}–"
          f"{miss[:, 1].max() * 100:.3g} cm after")
    print("\nratio cBLUE / calidar per point: median (5th–95th percentile)")
    print("| configuration | THU | TVU | calidar THU / TVU median (cm) |")
    print("|---|---|---|---|")
    rows = {}
    for (name, *_), (thu_c, tvu_c), (thu_b, tvu_b) in zip(configs, ours, theirs):
        rows[name] = (ratio(thu_b, thu_c), ratio(tvu_b, tvu_c))
        print(f"| {name} | {ratio_stats(rows[name][0])} | {ratio_stats(rows[name][1])} | "
              f"{np.median(thu_c) * 100:.2f} / {np.median(tvu_c) * 100:.2f} |")
    print("\nby |scan angle| (across-track beam angle), THU ratio / TVU ratio, medians (5th–95th):")
    for name in ("attitude (smrmsg)", "angle 0.02° (a = b)", "simulator's noise (all)"):
        print(f"  {name}:")
        for lo, hi in SCAN_BINS:
            m = (data["scan"] >= lo) & (data["scan"] < hi)
            if m.sum() > 100:
                print(f"    {lo:2d}–{hi:2d}° ({m.sum():7,d}): THU {ratio_stats(rows[name][0][m])}  "
                      f"TVU {ratio_stats(rows[name][1][m])}")
    print_truth(data, configs, ours, theirs)
    print(json.dumps({"points": int(data["t"].size), "seconds": round(float(np.sum(seconds)), 1)}))


if __name__ == "__main__":
    main()
