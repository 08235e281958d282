"""Benchmark: strip calibration at scale — streamed ingest + calibration, time and peak memory vs points.

    nice -n 10 env NUMBA_NUM_THREADS=1 OMP_NUM_THREADS=1 PYTHONPATH=src python benchmarks/strips_scale.py \
        [--sizes 2,4,8,16,64] [--methods planes,vgicp] [--budget 300000] [--quality]

The survey of ``benchmarks/strips.py`` (airborne preset, 6 parallel lines flown in alternate
directions + 2 cross lines, 3 cm / 0.002° trajectory errors and their smrmsg.out) simulated at
the densities that give ≈ 2, 4, 8, 16 and 64 million points (the lines and the overlaps stay
the same, the points per m² grow; at 1 M, 0.1 point/m² in the overlaps, no 25 m patch is
planar enough for a tie plane, in memory as streamed), each strip written as soon as it is simulated (one strip in
memory at a time) and cached under ``--cache`` (not timed). Each run is a child process doing
what ``calidar boresight`` does, end to end (default options: trajectory model on; each file a
task on the in-process threads): read the strips (two passes, the second, and the quality stages,
from what the first kept on disk within ``HOLD_POINTS_BYTES``; thinned to ``--budget``
points per strip, :mod:`calidar.ingest.strips`), calibrate, the three overlap-quality
stages of the whole strips, report and outputs; with ``--quality`` also ``calidar quality`` of
the strips. Wall time and peak RSS (``os.wait4`` of the child) are printed per size and method,
with the exponent of time ∝ points^k fitted over the sizes, and the boresight of the largest
survey and the 4 M survey streamed compared with the 4 M survey calibrated from every
overlapping point in memory (``--budget`` off), in units of their σ.
"""

from __future__ import annotations

import argparse
import json
import os
import platform
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
from strips import ERRORS, survey  # noqa: E402  (the shared 8-strip survey and its mounting errors)

POINTS_PER_DENSITY = 8.75e6 / 1.7  #: points of the 8-strip survey per unit of simulator density


def simulate(cache: Path, million: float) -> Path:
    """The survey of ≈ ``million`` M points, simulated once (one strip in memory at a time)."""
    from calidar.sim.survey import simulate_survey, utm_crs, write_strip

    density = round(million * 1e6 / POINTS_PER_DENSITY, 4)
    sim = cache / f"airborne_8_strips_d{density:g}"
    if (sim / "truth.json").exists():
        return sim
    cfg = survey(density)
    (sim / "strips").mkdir(parents=True, exist_ok=True)
    crs = utm_crs(*cfg.origin_deg[:2])
    t = time.perf_counter()
    res = simulate_survey(cfg, on_strip=lambda s: write_strip(sim, s, crs, force=True))
    res.write(sim, force=True)  # trajectory, smrmsg, sensor, truth (the strips are written)
    print(f"simulated {res.n_points / 1e6:.2f} M points (density {density:g}) in {time.perf_counter() - t:.0f} s "
          "(not timed)", flush=True)
    return sim


def child(sim: Path, what: str, budget: str) -> None:
    """One run, printing a JSON line: ``what`` = a method ("planes", "vgicp"): the whole
    ``calidar boresight`` run (ingest, calibration, the three overlap-quality stages, report and
    outputs into a temporary folder); "quality": ``calidar quality`` of the strips."""
    import tempfile

    from calidar.pipelines.boresight import calibrate_strips
    from calidar.pipelines.strip_config import StripConfig
    from calidar.strips.config import CalibrationConfig, matchers_named
    from calidar.pipelines.quality import measure
    from calidar.ingest.settings import IngestSettings

    strips = sorted((sim / "strips").glob("*.laz"))
    t0 = time.perf_counter()
    if what == "quality":
        _, _, pairs, _, _, _ = measure(strips)
        print(json.dumps({"points": None, "pairs": len(pairs)}))
        return
    stamps = {}
    ingest = IngestSettings(budget_points=None if budget == "off" else int(budget))
    config = StripConfig(CalibrationConfig(matchers=matchers_named(what)), ingest)
    with tempfile.TemporaryDirectory() as out:
        run = calibrate_strips(strips, sim / "sbet.out", sim / "sensor.toml", config, truth=sim / "truth.json",
                               progress=lambda d, done, total: stamps.__setitem__(d.split(":")[0].split(" (")[0],
                                                                                  time.perf_counter() - t0))
        run.write(Path(out))
    sol, inputs = run.results[what].solution, run.inputs
    print(json.dumps({"points": sum(inputs.source.counts.values()), "kept": sum(len(s) for s in inputs.strips),
                      "ingest_s": stamps["reading strips"], "calibrate_s": stamps["calibrating"] - stamps["reading strips"],
                      "quality_s": stamps["overlap quality"] - stamps["calibrating"],
                      "values": {k: sol.values[k] for k in ERRORS}, "sigma": {k: sol.sigma[k] for k in ERRORS},
                      "truth": {k: inputs.truth[k] for k in ERRORS}}))


