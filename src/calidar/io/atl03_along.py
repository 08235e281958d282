"""Along-track distance of ATL03 photons: segment_dist_x of a photon's 20 m segment +
dist_ph_along (ATL03 ATBD, Neumann et al. 2019), the segment found from the file's bookkeeping
(``ph_index_beg``/``segment_ph_cnt``) or, where subsetting broke it, from the photon's time
(:mod:`calidar.io.atl03` explains when and why).
"""

from __future__ import annotations

import numpy as np

from calidar.errors import InputError

#: along_track_source when the segment bookkeeping covers every photon
SEGMENTS_SOURCE = "segments"
#: along_track_source when the photons were placed on their segments by their times
BY_TIME_SOURCE = ("photon times (the segment bookkeeping ph_index_beg/segment_ph_cnt does not "
                  "match the photons, as in clipped or subset files: each photon placed on its "
                  "20 m segment by its time)")


def _tiling_segments(beam) -> np.ndarray | None:
    """Segment index of every photon when ph_index_beg/segment_ph_cnt tile photons 1…N exactly
    (in order, no gap, no overlap); None when the bookkeeping is partial."""
    n = beam.h.size
    cnt = beam.segment_ph_cnt.astype(np.int64)
    beg = beam.ph_index_beg.astype(np.int64)
    used = np.flatnonzero((cnt > 0) & (beg > 0))
    if n == 0 or used.size == 0:
        return None
    b, c = beg[used], cnt[used]
    if b[0] != 1 or np.any(b[1:] != b[:-1] + c[:-1]) or b[-1] + c[-1] - 1 != n:
        return None
    return np.repeat(used, c)


def _segment_starts(beam) -> np.ndarray | None:
    """The segments' along-track starts (m), None when the file has none."""
    return None if beam.segment_dist_x is None else np.asarray(beam.segment_dist_x, np.float64)


def along_track(beam) -> tuple[np.ndarray, str]:
    """(along-track distance of every photon (m), how it was found) of a
    :class:`calidar.io.atl03.PhotonBeam`; see the module docstring."""
    n = beam.h.size
    if n == 0:
        return np.zeros(0), SEGMENTS_SOURCE
    starts = _segment_starts(beam)
    seg = _tiling_segments(beam)
    if seg is not None:
        x = (starts[seg] if starts is not None else 0.0) + beam.dist_along
        if starts is not None or beam.segment_id.size == 1:
            return x, SEGMENTS_SOURCE
    if starts is not None and beam.segment_time is not None and beam.segment_time.size >= 2:
        x = _by_time(beam, starts)
        if x is not None:
            return x, BY_TIME_SOURCE
    missing = "segment_dist_x" if starts is None else "delta_time"
    raise InputError(beam.source, f"{beam.beam}/geolocation/{missing}",
                     "needed to place the photons on their 20 m segments: "
                     "ph_index_beg/segment_ph_cnt do not match the photons (a clipped or subset "
                     "file); expected the geolocation arrays of the granule")


def _by_time(beam, starts: np.ndarray) -> np.ndarray | None:
    """Along-track distance from each photon's time and dist_ph_along: the time predicts the
    distance (segments' reference times → their centres, linear between and beyond them); the
    photon's segment is the one whose start + dist_ph_along lies nearest. None when more than
    1 % of the photons land over 5 m from the prediction (the arrays do not belong together)."""
    order = np.argsort(beam.segment_time, kind="stable")
    ts, xs = beam.segment_time[order], starts[order]
    length = np.median(np.diff(xs)) if xs.size > 1 else 20.0
    centre = xs + 0.5 * length
    ok = np.concatenate([[True], np.diff(ts) > 0])
    ts, centre, xs = ts[ok], centre[ok], xs[ok]
    if ts.size < 2:
        return None
    speed = (centre[-1] - centre[0]) / (ts[-1] - ts[0])
    t = beam.delta_time
    pred = np.interp(t, ts, centre)
    pred = np.where(t < ts[0], centre[0] + speed * (t - ts[0]), pred)
    pred = np.where(t > ts[-1], centre[-1] + speed * (t - ts[-1]), pred)
    start_sorted = np.sort(xs)
    k = np.clip(np.searchsorted(start_sorted, pred - beam.dist_along), 1, start_sorted.size - 1)
    cand = np.stack([start_sorted[k - 1], start_sorted[k]]) + beam.dist_along
    x = np.where(np.abs(cand[0] - pred) <= np.abs(cand[1] - pred), cand[0], cand[1])
    if np.mean(np.abs(x - pred) > 5.0) > 0.01:
        return None
    return x
