"""The published grid search, the CCR windows' segments and the survey file."""

from __future__ import annotations

import numpy as np
import pytest

from calidar.errors import InputError
from calidar.photon.search import SearchSettings, _cross_errors, grid_search
from calidar.photon.segments import CCRSegment, CCRWindow, segment_of, with_silent_shots
from calidar.pipelines.ccr import read_ccr_csv


def test_cross_errors_equal_the_brute_force_over_every_candidate_chord():
    rng = np.random.default_rng(0)
    diam, biases = np.arange(8, 15.01, 0.1), np.arange(-12, 12, 0.05)
    for _ in range(10):
        y, n, missing = rng.uniform(-6, 6), int(rng.integers(3, 20)), int(rng.integers(0, 10))
        lengths = n * 0.7 + 0.1 * np.arange(int(np.ceil(missing * 0.7 / 0.1)) + 1)
        r = diam[:, None, None] / 2
        brute = np.hypot(np.abs(y - biases)[None, :, None] - np.sqrt(np.clip(r**2 - (lengths / 2) ** 2, 0, None)),
                         np.clip(lengths / 2 - r, 0, None)).min(axis=2)
        np.testing.assert_allclose(_cross_errors(y, n, missing, 0.7, diam, biases, 0.1), brute, atol=1e-12)


def window(x_ccr, y_ccr, shots_x, counts):
    return CCRWindow("p", 0, "c", x_ccr, y_ccr, 2.0, np.asarray(shots_x, float), np.asarray(counts), 0.0, 16)


def test_grid_search_finds_exact_chords():
    """Chords cut by an 11 m footprint with bias (+1.0, −0.5) at CCRs 3 m left and 2.5 m right."""
    d, b_a, b_c = 11.0, 1.0, -0.5
    segs = []
    for x, y in ((100.0, 3.0), (160.0, -2.5)):
        half = np.sqrt((d / 2) ** 2 - (y - b_c) ** 2)
        xs = np.arange(x - b_a - half + 0.35, x - b_a + half, 0.7)
        segs.append(CCRSegment(window(x, y, xs, np.ones(xs.size)), xs, np.ones(xs.size), 0.7))
    g = grid_search(segs, 0.7, SearchSettings())
    assert abs(g.along_bias - b_a) < 0.05 and abs(g.cross_bias - b_c) < 0.15 and abs(g.diameter - d) < 0.35
    assert g.sides == [1, -1]


def test_segment_is_the_longest_run_and_silent_shots_come_back():
    xs = np.arange(0.0, 35.0, 0.7)
    counts = np.zeros(xs.size, int)
    counts[[3]] = 1  # a stray background photon
    counts[20:30] = 4
    counts[25] = 0  # a lost shot inside the run
    seg = segment_of(window(14.0, 0.0, xs, counts), counts, 0.7)
    assert seg.n_shots == 9 and seg.missing_shots == 1 and seg.first == pytest.approx(14.0)
    gaps = np.delete(xs, [5, 6, 11])
    x, c = with_silent_shots(gaps, np.ones(gaps.size, int), 0.7)
    np.testing.assert_allclose(x, xs)
    assert c.sum() == gaps.size and c.size == xs.size


def test_ccr_csv_errors_name_file_line_and_field(tmp_path):
    p = tmp_path / "ccr.csv"
    cases = {
        "id,lat,lon,height,colour\nA,32.4,-106.4,2.0,red\n": r"header: unknown column\(s\) colour",
        "id,lat,lon,height\nA,32.4,west,2.0\n": r"line 2: lon: expected a finite number in \[-180, 360\] deg, got west",
        "id,lat,lon,height\nA,95,-106.4,2.0\n": r"line 2: lat: expected a finite number in \[-90, 90\] deg, got 95",
        "id,lat,lon,height\nA,32.4,-106.4,inf\n": r"line 2: height: expected a finite number",
        "id,lat,lon,height\nA,32.4,-106.4,2\nA,32.5,-106.4,2\n": "id: expected a unique, non-empty id per CCR",
        "id,lat,lon,height\n": "rows: no CCRs listed",
        "": "header: empty file",
    }
    for text, message in cases.items():
        p.write_text(text)
        with pytest.raises(InputError, match=message):
            read_ccr_csv(p)
    p.write_bytes("id,lat,lon,height\nÅ,32.4,-106.4,2.0\n".encode("cp1252"))
    with pytest.raises(InputError, match=r"ccr.csv: encoding: expected UTF-8 text, got byte 0xc5 at offset 18"):
        read_ccr_csv(p)
    p.write_bytes("\ufeffid,lat,lon,height\nA,32.4,-106.4,2.0\n".encode("utf-8"))  # a BOM, as spreadsheets write
    assert read_ccr_csv(p).ids == ["A"]
