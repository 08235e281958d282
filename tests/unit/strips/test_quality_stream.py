"""Streamed swath differences (cell moments chunk by chunk) and the point selection (issue 17/18)."""

from __future__ import annotations

import json

import numpy as np
import pytest

from calidar.errors import InputError
from calidar.io.las import write_las
from calidar.strips.cell_moments import CellMoments
from calidar.strips.quality import QualitySettings, swath_differences
from calidar.cli.options import parse_classes
from calidar.strips.selection import PointSelection, choose_selection

from test_strips_quality import _surface

UTM = np.array([500_000.0, 5_200_000.0, 400.0])  # projected coordinates: precision must survive them


def test_moments_merged_over_chunks_equal_moments_of_all_points():
    rng = np.random.default_rng(3)
    p = UTM + np.column_stack([rng.uniform(0, 40, (50_000, 2)), rng.normal(0, 0.05, 50_000)])
    whole = CellMoments.of_points(p, 1.0)
    parts = CellMoments.empty(1.0)
    for chunk in np.array_split(p, 7):
        parts = parts.merged(CellMoments.of_points(chunk, 1.0))
    assert np.array_equal(parts.keys, whole.keys) and np.array_equal(parts.count, whole.count)
    assert np.allclose(parts.centroid(), whole.centroid(), rtol=0, atol=1e-9)
    assert np.allclose(parts.scatter, whole.scatter, rtol=1e-9, atol=1e-12)
    coarse, direct = whole.coarsened(3), CellMoments.of_points(p, 3.0)  # 1 m cells into 3 m cells
    assert np.array_equal(coarse.keys, direct.keys) and np.array_equal(coarse.count, direct.count)
    assert np.allclose(coarse.centroid(), direct.centroid(), rtol=0, atol=1e-9)
    assert np.allclose(coarse.covariance(), direct.covariance(), rtol=0, atol=1e-12)
    i = np.argmax(direct.count)  # against numpy on one cell's points
    cell = np.all(np.floor(p[:, :2] / 3.0) == np.floor(direct.centroid()[i, :2] / 3.0), axis=1)
    assert direct.count[i] == cell.sum()
    assert np.allclose(direct.covariance()[i], np.cov(p[cell].T, bias=True), rtol=0, atol=1e-12)


@pytest.mark.parametrize("cell_m", [None, 2.0, 2.5])
def test_streamed_pairs_equal_in_memory_pairs(cell_m):
    rng = np.random.default_rng(4)
    a = UTM + _surface(rng, 120_000, shift=(0.1, -0.05, 0.03))
    b = UTM + _surface(rng, 100_000)
    s = QualitySettings(cell_m=cell_m)
    whole, _ = swath_differences({1: [a], 2: [b]}, s)
    streamed, _ = swath_differences({1: np.array_split(a, 9), 2: np.array_split(b[::-1], 4)}, s)
    (qw,), (qs,) = whole, streamed
    assert (qs.a, qs.b, qs.n_cells, qs.n_points_a, qs.n_points_b) == (qw.a, qw.b, qw.n_cells, qw.n_points_a,
                                                                       qw.n_points_b)
    assert qw.n_cells > 500 and qw.median_dz_m == pytest.approx(0.03, abs=0.005)
    for k in ("median_dz_m", "rmsdz_m", "max_abs_dz_m", "dx_m", "dy_m"):
        assert getattr(qs, k) == pytest.approx(getattr(qw, k), abs=1e-9), k


def test_classes_are_validated_and_must_be_present():
    assert parse_classes("6, 2,2") == (2, 6) and parse_classes(None) is None
    for bad in ("2,x", "256", "-1", "", "2.5"):
        with pytest.raises(InputError, match="--classes"):
            parse_classes(bad)
    assert choose_selection("f.laz", np.array([1, 2, 5])) == PointSelection("ground", (2,))
    assert choose_selection("f.laz", np.array([0, 1])).rule == "last returns"
    with pytest.raises(InputError, match=r"f\.laz.*no points of class 6 \(classes present: 1, 2\)"):
        choose_selection("f.laz", np.array([1, 2]), (2, 6))


def test_last_returns_rule_keeps_last_and_single_returns_off_vegetation():
    class P:
        classification = np.array([1, 1, 5, 1, 7])
        return_number = np.array([1, 2, 2, 1, 1])
        number_of_returns = np.array([1, 2, 2, 2, 1])
        xyz = np.zeros((5, 3))

    assert PointSelection("last returns").mask(P).tolist() == [True, True, False, False, False]
    assert PointSelection("classes", (1, 5)).mask(P).tolist() == [True, True, True, True, False]


