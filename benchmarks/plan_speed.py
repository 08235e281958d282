"""How long `calidar plan` takes for a 10-line plan (the issue asks for < 10 s on this machine).

    NUMBA_NUM_THREADS=1 PYTHONPATH=src python benchmarks/plan_speed.py [--estimate boresight,lever_arm] [--repeat 3] \
        [--scanner linear|palmer]

A 10-line plan over the UAV preset's built-in scene (300 m × 300 m: hills, a rough band, roofs, trees):
six north–south lines in alternate directions at 80 m, two at 120 m, two east–west cross lines, 20 kHz,
70° field of view, 8 m/s. The whole run as the command does it (:func:`calidar.pipelines.plan.run_plan`:
reading, prediction, seven candidate lines tried, plan.json, report.html with its figures), timed after one
warm-up run (numba's compiled kernels are cached on disk, as after the first use of an installation), in CPU
seconds of the process (single-threaded: its wall time on an idle core) and wall seconds at the machine's load.
``--scanner palmer``: the sensor.toml names a Palmer scanner (its oval: a 30 m swath at 80 m, each patch seen
ahead and back), the ten lines 10 m apart (six at 80 m, two at 120 m, two cross lines).
"""

from __future__ import annotations

import argparse
import os
import tempfile
import time
from pathlib import Path

from calidar.pipelines.plan import PlanOptions, TerrainChoice, run_plan
from calidar.sensor import Sensor
from calidar.strips.config import Estimate

LINES = """line,start_x,start_y,end_x,end_y,height_agl_m,speed_mps
1,-100,-120,-100,120,80,8
2,-60,120,-60,-120,80,8
3,-20,-120,-20,120,80,8
4,20,120,20,-120,80,8
5,60,-120,60,120,80,8
6,100,120,100,-120,80,8
7,-40,-120,-40,120,120,8
8,40,120,40,-120,120,8
9,-120,-20,120,-20,80,8
10,120,20,-120,20,80,8
"""
PALMER_LINES = """line,start_x,start_y,end_x,end_y,height_agl_m,speed_mps
1,-25,-120,-25,120,80,8
2,-15,120,-15,-120,80,8
3,-5,-120,-5,120,80,8
4,5,120,5,-120,80,8
5,15,-120,15,120,80,8
6,25,120,25,-120,80,8
7,-10,-120,-10,120,120,8
8,10,120,10,-120,120,8
9,-120,-10,120,-10,80,8
10,120,10,-120,10,80,8
"""


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--estimate", default="boresight,lever_arm")
    ap.add_argument("--repeat", type=int, default=3)
    ap.add_argument("--scanner", choices=("linear", "palmer"), default="linear")
    args = ap.parse_args()
    with tempfile.TemporaryDirectory() as tmp:
        root = Path(tmp)
        from calidar.scanners import SCANNERS

        (root / "lines.csv").write_text(PALMER_LINES if args.scanner == "palmer" else LINES)
        Sensor(lever_arm_x=0.05, lever_arm_z=0.12, scanner=SCANNERS[args.scanner]()).write(root / "sensor.toml")
        options = PlanOptions(terrain=TerrainChoice("scene", preset="uav", seed=0), estimate=Estimate.of(*args.estimate.split(",")))
        times = []
        for k in range(args.repeat + 1):
            out = root / f"out{k}"
            out.mkdir()
            t, cpu = time.perf_counter(), time.process_time()
            run = run_plan(root / "lines.csv", root / "sensor.toml", out, options)
            times.append(time.process_time() - cpu)
            print(f"run {k}{' (warm-up)' if k == 0 else ''}: {times[-1]:.1f} s CPU ({time.perf_counter() - t:.1f} s wall, "
                  f"load {os.getloadavg()[0]:.1f} on {os.cpu_count()} cores), "
                  f"{sum(p['tie_planes'] for p in run.doc['pairs'])} tie planes in {len(run.doc['pairs'])} pairs, "
                  f"{len(run.suggestions)} candidates; {run.doc['headline']}", flush=True)
    print(f"10-line plan, {args.scanner} scanner, --estimate {args.estimate}: median {sorted(times[1:])[len(times[1:]) // 2]:.1f} s CPU over "
          f"{args.repeat} runs after the warm-up")


if __name__ == "__main__":
    main()
