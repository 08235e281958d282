"""Where a planned line is when its beams sweep over a point: a linear scanner's scan plane (the
body's y–z plane), or a rotating scanner's pattern (Palmer oval, wedge cone) cut into the fore and
aft branches it sees each point with, in the body frame; the line's position by secant steps on the
wobbling platform (bracketing and bisection where they fail). Used by :mod:`calidar.planning.rows`
(``f``: its ``Flown`` line, ``inst``: its ``Instrument``)."""

from __future__ import annotations

from functools import lru_cache

import numpy as np

from calidar.sensor import Sensor


def pattern_looks(nominal: Sensor) -> np.ndarray | None:
    """How far ahead a rotating scanner looks: None for a linear scanner (its beams stay in the
    body's y–z plane), else (2, 2, n) the pattern's fore and aft branches, each as (p, q) over p =
    y/z (the across-track ratio, increasing) with q = x/z (along track) in the body frame."""
    if nominal.scanner.model == "linear":
        return None
    return _pattern_branches(nominal.scanner, tuple(np.asarray(nominal.r_bs, float).ravel()))


def pattern_half_fov(nominal: Sensor) -> float:
    """Largest across-track angle (rad) of a rotating scanner's beams in the body frame (its swath's
    edge)."""
    p = _pattern_branches(nominal.scanner, tuple(np.asarray(nominal.r_bs, float).ravel()))[0, 0]
    return float(np.arctan(np.max(np.abs(p))))


@lru_cache(maxsize=32)
def _pattern_branches(scanner, r_bs: tuple) -> np.ndarray:
    """The scanner's beams over one turn in the body frame (u_b = R_bs · u_s), cut at every
    across-track ratio p of a grid: the largest (fore) and smallest (aft) along-track ratio where
    the pattern crosses it."""
    beta = np.linspace(-np.pi, np.pi, 2881)
    u = scanner.directions(beta) @ np.reshape(r_bs, (3, 3)).T
    p, q = u[:, 1] / u[:, 2], u[:, 0] / u[:, 2]
    grid = np.linspace(p.min(), p.max(), 241)[1:-1]
    p0, p1, q0, q1 = p[:-1, None], p[1:, None], q[:-1, None], q[1:, None]
    cross = (grid[None, :] - p0) * (grid[None, :] - p1) <= 0.0
    with np.errstate(invalid="ignore", divide="ignore"):
        at = np.where(cross & (p1 != p0), q0 + (q1 - q0) * (grid[None, :] - p0) / (p1 - p0), np.nan)
    fore, aft = np.nanmax(at, axis=0), np.nanmin(at, axis=0)
    return np.array([[grid, fore], [grid, aft]])


def body_at(f, points: np.ndarray, s: np.ndarray, inst):
    """Line ``f`` at along-track ``s`` (m, per point): time, position, R_lb and the points in the
    body frame from the lever arm's origin, R_lbᵀ · (p − r) − a."""
    t = f.t0 + s / f.line.speed_mps
    on_line = f.line.start + s[:, None] * f.line.direction
    pos = np.column_stack([on_line, np.full(len(s), f.altitude_m)])
    R = f.r_lb(t, inst.motion_rad)
    return t, pos, R, np.einsum("nji,nj->ni", R, points - pos) - inst.nominal.lever_arm


def _miss(f, points: np.ndarray, s: np.ndarray, inst, branch) -> np.ndarray:
    """How far (m, along the body's x) each point is from where the beams sweep with the line at
    ``s``."""
    return _miss_of(body_at(f, points, s, inst)[3], branch)


def _miss_of(d_b: np.ndarray, branch) -> np.ndarray:
    """:func:`_miss` from the points in the body frame (n, 3)."""
    if branch is None:
        return d_b[:, 0]
    ahead = d_b[:, 2] * np.interp(d_b[:, 1] / d_b[:, 2], branch[0], branch[1])
    return d_b[:, 0] - ahead


def sweep_position(f, points: np.ndarray, inst, branch) -> np.ndarray:
    """Along-track position (m) of the line when its beams sweep over each point: a linear scanner's
    scan plane by one fixed-point step (cm); a rotating scanner's fore or aft ``branch`` by secant
    steps to < 1 mm (each point until its own converges), and where they fail (the wobbling body can
    cross a point more than once near the pattern's edge) by the sign change of the miss nearest the
    guess, then bisection."""
    s = f.local(points[:, :2])[0]
    miss = _miss(f, points, s, inst, branch)
    s = s + miss
    if branch is None:
        return s
    guess, last_s, last_m = s.copy(), s - miss, miss.copy()
    act = np.arange(len(s))
    for _ in range(6):
        m = _miss(f, points[act], s[act], inst, branch)
        with np.errstate(invalid="ignore", divide="ignore"):
            slope = (m - last_m[act]) / (s[act] - last_s[act])
        ok = np.isfinite(slope) & (np.abs(slope + 1.0) < 0.9)  # the miss falls ≈ 1 m a metre flown
        last_s[act], last_m[act] = s[act], m
        s[act] = s[act] - m / np.where(ok, slope, -1.0)
        act = act[np.abs(m) >= 1e-4]
        if act.size == 0:
            break
    d_b = body_at(f, points, s, inst)[3]
    # off the pattern's across-track range: a root of the clamped branch only
    across = d_b[:, 1] / d_b[:, 2]
    off_pattern = (across < branch[0][0]) | (across > branch[0][-1])
    bad = (np.abs(_miss_of(d_b, branch)) > 1e-3) | off_pattern
    if bad.any():
        s[bad] = _bracketed(f, points[bad], guess[bad], inst, branch)
    return s


def _bracketed(f, points: np.ndarray, s: np.ndarray, inst, branch) -> np.ndarray:
    """The sign change of the miss nearest ``s`` within ±16 m, refined by bisection (< 1 mm)."""
    steps = np.arange(-16.0, 16.5, 1.0)
    miss = np.stack([_miss(f, points, s + d, inst, branch) for d in steps])  # (steps, n)
    change = np.sign(miss[:-1]) != np.sign(miss[1:])
    order = np.argsort(np.abs(steps[:-1] + 0.5))  # nearest the guess first
    first = order[np.argmax(change[order], axis=0)]
    lo = s + steps[first]
    hi = lo + 1.0
    sign_lo = np.sign(miss[first, np.arange(len(s))])
    for _ in range(11):
        mid = 0.5 * (lo + hi)
        same = np.sign(_miss(f, points, mid, inst, branch)) == sign_lo
        lo, hi = np.where(same, mid, lo), np.where(same, hi, mid)
    return 0.5 * (lo + hi)
