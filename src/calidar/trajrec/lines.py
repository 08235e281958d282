"""Flight lines of the kept points: by point source id, each split where the GPS times have a gap
(the scanner stops in turns) or where the ground track reverses (a U-turn without a gap), so that a
wrong or missing point source id (all 0, or one id for several lines) still gives the lines."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from calidar.strips import lines as strip_lines

#: a pause in the GPS times longer than this (and 100 pulse intervals) splits a line
MIN_GAP_S = 2.0
TRACK_BIN_S = 2.0  #: ground-track headings are compared over bins of this length
REVERSAL_RAD = np.radians(120.0)  #: a heading change larger than this between bins splits a line


@dataclass
class LinePoints:
    """One flight line's kept points and rays (file CRS, times as stored, scan angles in deg)."""

    number: int  #: point source id (or the order of the line when ids are missing)
    part: int  #: 0 unless the id's points were split into several lines
    t: np.ndarray
    xyz: np.ndarray
    scan: np.ndarray
    ray_t: np.ndarray
    ray_first: np.ndarray
    ray_last: np.ndarray
    ray_scan: np.ndarray

    @property
    def label(self) -> str:
        return f"{self.number}" + (f".{self.part}" if self.part else "")

    @property
    def duration_s(self) -> float:
        return float(self.t[-1] - self.t[0]) if self.t.size else 0.0


def _breaks(t: np.ndarray, xy: np.ndarray) -> np.ndarray:
    """Times (sorted) where a line ends: gaps in time (:func:`calidar.strips.lines.split_lines`, the
    one splitter, at this scanner's own gap), reversals of the ground track."""
    dt = np.diff(t)
    gap = max(MIN_GAP_S, 100 * float(np.median(dt[dt > 0]))) if np.any(dt > 0) else MIN_GAP_S
    gap_starts = strip_lines.split_lines((), {}, t, t, gap).starts[1:]
    starts = np.searchsorted(t, gap_starts)  # the first point after each gap
    cuts = [0.5 * (t[i - 1] + t[i]) for i in starts]
    edges = np.arange(t[0], t[-1] + TRACK_BIN_S, TRACK_BIN_S)
    b = np.searchsorted(t, edges)
    centres = np.array([xy[s:e].mean(axis=0) if e > s else [np.nan, np.nan]
                        for s, e in zip(b[:-1], b[1:])])
    if len(centres) >= 3:
        v = np.diff(centres, axis=0)
        head = np.arctan2(v[:, 0], v[:, 1])
        turn = np.abs(np.angle(np.exp(1j * np.diff(head))))
        for k in np.flatnonzero(turn > REVERSAL_RAD):
            cuts.append(edges[k + 1])
    return np.sort(np.asarray(cuts, float))


def split_lines(a: dict) -> tuple[list[LinePoints], str]:
    """Lines from :meth:`calidar.trajrec.pulses.Kept.arrays`, and how they were found."""
    lines, split = [], False
    for source in np.unique(a["source"]):
        m = a["source"] == source
        order = np.argsort(a["t"][m], kind="stable")
        t, xyz, scan = a["t"][m][order], a["xyz"][m][order], a["scan"][m][order]
        if t.size < 2:
            continue
        cuts = _breaks(t, xyz[:, :2])
        split |= cuts.size > 0
        rm = a["ray_source"] == source
        rays = [a[key][rm] for key in ("ray_t", "ray_first", "ray_last", "ray_scan")]
        seg_p = np.searchsorted(cuts, t)
        seg_r = np.searchsorted(cuts, rays[0])
        for k in range(cuts.size + 1):
            p, r = seg_p == k, seg_r == k
            ro = np.argsort(rays[0][r], kind="stable")
            lines.append(LinePoints(int(source), k, t[p], xyz[p], scan[p],
                                    *(ray[r][ro] for ray in rays)))
    how = "point source ids" + (", split at time gaps and track reversals" if split else "")
    return lines, how
