"""``calidar quality``'s fused per-chunk kernels (ingest/chunk_pass.py, issue 32) equal the numpy
steps they replace, bit for bit: seconds, cells and selection masks; the held rows; the second
pass's scaled coordinates."""

from __future__ import annotations

from types import SimpleNamespace

import numpy as np
import pytest

from calidar.ingest.cell_counts import _seconds_cells, held_arrays
from calidar.ingest.chunk_pass import (chunk_pass, held_rows, selected_points,
                                       selection_tables)
from calidar.strips.selection import PointSelection

SELECTIONS = [
    [PointSelection("ground", (2,)), PointSelection("last returns")],
    [PointSelection("classes", (2, 6, 255))],
    [PointSelection("classes", (0,)), PointSelection("last returns"),
     PointSelection("ground", (2,))],
]


def _chunk(rng, n=20_000):
    """Raw fields as laspy gives them, with the edges: NaN / infinite / negative / huge times,
    every class, returns equal and not, coordinates on cell edges and negative."""
    t = rng.uniform(-5.0, 4e5, n)
    xyz = np.c_[rng.uniform(-1e3, 1e3, n), rng.uniform(-50.0, 5e6, n), rng.normal(0, 10, n)]
    if n >= 60:
        t[:40] = [np.nan, np.inf, -np.inf, -1.5, 0.0, 1e19, 4294967295.5, 4294967296.0,
                  2.0**62, 1.0] * 4
        xyz[40:60, :2] = np.arange(-10, 10)[:, None] * 5.0  # on cell edges
    rn = rng.integers(1, 4, n).astype(np.uint8)
    nr = np.maximum(rn, rng.integers(1, 4, n)).astype(np.uint8)
    return {"gps_time": t, "xyz": xyz, "classification": rng.integers(0, 256, n).astype(np.uint8),
            "return_number": rn, "number_of_returns": nr,
            "X": rng.integers(-2**31, 2**31 - 1, n, dtype=np.int64).astype(np.int32),
            "Y": rng.integers(-1000, 1000, n).astype(np.int32),
            "Z": rng.integers(0, 99, n).astype(np.int32),
            "point_source_id": rng.integers(0, 65536, n).astype(np.uint16)}


@pytest.mark.parametrize("selections", SELECTIONS)
@pytest.mark.parametrize("grid", [5.0, 3.0, 0.7])
def test_seconds_cells_and_bits_equal_the_numpy_steps(selections, grid):
    c = _chunk(np.random.default_rng(7))
    sec, ij, bits = chunk_pass(c["gps_time"], c["xyz"], grid, c, selections)
    sec0, ij0 = _seconds_cells(c["gps_time"], c["xyz"], grid)
    np.testing.assert_array_equal(sec, sec0)
    np.testing.assert_array_equal(ij, ij0)
    fields = SimpleNamespace(xyz=ij0, **{f: c[f] for f in ("classification", "return_number",
                                                            "number_of_returns")})
    for k, s in enumerate(selections):
        np.testing.assert_array_equal((bits & (1 << k)) != 0, s.mask(fields))
    some = [s.mask(fields).any() and not s.mask(fields).all() for s in selections]
    assert all(some)  # each mask keeps some points and drops others: the test can fail


def test_not_described_goes_the_numpy_way():
    c = _chunk(np.random.default_rng(1), 100)
    nine = [PointSelection("classes", (k,)) for k in range(9)]
    assert chunk_pass(c["gps_time"], c["xyz"], 5.0, c, nine) is None  # more than a byte of bits
    assert selection_tables([PointSelection("classes", (300,))]) is None
    wide = {**c, "classification": c["classification"].astype(np.int64)}
    assert chunk_pass(c["gps_time"], c["xyz"], 5.0, wide, SELECTIONS[0]) is None
    no_returns = {**c, "return_number": None}
    assert chunk_pass(c["gps_time"], c["xyz"], 5.0, no_returns, SELECTIONS[0]) is None
    f32 = c["xyz"].astype(np.float32)
    assert chunk_pass(c["gps_time"], f32, 5.0, c, SELECTIONS[0]) is None


