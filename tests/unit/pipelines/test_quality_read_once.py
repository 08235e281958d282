"""``calidar quality`` decompresses every point once (issue 32): the first pass keeps what the
second needs (ingest/held.py), exactly, and the results equal the points' in memory."""

from __future__ import annotations

import sys
from pathlib import Path

import numpy as np
import pytest

import calidar.io.las as las
from calidar.io.las import iter_las_chunks, write_las
from calidar.ingest.held import HeldPoints
from calidar.ingest.cell_counts import Metric, _first_rows, _token_counts, held_chunks
from calidar.pipelines.quality import QualityConfig, measure
from calidar.ingest.lines import _second_spans
from calidar.strips.quality import QualitySettings, swath_differences

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "strips"))
from test_strips_quality import _surface  # noqa: E402

UTM = np.array([500_000.0, 5_200_000.0, 400.0])


def _strips(tmp_path, rng, crs="EPSG:32632", origin=UTM, scale=1.0):
    """Two overlapping strips (ids 1 and 2, a quarter of b's points vegetation: class 5) as LAZ."""
    a = _surface(rng, 60_000, shift=(0.1, -0.05, 0.03))
    b = _surface(rng, 50_000)
    cls_b = np.where(rng.random(len(b)) < 0.25, 5, 2)
    paths = []
    for i, (p, cls) in enumerate([(a, np.full(len(a), 2)), (b, cls_b)], start=1):
        xyz = origin + p * [scale, scale, 1.0]
        paths.append(write_las(tmp_path / f"s{i}.laz", xyz, crs, gps_time=100.0 * i + np.linspace(0, 50, len(p)),
                               scan_angle_deg=np.zeros(len(p)), point_source_id=i, classification=cls))
    return paths, a, b[cls_b == 2]


def test_each_point_decompressed_once_and_pairs_equal_the_points_in_memory(tmp_path, monkeypatch):
    paths, _, _ = _strips(tmp_path, np.random.default_rng(1))
    read: dict[str, int] = {}
    records = las._records

    def counted(reader, chunk_points, path, start=0, stop=None):
        for first, rec in records(reader, chunk_points, path, start, stop):
            read[Path(path).name] = read.get(Path(path).name, 0) + len(rec)
            yield first, rec

    monkeypatch.setattr(las, "_records", counted)
    _, _, pairs, _, selections, _ = measure(paths, QualityConfig(chunk_points=7_000))  # many chunks, each line split
    assert read == {"s1.laz": 60_000, "s2.laz": 50_000}
    assert {p.name: s.rule for p, s in selections.items()} == {"s1.laz": "ground", "s2.laz": "ground"}
    (q,) = pairs
    whole = [las.read_las(p) for p in paths]  # every point at once, as the files hold them
    (ref,), _ = swath_differences({i + 1: [w.xyz[w.classification == 2]] for i, w in enumerate(whole)},
                                  QualitySettings())
    assert (q.a, q.b, q.n_cells, q.n_points_a, q.n_points_b) == (ref.a, ref.b, ref.n_cells, ref.n_points_a,
                                                                 ref.n_points_b)
    assert q.n_cells > 500 and q.median_dz_m == pytest.approx(0.03, abs=0.005)
    for k in ("median_dz_m", "rmsdz_m", "max_abs_dz_m", "dx_m", "dy_m"):
        assert getattr(q, k) == pytest.approx(getattr(ref, k), abs=1e-9), k


def test_geographic_strips_measured_in_a_local_frame(tmp_path):
    deg = 1.0 / 111_000  # ≈ 1 m in degrees: the surface on a geographic CRS, metric in a LocalFrame
    paths, _, _ = _strips(tmp_path, np.random.default_rng(2), crs="EPSG:4326", origin=np.array([7.0, 45.0, 400.0]),
                          scale=deg)
    _, _, (q,), _, _, _ = measure(paths, QualityConfig(chunk_points=9_000))
    assert q.n_cells > 300 and q.median_dz_m == pytest.approx(0.03, abs=0.006)


def test_held_coordinates_are_laspys_to_the_bit(tmp_path):
    paths, _, _ = _strips(tmp_path, np.random.default_rng(3))
    held = HeldPoints(tmp_path)
    metric = Metric()
    for c in las.iter_las_fields(paths[1], ("X", "Y", "Z", "x", "y", "z", "point_source_id", "gps_time"), 6_000):
        held.add(paths[1], X=c["X"], Y=c["Y"], Z=c["Z"], point_source_id=c["point_source_id"],
                 gps_time=c["gps_time"], bits=np.ones(len(c["gps_time"]), np.uint8))
    got = list(held_chunks(held, paths[1], 0, metric))
    want = list(iter_las_chunks(paths[1], 6_000, fields=("point_source_id",)))
    assert [len(x) for x, _, _ in got] == [len(w) for w in want] and len(want) == 9
    for (xyz, psid, t), w in zip(got, want):
        assert np.array_equal(xyz, w.xyz) and np.array_equal(psid, w.point_source_id)
        assert np.array_equal(t, w.gps_time)
    assert held.nbytes == 50_000 * 23


def test_token_counts_one_bincount_equal_the_sort():
    from collections import Counter

    rng = np.random.default_rng(4)
    n = 20_000
    tokens = (rng.integers(1, 4, n) << 32) | rng.integers(1000, 1010, n)
    ij = rng.integers(-30, 30, (n, 2))
    keys = (ij[:, 0] << 32) + (ij[:, 1] & 0xFFFFFFFF)
    far = tokens.copy()
    far[0] = (9 << 32) | 4_000_000  # the (line, second, cell) box is no longer small: sorted instead

    def as_set(t, k, c):
        return {(int(a), int(b), int(m)) for a, b, m in zip(t, k, c)}

    for tok in (tokens, far):
        want = {(a, b, m) for (a, b), m in Counter(zip(tok.tolist(), keys.tolist())).items()}
        got = _token_counts(tok, keys)
        assert as_set(*got) == want and len(got[0]) == len(want)
        again = _token_counts(*(np.concatenate([x, x]) for x in got[:2]), np.concatenate([got[2], got[2]]))
        assert as_set(*again) == {(a, b, 2 * m) for a, b, m in want}  # rows already counted, summed
    assert sorted(_first_rows(tokens)) == sorted(np.unique(tokens, return_index=True)[1])
    assert sorted(_first_rows(far)) == sorted(np.unique(far, return_index=True)[1])


def test_second_spans_dense_equal_the_sort():
    rng = np.random.default_rng(5)
    t = np.r_[rng.uniform(100, 160, 5000), np.nan, rng.uniform(300, 301, 10)]
    lo, hi = _second_spans(t)
    s = np.sort(t[np.isfinite(t)])
    sec = np.floor(s)
    starts = np.r_[0, np.flatnonzero(np.diff(sec)) + 1]
    assert np.array_equal(lo, s[starts]) and np.array_equal(hi, s[np.r_[starts[1:], s.size] - 1])
    lo, hi = _second_spans(np.array([1.5, 1e12, 1.2]))  # far apart: sorted instead
    assert lo.tolist() == [1.2, 1e12] and hi.tolist() == [1.5, 1e12]