def _two_lines(tmp_path, classes_a, classes_b):
    rng = np.random.default_rng(5)
    paths = []
    for k, (cls, dz) in enumerate(((classes_a, 0.04), (classes_b, 0.0))):
        xyz = UTM + np.column_stack([rng.uniform(0, 60, (30_000, 2)), rng.normal(dz, 0.01, 30_000)])
        c = np.asarray(cls)[np.arange(30_000) % len(cls)]
        xyz[c == 5, 2] += rng.uniform(2, 15, int((c == 5).sum()))  # "trees" above the ground
        paths.append(write_las(tmp_path / f"l{k}.laz", xyz, "EPSG:32632", gps_time=np.linspace(100 * k, 100 * k + 9, 30_000),
                               scan_angle_deg=np.zeros(30_000), point_source_id=k + 1, classification=c))
    return paths


def test_cli_ground_by_default_and_explicit_classes(cli, tmp_path):
    paths = _two_lines(tmp_path, [2, 5], [2, 2, 5])
    code, out, err = cli("quality", *paths, "--json", "--cell", "2")
    assert code == 0, err
    doc = json.loads(out)
    (pair,) = doc["pairs"]
    assert pair["median_dz_m"] == pytest.approx(0.04, abs=0.003)  # trees, the class-5 points, left out
    assert all(v["rule"] == "ground" and v["classes"] == [2] for v in doc["points_used"].values())
    assert pair["points_a"][0]["classes"] == [2] and 0 < pair["n_points_a"] <= 15_000 and pair["n_points_b"] <= 20_000
    code, out, err = cli("quality", *paths, "--json", "--cell", "2", "--classes", "2,5")
    # every cell holds "trees" (class 5): none is smooth, so no cell is kept — a clear error, not 0 cells
    assert code == 1 and "--cell" in err and "smooth" in err and "Traceback" not in err
    code, out, err = cli("quality", *paths, "--classes", "6")
    assert code == 1 and "l0.laz" in err and "no points of class 6" in err and "Traceback" not in err
    code, out, err = cli("quality", *paths, "--classes", "300")
    assert code == 1 and "--classes" in err and "0–255" in err


def test_cli_streams_in_small_chunks_with_the_same_results(tmp_path, monkeypatch, cli):
    import calidar.pipelines.quality as pq

    paths = _two_lines(tmp_path, [1], [1])  # unclassified: the last-returns rule
    code, out, _ = cli("quality", *paths, "--json")
    whole = json.loads(out)
    monkeypatch.setattr(pq, "CHUNK_POINTS", 4_000)
    monkeypatch.setattr(pq.measure, "__defaults__", (None, None, pq.PointOptions(), 4_000))
    code, out, _ = cli("quality", *paths, "--json")
    streamed = json.loads(out)
    assert code == 0 and whole["points_used"][str(paths[0])]["rule"] == "last returns"
    for a, b in zip(whole["pairs"], streamed["pairs"]):
        assert a["n_cells"] == b["n_cells"] > 100
        assert a["median_dz_m"] == pytest.approx(b["median_dz_m"], abs=1e-9)
        assert a["rmsdz_m"] == pytest.approx(b["rmsdz_m"], abs=1e-9)


def test_geographic_lines_are_compared_in_one_local_frame(cli, tmp_path):
    """Lines in lon/lat are compared in one local metric frame: dz as in the projected CRS."""
    import pyproj

    paths = _two_lines(tmp_path, [2], [2])
    to_geo = pyproj.Transformer.from_crs("EPSG:32632", "EPSG:4326", always_xy=True)
    geo = []
    for k, p in enumerate(paths):
        from calidar.io.las import read_las

        las = read_las(p)
        lon, lat = to_geo.transform(las.xyz[:, 0], las.xyz[:, 1])
        geo.append(write_las(tmp_path / f"geo{k}.laz", np.c_[lon, lat, las.xyz[:, 2]], "EPSG:4326",
                             gps_time=las.gps_time, scan_angle_deg=las.scan_angle_deg, point_source_id=k + 1,
                             classification=las.classification))
    (projected,) = json.loads(cli("quality", *paths, "--json")[1])["pairs"]
    code, out, err = cli("quality", *geo, "--json")
    assert code == 0, err
    (geographic,) = json.loads(out)["pairs"]
    assert geographic["median_dz_m"] == pytest.approx(projected["median_dz_m"], abs=0.002)
    assert geographic["median_dz_m"] == pytest.approx(0.04, abs=0.003)