def test_empty_chunk():
    c = {k: v[:0] for k, v in _chunk(np.random.default_rng(2), 10).items()}
    sec, ij, bits = chunk_pass(c["gps_time"], c["xyz"], 5.0, c, SELECTIONS[0])
    assert sec.shape == (0,) and ij.shape == (0, 2) and bits.shape == (0,)
    held = held_rows(bits, {a: c[a] for a in ("X", "Y", "Z", "point_source_id", "gps_time")})
    assert all(v.size == 0 for v in held.values())


@pytest.mark.parametrize("selections", SELECTIONS)
def test_held_rows_and_selected_points_equal_the_numpy_steps(selections):
    c = _chunk(np.random.default_rng(3))
    _, ij, bits = chunk_pass(c["gps_time"], c["xyz"], 5.0, c, selections)
    masks = [(bits & (1 << k)) != 0 for k in range(len(selections))]
    fast = held_arrays(c, None, masks, bits)
    slow = held_arrays(c, None, masks)  # the numpy way: bits from the masks, takes
    assert fast.keys() == slow.keys()
    for k in slow:
        assert fast[k].dtype == slow[k].dtype
        np.testing.assert_array_equal(fast[k], slow[k])
    assert 0 < fast["bits"].size < bits.size
    scales, offsets = np.array([0.001, 0.01, 0.0025]), np.array([500_000.0, 5.2e6, -17.3])
    for bit in range(len(selections)):
        xyz, psid, t = selected_points(fast, bit, scales, offsets)
        rows = np.flatnonzero((slow["bits"] >> bit) & 1)
        want = np.stack([slow[a][rows] * scales[k] + offsets[k] for k, a in enumerate("XYZ")],
                        axis=1)
        assert xyz.tobytes() == want.tobytes()  # every bit, NaN patterns included
        np.testing.assert_array_equal(psid, slow["point_source_id"][rows])
        assert t.tobytes() == slow["gps_time"][rows].tobytes()


def test_held_rows_refuse_other_dtypes():
    c = _chunk(np.random.default_rng(4), 50)
    bits = np.ones(50, np.uint8)
    arrays = {a: c[a] for a in ("X", "Y", "Z", "point_source_id", "gps_time")}
    assert held_rows(bits, {**arrays, "X": c["X"].astype(float)}) is None
    assert held_rows(bits, {**arrays, "gps_time": c["gps_time"].astype(np.float32)}) is None
    assert selected_points({**arrays, "bits": bits, "X": c["X"].astype(float)}, 0, [1, 1, 1],
                           [0, 0, 0]) is None


@pytest.mark.parametrize("case", ["usual", "edges", "wide seconds", "no finite time", "empty"])
def test_chunk_summary_equals_distinct_second_spans_and_add_spans(case):
    from calidar.ingest.chunk_pass import chunk_summary
    from calidar.ingest.lines import _second_spans
    from calidar.strips.lines import add_spans, distinct

    rng = np.random.default_rng(5)
    n = 0 if case == "empty" else 30_000
    psid = rng.choice(np.array([3, 7, 65535, 0], np.uint16), n)
    cls = rng.integers(0, 256, n).astype(np.uint8)
    t = np.sort(rng.uniform(1e5, 1.0e5 + 900, n))
    if case == "edges":
        t[::97] = np.nan
        t[::101] = np.inf
        t[5::103] = -np.inf
        t[7::89] = -3.25
    if case == "wide seconds":  # the dense table too large: the caller sorts
        t[::2] += 1e9
    if case == "no finite time":
        t[:] = np.nan
    ids, classes, seconds, spans = chunk_summary(psid, cls, t)
    np.testing.assert_array_equal(ids, distinct(psid))
    np.testing.assert_array_equal(classes, distinct(cls))
    if case == "wide seconds":
        assert seconds is None
    else:
        for got, want in zip(seconds, _second_spans(t)):
            assert got.tobytes() == want.tobytes()
    want: dict = {}
    add_spans(want, psid, t, "f.laz")
    assert {(i, "f.laz"): s for i, s in spans.items()} == want
    if case == "usual":
        assert len(spans) == 4 and seconds[0].size > 800
    assert chunk_summary(psid.astype(np.int64), cls, t) is None