def run(sim: Path, what: str, budget: str = "300000") -> dict:
    """A child run: its JSON, wall time (s) and peak RSS (GiB)."""
    env = {**os.environ, "PYTHONPATH": str(Path(__file__).resolve().parents[1] / "src")}
    t = time.perf_counter()
    proc = subprocess.Popen([sys.executable, __file__, "--child", str(sim), what, budget], env=env,
                            stdout=subprocess.PIPE, text=True)
    out = proc.stdout.read()
    _, status, usage = os.wait4(proc.pid, 0)
    proc.returncode = os.waitstatus_to_exitcode(status)
    if proc.returncode:
        raise SystemExit(f"run failed: {sim} {what} {budget}")
    doc = json.loads(out.strip().splitlines()[-1])
    return {**doc, "wall_s": time.perf_counter() - t, "rss_gib": usage.ru_maxrss * 1024 / 2**30}


def exponent(points: list[float], seconds: list[float]) -> float:
    """k of seconds ∝ points^k (least squares in logs)."""
    return float(np.polyfit(np.log(points), np.log(seconds), 1)[0])


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--sizes", default="2,4,8,16,64", help="survey sizes, million points")
    ap.add_argument("--methods", default="planes,vgicp")
    ap.add_argument("--budget", default="300000", help="points kept per strip ('off': every overlapping point)")
    ap.add_argument("--cache", type=Path, default=Path(tempfile.gettempdir()) / "calidar_bench_strips_scale")
    ap.add_argument("--quality", action="store_true", help="also time `calidar quality` of the strips")
    ap.add_argument("--child", nargs=3, help=argparse.SUPPRESS)
    args = ap.parse_args()
    if args.child:
        return child(Path(args.child[0]), args.child[1], args.child[2])
    sizes = [float(s) for s in args.sizes.split(",")]
    methods = args.methods.split(",")
    sims = {m: simulate(args.cache, m) for m in sizes}
    print(f"machine: {platform.machine()}, {os.cpu_count()} cores, python {platform.python_version()}; "
          f"NUMBA_NUM_THREADS={os.environ.get('NUMBA_NUM_THREADS')} OMP_NUM_THREADS={os.environ.get('OMP_NUM_THREADS')}; "
          f"load average {os.getloadavg()[0]:.2f}; budget {args.budget} points per strip", flush=True)
    print(f"{'method':7s} {'points':>8s} {'kept':>7s} {'wall s':>7s} {'ingest s':>8s} {'calib s':>7s} {'quality s':>9s} "
          f"{'peak GiB':>8s}  "
          "boresight error / σ (roll, pitch, yaw)", flush=True)
    results = {}
    for method in methods:
        for m in sizes:
            r = results[method, m] = run(sims[m], method, args.budget)
            z = ", ".join(f"{(r['values'][k] - r['truth'][k]) / r['sigma'][k]:+.1f}" for k in ERRORS)
            print(f"{method:7s} {r['points'] / 1e6:7.2f}M {r['kept'] / 1e6:6.2f}M {r['wall_s']:7.1f} {r['ingest_s']:8.1f} "
                  f"{r['calibrate_s']:7.1f} {r['quality_s']:9.1f} {r['rss_gib']:8.2f}  {z}   "
                  f"(load {os.getloadavg()[0]:.2f})", flush=True)
        if len(sizes) > 1:
            k = exponent([results[method, m]["points"] for m in sizes], [results[method, m]["wall_s"] for m in sizes])
            print(f"{method}: wall time ∝ points^{k:.2f} over {sizes[0]:g}–{sizes[-1]:g} M", flush=True)
        if 4.0 in sizes and sizes[-1] != 4.0:
            ref = run(sims[4.0], method, "off")
            compare(method, ref, results[method, sizes[-1]])  # another survey: its own points and noise
            compare(method, ref, results[method, 4.0])  # the same survey, streamed: what thinning moves
    if args.quality:
        for m in sizes:
            r = results["quality", m] = run(sims[m], "quality")
            print(f"quality {m:7.2f}M {'':7s} {r['wall_s']:7.1f} {'':8s} {'':7s} {'':9s} {r['rss_gib']:8.2f}  "
                  f"{r['pairs']} pairs   (load {os.getloadavg()[0]:.2f})", flush=True)
        if len(sizes) > 1:
            k = exponent([results[methods[0], m]["points"] for m in sizes], [results["quality", m]["wall_s"] for m in sizes])
            print(f"quality: wall time ∝ points^{k:.2f}", flush=True)


def compare(method: str, ref: dict, big: dict) -> None:
    """A streamed survey's boresight against the 4 M survey calibrated in memory, in σ."""
    z = ", ".join(f"{(ref['values'][k] - ref['truth'][k]) / ref['sigma'][k]:+.1f}" for k in ERRORS)
    print(f"{method}: 4 M in memory (every overlapping point, {ref['kept'] / 1e6:.2f} M, {ref['wall_s']:.0f} s, "
          f"{ref['rss_gib']:.2f} GiB; error / σ {z}) vs {big['points'] / 1e6:.0f} M streamed "
          f"({big['kept'] / 1e6:.2f} M kept):", flush=True)
    for k in ERRORS:
        d = big["values"][k] - ref["values"][k]
        s = max(big["sigma"][k], ref["sigma"][k])
        print(f"  {k:16s} {np.degrees(big['values'][k]):+.5f}° vs {np.degrees(ref['values'][k]):+.5f}°: "
              f"Δ {np.degrees(d):+.5f}° = {d / s:+.2f} σ (σ {np.degrees(s):.5f}°)", flush=True)


if __name__ == "__main__":
    main()