def test_streamed_line_index_splits_at_time_gaps_as_line_ids(tmp_path):
    from calidar.ingest.lines import index_flight_lines
    from calidar.strips.lines import line_ids

    rng = np.random.default_rng(6)
    t = np.sort(np.r_[rng.uniform(0, 30, 3000), rng.uniform(40.5, 70, 3000), rng.uniform(80.2, 81, 500)])
    xyz = UTM + np.column_stack([rng.uniform(0, 50, (t.size, 2)), np.zeros(t.size)])
    path = write_las(tmp_path / "gaps.laz", xyz, "EPSG:32632", gps_time=t, scan_angle_deg=np.zeros(t.size),
                     point_source_id=0, classification=np.full(t.size, 2))
    index = index_flight_lines([path], chunk_points=700)
    expected, how = line_ids(np.zeros(t.size, int), t)
    assert index.how == how == "gps_time_gaps" and index.ids == (1, 2, 3)
    assert np.array_equal(index.of(None, t), expected) and index.classes[path].tolist() == [2]


def test_cli_lines_from_time_gaps_stream_in_small_chunks(cli, tmp_path, monkeypatch):
    import calidar.pipelines.quality as pq
    from calidar.io.las import read_las

    paths = []
    for k, p in enumerate(_two_lines(tmp_path, [2], [2])):  # the same lines without point_source_id
        las = read_las(p)
        paths.append(write_las(tmp_path / f"anon{k}.laz", las.xyz, las.crs, gps_time=las.gps_time,
                               scan_angle_deg=las.scan_angle_deg, point_source_id=0, classification=las.classification))
    code, out, err = cli("quality", *paths, "--json")
    assert code == 0, err
    monkeypatch.setattr(pq.measure, "__defaults__", (None, None, pq.PointOptions(), 3_000))
    small = json.loads(cli("quality", *paths, "--json")[1])
    whole = json.loads(out)
    assert whole["lines_from"] == small["lines_from"] == "gps_time_gaps"
    (a,), (b,) = whole["pairs"], small["pairs"]
    assert (a["a"], a["b"], a["n_cells"]) == (b["a"], b["b"], b["n_cells"]) == (1, 2, a["n_cells"]) and a["n_cells"] > 100
    assert a["median_dz_m"] == pytest.approx(0.04, abs=0.003)
    assert b["median_dz_m"] == pytest.approx(a["median_dz_m"], abs=1e-9)


def test_moments_spilled_to_disk_give_the_same_differences(tmp_path, monkeypatch):
    """Past HOLD_BYTES an accumulator with a spill folder writes its lines' moments to disk
    (the memory of a 10⁹-point survey's cells stays bounded); the differences do not change."""
    import calidar.strips.quality as quality
    from calidar.strips.quality import SwathAccumulator

    rng = np.random.default_rng(8)
    lines = {1: UTM + np.c_[rng.uniform(0, 60, (40_000, 2)), rng.normal(0, 0.01, 40_000)],
             2: UTM + np.c_[rng.uniform(30, 90, (40_000, 2)), rng.normal(0.02, 0.01, 40_000)]}
    held = SwathAccumulator()
    for i, p in lines.items():
        for chunk in np.array_split(p, 20):
            held.add(i, chunk)
    monkeypatch.setattr(quality, "HOLD_BYTES", 50_000)
    spilled, other = SwathAccumulator(spill_dir=tmp_path), SwathAccumulator(spill_dir=tmp_path)  # one folder
    for i, p in lines.items():
        for chunk in np.array_split(p, 20):
            spilled.add(i, chunk)
            other.add(i, chunk + [0.0, 0.0, 1.0])  # another stage: 1 m higher
    assert sum(len(f) for f in spilled.spilled.values()) > 2 and len(list(tmp_path.rglob("*.npy"))) > 4
    (a,), _ = held.differences()
    (b,), _ = spilled.differences()
    assert (a.n_cells, a.cell_m) == (b.n_cells, b.cell_m) and a.n_cells > 100
    assert b.median_dz_m == pytest.approx(a.median_dz_m, abs=1e-12) and b.median_dz_m == pytest.approx(-0.02, abs=0.003)
    assert b.rmsdz_m == pytest.approx(a.rmsdz_m, abs=1e-12)
    assert len(list(spilled.spill_dir.glob("*.npy"))) == len(spilled.spilled)  # combined once read: one file a line
    (c,), _ = other.differences()  # its own files, not the first accumulator's
    assert c.median_dz_m == pytest.approx(a.median_dz_m, abs=1e-9)
    assert other._combined(1, 1.0).centroid()[:, 2].mean() == pytest.approx(
        spilled._combined(1, 1.0).centroid()[:, 2].mean() + 1.0, abs=1e-9)
