"""The published method's grid search (Magruder et al. 2019, 2021): the start of the fit.

For each footprint diameter D (range, step Δr) and cross-track bias b_c, every CCR's
theoretical cross-track distance from the footprint track is √((D/2)² − (L/2)²) on either
side of the track, with candidate chord lengths L = l + Δl·k (k = 0 … enough to restore the
segment's missing shots); the cross-track RMS of surveyed minus theoretical positions (best
side and candidate per CCR) plus the along-track RMS of (surveyed − midpoint − b_a) is
minimised. Which side of the track a single CCR lies on is not determined by its chord
(the chord fixes |y − b_c| only); with CCRs at different cross-track offsets the grid tests
both sides of each and only one assignment fits all chords with one diameter.
"""

from __future__ import annotations

from dataclasses import dataclass

import numba
import numpy as np


@dataclass(frozen=True)
class SearchSettings:
    """Grid-search, bounds and σ settings (m unless stated)."""

    diameter_min: float = 8.0  #: the fit's bounds on the footprint diameter too
    diameter_max: float = 15.0
    diameter_step: float = 0.1  #: Δr
    length_step: float = 0.1  #: Δl
    bias_step: float = 0.05  #: cross-track bias grid step
    max_bias: float = 10.0  #: largest |bias| accepted (sets the CCR search window)
    bootstrap: int = 100  #: parametric bootstrap replicates (0 = none)
    seed: int = 0
    shared_bias: bool = False  #: one along/cross bias for every beam (else one per beam)
    surface_points: int = 9  #: likelihood surface grid (per axis) for the report; 0 = none

    @property
    def reach(self) -> float:
        """Half-length (m) of a CCR's window of shots along track."""
        return self.diameter_max / 2.0 + self.max_bias


@dataclass
class GridResult:
    """The grid search of one beam: RMS (m) over footprint diameters × cross-track biases."""

    diameters: np.ndarray
    cross_biases: np.ndarray
    rms_cross: np.ndarray  #: (n_diameters, n_biases)
    rms_along: float
    along_bias: float
    cross_bias: float
    diameter: float
    sides: list[int]  #: +1 CCR left of the footprint track, −1 right
    loss_rate: float  #: shot-loss rate inside the segments' centres
    #: (cross bias, diameter) of the other local minima over b_c
    alternatives: list[tuple[float, float]]

    @property
    def total(self) -> np.ndarray:
        return self.rms_cross + self.rms_along

    def to_dict(self) -> dict:
        return {"along_track_bias": self.along_bias, "cross_track_bias": self.cross_bias,
                "footprint_diameter": self.diameter, "rms_along": self.rms_along,
                "rms_cross": float(self.rms_cross.min()), "ccr_sides": self.sides,
                "shot_loss_rate": self.loss_rate, "unit": "m"}


def shot_loss_rate(segments, spacing: float) -> float:
    """Fraction of shots lost inside the central half of the segments (where detection is sure)."""
    det = exp = 0
    for s in segments:
        lo, hi = s.midpoint - s.length / 4.0, s.midpoint + s.length / 4.0
        det += int(np.count_nonzero((s.shot_x >= lo) & (s.shot_x <= hi)))
        # the shots of the segment's spacing grid that fall in [lo, hi]
        last = np.floor((hi - s.first) / spacing + 1e-6)
        first = np.ceil((lo - s.first) / spacing - 1e-6)
        exp += int(last - first + 1)
    return float(np.clip(1.0 - det / exp, 0.0, 0.8)) if exp else 0.0


def chords(segments, spacing: float, loss: float) -> np.ndarray:
    """Chord length per segment (m): n_shots·d_l / (1 − q)."""
    return np.array([s.n_shots for s in segments]) * spacing / (1.0 - loss)


