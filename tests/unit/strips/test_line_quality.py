"""The boresight report's overlap-quality stages in one read: measured on the delivered plan,
read again on its own plan when a stage's own counts give another one; every stage equals the
swath differences of its points held in memory."""

from __future__ import annotations

from types import SimpleNamespace

import numpy as np
import pytest

from calidar.ingest.stages import LineCounts, lines_quality, stage_pass
from calidar.ingest.cell_counts import Metric
from calidar.strips.overlap import cell_keys
from calidar.strips.quality import overlap_cell, swath_differences


def _line(rng, x0, x1, y0, y1, density=4.0, dz=0.0):
    n = int((x1 - x0) * (y1 - y0) * density)
    x, y = rng.uniform(x0, x1, n), rng.uniform(y0, y1, n)
    return np.c_[x, y, 0.02 * x + 0.01 * y + dz + rng.normal(0, 0.01, n)]


def _points(xyz):  # no classification, no returns: every point is a "last return"
    return SimpleNamespace(xyz=xyz, classification=None, return_number=None, number_of_returns=None)


@pytest.mark.parametrize("shift_y, reads", [(0.0, 1), (25.0, 2)])
def test_each_stage_equals_the_in_memory_swath_differences(shift_y, reads):
    rng = np.random.default_rng(4)
    stage0 = {1: _line(rng, 0, 100, 0, 60), 2: _line(rng, 0, 100, 40, 100), 3: _line(rng, 80, 180, 0, 60)}
    stage1 = {i: p + [0.0, shift_y if i == 2 else 0.0, 0.03 if i == 2 else 0.0] for i, p in stage0.items()}
    chunks = [(i, [_points(stage0[i][s]), _points(stage1[i][s])]) for i in stage0
              for s in np.array_split(np.arange(len(stage0[i])), 3)]
    first = LineCounts(overlap_cell(None))
    for i, (p, _) in chunks:
        first.add(i, p, cell_keys(p.xyz, first.grid_m))
    calls = []

    def read(plans, chosen, count):
        calls.append([p is not None for p in plans])
        return stage_pass(chunks, Metric(), plans, chosen, count=count)

    got = lines_quality(read, first, 2)
    assert len(calls) == reads and (reads == 1 or calls[1] == [False, True])  # only the stage whose plan moved
    for stage, pairs in zip((stage0, stage1), got):
        want, _ = swath_differences({i: [p] for i, p in stage.items()})
        assert [(q.a, q.b, q.n_cells, q.cell_m) for q in pairs] == [(q.a, q.b, q.n_cells, q.cell_m) for q in want]
        for q, w in zip(pairs, want):
            assert q.median_dz_m == pytest.approx(w.median_dz_m, abs=1e-9)
            assert q.rmsdz_m == pytest.approx(w.rmsdz_m, abs=1e-9)
    assert [(q.a, q.b) for q in got[1]] == ([(1, 2), (1, 3), (2, 3)] if shift_y == 0 else [(1, 3)])
    dz12 = next(q for q in got[1] if (q.a, q.b) == (1, 2)) if shift_y == 0 else None
    assert dz12 is None or dz12.median_dz_m == pytest.approx(-0.03, abs=0.003)
