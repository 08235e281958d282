"""Benchmark: a measured large flight (issue 32) — simulated fast to LAZ on disk, then calibrated
from the files by ``calidar boresight``, against the floor of reading them.

    # simulate (once per size; the strips of the 8-line survey of benchmarks/strips_scale.py)
    nice -n 10 env NUMBA_NUM_THREADS=1 OMP_NUM_THREADS=1 PYTHONPATH=src python benchmarks/large_flight.py \
        simulate --size 1000 --data /work/bigsim [--workers 2]
    # measure: the floor (laspy + lazrs reading every field) and `calidar boresight`, interleaved
    nice -n 10 env NUMBA_NUM_THREADS=1 OMP_NUM_THREADS=1 PYTHONPATH=src python benchmarks/large_flight.py \
        measure --size 1000 --data /work/bigsim [--runs 1] [--method planes]

The survey is benchmarks/strips.py's (airborne preset, 6 parallel lines flown in alternate
directions + 2 cross lines, boresight errors 0.03 / −0.04 / 0.05°, the preset's 3 cm / 0.002°
trajectory errors and their smrmsg.out, 3 cm range noise) at the density that gives ≈ ``--size``
million points, simulated by :func:`calidar.sim.large_survey.simulate_large_survey` (the same
flight over a closed-form piecewise-planar ground, one return per pulse, ≈ 5 B a point in LAZ)
in a child process: wall, CPU seconds and peak RSS (``os.wait4``) into ``DIR/<size>/simulate.json``.
``--stages`` (or ``stages`` alone): then one run of the same pipeline in one process with each
stage's start stamped live (wall, CPU, peak RSS so far) into ``DIR/flight_<size>M/stages_<method>.log``:
where the time goes, and how far a run got if stopped. ``measure`` runs whole child processes — the floor (benchmarks/against_read.py's: every field of
every file decompressed by laspy + lazrs) then ``python -m calidar boresight STRIPS --trajectory
--sensor --method --out DIR/<size>/out_<method>``, ``--runs`` times interleaved — and prints each
one's wall and CPU seconds and peak RSS (``os.wait4``), the ratio to the floor run just before it,
and the boresight's error against truth.json in units of its σ; the command's stderr (its
progress) goes to ``DIR/<size>/boresight_<method>_<run>.log``. Data stay outside the repository:
delete ``DIR/flight_<size>M`` when done.
"""

from __future__ import annotations

import argparse
import json
import os
import platform
import subprocess
import sys
import time
from dataclasses import replace
from pathlib import Path

import numpy as np

ERRORS = {"boresight_roll": np.radians(0.03), "boresight_pitch": np.radians(-0.04), "boresight_yaw": np.radians(0.05)}
PULSES_PER_DENSITY = 4.86e6  #: points of the 8-line survey per unit of simulator density (one return a pulse)
HERE = Path(__file__).resolve()


def survey(density: float):
    """benchmarks/strips.py's 8-line airborne survey at ``density``."""
    from calidar.sim.survey import PRESETS, survey_config

    scene = replace(PRESETS["airborne"].scene, width_m=3300.0)
    return survey_config("airborne", seed=5, density=density, directions="cross", scene=scene, errors=ERRORS,
                         range_noise_m=0.03)


def folder(data: Path, size: float, crop: str | None = None) -> Path:
    return data / (f"flight_{size:g}M" + (f"_crop{crop.replace(',', 'x')}" if crop else ""))


def child_simulate(sim: Path, size: float, workers: int, crop: str = "") -> None:
    from calidar.sim.large_survey import simulate_large_survey

    density = round(size * 1e6 / PULSES_PER_DENSITY, 4)
    box = tuple(float(v) for v in crop.split(",")) if crop else None
    res = simulate_large_survey(survey(density), sim, workers=workers, crop=box)
    print(json.dumps({"points": res.n_points, "density": density, "files": len(res.lines)}))


