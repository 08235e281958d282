"""CPU time the one engine spends: 100 range calibrations (small problems: the engine's own overhead)
and the strip adjustment's solves of one boresight run (StripProblem + engine, matching excluded).

    python benchmarks/engine_speed.py [--survey FOLDER]

FOLDER: a `calidar simulate survey` output (strips/*.laz, sbet.out, sensor.toml). Run it with two
installations' interpreters, alternating, to compare them (docs/validation.md, issue 29).
"""

from __future__ import annotations

import argparse
import time
from pathlib import Path


def range_calibrations(n: int = 100) -> float:
    """CPU seconds of ``n`` range calibrations of simulated total-station observations."""
    from calidar.rangecal import calibrate
    from calidar.sim.total_station import simulate_total_station

    obs = [simulate_total_station(s)[0] for s in range(1000, 1000 + n)]
    calibrate(obs[0])  # imports and compilation outside the clock
    t = time.process_time()
    for o in obs:
        calibrate(o)
    return time.process_time() - t


def strip_solves(folder: Path) -> tuple[float, float]:
    """(CPU seconds in the strip adjustment's solves, CPU seconds of the whole calibration) of one
    ``calidar.calibrate_strips`` run on a simulated survey folder."""
    import calidar
    import calidar.strips.outer_loop as cal
    from calidar.adjust import solver

    spent, depth = [0.0], [0]

    def timed(fn):
        def wrap(*a, **k):
            depth[0] += 1
            t = time.process_time()
            try:
                return fn(*a, **k)
            finally:
                depth[0] -= 1
                if depth[0] == 0:  # nested calls (estimate → refine) counted once
                    spent[0] += time.process_time() - t
        return wrap

    cal.Run.solve = timed(cal.Run.solve)
    cal.Run.solution = timed(cal.Run.solution)
    solver.Estimate.refine = timed(solver.Estimate.refine)
    t0 = time.process_time()
    calidar.calibrate_strips(sorted((folder / "strips").glob("*.laz")), folder / "sbet.out", folder / "sensor.toml")
    return spent[0], time.process_time() - t0


def main(argv=None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--survey", type=Path, help="a simulated survey folder for the strip solves")
    args = ap.parse_args(argv)
    print(f"range-cal x100: {range_calibrations():.2f} s CPU")
    if args.survey:
        solves, total = strip_solves(args.survey)
        print(f"strip solves: {solves:.2f} s CPU of {total:.1f} s CPU")


if __name__ == "__main__":
    main()
