"""Starting values of a line's trajectory from the geometry of its scan lines (no iteration).

The ground track (the points' centre in short time bins, smoothed) gives the course. Within one
bin the scan-angle field θ (the beam's angle about the along-track axis) and a point's offset a
across the track and height u tie the sensor's across-track offset s and height U together:
a = s + (U − u)·tan θ, i.e. a + u·tan θ = s + U·tan θ, a straight-line fit per bin (roll ignored
here; the full fit estimates it). Where the scan angles say nothing, the rays of multi-return
pulses are intersected per bin instead: (Σ P⊥) S = Σ P⊥ p, P⊥ = I − d dᵀ.
"""

from __future__ import annotations

import numpy as np

from calidar.trajrec.spline import Spline

BIN_S = 0.5  #: time bins of the starting values, s
TRACK_KNOT_S = 2.0  #: knot spacing of the smoothed ground track, s


def _bins(t: np.ndarray, width: float) -> tuple[np.ndarray, np.ndarray]:
    edges = np.arange(t[0], t[-1] + width, width)
    return edges, np.searchsorted(t, edges)


def ground_track(t: np.ndarray, p: np.ndarray) -> tuple[Spline, np.ndarray]:
    """A smooth spline (east, north, up) through the points' per-bin medians (t sorted)."""
    edges, b = _bins(t, BIN_S)
    tc, c = [], []
    for s, e in zip(b[:-1], b[1:]):
        if e - s >= 3:
            tc.append(float(np.median(t[s:e])))
            c.append(np.median(p[s:e], axis=0))
    sp = Spline.covering(t[0], t[-1], TRACK_KNOT_S)
    return sp, sp.fit(np.asarray(tc), np.asarray(c))


def course(sp: Spline, coef: np.ndarray, t) -> np.ndarray:
    """Heading (rad, clockwise from north) of the track's velocity at ``t``, unwrapped."""
    v = sp.derivative(coef, t)
    return np.unwrap(np.arctan2(v[:, 0], v[:, 1]))


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
    psi = course(sp, coef, t)
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
