"""From CCR windows to the maximum-likelihood estimate: the windows of the passes, the
likelihood's shots, the published grid search per beam for the starts, and the best maximum of
the likelihood over those starts (steps 2–3 of :mod:`calidar.photon.ccr`). The bootstrap re-runs
:func:`estimate` on simulated counts, so the σ it gives belong to this very estimator."""

from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np

from calidar.errors import CalibrationError
from calidar.photon.fit import Bounds, Fit, Layout, Problem, maximise, observed_information_solution
from calidar.photon.likelihood import Shots
from calidar.photon.passes import PassData, SystemParameters
from calidar.photon.search import GridResult, SearchSettings, grid_search
from calidar.photon.segments import CCRSegment, CCRWindow, ccr_window, segment_of


@dataclass
class Estimate:
    """Steps 2–3 on one set of counts: the maximum-likelihood fit, the grids and segments it
    started from."""

    fit: Fit
    grids: list[GridResult]
    segments: list[CCRSegment]


def windows_of(passes: list[PassData], survey, system: SystemParameters, settings: SearchSettings):
    """Every CCR window of every pass, and warnings for the CCRs a pass did not light (those far
    off the pass or across its track are named in one line per pass)."""
    windows, warnings = [], []
    for p in passes:
        if p.ground is None:
            warnings.append(f"{p.name}: no photons near any CCR; pass not used")
            continue
        outside, across = [], []
        for k, cid in enumerate(survey.ids):
            x, y = p.ccr_x[k], p.ccr_y[k]
            if not np.isfinite(x) or not p.x[0] - settings.reach <= x <= p.x[-1] + settings.reach:
                outside.append(f"{cid} ({p.ccr_distance[k]:.0f} m)")
            elif abs(y) > settings.reach:
                across.append(f"{cid} ({y:+.1f} m)")
            else:
                w, why = ccr_window(p, k, x, y, survey, system, settings.reach)
                windows.append(w) if w is not None else warnings.append(why)
        if outside:
            warnings.append(f"{p.name}: {_few(outside)} outside the pass (distance to its nearest "
                            "photon); ignored")
        if across:
            warnings.append(f"{p.name}: {_few(across)} across the track beyond any footprint "
                            f"(more than ±{settings.reach:g} m); ignored")
    return windows, warnings


def _few(items: list[str], most: int = 6) -> str:
    """'CCR a, b and c' or 'CCRs a, b, … and 4 more'."""
    head = ", ".join(items[:most])
    more = f" and {len(items) - most} more" if len(items) > most else ""
    return f"CCR{'s' if len(items) > 1 else ''} {head}{more}"


def shots_of(windows: list[CCRWindow], counts: list[np.ndarray] | None = None) -> Shots:
    """The likelihood's shots of the windows (with ``counts`` instead of the recorded ones when
    given)."""
    cnt = counts or [w.counts for w in windows]
    n = [w.shot_x.size for w in windows]
    rep = lambda f: np.repeat([f(w) for w in windows], n)  # noqa: E731
    return Shots(np.concatenate([w.shot_x for w in windows]), rep(lambda w: w.x_ccr).astype(float),
                 rep(lambda w: w.y_ccr).astype(float), rep(lambda w: w.background).astype(float),
                 np.concatenate(cnt).astype(np.int64), rep(lambda w: w.group).astype(np.int64),
                 rep(lambda w: w.channels).astype(np.int64), np.repeat(np.arange(len(windows)), n))


def _starts(layout: Layout, grids: list[GridResult],
            segments: list[CCRSegment]) -> list[dict[str, float]]:
    """The grid optimum, and each beam's alternative local minima with the other beams at their
    optimum."""
    base = []
    for g, grid in enumerate(grids):
        segs = [s for s in segments if s.window.group == g]
        n = segs[0].window.channels
        peak = max(max(s.central_count for s in segs), 1.0)
        # the mean photons Λ that fill ``peak`` of n channels: n·(1 − e^(−Λ/n)) = peak
        lam = float(-n * np.log1p(-min(peak, n - 0.5) / n))
        base.append([grid.along_bias, grid.cross_bias, grid.diameter, max(lam, 2.0),
                     grid.loss_rate])
    theta = np.array(base)
    if layout.shared_bias:
        weights = np.array([sum(s.n_shots for s in segments if s.window.group == g)
                            for g in range(len(grids))])
        theta[:, :2] = np.average(theta[:, :2], axis=0, weights=weights)
    starts = [layout.values(theta)]
    for g, grid in enumerate(grids):
        for bc, d in grid.alternatives:
            alt = theta.copy()
            alt[g if not layout.shared_bias else slice(None), 1] = bc
            alt[g, 2] = d
            starts.append(layout.values(alt))
    return starts


def estimate(windows: list[CCRWindow], problem: Problem, settings: SearchSettings, spacing: float,
             counts: list[np.ndarray] | None = None, covariance: bool = True) -> Estimate:
    """Segments → grid search per beam → the best maximum likelihood over the starts (raises
    CalibrationError when a beam lacks two lit CCRs at different cross-track offsets)."""
    counts = counts or [w.counts for w in windows]
    segments = [s for w, c in zip(windows, counts) if (s := segment_of(w, c, spacing)) is not None]
    grids = []
    for g, key in enumerate(problem.layout.groups):
        segs = [s for s in segments if s.window.group == g]
        ys = np.array([s.window.y_ccr for s in segs])
        if len(segs) < 2 or np.ptp(ys) < 0.5:
            raise CalibrationError(
                f"{key}: {len(segs)} lit CCR segment(s) at cross-track offsets "
                f"{np.round(ys, 2).tolist()} m: need at least two CCRs at different cross-track "
                "offsets (one chord gives |cross-track offset| only, not its side, and not the "
                "footprint diameter)")
        grids.append(grid_search(segs, spacing, settings))
    bounds = Bounds(settings.diameter_min, settings.diameter_max, settings.max_bias)
    fits, errors = [], []
    for start in _starts(problem.layout, grids, segments):
        try:
            fits.append(maximise(problem.with_counts(counts), start, bounds, covariance=False))
        except CalibrationError as e:
            errors.append(str(e))
    if not fits:
        raise CalibrationError(errors[0])
    best = min(fits, key=lambda f: f.nll)
    if covariance:
        solution = observed_information_solution(problem.with_counts(counts), best.solution,
                                                  best.at_limit)
        best = replace(best, solution=solution)
    return Estimate(best, grids, segments)
