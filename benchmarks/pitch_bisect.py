"""Benchmark (issue 26/32): the boresight of a simulated survey folder calibrated with variants of
the tie-plane, trajectory-model and outer-loop settings, each with its error against truth.json in
units of its σ and the pitch's error after every outer iteration (how far the loop got).

The strips are read once (``calidar boresight``'s ingest, ``BUDGET`` points a strip, 0: all), then
each variant (comma-separated key=value; plane settings by name, and ``traj=off``, ``block_s``,
``corr_att`` (the attitude's correlation time, s), ``robust`` (cauchy, huber, none), ``max_outer``,
``thr`` (the matcher's stopping threshold, m)) is calibrated:

    export NUMBA_NUM_THREADS=1 OMP_NUM_THREADS=1 PYTHONPATH=src
    nice -n 10 python benchmarks/pitch_bisect.py /work/bigsim/cells_1000M 0 \\
        "" "max_outer=30,thr=1e-7" "cell_m=1.0" "traj=off"
"""

from __future__ import annotations

import json
import sys
import time
from dataclasses import replace
from pathlib import Path

import numpy as np

KEYS = ("boresight_roll", "boresight_pitch", "boresight_yaw")
TRACE: list = []  #: each calibration's parameter values after every outer iteration


def traced() -> None:
    """calidar.strips.calibrate's outer loop, its iterations' values kept in TRACE."""
    import calidar.strips.calibrate as cal
    import calidar.strips.outer_loop as loop

    def outer_loop(*args, **kw):
        res = loop.outer_loop(*args, **kw)
        TRACE.append([h["values"] for h in res[0]])
        return res

    cal.outer_loop = outer_loop


def config(spec: str):
    """The calibration configuration of one variant."""
    from calidar.strips.config import CalibrationConfig, TrajectorySettings
    from calidar.strips.matchers import TiePlanes
    from calidar.strips.planes import PlaneSettings

    plane, other = {}, {}
    for item in filter(None, spec.split(",")):
        k, v = item.split("=")
        if k in PlaneSettings.__dataclass_fields__:
            plane[k] = float(v) if "." in v or "e" in v else int(v)
        else:
            other[k] = v
    cal = CalibrationConfig(matchers=(TiePlanes(PlaneSettings(**plane),
                                                threshold_m=float(other.get("thr", 2e-4))),))
    if "block_s" in other or "corr_att" in other:
        cal = replace(cal, trajectory=TrajectorySettings(
            block_s=float(other.get("block_s", 1.0)),
            correlation_s=(20.0, float(other.get("corr_att", 3.5)))))
    if other.get("traj") == "off":
        cal = replace(cal, trajectory=None)
    solver = cal.solver
    if "robust" in other:
        robust = None if other["robust"] == "none" else other["robust"]
        solver = replace(solver, adjustment=replace(solver.adjustment, robust=robust))
    if "max_outer" in other:
        solver = replace(solver, max_outer=int(other["max_outer"]))
    return replace(cal, solver=solver)


def main() -> None:
    from calidar.ingest.settings import IngestSettings
    from calidar.pipelines.boresight import calibrate_inputs, load_inputs
    from calidar.pipelines.strip_config import StripConfig

    sim, budget, variants = Path(sys.argv[1]), int(sys.argv[2]), sys.argv[3:] or [""]
    truth = json.loads((sim / "truth.json").read_text())["parameters"]
    traced()
    ingest = IngestSettings(budget_points=budget or None)
    inputs = load_inputs(sorted((sim / "strips").glob("*.laz")), sim / "sbet.out",
                         sim / "sensor.toml", StripConfig(ingest=ingest))
    for spec in variants:
        run = replace(inputs, config=replace(inputs.config, calibration=config(spec)))
        clock, cpu = time.perf_counter(), time.process_time()
        sol = calibrate_inputs(run)["planes"].solution
        cpu = time.process_time() - cpu
        deg = {k: np.degrees(sol.values[k]) for k in KEYS}
        sig = {k: np.degrees(sol.sigma[k]) for k in KEYS}
        z = [(deg[k] - truth[k]["value"]) / sig[k] for k in KEYS]
        p = "boresight_pitch"
        trace = [(np.degrees(v[p]) - truth[p]["value"]) / sig[p] for v in TRACE[-1]]
        print(f"[{spec or 'default'}] error/σ roll, pitch, yaw {z[0]:+.2f} {z[1]:+.2f} {z[2]:+.2f}"
              f" (σ {sig[KEYS[0]]:.5f} {sig[p]:.5f} {sig[KEYS[2]]:.5f}°), σ0 {sol.sigma0:.3f}; "
              f"pitch error/σ per outer iteration {' '.join(f'{t:+.2f}' for t in trace)}; "
              f"{time.perf_counter() - clock:.0f} s wall, {cpu:.1f} s CPU", flush=True)


if __name__ == "__main__":
    main()
