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
    bin's median point, and the heading normal to the scan lines' trace on the ground (the
    principal axis of the bin's points, across the track whatever the crab; its sense from the
    line's motion). The trace is normal to the scan plane, hence to the body's x axis: the
    heading, not the course."""
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
        raise InputError(None, "gps_time", "fewer than two time bins of 0.5 s with ≥ 10 points; "
                         "the method needs several scan lines of one flight line")
    tc, c, across = np.asarray(tc), np.asarray(c), np.asarray(across)
    motion = c[-1, :2] - c[0, :2]
    # normal to the trace, either sense, turned to the sense the line flies
    forward = np.stack([across[:, 1], -across[:, 0]], axis=1)
    forward *= np.sign(forward @ motion)[:, None]
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


def _grouped_median(v: np.ndarray, labels: np.ndarray, starts: np.ndarray,
                    keep: np.ndarray) -> np.ndarray:
    """The median of ``v[keep]`` in each group of consecutive ``labels`` (group k starts at
    ``starts[k]``); NaN for an empty group."""
    vv = np.where(keep, v, np.inf)
    s = vv[np.lexsort((vv, labels))]
    n = np.bincount(labels, weights=keep, minlength=starts.size).astype(np.int64)
    lo, hi = np.clip(starts + (n - 1) // 2, 0, v.size - 1), np.clip(starts + n // 2, 0, v.size - 1)
    return np.where(n > 0, 0.5 * (s[lo] + s[hi]), np.nan)


def _line_fits(x: np.ndarray, y: np.ndarray, labels: np.ndarray, starts: np.ndarray):
    """Per group of consecutive ``labels``, the robust straight line y = c0 + c1·x (two
    least-squares passes dropping > 3 MAD) and the residuals' MAD: (c0, c1, mad), NaN and inf
    where fewer than 5 points or no spread in x are left. All groups at once, by weighted sums."""
    nb = starts.size
    keep = np.ones(x.size, bool)
    c0 = c1 = np.full(nb, np.nan)
    mad = np.full(nb, np.inf)
    ok = np.ones(nb, bool)
    for _ in range(2):
        w = keep.astype(float)

        def total(v):
            return np.bincount(labels, weights=w * v, minlength=nb)

        s0, sx, sy = total(np.ones_like(x)), total(x), total(y)
        sxx = np.bincount(labels, weights=w * x * x, minlength=nb)
        sxy = np.bincount(labels, weights=w * x * y, minlength=nb)
        det = s0 * sxx - sx * sx
        ok &= (s0 >= 5) & (det > 1e-12 * np.maximum(s0, 1.0) ** 2)
        d = np.where(ok, det, 1.0)
        c1 = np.where(ok, (s0 * sxy - sx * sy) / d, np.nan)
        c0 = np.where(ok, (sy - c1 * sx) / np.maximum(s0, 1.0), np.nan)
        r = np.abs(y - c0[labels] - c1[labels] * x)
        mad = np.where(ok, _grouped_median(r, labels, starts, keep) + 1e-9, np.inf)
        keep = r < 3 * 1.4826 * mad[labels]
    return c0, c1, mad


def scan_angle_start(t, p, scan_rad, sp, coef) -> tuple[np.ndarray, int, float]:
    """Rows (time, across offset, height) per bin from the scan angles, the sign of the scan-angle
    field that fits (+1: positive right of the flight direction, as LAS says; −1: the file's are
    flipped) and the median misfit (m)."""
    track = sp.evaluate(coef, t)
    psi = track[:, 3]
    right = np.stack([np.cos(psi), -np.sin(psi)], axis=1)
    a = np.einsum("ij,ij->i", p[:, :2] - track[:, :2], right)
    _, b = _bins(t, BIN_S)
    starts = b[:-1]
    labels = np.repeat(np.arange(starts.size), np.diff(b))
    every = np.ones(t.size, bool)
    t_mid = _grouped_median(t, labels, starts, every)
    z_mid = _grouped_median(p[:, 2], labels, starts, every)
    best = None
    for sign in (1, -1):
        tan = np.tan(sign * scan_rad)
        c0, c1, mad = _line_fits(tan, a + p[:, 2] * tan, labels, starts)
        good = np.isfinite(c0) & np.isfinite(c1) & (c1 > z_mid)
        rows = np.stack([t_mid[good], c0[good], c1[good]], axis=1)
        score = float(np.median(mad[good])) if good.sum() >= max(2, 0.5 * starts.size) else np.inf
        if best is None or score < best[2]:
            best = (rows, sign, score)
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
            # the point nearest every ray: Σ (I − d dᵀ) x = Σ (I − d dᵀ) q
            proj = np.eye(3)[None] - d[keep, :, None] * d[keep, None, :]
            rhs = np.einsum("nij,nj->i", proj, q[keep])
            x = np.linalg.lstsq(proj.sum(axis=0), rhs, rcond=None)[0]
            w = x - q
            off = np.linalg.norm(w - np.einsum("ij,ij->i", w, d)[:, None] * d, axis=1)
            keep = off <= 3 * np.median(off[keep]) + 1e-6
        out.append((float(np.median(ray_t[s:e])), *x))
    return np.asarray(out).reshape(-1, 4)
