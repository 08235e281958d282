"""What trajectory reconstruction keeps of streamed points: the rays of multi-return pulses and a
thinned sample of all points, chunk by chunk (a file is never held whole).

A pulse is the points sharing one GPS time (and one scan angle, so that the returns of several
pulses in the air stamped with the same time stay apart). Its ray runs from the lowest point up
through the highest: the first return is the one nearest the sensor whatever the return numbers
say, so repeated or missing return numbers do no harm. Rays shorter than ``MIN_SEPARATION_M`` or
steeper than ``MAX_RAY_ANGLE_RAD`` off the vertical are no rays of one pulse and are dropped.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
from numba import njit

MIN_SEPARATION_M = 1.0  #: returns of one pulse closer than this give no usable direction
MAX_RAY_ANGLE_RAD = np.radians(75.0)  #: a pulse's ray further from the vertical is not one pulse
MIN_KEEP = 5000  #: points (and rays) a chunk keeps at least, whatever the rate: small files whole


@dataclass
class Kept:
    """Arrays kept from a file's chunks (coordinates in the file's CRS, times as stored)."""

    t: list = field(default_factory=list)
    xyz: list = field(default_factory=list)
    scan: list = field(default_factory=list)
    source: list = field(default_factory=list)
    ray_t: list = field(default_factory=list)
    ray_first: list = field(default_factory=list)
    ray_last: list = field(default_factory=list)
    ray_scan: list = field(default_factory=list)
    ray_source: list = field(default_factory=list)
    n_read: int = 0
    n_bad_time: int = 0
    n_multi: int = 0  #: points of pulses with more than one return (by their number_of_returns)
    return_numbers_repeated: int = 0  #: pulses whose points repeat a return number

    def arrays(self) -> dict:
        """Each list concatenated (empty arrays of the right shape when nothing was kept)."""
        out = {}
        for k in ("t", "scan", "source", "ray_t", "ray_scan", "ray_source"):
            out[k] = np.concatenate(getattr(self, k)) if getattr(self, k) else np.empty(0)
        for k in ("xyz", "ray_first", "ray_last"):
            out[k] = np.concatenate(getattr(self, k)) if getattr(self, k) else np.empty((0, 3))
        return out


def pulse_rays(t, xyz, scan, source, return_number=None):
    """Rays of the multi-point pulses among points: (index of first, index of last, repeated-return
    pulses); first = highest point, last = lowest. Only points whose time another point shares are
    looked at (a tenth of an airborne file), in runs of one time (:func:`_pulse_groups`)."""
    if np.all(t[1:] >= t[:-1]):  # files are mostly in time order
        same = t[1:] == t[:-1]
        cand = np.flatnonzero(np.r_[same, False] | np.r_[False, same])
    else:
        order = np.argsort(t, kind="stable")
        ts = t[order]
        same = ts[1:] == ts[:-1]
        cand = order[np.r_[same, False] | np.r_[False, same]]
    if cand.size == 0:
        return np.empty(0, np.int64), np.empty(0, np.int64), 0
    key_scan = np.zeros(cand.size) if scan is None else np.nan_to_num(np.asarray(scan, float)[cand])
    if return_number is None:
        rn = np.zeros(cand.size, np.int64)
    else:
        rn = np.asarray(return_number, np.int64)[cand]
    t_cand, source_cand = np.asarray(t, float)[cand], np.asarray(source, float)[cand]
    z_cand = np.asarray(xyz[cand, 2], float)
    first, last, repeated = _pulse_groups(np.arange(cand.size), t_cand, source_cand, key_scan,
                                          z_cand, rn, return_number is not None)
    first, last = cand[first], cand[last]
    d = xyz[first] - xyz[last]
    sep = np.linalg.norm(d, axis=1)
    ok = (sep >= MIN_SEPARATION_M) & (d[:, 2] > np.cos(MAX_RAY_ANGLE_RAD) * sep)
    return first[ok], last[ok], int(repeated)


@njit(cache=True, nogil=True, inline="always")
def _before(v, w, source, scan, z):
    """(source, scan, −z) of point v sorts before that of w."""
    if source[v] != source[w]:
        return source[v] < source[w]
    if scan[v] != scan[w]:
        return scan[v] < scan[w]
    return z[v] > z[w]


@njit(cache=True, nogil=True)
def _pulse_groups(cand, t, source, scan, z, rn, has_rn):  # pragma: no cover - numba
    """Per run of ``cand`` (indices in time order) sharing one time, its points sorted by (point
    source, scan angle, height downwards; stable) and cut where source or scan angle change: a
    pulse of ≥ 2 points gives (its highest, its lowest) point; a pulse with two height-adjacent
    points of one return number counts as repeating it. The same as a lexsort of all candidates by
    (time, source, scan, −z), without it (runs are 2–5 points: an insertion sort each)."""
    n = cand.size
    first, last = np.empty(n, np.int64), np.empty(n, np.int64)
    buf = np.empty(n, np.int64)
    m, repeated, s = 0, 0, 0
    while s < n:
        e = s + 1
        while e < n and t[cand[e]] == t[cand[s]]:
            e += 1
        g = e - s
        for a in range(g):
            v = cand[s + a]
            b = a - 1
            while b >= 0 and _before(v, buf[b], source, scan, z):
                buf[b + 1] = buf[b]
                b -= 1
            buf[b + 1] = v
        a = 0
        while a < g:
            c = a + 1
            while c < g and source[buf[c]] == source[buf[a]] and scan[buf[c]] == scan[buf[a]]:
                c += 1
            if c - a > 1:
                first[m], last[m] = buf[a], buf[c - 1]
                m += 1
                if has_rn:
                    for q in range(a + 1, c):
                        if rn[buf[q]] == rn[buf[q - 1]]:
                            repeated += 1
                            break
            a = c
        s = e
    return first[:m], last[:m], repeated


def keep_chunk(kept: Kept, chunk, rate_per_s: float) -> None:
    """Add one chunk (:class:`calidar.io.las.LasPoints`): about ``rate_per_s`` points and as many
    pulses' rays a second (a random thinning; all of them when fewer). Points with a time ≤ 0 or not
    finite (damaged GPS times) are counted and dropped."""
    n = len(chunk)
    kept.n_read += n
    t = chunk.gps_time
    good = np.isfinite(t) & (t > 0)
    kept.n_bad_time += int(n - good.sum())
    if not good.any():
        return
    idx = slice(None) if good.all() else np.flatnonzero(good)  # no copies of a clean chunk
    t, xyz = t[idx], chunk.xyz[idx]
    scan = None if chunk.scan_angle_deg is None else np.asarray(chunk.scan_angle_deg, float)[idx]
    if chunk.point_source_id is None:
        source = np.zeros(t.size)
    else:
        source = np.asarray(chunk.point_source_id)[idx]
    rn = None if chunk.return_number is None else chunk.return_number[idx]
    if chunk.number_of_returns is not None:
        kept.n_multi += int(np.count_nonzero(chunk.number_of_returns[idx] > 1))
    first, last, repeated = pulse_rays(t, xyz, scan, source, rn)
    kept.return_numbers_repeated += repeated
    lo, hi = np.percentile(t[:: max(1, t.size // 10000)], [1, 99])
    span = max((hi - lo) * rate_per_s, MIN_KEEP)  # small files are kept whole
    # a random thinning (seeded: the same file gives the same result), never a regular stride: a
    # scanner firing a whole number of pulses per scan period would have every kept point at one of
    # a few scan angles, their quantisation errors the same in every sweep (a bias, not noise)
    rng = np.random.default_rng(kept.n_read)
    keep = rng.random(first.size) < span / max(first.size, 1)
    first, last = first[keep], last[keep]
    kept.ray_t.append(t[first])
    kept.ray_first.append(xyz[first])
    kept.ray_last.append(xyz[last])
    kept.ray_scan.append(np.full(first.size, np.nan) if scan is None else scan[first])
    kept.ray_source.append(source[first].astype(float))
    sel = np.flatnonzero(rng.random(t.size) < span / t.size)
    kept.t.append(t[sel])
    kept.xyz.append(xyz[sel])
    kept.scan.append(np.full(sel.size, np.nan) if scan is None else scan[sel])
    kept.source.append(source[sel].astype(float))
