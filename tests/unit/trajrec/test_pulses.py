"""What trajectory reconstruction keeps of the points: rays of multi-return pulses robust to repeated
return numbers and several pulses in the air, bad GPS times dropped, lines split without ids."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from calidar.io.las import LasPoints
from calidar.trajrec.lines import split_lines
from calidar.trajrec.pulses import Kept, keep_chunk, pulse_rays


def _pulse(t, top, bottom, scan):
    return [(t, *top, scan), (t, *bottom, scan)]


def test_rays_run_from_the_lowest_to_the_highest_point_whatever_the_return_numbers():
    rows = _pulse(1.0, (0, 0, 10.0), (1, 0, 0.0), 5.0) + [(1.5, 3, 3, 0.0, 1.0)]  # one pulse, one single return
    a = np.array(rows)
    t, xyz, scan = a[:, 0], a[:, 1:4], a[:, 4]
    first, last, repeated = pulse_rays(t, xyz, scan, np.zeros(t.size), np.array([2, 2, 1]))  # return number repeated
    assert first.tolist() == [0] and last.tolist() == [1] and repeated == 1


def test_pulses_in_the_air_sharing_a_time_stay_apart_by_scan_angle():
    # two pulses stamped with the same time, 400 m apart across the swath: each keeps its own ray
    a = np.array(_pulse(2.0, (0, 0, 10), (0.5, 0, 0), -10.0) + _pulse(2.0, (400, 0, 12), (399.5, 0, 1), 12.0))
    first, last, _ = pulse_rays(a[:, 0], a[:, 1:4], a[:, 4], np.zeros(4))
    assert sorted(zip(first.tolist(), last.tolist())) == [(0, 1), (2, 3)]
    # without scan angles they would be one "pulse" whose ray lies flat: dropped, not used
    first, last, _ = pulse_rays(a[:, 0], a[:, 1:4], None, np.zeros(4))
    assert first.size == 0


def test_bad_times_are_dropped_and_counted():
    n = 1000
    t = np.linspace(10, 20, n)
    t[::50] = 0.0
    t[7] = np.nan
    pts = LasPoints(np.c_[np.zeros(n), np.linspace(0, 600, n), np.zeros(n)], t, "gps_week_seconds", None, Path("x"),
                    np.zeros(n), np.zeros(n, np.uint16), np.ones(n, np.uint8), np.ones(n, np.uint8))
    kept = Kept()
    keep_chunk(kept, pts, 1e6)
    a = kept.arrays()
    assert kept.n_bad_time == 21 and a["t"].size == n - 21 and np.all(a["t"] > 0)


def test_lines_without_ids_are_split_at_time_gaps_and_reversals():
    t1 = np.linspace(0, 30, 3000)
    t2 = np.linspace(100, 130, 3000)  # after a 70 s turn
    t3 = np.linspace(130.01, 160, 3000)  # no gap, but flown back the other way
    y = np.r_[60 * t1, 60 * (t2 - 100), 1800 - 60 * (t3 - 130)]
    t = np.r_[t1, t2, t3]
    a = {"t": t, "xyz": np.c_[np.zeros(t.size), y, np.zeros(t.size)], "scan": np.zeros(t.size),
         "source": np.zeros(t.size), "ray_t": np.empty(0), "ray_first": np.empty((0, 3)), "ray_last": np.empty((0, 3)),
         "ray_scan": np.empty(0), "ray_source": np.empty(0)}
    lines, how = split_lines(a)
    assert [round(ln.duration_s) for ln in lines] == [30, 30, 30] and "split" in how
