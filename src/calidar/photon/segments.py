"""What one pass recorded of each CCR: its window of shots with their photon counts, and the
published method's segment (the run of shots that saw it).

After Magruder et al. (2019, 2021; ICESat-2 CCR arrays at White Sands): CCR photons lie
h_p ± Δh above the ground, Δh = min(c·t_d/2, 3·c·σ) (t_d dead time, σ RMS pulse width); a
line is fitted to them (h = a·x + b above ground; photons > 3σ off it dropped; reported). A
CCR is a point, so all its photons share one ellipsoidal height (their median): every shot of
the window around the CCR (±(D_max/2 + max bias) along track; shots that recorded no photon
at all, absent from ATL03, put back with count 0) gets its photon count in the band
±min(3·c·σ/2, Δh) around that height (not around the line: extrapolated over the window, a
line through a few photons tilts the band into the ground). Shots where the ground rises to
within two band half-heights of the CCR are left out (their ground photons would count as CCR
photons). These counts are the data of the likelihood; the background rate is measured in an
empty 4 m band above. The segment is the longest run of counting shots with gaps ≤ 7 shot spacings:
its first/last shot, length l, midpoint and the shots missing inside it (stepping d_l).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

BACKGROUND_BAND = 4.0  #: m of height above the count band where the background rate is measured
#: count band half-heights the ground must lie below a CCR for a shot to count
GROUND_CLEARANCE = 2.0
RUN_GAP_SPACINGS = 7.0  #: largest gap (in shot spacings) inside one CCR segment


@dataclass
class CCRWindow:
    """The shots of one pass around one CCR (distances m)."""

    pass_name: str
    group: int  #: parameter group (beam) index
    ccr_id: str
    x_ccr: float  #: surveyed along-track position
    y_ccr: float  #: surveyed cross-track position (left positive)
    pole_height: float
    shot_x: np.ndarray  #: reported along-track position of every shot of the window (sorted)
    counts: np.ndarray  #: photons in the count band per shot (mostly 0)
    background: float  #: mean background photons per shot in the count band
    channels: int  #: detector channels of the beam
    angle: float = 0.0  #: rad, slope of the CCR photons' height line
    intercept: float = 0.0  #: m, the line's height above ground at the photons' mean x
    photon_index: np.ndarray | None = None  #: the pass's photons counted (for plots)


@dataclass
class CCRSegment:
    """The run of shots that returned photons from one CCR (the published method's segment)."""

    window: CCRWindow
    shot_x: np.ndarray  #: along-track positions of the shots of the run that saw the CCR (sorted)
    shot_counts: np.ndarray  #: their photon counts
    spacing: float  #: m, shot spacing d_l

    @property
    def first(self) -> float:
        return float(self.shot_x[0])

    @property
    def last(self) -> float:
        return float(self.shot_x[-1])

    @property
    def length(self) -> float:
        """Span l between the first and last shot that saw the CCR (m)."""
        return self.last - self.first

    @property
    def midpoint(self) -> float:
        """Mean along-track position of the shots that saw the CCR (robust to a stray edge
        photon)."""
        return float(self.shot_x.mean())

    @property
    def n_shots(self) -> int:
        return int(self.shot_x.size)

    @property
    def missing_shots(self) -> int:
        """Shots inside the span that returned nothing from the CCR."""
        return int(round(self.length / self.spacing)) + 1 - self.n_shots

    @property
    def central_count(self) -> float:
        """Mean CCR photons per detecting shot in the central half of the segment."""
        c = np.abs(self.shot_x - self.midpoint) <= max(self.length / 4.0, 1e-9)
        return float(self.shot_counts[c].mean()) if c.any() else float(self.shot_counts.mean())

    def summary(self) -> dict:
        w = self.window
        return {"pass": w.pass_name, "ccr": w.ccr_id, "x_ccr": w.x_ccr, "y_ccr": w.y_ccr,
                "pole_height": w.pole_height, "n_photons": int(self.shot_counts.sum()),
                "n_shots": self.n_shots, "missing_shots": self.missing_shots,
                "first": self.first, "last": self.last, "length": self.length,
                "midpoint": self.midpoint, "angle_rad": w.angle,
                "intercept_above_ground": w.intercept,
                "central_photons_per_shot": self.central_count}


def _runs(index: np.ndarray, x: np.ndarray, gap: float) -> list[np.ndarray]:
    """``index`` (into ``x``, m, increasing) cut where consecutive positions are over ``gap``
    m apart."""
    return np.split(index, np.flatnonzero(np.diff(x[index]) > gap) + 1)


def segment_of(window: CCRWindow, counts: np.ndarray, spacing: float,
               min_shots: int = 3) -> CCRSegment | None:
    """The longest run of shots of ``window`` with counts > 0 (gaps ≤ RUN_GAP_SPACINGS·d_l); None
    when it has fewer than ``min_shots`` shots."""
    hit = np.flatnonzero(counts > 0)
    if hit.size < min_shots:
        return None
    run = max(_runs(hit, window.shot_x, RUN_GAP_SPACINGS * spacing), key=len)
    if run.size < min_shots:
        return None
    return CCRSegment(window, window.shot_x[run], counts[run], spacing)


def with_silent_shots(x: np.ndarray, counts: np.ndarray,
                      spacing: float) -> tuple[np.ndarray, np.ndarray]:
    """Insert the shots that recorded no photon at all (absent from ATL03) with count 0:
    where consecutive shots at along-track x (m, increasing) are ≥ 1.5 spacings apart."""
    step = np.diff(x)
    gaps = np.rint(step / spacing).astype(int)
    missing = np.clip(gaps - 1, 0, None)
    if not missing.any():
        return x, counts
    i = np.repeat(np.arange(gaps.size), missing)
    # 1 … missing within each gap
    j = np.arange(i.size) - np.repeat(np.cumsum(missing) - missing, missing) + 1
    xs = np.concatenate([x, x[i] + j * step[i] / gaps[i]])
    order = np.argsort(xs, kind="stable")
    return xs[order], np.concatenate([counts, np.zeros(i.size, counts.dtype)])[order]


def ccr_window(p, k: int, x_ccr: float, y_ccr: float, survey, system, reach: float):
    """The window of CCR ``k`` of ``survey`` in pass ``p``
    (:class:`~calidar.photon.passes.PassData`), or a sentence saying why there is none."""
    cid, pole = survey.ids[k], float(survey.height[k])
    above = p.above_ground
    lo, hi = np.searchsorted(p.x, [x_ccr - reach, x_ccr + reach + 1e-9])
    band = _ccr_band(p, lo, hi, pole, system)
    if np.unique(p.shot[band]).size < 3:
        shots = np.unique(p.shot[band]).size
        return None, (f"{p.name}: no CCR photons found for CCR {cid} ({shots} shots in the "
                      f"{pole:.2f} ± {system.delta_h:.2f} m band)")
    x_mean = float(p.x[band].mean())
    a, b = np.polyfit(p.x[band] - x_mean, above[band], 1)  # the published method's line (reported)
    h_ccr = float(np.median(p.h[band]))  # a CCR is a point: all its photons share its height
    win = np.arange(lo, hi)
    off = p.h[win] - h_ccr
    half = min(3.0 * system.height_sigma, system.delta_h)
    wshots, wone = np.unique(p.shot[win], return_index=True)
    inband = np.abs(off) <= half
    counts = np.bincount(np.searchsorted(wshots, p.shot[win][inband]), minlength=wshots.size)
    wx, counts = with_silent_shots(p.x[win][wone], counts, system.shot_spacing)
    # where the ground rises into the band, photons of the ground and of the CCR cannot be told
    # apart: those shots are left out
    clear = h_ccr - p.ground(wx) >= GROUND_CLEARANCE * half
    wx, counts = wx[clear], counts[clear]
    n_ref = np.count_nonzero((off > 3.0 * half) & (off <= 3.0 * half + BACKGROUND_BAND))
    # + ½: never exactly 0
    background = (n_ref + 0.5) / (wx.size * BACKGROUND_BAND) * 2.0 * half
    return CCRWindow(p.name, p.group, cid, float(x_ccr), float(y_ccr), pole, wx, counts,
                     float(background), p.channels, float(np.arctan(a)), float(b),
                     win[inband]), None


def _ccr_band(p, lo: int, hi: int, pole: float, system) -> np.ndarray:
    """The photons (indices into ``p``'s) of rows [lo, hi) in the CCR's height band: its pole
    height above ground ± Δh, the longest run of them (a stray photon far out does not tilt the
    line), within 3σ of their straight line."""
    above = p.above_ground
    band = lo + np.flatnonzero(p.coarse[lo:hi] & (np.abs(above[lo:hi] - pole) <= system.delta_h))
    if band.size:
        band = max(_runs(band, p.x, RUN_GAP_SPACINGS * system.shot_spacing), key=len)
    if band.size >= 3:
        a, b = np.polyfit(p.x[band], above[band], 1)
        band = band[np.abs(above[band] - (a * p.x[band] + b)) <= 3.0 * system.height_sigma]
    return band