def child_stages(sim: Path, method: str) -> None:
    """``calidar boresight``'s pipeline in this process (:func:`calidar.pipelines.boresight.calibrate_strips`,
    default settings, outputs into a temporary folder), a JSON line on stderr as each stage begins
    (wall and CPU seconds so far, peak RSS so far: a run stopped early still says where it got),
    the solution's boresight and σ on stdout at the end."""
    import tempfile

    from calidar.pipelines.boresight import calibrate_strips
    from calidar.pipelines.strip_config import StripConfig
    from calidar.strips.config import CalibrationConfig, matchers_named

    t0, last = time.perf_counter(), [None, -1]

    def stamp(description: str, done: int, total: int) -> None:
        stage = description.split(":")[0].split(" (")[0]
        tenth = int(10 * done / total) if total else 0  # and at each tenth of a stage
        if stage != last[0] or tenth > last[1]:
            last[0], last[1] = stage, tenth
            hwm = next(int(ln.split()[1]) for ln in open("/proc/self/status") if ln.startswith("VmHWM"))
            print(json.dumps({"stage": stage, "done": f"{done}/{total}", "wall_s": round(time.perf_counter() - t0, 1),
                              "cpu_s": round(time.process_time(), 1), "peak_gib": round(hwm / 2**20, 3)}),
                  file=sys.stderr, flush=True)

    strips = sorted((sim / "strips").glob("*.laz"))
    config = StripConfig(CalibrationConfig(matchers=matchers_named(method)))
    with tempfile.TemporaryDirectory() as out:
        run = calibrate_strips(strips, sim / "sbet.out", sim / "sensor.toml", config, progress=stamp)
        stamp("writing outputs", 0, 1)
        run.write(Path(out))
    stamp("done", 1, 1)
    sol = run.results[method].solution
    print(json.dumps({"values": {k: float(np.degrees(sol.values[k])) for k in ERRORS},
                      "sigma": {k: float(np.degrees(sol.sigma[k])) for k in ERRORS}}))


def measured(cmd: list[str], log: Path | None = None) -> dict:
    """A child process: its last JSON line (if any), wall and CPU seconds, peak RSS GiB."""
    env = {**os.environ, "PYTHONPATH": str(HERE.parents[1] / "src")}
    load = os.getloadavg()[0]
    t = time.perf_counter()
    with open(log or os.devnull, "w") as err:
        proc = subprocess.Popen(cmd, env=env, stdout=subprocess.PIPE, stderr=err, text=True)
        text = proc.stdout.read()
        _, status, usage = os.wait4(proc.pid, 0)
    wall = time.perf_counter() - t
    code = os.waitstatus_to_exitcode(status)
    if code not in (0, 3):  # 3: a FAIL verdict, outputs written
        raise SystemExit(f"run failed ({code}): {' '.join(cmd[:4])} …")
    lines = [ln for ln in text.strip().splitlines() if ln.startswith("{")]
    return {"wall_s": wall, "cpu_s": usage.ru_utime + usage.ru_stime, "rss_gib": usage.ru_maxrss * 1024 / 2**30,
            "load": load, "out": json.loads(lines[-1]) if lines else None}


def simulate(data: Path, size: float, workers: int, crop: str | None = None) -> dict:
    sim = folder(data, size, crop)
    r = measured([sys.executable, str(HERE), "--child-simulate", str(sim), str(size), str(workers),
                  crop or ""])
    gb = sum(p.stat().st_size for p in (sim / "strips").glob("*.laz")) / 1e9
    out = r.pop("out")
    doc = {**r, **out, "gb": gb, "workers": workers}
    (sim / "simulate.json").write_text(json.dumps(doc, indent=1))
    print(f"simulated {doc['points'] / 1e6:.1f} M points in {doc['files']} files, {gb:.2f} GB: {r['wall_s']:.0f} s wall, "
          f"{r['cpu_s']:.0f} s CPU, peak {r['rss_gib']:.2f} GiB, {workers} worker(s), load {r['load']:.1f}", flush=True)
    return doc


def errors_in_sigma(out: Path, sim: Path) -> dict:
    """The boresight's error against truth.json in units of its σ (roll, pitch, yaw)."""
    sol = json.loads((out / "solution.json").read_text())["parameters"]
    truth = json.loads((sim / "truth.json").read_text())["parameters"]
    return {k: (sol[k]["value"] - truth[k]["value"]) / sol[k]["sigma"] for k in ERRORS}


