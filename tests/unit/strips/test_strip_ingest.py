"""Streaming strip ingest: chunk-size independence, footprints equal to the whole-file ones,
thinning by whole blocks within the budget, flight lines from GPS-time gaps."""

from __future__ import annotations

from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest

from calidar.io.las import read_las, write_las
from calidar.io.trajectory import read_trajectory
from calidar.ingest.footprints import files_to_hold, first_pass
from calidar.ingest.strips import StripIngest, _plan
from calidar.ingest.settings import HELD_BYTES_PER_POINT, IngestSettings
from calidar.ingest.source import planar_xy
from calidar.sensor import Sensor
from calidar.sim.survey import simulate_survey, survey_config
from calidar.ingest.lines import read_flight_lines
from calidar.strips.lines import line_ids
from calidar.strips.selection import EXCLUDED_CLASSES
from calidar.strips.overlap import cell_counts, cell_keys, common_cells, find_overlaps
from calidar.strips.thin import spread_rank, thin_cells


@pytest.fixture(scope="module")
def survey(tmp_path_factory) -> Path:
    res = simulate_survey(survey_config("uav", seed=11, density=0.02, directions="cross"))
    return res.write(tmp_path_factory.mktemp("ingest") / "sim")


def _inputs(sim: Path):
    return sorted((sim / "strips").glob("*.laz")), read_trajectory(sim / "sbet.out"), Sensor.read(sim / "sensor.toml")


def test_kept_points_do_not_depend_on_the_chunk_size(survey):
    paths, traj, sensor = _inputs(survey)
    big, _, src, _ = StripIngest(IngestSettings(budget_points=20_000)).read(paths, traj, sensor)
    small, _, _, _ = StripIngest(IngestSettings(budget_points=20_000, chunk_points=7_777)).read(paths, traj, sensor)
    assert [s.id for s in big] == [s.id for s in small] and len(big) >= 3
    for a, b in zip(big, small):
        assert np.array_equal(a.points, b.points) and np.array_equal(a.time, b.time)
        assert a.time_span == b.time_span
        assert len(a) < src.counts[a.id]  # thinned: a subset of the line
        assert a.time_span[0] <= a.time.min() and a.time.max() <= a.time_span[1]


@pytest.mark.parametrize("held_files", [0, 1])
def test_points_held_by_pass_1_give_the_strips_read_twice(survey, held_files, monkeypatch):
    """Pass 2 from what pass 1 held in memory (all files, or the first only) equals pass 2 reading
    the files again, and the held files are not read a second time."""
    import calidar.ingest.footprints as ingest
    import calidar.ingest.source as source

    paths, traj, sensor = _inputs(survey)
    read_twice, _, _, _ = StripIngest(IngestSettings(budget_points=20_000, hold_bytes=0)).read(paths, traj, sensor)
    reads = []
    real = ingest.iter_las_chunks
    for module in (ingest, source):  # pass 1 reads in the one, pass 2 in the other
        monkeypatch.setattr(module, "iter_las_chunks", lambda path, *a, **k: reads.append(path) or real(path, *a, **k))
    first = HELD_BYTES_PER_POINT * ingest.las_header(paths[0]).point_count
    options = IngestSettings(budget_points=20_000, chunk_points=7_777, hold_bytes=first if held_files else 10**12)
    held, _, _, _ = StripIngest(options).read(paths, traj, sensor)
    assert [s.id for s in held] == [s.id for s in read_twice]
    for a, b in zip(held, read_twice):
        assert np.array_equal(a.points, b.points) and np.array_equal(a.time, b.time)
    twice = sorted(p for p in set(reads) if reads.count(p) == 2)
    assert twice == (sorted(paths[1:]) if held_files else [])
    assert files_to_hold([10, 30, 20], 30 * HELD_BYTES_PER_POINT) == [True, False, True]  # in file order while they fit


