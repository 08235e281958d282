"""Starting values of a line's trajectory from the geometry of its scan lines (no iteration).

The ground track (the points' centre in short time bins, smoothed) and the scan lines' trace on
the ground (normal to the heading) give the path and the heading. Within one
bin the scan-angle field θ (the beam's angle about the along-track axis) and a point's offset a
across the track and height u tie the sensor's across-track offset s and height U together:
a = s + (U − u)·tan θ, i.e. a + u·tan θ = s + U·tan θ, a straight-line fit per bin (roll ignored
here; the full fit estimates it). Where the scan angles say nothing, the rays of multi-return
pulses are intersected per bin instead: (Σ P⊥) S = Σ P⊥ p, P⊥ = I − d dᵀ.
"""

from __future__ import annotations

import numpy as np

from calidar.errors import InputError
from calidar.trajrec.spline import Spline

BIN_S = 0.5  #: time bins of the starting values, s
TRACK_KNOT_S = 2.0  #: knot spacing of the smoothed ground track, s


def _bins(t: np.ndarray, width: float) -> tuple[np.ndarray, np.ndarray]:
    edges = np.arange(t[0], t[-1] + width, width)
    return edges, np.searchsorted(t, edges)


def ground_track(t: np.ndarray, p: np.ndarray) -> tuple[Spline, np.ndarray]:
    """A smooth spline over (east, north, up, heading) of the points, bin by bin (t sorted): the
    bin's median point, and the heading normal to the scan lines' trace on the ground (the principal
    axis of the bin's points, across the track whatever the crab; its sense from the line's motion).
    The trace is normal to the scan plane, hence to the body's x axis: the heading, not the course."""
    edges, b = _bins(t, BIN_S)
    tc, c, across = [], [], []
    for s, e in zip(b[:-1], b[1:]):
        if e - s >= 10:
            xy = p[s:e, :2] - np.median(p[s:e, :2], axis=0)
            w, v = np.linalg.eigh(xy.T @ xy)
            tc.append(float(np.median(t[s:e])))
            c.append(np.median(p[s:e], axis=0))
            across.append(v[:, 1] if w[1] > 4 * w[0] else np.array([np.nan, np.nan]))
    if len(tc) < 2:
        raise InputError(None, "gps_time", "fewer than two time bins of 0.5 s with ≥ 10 points; the method needs "
                         "several scan lines of one flight line")
    tc, c, across = np.asarray(tc), np.asarray(c), np.asarray(across)
    motion = c[-1, :2] - c[0, :2]
    forward = np.stack([across[:, 1], -across[:, 0]], axis=1)  # normal to the trace, either sense ...
    forward *= np.sign(forward @ motion)[:, None]  # ... turned to the sense the line flies
    ok = np.all(np.isfinite(forward), axis=1)
    if ok.sum() < 2:  # no clear scan lines: the course over ground
        forward = np.gradient(c[:, :2], tc, axis=0)
        ok = np.ones(tc.size, bool)
    head = np.unwrap(np.arctan2(forward[ok, 0], forward[ok, 1]))
    head = np.interp(tc, tc[ok], _median3(head))
    sp = Spline.covering(t[0], t[-1], TRACK_KNOT_S)
    return sp, sp.fit(tc, np.c_[c, head])


def _median3(a: np.ndarray) -> np.ndarray:
    """Running median of 5 (a bin's heading can be spoilt by a building's edge)."""
    if a.size < 5:
        return a
    pad = np.r_[a[:2], a, a[-2:]]
    return np.median(np.lib.stride_tricks.sliding_window_view(pad, 5), axis=1)


def course(sp: Spline, coef: np.ndarray, t) -> np.ndarray:
    """The start heading (rad, clockwise from north) at ``t``."""
    return sp.evaluate(coef, t)[:, 3]


def _line_fit(x: np.ndarray, y: np.ndarray) -> tuple[np.ndarray, float]:
    """Robust straight line y = c0 + c1·x (two passes dropping > 3 MAD), and the residuals' MAD."""
    keep = np.ones(x.size, bool)
    c, mad = np.array([np.nan, np.nan]), np.inf
    for _ in range(2):
        if keep.sum() < 5 or np.ptp(x[keep]) <= 0:
            return np.array([np.nan, np.nan]), np.inf
        a = np.stack([np.ones(keep.sum()), x[keep]], axis=1)
        c = np.linalg.lstsq(a, y[keep], rcond=None)[0]
        r = y - c[0] - c[1] * x
        mad = float(np.median(np.abs(r[keep]))) + 1e-9
        keep = np.abs(r) < 3 * 1.4826 * mad
    return c, mad


def scan_angle_start(t, p, scan_rad, sp, coef) -> tuple[np.ndarray, int, float]:
    """Rows (time, across offset, height) per bin from the scan angles, the sign of the scan-angle field
    that fits (+1: positive right of the flight direction, as LAS says; −1: the file's are flipped)
    and the median misfit (m)."""
    track = sp.evaluate(coef, t)
    psi = track[:, 3]
    right = np.stack([np.cos(psi), -np.sin(psi)], axis=1)
    a = np.einsum("ij,ij->i", p[:, :2] - track[:, :2], right)
    edges, b = _bins(t, BIN_S)
    best = None
    for sign in (1, -1):
        tan = np.tan(sign * scan_rad)
        rows, mads = [], []
        for s, e in zip(b[:-1], b[1:]):
            c, mad = _line_fit(tan[s:e], a[s:e] + p[s:e, 2] * tan[s:e])
            if np.all(np.isfinite(c)) and c[1] > np.median(p[s:e, 2]):
                rows.append((float(np.median(t[s:e])), c[0], c[1]))
                mads.append(mad)
        score = np.median(mads) if len(rows) >= max(2, 0.5 * (len(b) - 1)) else np.inf
        if best is None or score < best[2]:
            best = (np.asarray(rows).reshape(-1, 3), sign, float(score))
    return best


def ray_start(ray_t, last, direction) -> np.ndarray:
    """Per bin (time, east, north, up): the least-squares intersection of the bin's rays."""
    out = []
    if ray_t.size < 10:
        return np.empty((0, 4))
    edges, b = _bins(ray_t, 4 * BIN_S)
    for s, e in zip(b[:-1], b[1:]):
        if e - s < 10:
            continue
        d, q = direction[s:e], last[s:e]
        keep = np.ones(e - s, bool)
        for _ in range(3):
            proj = np.eye(3)[None] - d[keep, :, None] * d[keep, None, :]
            x = np.linalg.lstsq(proj.sum(axis=0), np.einsum("nij,nj->i", proj, q[keep]), rcond=None)[0]
            w = x - q
            off = np.linalg.norm(w - np.einsum("ij,ij->i", w, d)[:, None] * d, axis=1)
            keep = off <= 3 * np.median(off[keep]) + 1e-6
        out.append((float(np.median(ray_t[s:e])), *x))
    return np.asarray(out).reshape(-1, 4)
