"""Benchmark (issue 26/32): the 10⁹-point flight of benchmarks/large_flight.py calibrated from
only the points its run keeps, simulated at its density — the same lines, the same kept cells, a
few million points instead of 10⁹.

``calidar boresight`` keeps whole 5 m overlap cells per strip (300 000 points a strip by default,
:mod:`calidar.strips.thin`); which cells depends on the lines' footprints only, so a low-density
simulation of the same flight (``large_flight.py simulate --size SMALL``) gives them with the
budget scaled by the densities (``300 000 × SMALL / SIZE``, blocks of one cell as at ≥ 20
points/m²). Then, per line, the pulses flown while the line passes over its kept cells (the
low-density points' times in them, ± ``PAD_S``) are simulated at the density of ``--size`` and
only those delivered into the kept cells written (the points the full run's second pass keeps);
sbet.out, smrmsg.out, sensor.toml and truth.json as the full flight's. Calibrate them with
``--strip-points 0``:

    export NUMBA_NUM_THREADS=1 OMP_NUM_THREADS=1 PYTHONPATH=src
    nice -n 10 python benchmarks/large_flight.py simulate --size 20 --data /work/bigsim
    nice -n 10 python benchmarks/large_flight_cells.py --size 1000 --from /work/bigsim/flight_20M \
        --out /work/bigsim/cells_1000M
    cd /work/bigsim/cells_1000M && calidar boresight strips/*.laz --trajectory sbet.out \
        --sensor sensor.toml --truth truth.json --strip-points 0 --out cal
"""

from __future__ import annotations

import argparse
import json
import sys
import time
from dataclasses import replace
from pathlib import Path

import laspy
import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
from large_flight import PULSES_PER_DENSITY, survey  # noqa: E402

PAD_S = 0.05  #: pulses simulated this long before and after a line's points in a kept cell (s)
GAP_S = 0.2  #: a line's times in its kept cells further apart than this start a new window (s)


def kept_cells(small: Path, budget: int) -> dict[int, np.ndarray]:
    """Point_source_id → the overlap cells its line keeps, as the ingest plans them for the files
    of ``small`` with ``budget`` points a strip and blocks of one cell."""
    from calidar.ingest.footprints import first_pass
    from calidar.ingest.settings import IngestSettings
    from calidar.ingest.strips import _files, _frame, _plan
    from calidar.sensor import Sensor
    from calidar.io.trajectory import read_trajectory

    traj = read_trajectory(small / "sbet.out")
    settings = IngestSettings(budget_points=budget, block_cells=1)
    sensor = Sensor.read(small / "sensor.toml")
    files = _files(sorted((small / "strips").glob("*.laz")), traj, sensor, settings)
    acc, _, _ = first_pass(files, _frame(files), traj, settings, lambda *a: None, None, False)
    groups, line, how, *_, kept = _plan(acc, settings)
    assert how == "point_source_id", how
    return kept


def windows(path: Path, cells: np.ndarray) -> list[tuple[float, float]]:
    """GPS time windows (s) in which the line of ``path`` flies over ``cells``."""
    from calidar.strips.overlap import cell_keys

    las = laspy.read(path)
    keys = cell_keys(np.c_[las.x, las.y], 5.0)
    pos = np.minimum(np.searchsorted(cells, keys), cells.size - 1)
    t = np.sort(np.asarray(las.gps_time)[cells[pos] == keys])
    if t.size == 0:
        return []
    cut = np.flatnonzero(np.diff(t) > GAP_S)
    return [(a - PAD_S, b + PAD_S) for a, b in zip(t[np.r_[0, cut + 1]], t[np.r_[cut, t.size - 1]])]


def main() -> None:
    from calidar.crs import to_crs
    from calidar.io.las_write import LasChunkWriter
    from calidar.sim.large_survey import las_record, plan_large_survey, simulate_chunk, tiled_to_crs
    from calidar.sim.survey import SIMULATION_DATE
    from calidar.strips.overlap import cell_keys

    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--size", type=float, default=1000.0, help="the full flight's million points")
    ap.add_argument("--from", dest="small", type=Path, required=True,
                    help="a low-density simulation")
    ap.add_argument("--out", type=Path, required=True)
    ap.add_argument("--budget", type=int, default=300_000,
                    help="the full run's points kept a strip")
    ap.add_argument("--range-noise", type=float, default=0.03, help="m (the survey's: 0.03)")
    args = ap.parse_args()
    density = round(args.size * 1e6 / PULSES_PER_DENSITY, 4)
    small = json.loads((args.small / "simulate.json").read_text())
    budget = round(args.budget * small["density"] / density)
    t0 = time.perf_counter()
    kept = kept_cells(args.small, budget)
    plan = plan_large_survey(replace(survey(density), range_noise_m=args.range_noise))
    (args.out / "strips").mkdir(parents=True, exist_ok=True)
    offsets = np.floor(to_crs(plan.scene.origin_ecef[None], plan.crs)[0] / 1000.0) * 1000.0
    total, shot = 0, 0
    for k, line in enumerate(plan.lines):
        cells = kept.get(line.number)
        if cells is None:
            continue
        src = args.small / "strips" / f"line_{line.number:03d}.laz"
        path = args.out / "strips" / src.name
        with LasChunkWriter(path, plan.crs, offsets, force=True) as writer:
            writer.header.creation_date = SIMULATION_DATE
            for w, (a, b) in enumerate(windows(src, cells)):
                first = max(int(np.ceil((a - plan.windows[k][0]) * plan.pulse_rate_hz)), 0)
                last = min(int((b - plan.windows[k][0]) * plan.pulse_rate_hz), plan.pulses(k))
                for c, start in enumerate(range(first, last, 1_000_000)):
                    rng = np.random.default_rng([plan.config.seed, 33, k, w, c])
                    chunk = simulate_chunk(plan, k, start, min(1_000_000, last - start), rng)
                    xyz = tiled_to_crs(chunk["ecef"], chunk["true_enu"][:, :2], plan.crs)
                    keys = cell_keys(xyz, 5.0)
                    pos = np.minimum(np.searchsorted(cells, keys), cells.size - 1)
                    sel = cells[pos] == keys
                    part = {n: v[sel] for n, v in chunk.items()}
                    writer.write_record(las_record(writer.header, xyz[sel], part, line.number))
                    total, shot = total + int(sel.sum()), shot + sel.size
        print(f"line {line.number}: {cells.size} kept cells, {total} points so far", flush=True)
    plan.result(total).write(args.out, force=True)
    print(json.dumps({"points": total, "pulses_shot": shot, "density": density,
                      "budget_small": budget, "wall_s": round(time.perf_counter() - t0, 1)}),
          flush=True)


if __name__ == "__main__":
    main()