@pytest.mark.parametrize("all_classes", [False, True])
def test_footprints_and_overlaps_equal_the_whole_file_ones(survey, all_classes):
    """The footprints count the calibration's points: every class with all_classes, else all but
    the vegetation, noise and water classes (the survey has class 5 trees)."""
    paths, traj, sensor = _inputs(survey)
    options = IngestSettings(chunk_points=5_000, all_classes=all_classes)
    _, _, src, _ = StripIngest(options).read(paths, traj, sensor)
    acc, _, _ = first_pass(src.files, src.frame, traj, options, lambda *a: None)
    _, _, how, footprint, _, pairs, _ = _plan(acc, options)
    lines, how_whole = read_flight_lines(paths)
    assert how == how_whole == "point_source_id" and sorted(footprint) == sorted(lines)
    assert any((p.classification == 5).any() for p in lines.values())
    if not all_classes:
        lines = {i: p.select(~np.isin(p.classification, EXCLUDED_CLASSES)) for i, p in lines.items()}
    xy = {i: planar_xy(p, src.frame) for i, p in lines.items()}
    for i, p in xy.items():
        cells, counts = cell_counts(cell_keys(p, options.cell_m))
        assert np.array_equal(footprint[i][0], cells) and np.array_equal(footprint[i][1], counts)
    whole, _ = find_overlaps(xy, options.cell_m, options.min_cells, options.min_points_per_cell)
    assert [(o.a, o.b, o.n_cells) for o in whole] == [(a, b, c.size) for a, b, c in pairs] and len(whole) >= 2


def test_thinning_keeps_whole_cells_of_whole_blocks_within_the_budget(survey):
    paths, traj, sensor = _inputs(survey)
    budget = 8_000
    options = IngestSettings(budget_points=budget, block_cells=2)
    strips, _, src, _ = StripIngest(options).read(paths, traj, sensor)
    acc, _, _ = first_pass(src.files, src.frame, traj, options, lambda *a: None)
    _, _, _, footprint, _, pairs, kept = _plan(acc, options)
    lines, _ = read_flight_lines(paths)
    for s in strips:
        assert 0.5 * budget < len(s) <= budget  # the budget is used, never exceeded
        keys = cell_keys(planar_xy(lines[s.id], src.frame), options.cell_m)
        # every point of a kept cell but the vegetation, noise and water classes, nothing else
        inside = np.isin(keys, kept[s.id]) & ~np.isin(lines[s.id].classification, EXCLUDED_CLASSES)
        assert inside.sum() == len(s)
        assert np.array_equal(np.sort(lines[s.id].gps_time[inside]), np.sort(s.time))
    for a, b, common in pairs:  # a pair keeps its common cells by whole blocks
        rank = spread_rank(common, 2)
        both = np.isin(common, kept[a]) & np.isin(common, kept[b])
        assert both.any() and not (rank[both][:, None] == rank[~both][None, :]).any()
    unlimited = thin_cells(pairs, footprint, None)
    assert all(np.array_equal(unlimited[i], np.unique(np.concatenate([c for a, b, c in pairs if i in (a, b)])))
               for i in unlimited)


