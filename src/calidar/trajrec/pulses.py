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
    sorted (a tenth of an airborne file), so this costs little."""
    order = np.arange(t.size) if np.all(t[1:] >= t[:-1]) else np.argsort(t, kind="stable")  # files are mostly in time order
    ts = t[order]
    same = ts[1:] == ts[:-1]
    cand = order[np.r_[same, False] | np.r_[False, same]]
    if cand.size == 0:
        return np.empty(0, np.int64), np.empty(0, np.int64), 0
    key_scan = np.zeros(cand.size) if scan is None else np.nan_to_num(scan[cand])
    o = cand[np.lexsort((-xyz[cand, 2], key_scan, source[cand], t[cand]))]
    ts, ss, sc = t[o], (np.zeros(o.size) if scan is None else np.nan_to_num(scan[o])), source[o]
    new = np.r_[True, (ts[1:] != ts[:-1]) | (ss[1:] != ss[:-1]) | (sc[1:] != sc[:-1])]
    start = np.flatnonzero(new)
    end = np.r_[start[1:], ts.size] - 1
    multi = end > start
    first, last = o[start[multi]], o[end[multi]]
    repeated = 0
    if return_number is not None and multi.any():
        rn = np.asarray(return_number)[o]
        dup = np.r_[False, (~new[1:]) & (rn[1:] == rn[:-1])]
        repeated = int(np.unique(np.cumsum(new)[dup]).size)
    d = xyz[first] - xyz[last]
    sep = np.linalg.norm(d, axis=1)
    ok = (sep >= MIN_SEPARATION_M) & (d[:, 2] > np.cos(MAX_RAY_ANGLE_RAD) * sep)
    return first[ok], last[ok], repeated


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
    source = np.zeros(t.size) if chunk.point_source_id is None else np.asarray(chunk.point_source_id)[idx]
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