def measure(sim: Path, runs: int, method: str, stages: bool = False) -> None:
    strips = [str(p) for p in sorted((sim / "strips").glob("*.laz"))]
    out = sim / f"out_{method}"
    cmd = [sys.executable, "-m", "calidar", "boresight", *strips, "--trajectory", str(sim / "sbet.out"), "--sensor",
           str(sim / "sensor.toml"), "--method", method, "--out", str(out), "--force"]
    print(f"machine: {platform.machine()}, {os.cpu_count()} cores, python {platform.python_version()}; "
          f"NUMBA_NUM_THREADS={os.environ.get('NUMBA_NUM_THREADS')}; {sim}", flush=True)
    for k in range(runs):
        floor = measured([sys.executable, str(HERE.parent / "against_read.py"), "--child", str(sim)])
        print(f"run {k + 1}: read {floor['out']['points'] / 1e6:.1f} M points: {floor['wall_s']:.1f} s wall, "
              f"{floor['cpu_s']:.1f} s CPU, peak {floor['rss_gib']:.2f} GiB, load {floor['load']:.1f}", flush=True)
        r = measured(cmd, log=sim / f"boresight_{method}_{k + 1}.log")
        z = errors_in_sigma(out, sim)
        print(f"run {k + 1}: boresight ({method}) {r['wall_s']:.1f} s wall ({r['wall_s'] / floor['wall_s']:.2f}× the read), "
              f"{r['cpu_s']:.1f} s CPU ({r['cpu_s'] / floor['cpu_s']:.2f}×), peak {r['rss_gib']:.2f} GiB, "
              f"load {r['load']:.1f}; error/σ roll {z['boresight_roll']:+.2f}, pitch {z['boresight_pitch']:+.2f}, "
              f"yaw {z['boresight_yaw']:+.2f}", flush=True)
    if stages:
        stage_run(sim, method)


def stage_run(sim: Path, method: str) -> None:
    """Where the time goes: :func:`child_stages` (the same pipeline with its stages stamped, live,
    into ``DIR/<size>/stages_<method>.log``)."""
    log = sim / f"stages_{method}.log"
    r = measured([sys.executable, str(HERE), "--child-stages", str(sim), method], log=log)
    stamps = [json.loads(ln) for ln in log.read_text().splitlines() if ln.startswith("{")]
    truth = json.loads((sim / "truth.json").read_text())["parameters"]
    z = ", ".join(f"{(r['out']['values'][k] - truth[k]['value']) / r['out']['sigma'][k]:+.2f}" for k in ERRORS)
    print(f"stages ({method}, the pipeline in one process): {r['wall_s']:.1f} s wall, {r['cpu_s']:.1f} s CPU, "
          f"peak {r['rss_gib']:.2f} GiB; error/σ {z}; stage starts (wall s / CPU s / peak GiB so far): "
          + "; ".join(f"{s['stage']} {s['done']} {s['wall_s']}/{s['cpu_s']}/{s['peak_gib']}" for s in stamps), flush=True)


def main() -> None:
    if len(sys.argv) > 1 and sys.argv[1] == "--child-simulate":
        return child_simulate(Path(sys.argv[2]), float(sys.argv[3]), int(sys.argv[4]),
                              *sys.argv[5:])
    if len(sys.argv) > 1 and sys.argv[1] == "--child-stages":
        return child_stages(Path(sys.argv[2]), sys.argv[3])
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("what", choices=["simulate", "measure", "stages"])
    ap.add_argument("--size", type=float, default=64.0, help="million points")
    ap.add_argument("--data", type=Path, default=Path("/work/bigsim"))
    ap.add_argument("--workers", type=int, default=2, help="simulate: processes writing strips")
    ap.add_argument("--runs", type=int, default=1, help="measure: interleaved floor + boresight rounds")
    ap.add_argument("--method", default="planes", choices=["planes", "vgicp"])
    ap.add_argument("--stages", action="store_true", help="measure: then one run timed per stage")
    ap.add_argument("--crop", metavar="E,N",
                    help="only the lines' parts flown within E m east and N m north of the "
                    "scene's centre: the --size flight's density on a smaller area (issue 26/32: "
                    "the 10⁹ run's density in 10⁸ points)")
    args = ap.parse_args()
    sim = folder(args.data, args.size, args.crop)
    if args.what == "simulate":
        simulate(args.data, args.size, args.workers, args.crop)
    elif args.what == "stages":
        stage_run(sim, args.method)
    else:
        measure(sim, args.runs, args.method, args.stages)


if __name__ == "__main__":
    main()