@numba.njit(cache=True)
def _squared_cross_errors(y, n_shots, n_cand, spacing, diam, biases,
                          length_step):  # pragma: no cover - numba
    """Σ over CCRs of the squared |surveyed − theoretical| cross-track distance (m²), best side and
    chord candidate each, for every (diameter, bias): (n_diameters, n_biases). The distance
    √(r² − (L/2)²) falls with the candidate L = l + Δl·k, so the best candidate is one of the two
    around L* = 2√(r² − a²), a = |y − b|; a chord longer than the footprint (L/2 > r) is off by its
    excess."""
    out = np.zeros((diam.size, biases.size))
    for c in range(y.size):
        l0 = n_shots[c] * spacing
        for i in range(diam.size):
            r = diam[i] / 2.0
            for j in range(biases.size):
                a = abs(y[c] - biases[j])
                k_star = (2.0 * np.sqrt(max(r * r - a * a, 0.0)) - l0) / length_step
                best = np.inf
                for k in (np.floor(k_star), np.ceil(k_star)):
                    half = 0.5 * (l0 + length_step * min(max(k, 0.0), n_cand[c] - 1.0))
                    e = np.hypot(a - np.sqrt(max(r * r - half * half, 0.0)), max(half - r, 0.0))
                    best = min(best, e)
                out[i, j] += best * best
    return out


def _cross_errors(y: float, n_shots: int, missing: int, spacing: float, diam: np.ndarray,
                  biases: np.ndarray, length_step: float) -> np.ndarray:
    """|surveyed − theoretical| cross-track distance (m) of one CCR for every (diameter, bias)."""
    n_cand = np.array([int(np.ceil(missing * spacing / length_step)) + 1])
    sq = _squared_cross_errors(np.array([y]), np.array([n_shots]), n_cand, spacing, diam, biases,
                               length_step)
    return np.sqrt(sq)


def grid_search(segments, spacing: float, settings: SearchSettings) -> GridResult:
    """Minimise along-track RMS + cross-track RMS over footprint diameter and cross-track bias."""
    y = np.array([s.window.y_ccr for s in segments])
    resid_a = np.array([s.window.x_ccr - s.midpoint for s in segments])
    b_a = float(resid_a.mean())
    rms_a = float(np.sqrt(np.mean((resid_a - b_a) ** 2)))
    diam = np.arange(settings.diameter_min, settings.diameter_max + 1e-9, settings.diameter_step)
    half = settings.diameter_max / 2.0
    lo, hi = max(y.min() - half, -settings.max_bias), min(y.max() + half, settings.max_bias)
    biases = np.arange(lo, hi + 1e-9, settings.bias_step)
    if biases.size == 0:
        biases = np.array([float(np.clip(y.mean(), -settings.max_bias, settings.max_bias))])
    # chord candidates: the lit shots' length plus up to the missing shots, Δl apart
    n_cand = np.array([int(np.ceil(s.missing_shots * spacing / settings.length_step)) + 1
                       for s in segments])
    n_shots = np.array([s.n_shots for s in segments])
    sq = _squared_cross_errors(y, n_shots, n_cand, spacing, diam, biases, settings.length_step)
    rms_c = np.sqrt(sq / len(segments))
    i, j = np.unravel_index(np.argmin(rms_c + rms_a), rms_c.shape)
    sides = [int(np.sign(yi - biases[j]) or 1) for yi in y]
    return GridResult(diam, biases, rms_c, rms_a, b_a, float(biases[j]), float(diam[i]), sides,
                      shot_loss_rate(segments, spacing), _other_minima(rms_c, diam, biases, j))


#: an alternative minimum competes when its RMS ≤ 1.25 × the best + 0.05 m
COMPETING_RMS = (1.25, 0.05)


def _other_minima(rms_c: np.ndarray, diam: np.ndarray, biases: np.ndarray, best: int, n: int = 2,
                  separation: float = 1.0) -> list[tuple[float, float]]:
    """Up to ``n`` other local minima over the cross-track bias of min-over-D RMS that compete with
    the best (COMPETING_RMS), ≥ ``separation`` m from it and from each other, best first: (bias,
    diameter)."""
    profile = rms_c.min(axis=0)
    lm = np.flatnonzero((profile <= np.roll(profile, 1)) & (profile <= np.roll(profile, -1)))
    lm = lm[profile[lm] <= COMPETING_RMS[0] * profile[best] + COMPETING_RMS[1]]
    taken, out = [biases[best]], []
    for j in lm[np.argsort(profile[lm])]:
        if all(abs(biases[j] - t) >= separation for t in taken):
            taken.append(biases[j])
            out.append((float(biases[j]), float(diam[np.argmin(rms_c[:, j])])))
        if len(out) == n:
            break
    return out
