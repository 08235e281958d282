"""Files sharing one point_source_id (calidar.strips.lines, issue 27): separate passes are kept
apart, one line cut into tiles stays one line."""

import numpy as np

from calidar.io import write_las
from calidar.ingest.lines import index_flight_lines, read_flight_lines
from calidar.strips.lines import shared_id_splits


def _file(path, t0, t1, psid, x0=500000.0, n=500):
    rng = np.random.default_rng(int(t0))
    xyz = np.c_[x0 + rng.uniform(0, 100, n), 5200000 + rng.uniform(0, 100, n), rng.uniform(400, 410, n)]
    return write_las(path, xyz, "EPSG:32632", gps_time=np.linspace(t0, t1, n), scan_angle_deg=np.zeros(n),
                     point_source_id=psid)


def test_separate_passes_with_one_id_are_two_lines(tmp_path):
    a = _file(tmp_path / "a.las", 100.0, 130.0, 7)
    b = _file(tmp_path / "b.las", 200.0, 230.0, 7)
    c = _file(tmp_path / "c.las", 300.0, 330.0, 8)
    lines, how = read_flight_lines([a, b, c])
    assert how == "point_source_id" and sorted(lines) == [7, 8, 9]
    assert {lines[i].path.name: len(lines[i]) for i in lines} == {"a.las": 500, "b.las": 500, "c.las": 500}
    index = index_flight_lines([a, b, c])
    assert index.ids == (7, 8, 9) and "kept apart as 2 flight lines" in index.notes[0]
    assert index.of(np.array([7, 7, 8]), np.array([110.0, 210.0, 310.0])).tolist() == [7, 9, 8]


def test_one_line_in_tiles_stays_one_line(tmp_path):
    """Tiles of one pass: their times touch or interleave (within 10 s)."""
    a = _file(tmp_path / "a.las", 100.0, 130.0, 7)
    b = _file(tmp_path / "b.las", 128.0, 160.0, 7, x0=500100.0)
    c = _file(tmp_path / "c.las", 300.0, 330.0, 8)
    lines, _ = read_flight_lines([a, b, c])
    assert sorted(lines) == [7, 8] and len(lines[7]) == 1000
    assert index_flight_lines([a, b, c]).notes == ()


def test_splits_number_the_new_lines_above_every_id():
    splits, notes = shared_id_splits({(3, "a"): (0.0, 10.0), (3, "b"): (100.0, 110.0), (3, "c"): (200.0, 210.0),
                                      (5, "d"): (0.0, 10.0)})
    starts, ids = splits[3]
    assert starts.tolist() == [0.0, 100.0, 200.0] and ids.tolist() == [3, 6, 7] and 5 not in splits
    assert notes == ["point_source_id 3 is held by 3 files whose GPS times do not interleave: kept apart as 3 flight "
                     "lines: a (0.0–10.0 s) as line 3; b (100.0–110.0 s) as line 6; c (200.0–210.0 s) as line 7"]
