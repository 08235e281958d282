"""The overlapping strip pairs of the shared 8-strip survey (``benchmarks/strips_scale.py``), set up
once for the pair benchmarks (``benchmarks/vgicp_pairs.py``, ``benchmarks/pair_processes.py``): the
survey simulated under ``cache`` (not timed), its strips built as ``calidar boresight`` builds them
(streamed ingest, 300 000 points per strip), the overlaps found as the calibrator finds them (5 m
cells, ≥ 4 points) and each pair's points georeferenced with the nominal sensor."""

from __future__ import annotations

import sys
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
from strips_scale import simulate  # noqa: E402  (the shared 8-strip survey at a size)


def survey_pairs(cache: Path, million: float,
                 sim: Path | None = None) -> list[tuple[int, np.ndarray, int, np.ndarray]]:
    """(a, points of a, b, points of b) (N, 3) metric for every overlapping pair, in the
    calibrator's order; ``sim``: a survey simulated already (strips/*.laz, sbet.out, sensor.toml),
    such as ``benchmarks/large_flight.py``'s, instead of the shared one."""
    from calidar.io.trajectory import read_trajectory
    from calidar.pipelines.boresight import load_strips
    from calidar.sensor import Sensor
    from calidar.strips.overlap import find_overlaps

    sim = sim if sim is not None else simulate(cache, million)
    nominal = Sensor.read(sim / "sensor.toml")
    strips, _ = load_strips(sorted((sim / "strips").glob("*.laz")), read_trajectory(sim / "sbet.out"), nominal)
    by_id = {s.id: s for s in strips}
    overlaps, _ = find_overlaps({i: s.points for i, s in by_id.items()}, 5.0, 4)
    return [(o.a, by_id[o.a].georeference(nominal, o.index_a), o.b, by_id[o.b].georeference(nominal, o.index_b))
            for o in overlaps]