def test_spread_rank_lowest_cells_form_a_regular_lattice():
    ij = np.array([(i, j) for i in range(-8, 8) for j in range(-8, 8)])
    cells = cell_keys(ij + 0.5, 1.0)
    rank = spread_rank(cells)
    assert np.unique(rank).size == cells.size and rank.min() >= 0 and rank.max() < 1
    low = ij[rank < 0.25]  # a quarter of the cells: every second column and row
    assert low.shape[0] == 64 and np.unique(low[:, 0] % 2).size == 1 and np.unique(low[:, 1] % 2).size == 1
    blocks = spread_rank(cells, 4)
    assert np.unique(blocks).size == 16 and np.unique(blocks[(ij[:, 0] // 4 == -1) & (ij[:, 1] // 4 == 1)]).size == 1


def test_lines_from_time_gaps_when_point_source_ids_do_not_tell(survey, tmp_path):
    paths, traj, sensor = _inputs(survey)
    merged = []
    for p in paths:  # the same points, one point_source_id for all
        las = read_las(p)
        merged.append(write_las(tmp_path / p.name, las.xyz, las.crs, gps_time=las.gps_time,
                                scan_angle_deg=las.scan_angle_deg, point_source_id=1))
    strips, _, src, _ = StripIngest(IngestSettings(chunk_points=3_000)).read(merged, traj, sensor)
    assert src.how == "gps_time_gaps"
    t = np.concatenate([read_las(p).gps_time for p in merged])
    ids, how = line_ids(np.ones(t.size, np.int64), t)
    assert how == "gps_time_gaps"
    assert src.counts == {int(i): int(n) for i, n in zip(*np.unique(ids, return_counts=True))}
    # the same lines, numbered in time (unclassified files: every class, as all_classes reads the others)
    reference, _, _, _ = StripIngest(IngestSettings(all_classes=True)).read(paths, traj, sensor)
    assert sorted(len(s) for s in strips) == sorted(len(s) for s in reference)


def test_strip_points_option_is_checked_and_used(survey, cli, tmp_path):
    paths, _, _ = _inputs(survey)
    args = ["boresight", *paths, "--trajectory", survey / "sbet.out", "--sensor", survey / "sensor.toml"]
    code, _, err = cli(*args, "--strip-points", "500", "--out", tmp_path / "bad")
    assert code == 1 and "--strip-points" in err and "at least 10000" in err and "Traceback" not in err
    assert not (tmp_path / "bad").exists()
    code, _, err = cli(*args, "--strip-points", "10000", "--trajectory-model", "off", "--out", tmp_path / "o")
    doc = __import__("json").loads((tmp_path / "o" / "solution.json").read_text())
    assert doc["run"]["options"]["ingest"]["strip_points"] == 10000
    assert doc["run"]["options"]["ingest"]["all_classes"] is False  # and the report says so:
    assert "but vegetation (3–5), noise (7, 18) and water (9)" in (tmp_path / "o" / "report.html").read_text()
    # the outputs are written either way; exit 3 says the verdict (the trajectory taken as exact) is FAIL
    assert code == (3 if doc["verdict"]["status"] == "fail" else 0), err


def test_adjusted_standard_times_become_the_trajectorys_week_seconds(survey, tmp_path):
    from calidar.io.las import week_seconds_to_adjusted_standard

    paths, traj, sensor = _inputs(survey)
    adjusted = []
    for p in paths:
        las = read_las(p)
        adjusted.append(write_las(tmp_path / p.name, las.xyz, las.crs, point_source_id=las.point_source_id,
                                  gps_time=week_seconds_to_adjusted_standard(las.gps_time, 2345),
                                  scan_angle_deg=las.scan_angle_deg, time_system="gps_adjusted_standard"))
    options = IngestSettings(budget_points=20_000, chunk_points=4_000)
    got, _, src, _ = StripIngest(options).read(adjusted, traj, sensor)
    # the rewritten files are unclassified: every class, as all_classes reads the originals
    want, _, _, _ = StripIngest(replace(options, all_classes=True)).read(paths, traj, sensor)
    assert set(src.weeks.values()) == {2345} and [s.id for s in got] == [s.id for s in want]
    for a, b in zip(got, want):
        assert np.allclose(a.time, b.time, atol=1e-6, rtol=0) and np.array_equal(a.points, b.points)


def test_files_read_on_two_threads_give_the_same_strips_and_quality_counts(survey):
    from calidar.strips.distribute import Workers

    paths, traj, sensor = _inputs(survey)
    options = IngestSettings(budget_points=20_000, chunk_points=9_000)
    one, _, src1, _ = StripIngest(options).read(paths, traj, sensor)
    two, _, src2, _ = StripIngest(options).read(paths, traj, sensor, work=Workers(threads=2))
    assert [s.id for s in one] == [s.id for s in two]
    for a, b in zip(one, two):
        assert np.array_equal(a.points, b.points) and np.array_equal(a.time, b.time) and a.source == b.source
    assert src1.quality.counts.keys() == src2.quality.counts.keys() and src1.names == src2.names
    for k, (keys, n) in src1.quality.counts.items():
        assert np.array_equal(keys, src2.quality.counts[k][0]) and np.array_equal(n, src2.quality.counts[k][1])
    lines, _ = read_flight_lines(paths)  # the quality counts are those of the whole line's selected points
    for i, sel in src1.quality.chosen({}).items():
        keys, n = src1.quality.counts[i, sel]
        assert n.sum() == sel.mask(lines[i]).sum() > 0 and np.all(np.diff(keys) > 0)


def test_overlap_quality_read_in_point_ranges_equals_whole_files(survey, monkeypatch):
    """The quality stages' tasks read files in ranges of TASK_POINTS (seeking in the LAZ): the
    same pairs and differences as one task a file."""
    import calidar.ingest.measure as measure
    from calidar.pipelines.boresight import load_inputs

    inputs = load_inputs(*_inputs_paths(survey))
    models = [None, (inputs.nominal, inputs.trajectory)]
    whole = measure.measure_lines(inputs.source, inputs.nominal, models)
    monkeypatch.setattr(measure, "TASK_POINTS", 3_001)
    ranged = measure.measure_lines(inputs.source, inputs.nominal, models)
    for a, b in zip(whole, ranged):
        assert [(q.a, q.b, q.n_cells, q.n_points_a) for q in a] == [(q.a, q.b, q.n_cells, q.n_points_a) for q in b]
        assert all(q.median_dz_m == pytest.approx(r.median_dz_m, abs=1e-9) for q, r in zip(a, b) if q.n_cells)
    assert sum(q.n_cells for q in whole[0]) > 50


def _inputs_paths(sim: Path):
    return sorted((sim / "strips").glob("*.laz")), sim / "sbet.out", sim / "sensor.toml"


@pytest.fixture(scope="module")
def denser(tmp_path_factory) -> Path:
    res = simulate_survey(survey_config("uav", seed=11, density=0.1, directions="cross"))
    return res.write(tmp_path_factory.mktemp("ingest") / "sim")


def test_geographic_strips_get_the_projected_quality_in_one_read(denser, tmp_path, monkeypatch):
    """Strips in lon/lat (EPSG:4979): the ingest's grid (its local frame) is the quality's, so the
    stages are measured in one read, with the dz of the same strips in UTM."""
    import shutil

    import pyproj

    import calidar.ingest.measure as measure
    from calidar.pipelines.boresight import load_inputs

    paths, traj, _ = _inputs_paths(denser)
    (tmp_path / "strips").mkdir()
    for f in ("sbet.out", "sensor.toml", "smrmsg.out"):
        shutil.copy(denser / f, tmp_path / f)
    for p in paths:
        las = read_las(p)
        lon, lat = pyproj.Transformer.from_crs(las.crs, "EPSG:4326", always_xy=True).transform(las.xyz[:, 0], las.xyz[:, 1])
        write_las(tmp_path / "strips" / p.name, np.c_[lon, lat, las.xyz[:, 2]], "EPSG:4979", gps_time=las.gps_time,
                  scan_angle_deg=las.scan_angle_deg, point_source_id=las.point_source_id,
                  classification=las.classification, return_number=las.return_number,
                  number_of_returns=las.number_of_returns)
    tasks = []
    task = measure._file_stages
    monkeypatch.setattr(measure, "_file_stages", lambda *a: tasks.append(a[-3:]) or task(*a))
    got = {}
    for name, sim in (("utm", denser), ("geo", tmp_path)):
        inputs = load_inputs(*_inputs_paths(sim))
        tasks.clear()
        got[name] = measure.measure_lines(inputs.source, inputs.nominal, [None, (inputs.nominal, inputs.trajectory)])
        assert len(tasks) == len(paths)  # one read: every stage's own plan is the ingest's
    for utm, geo in zip(got["utm"], got["geo"]):
        assert [(q.a, q.b) for q in utm] == [(q.a, q.b) for q in geo] and len(utm) >= 2
        # the two grids differ (UTM's and the local frame's, turned by the meridian convergence), so
        # a sliver's count of cells each holding enough points of both strips does not carry from one
        # to the other (pair 1–3 of seed 11: 44 cells of 545 / 685 points in UTM, 23 of 487 / 644 in
        # the local frame); overlaps of ≥ 100 cells agree in cells and dz
        for q, r in zip(utm, geo):
            if q.n_cells >= 100:
                assert abs(q.n_cells - r.n_cells) <= 0.05 * q.n_cells + 2
                assert r.median_dz_m == pytest.approx(q.median_dz_m, abs=0.002)
        assert sum(q.n_cells >= 100 for q in utm) >= 2


@pytest.fixture(scope="module")
def noisy(survey, tmp_path_factory) -> list[Path]:
    """The survey's strips with every 40th ground point made noise (7, 18 by turns): classified
    files holding canopy (5) and noise."""
    out = tmp_path_factory.mktemp("noisy")
    paths = []
    for p in _inputs(survey)[0]:
        las = read_las(p)
        cls = las.classification.copy()
        ground = np.flatnonzero(cls == 2)[::40]
        cls[ground] = np.where(np.arange(ground.size) % 2, 7, 18)
        paths.append(write_las(out / p.name, las.xyz, las.crs, gps_time=las.gps_time,
                               scan_angle_deg=las.scan_angle_deg, point_source_id=las.point_source_id,
                               return_number=las.return_number, number_of_returns=las.number_of_returns,
                               classification=cls))
    return paths


def _kept_classes(strips, paths, frame) -> dict[int, np.ndarray]:
    """The LAS class of each kept point of each strip (the line's point at the same place and
    time: a pulse's returns share its time)."""
    from scipy.spatial import cKDTree

    from calidar.ingest.times import points_ecef

    lines, _ = read_flight_lines(paths)
    out = {}
    for s in strips:
        line = lines[s.id]
        local = frame.to_local(points_ecef(line))
        d, pos = cKDTree(local).query(s.points)
        assert d.max() < 1e-6 and np.array_equal(line.gps_time[pos], s.time)
        out[s.id] = line.classification[pos]
    return out


@pytest.mark.parametrize("hold_bytes", [0, 10**12])  # pass 2 reads the files again / the held points
def test_canopy_and_noise_points_are_left_out_before_the_budget_unless_all_classes(survey, noisy, hold_bytes):
    """Classified strips: the default keeps none of the vegetation, noise or water classes, and the
    budget goes to the other points; all_classes keeps canopy and noise as before."""
    _, traj, sensor = _inputs(survey)
    options = IngestSettings(budget_points=5_000, chunk_points=7_777, hold_bytes=hold_bytes)
    default, _, src, _ = StripIngest(options).read(noisy, traj, sensor)
    every, _, _, _ = StripIngest(replace(options, all_classes=True)).read(noisy, traj, sensor)
    assert [s.id for s in default] == [s.id for s in every] and len(default) >= 3
    mine, theirs = _kept_classes(default, noisy, src.frame), _kept_classes(every, noisy, src.frame)
    for s in default:
        assert not np.isin(mine[s.id], EXCLUDED_CLASSES).any()
        assert len(s) <= 5_000 and np.isin(mine[s.id], (2, 6)).all()
    kept_all = np.concatenate(list(theirs.values()))
    assert all((kept_all == c).sum() > 50 for c in (5, 7, 18))  # canopy and noise were there
    # the budget spent on the other points: their share of it that canopy and noise took
    # (≈ 7 % here) comes back to them, at least half of it
    share = np.isin(kept_all, EXCLUDED_CLASSES).mean()
    used = sum(np.isin(c, (2, 6)).sum() for c in mine.values())
    used_all = sum(np.isin(c, (2, 6)).sum() for c in theirs.values())
    assert share > 0.03 and used > used_all / (1 - share / 2), (share, used, used_all)


def test_all_classes_option_from_the_command_line_and_the_config_file(tmp_path):
    from calidar.cli.boresight_config import strip_config
    from calidar.pipelines.strip_config import StripConfig

    assert strip_config(None, {}).ingest.all_classes is False
    config = strip_config(None, {"all_classes": True})
    assert config.ingest.all_classes is True and config.to_dict()["ingest"]["all_classes"] is True
    path = config.write(tmp_path / "config.toml")
    assert StripConfig.read(path) == config
    assert strip_config(path, {"all_classes": False}).ingest.all_classes is False
    bad = tmp_path / "bad.toml"
    bad.write_text(path.read_text().replace("all_classes = true", 'all_classes = "yes"'))
    with pytest.raises(Exception, match="ingest.all_classes"):
        StripConfig.read(bad)
