"""The one flight-line splitter (calidar.strips.lines.split_lines, issue 29): by point_source_id when
two or more are held, else by gaps in GPS time; every reader of strips sorts its points with it
(points at once, a streamed pass's seconds, the strip ingest's groups, trajrec's time gaps)."""

from __future__ import annotations

import numpy as np

from calidar.strips.lines import GAP_S, line_ids, split_lines


def _reference_gap_lines(first: np.ndarray, last: np.ndarray, gap_s: float) -> np.ndarray:
    """Line number of each span by the definition: sorted by start, a new line where a span starts
    more than gap_s after the latest end so far (a loop, not the vectorized code)."""
    order = sorted(range(first.size), key=lambda k: (first[k], k))
    line, reach, n = np.empty(first.size, np.int64), -np.inf, 0
    for k in order:
        if n == 0 or first[k] - reach > gap_s:
            n += 1
        line[k], reach = n, max(reach, last[k])
    return line


def test_time_gaps_split_overlapping_spans_by_the_latest_end():
    """A span that ends late bridges the next one's start: no new line although its own
    predecessor in start order ended long before (what the ingest's groups and a file's seconds need)."""
    first = np.array([0.0, 1.0, 30.0, 45.0, 100.0])
    last = np.array([50.0, 2.0, 31.0, 46.0, 101.0])
    index = split_lines((), {}, first, last, gap_s=10.0)
    assert index.how == "gps_time_gaps" and index.ids == (1, 2)
    assert index.of(None, first).tolist() == [1, 1, 1, 1, 2]
    assert index.starts.tolist() == [0.0, 100.0]


def test_random_spans_match_the_definition():
    rng = np.random.default_rng(5)
    for _ in range(50):
        first = rng.uniform(0, 300, rng.integers(1, 40))
        last = first + rng.exponential(3.0, first.size)
        index = split_lines([7], {}, first, last, GAP_S)  # one point_source_id: lines by time
        np.testing.assert_array_equal(index.of(np.full(first.size, 7), first), _reference_gap_lines(first, last, GAP_S))


def test_points_at_once_are_spans_of_one_point():
    t = np.r_[np.arange(0, 5, 0.5), np.arange(40, 42, 0.1), np.nan, np.arange(80, 81, 0.2)]
    ids, how = line_ids(None, t)
    assert how == "gps_time_gaps"
    assert ids.tolist() == [1] * 10 + [2] * 20 + [3] + [3] * 5  # NaN times join the last line, as sorted last


def test_point_source_ids_with_files_apart_in_time_kept_apart():
    spans = {(1, "a.laz"): (0.0, 10.0), (1, "b.laz"): (500.0, 510.0), (2, "c.laz"): (20.0, 30.0)}
    index = split_lines([1, 2], spans, np.zeros(0), np.zeros(0))
    assert index.how == "point_source_id" and index.ids == (1, 2, 3) and len(index.notes) == 1
    assert index.of(np.array([1, 1, 2]), np.array([5.0, 505.0, 25.0])).tolist() == [1, 3, 2]


def test_trajrec_cuts_lines_at_the_splitters_gaps():
    """trajrec's lines (gaps at its scanner's own threshold, and track reversals) take their time gaps
    from the one splitter: a cut halfway between the points either side of each gap."""
    from calidar.trajrec.lines import _breaks

    t = np.r_[np.arange(0.0, 10.0, 0.01), np.arange(20.0, 30.0, 0.01)]
    xy = np.c_[np.zeros(t.size), 50.0 * (t % 100)]  # one direction: no reversal
    cuts = _breaks(t, xy)
    np.testing.assert_allclose(cuts, [0.5 * (t[999] + t[1000])])
