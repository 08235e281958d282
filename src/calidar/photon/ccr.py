"""Geolocation calibration of a photon-counting lidar from corner-cube retroreflector (CCR) returns.

After the method of Magruder et al. (2019, 2021; ICESat-2 CCR arrays at White Sands) as
formulated for a grid search over footprint diameter and bias:

1. denoise (coarse histogram, then DBSCAN) and model the ground (smoothing spline);
2. CCR photons are the photons h_p ± Δh above the ground, Δh = min(c·t_d/2, 3·c·σ)
   (t_d detector dead time, σ RMS pulse width), within a search window around each CCR;
   one segment per CCR: the along-track run of shots that saw it (gaps ≤ 7 d_l). They are
   taken after the histogram stage only: DBSCAN drops the sparse ends of weak CCR runs
   (CCR near the footprint edge, lost shots), and the height band, the search window and
   the run split already reject the background;
3. per segment: photon and shot counts, first/last shot, length l (span), midpoint, a
   least-squares line h = a·x + b (angle, intercept; photons > 3σ off it are dropped), and
   the shots missing inside the span (stepping the shot spacing d_l);
4. grid search: for each footprint diameter D (range, step Δr) and cross-track bias b_c,
   every CCR's theoretical cross-track distance from the footprint track is
   √((D/2)² − (L/2)²) on either side of the track, with candidate chord lengths
   L = l + Δl·k (k = 0 … enough to restore the missing shots); the cross-track RMS of
   surveyed minus theoretical positions (best side and candidate per CCR) plus the
   along-track RMS of (surveyed − midpoint − b_a) is minimised.

Which side of the track a single CCR lies on is NOT determined by its chord alone (the
chord fixes |y − b_c| only). With two or more CCRs at different cross-track offsets the
sides are fixed jointly: the grid search over b_c tests both sides of each CCR and only
one assignment fits all chords with one footprint diameter. One lit CCR is refused.

Beyond the published method: the grid optimum starts a least squares
(:func:`calidar.adjust.solve`) on every shot's CCR photon count in each CCR's window (shots
that recorded no photon at all, absent from ATL03, are put back as empty): the detection
indicator and the count given detection under a Gaussian footprint blurred by the known
pointing jitter (:func:`mean_ccr_photons`), with the CCR peak photons Λ and the shot-loss
rate q as nuisance parameters; solved twice, the second time weighted by the model's own
binomial variances. σ by bootstrap over CCRs and over the shots of each segment; the
Cramér–Rao bound (:mod:`calidar.photon.likelihood`) at the estimate is reported beside it, to
show how well the pass can fix the diameter at all. Several passes are solved jointly (one
bias for all of them).

Conventions: true footprint position = reported + bias; along-track positive in the
direction of travel; cross-track positive to the left of it.
"""

from __future__ import annotations

import csv
from dataclasses import dataclass, field, replace
from pathlib import Path
from warnings import catch_warnings, simplefilter

import numpy as np

from calidar.adjust import Parameter, ParameterSet, solve
from calidar.errors import CalibrationError, InputError
from calidar.io.atl03 import PhotonBeam
from calidar.photon.denoise import denoise_stages
from calidar.photon.ground import ground_profile
from calidar.photon.likelihood import cramer_rao_sigma, footprint_radius_1e2
from calidar.photon.track import TrackLine

C_LIGHT = 299_792_458.0  #: m/s
PARAMETERS = ("along_track_bias", "cross_track_bias", "footprint_diameter")


@dataclass(frozen=True)
class SystemParameters:
    """Instrument constants: dead time t_d (s), RMS pulse width σ (s), along-track shot spacing d_l (m),
    detector channels (a CCR return arrives within the dead time, so each channel records ≤ 1 photon)."""

    dead_time: float = 3.2e-9
    pulse_width: float = 1.0e-9
    shot_spacing: float = 0.7
    channels: int = 16  #: detector channels of the beam (ATLAS strong beam: 16)
    pointing_jitter: float = 0.3  #: m, RMS shot-to-shot footprint position noise on each axis

    @property
    def delta_h(self) -> float:
        """Half-height (m) of the CCR photon band: Δh = min(c·t_d/2, 3·c·σ)."""
        return min(C_LIGHT * self.dead_time / 2.0, 3.0 * C_LIGHT * self.pulse_width)

    @property
    def height_sigma(self) -> float:
        """Range noise of one photon (m): c·σ/2."""
        return C_LIGHT * self.pulse_width / 2.0


@dataclass(frozen=True)
class SearchSettings:
    """Grid-search and solver settings (m unless stated)."""

    diameter_min: float = 8.0
    diameter_max: float = 15.0
    diameter_step: float = 0.1  #: Δr
    length_step: float = 0.1  #: Δl
    bias_step: float = 0.05  #: cross-track bias grid step
    max_bias: float = 10.0  #: largest |bias| searched for (sets the CCR search window)
    bootstrap: int = 200  #: replicates (0 = none)
    seed: int = 0


@dataclass
class CCRSurvey:
    """Surveyed CCRs: geodetic (rad) or track (m) positions, and pole heights above ground (m)."""

    ids: list[str]
    height: np.ndarray
    lat: np.ndarray | None = None
    lon: np.ndarray | None = None
    x: np.ndarray | None = None
    y: np.ndarray | None = None
    source: str | None = None

    def in_track(self, x_m: np.ndarray, lat_rad: np.ndarray, lon_rad: np.ndarray,
                 local_m: float = 1000.0) -> tuple[np.ndarray, np.ndarray]:
        """(along-track x, cross-track y left positive) of every CCR (m) in the track of a pass
        whose photons are at along-track x_m and lat/lon (rad); the track line is fitted to the
        photons within ``local_m`` of each CCR (a long pass is not straight in a tangent plane)."""
        if self.lat is None:
            return self.x, self.y
        xk, yk = TrackLine.fit(x_m, lat_rad, lon_rad).to_track(self.lat, self.lon)
        step = max(1, x_m.size // 200_000)  # a subsample is plenty for a line fit
        xs, la, lo = x_m[::step], lat_rad[::step], lon_rad[::step]
        for k in range(xk.size):
            near = np.abs(xs - xk[k]) <= local_m
            if near.sum() >= 10:
                xl, yl = TrackLine.fit(xs[near], la[near], lo[near]).to_track(self.lat[k:k + 1], self.lon[k:k + 1])
                xk[k], yk[k] = xl[0], yl[0]
        return xk, yk


CCR_COLUMNS = ({"id", "lat", "lon", "height"}, {"id", "x", "y", "height"})


def read_ccr_csv(path: str | Path) -> CCRSurvey:
    """Read a CCR survey CSV: ``id,lat,lon,height`` (deg, deg, m above ground) or
    ``id,x,y,height`` (m along track, m cross-track left of the pass's reported track, m; these
    belong to one pass's track, so :func:`calibrate` refuses them with several passes)."""
    path = Path(path)
    with open(path, newline="", encoding="utf-8") as fh:
        rows = list(csv.reader(fh))
    if not rows:
        raise InputError(path, "header", "empty file; expected id,lat,lon,height or id,x,y,height")
    header = [c.strip().lower() for c in rows[0]]
    cols = set(header)
    unknown = sorted(cols - {"id", "lat", "lon", "x", "y", "height"})
    if unknown or cols not in CCR_COLUMNS:
        what = f"unknown column(s) {', '.join(unknown)}" if unknown else f"columns {','.join(header)}"
        raise InputError(path, "header", f"{what}; expected id,lat,lon,height or id,x,y,height")
    data = [r for r in rows[1:] if any(c.strip() for c in r)]
    if not data:
        raise InputError(path, "rows", "no CCRs listed")
    vals = {c: [] for c in header}
    for n, r in enumerate(data, start=2):
        if len(r) != len(header):
            raise InputError(path, f"line {n}", f"expected {len(header)} values, got {len(r)}")
        for c, v in zip(header, r):
            if c == "id":
                vals[c].append(v.strip())
                continue
            try:
                vals[c].append(float(v))
            except ValueError:
                raise InputError(path, f"line {n}: {c}", f"expected a number, got {v!r}") from None
    if len(set(vals["id"])) != len(vals["id"]):
        raise InputError(path, "id", "CCR ids must be unique")
    height = np.asarray(vals["height"])
    if "lat" in cols:
        lat, lon = np.asarray(vals["lat"]), np.asarray(vals["lon"])
        if np.any(np.abs(lat) > 90) or np.any(np.abs(lon) > 360):
            raise InputError(path, "lat/lon", "expected degrees (|lat| ≤ 90, |lon| ≤ 360)")
        return CCRSurvey(vals["id"], height, lat=np.radians(lat), lon=np.radians(lon), source=str(path))
    return CCRSurvey(vals["id"], height, x=np.asarray(vals["x"]), y=np.asarray(vals["y"]), source=str(path))


@dataclass
class PassData:
    """One pass ready for CCR extraction: photons (x along track m, h m), shot ids, signal mask, ground."""

    name: str
    x: np.ndarray
    h: np.ndarray
    shot: np.ndarray
    signal: np.ndarray  #: both denoising stages (surface photons)
    coarse: np.ndarray  #: histogram stage only (CCR photons are taken from these)
    ground: object  #: callable x (m) → ground height (m)
    lat: np.ndarray  #: rad, photon latitudes
    lon: np.ndarray  #: rad


def prepare_pass(beam: PhotonBeam, system: SystemParameters, name: str | None = None) -> PassData:
    """Denoise a beam and model its ground."""
    x, h = beam.x, beam.h
    coarse, signal = denoise_stages(x, h, system.shot_spacing)
    if signal.sum() < 10:
        raise CalibrationError(f"{name or beam.source}: {beam.beam}: denoising kept {signal.sum()} photons; no surface found")
    ground = ground_profile(x[signal], h[signal])
    return PassData(name or str(beam.source), x, h, beam.shot_index(), signal, coarse, ground,
                    beam.lat, beam.lon)


@dataclass
class CCRSegment:
    """The run of shots of one pass that returned photons from one CCR (distances m, angle rad)."""

    pass_name: str
    ccr_id: str
    x_ccr: float  #: surveyed along-track position
    y_ccr: float  #: surveyed cross-track position (left positive)
    pole_height: float
    photon_index: np.ndarray  #: indices into the pass's photons
    shot_x: np.ndarray  #: along-track positions of the shots that saw the CCR (sorted)
    angle: float  #: slope angle of the least-squares line h(x) through the CCR photons
    intercept: float  #: line height above ground at the midpoint
    shot_counts: np.ndarray  #: CCR photons recorded per shot of ``shot_x``
    window_x: np.ndarray  #: along-track positions of every shot of the pass in the search window
    window_counts: np.ndarray  #: photons in the CCR's count band recorded by each of those shots (mostly 0)
    background: float = 0.0  #: mean background photons per shot in the count band

    @property
    def central_count(self) -> float:
        """Mean CCR photons per detecting shot in the central half of the segment."""
        c = np.abs(self.shot_x - self.midpoint) <= max(self.length / 4.0, 1e-9)
        return float(self.shot_counts[c].mean()) if c.any() else float(self.shot_counts.mean())

    @property
    def first(self) -> float:
        return float(self.shot_x[0])

    @property
    def last(self) -> float:
        return float(self.shot_x[-1])

    @property
    def length(self) -> float:
        """Span l between the first and last shot that saw the CCR."""
        return self.last - self.first

    @property
    def midpoint(self) -> float:
        """Mean along-track position of the shots that saw the CCR (robust to a stray edge photon)."""
        return float(self.shot_x.mean())

    @property
    def n_shots(self) -> int:
        return int(self.shot_x.size)

    def missing_shots(self, spacing: float) -> int:
        """Shots inside the span that returned nothing from the CCR."""
        return int(round(self.length / spacing)) + 1 - self.n_shots

    def summary(self, spacing: float) -> dict:
        return {
            "pass": self.pass_name, "ccr": self.ccr_id, "x_ccr": self.x_ccr, "y_ccr": self.y_ccr,
            "pole_height": self.pole_height, "n_photons": int(self.photon_index.size), "n_shots": self.n_shots,
            "missing_shots": self.missing_shots(spacing), "first": self.first, "last": self.last,
            "length": self.length, "midpoint": self.midpoint, "angle_rad": self.angle,
            "intercept_above_ground": self.intercept, "central_photons_per_shot": self.central_count,
        }


BACKGROUND_BAND = 4.0  #: m of height above the CCR count band where the background rate is measured


def with_silent_shots(x: np.ndarray, counts: np.ndarray, spacing: float) -> tuple[np.ndarray, np.ndarray]:
    """Insert the shots that recorded no photon at all (absent from ATL03) with count 0:
    where consecutive shots at along-track x (m, increasing) are ≥ 1.5 spacings apart."""
    step = np.diff(x)
    gaps = np.rint(step / spacing).astype(int)
    missing = np.clip(gaps - 1, 0, None)
    if not missing.any():
        return x, counts
    i = np.repeat(np.arange(gaps.size), missing)
    j = np.arange(i.size) - np.repeat(np.cumsum(missing) - missing, missing) + 1  # 1 … missing within each gap
    xs = np.concatenate([x, x[i] + j * step[i] / gaps[i]])
    order = np.argsort(xs, kind="stable")
    return xs[order], np.concatenate([counts, np.zeros(i.size, counts.dtype)])[order]


def extract_segments(p: PassData, survey: CCRSurvey, system: SystemParameters, settings: SearchSettings
                     ) -> tuple[list[CCRSegment], list[str]]:
    """One segment per CCR of the survey lit in pass ``p``; warnings for the others."""
    xk, yk = survey.in_track(p.x, p.lat, p.lon)
    reach = settings.diameter_max / 2.0 + settings.max_bias
    gap = 7.0 * system.shot_spacing
    above = p.h - p.ground(p.x)
    xmin, xmax = p.x.min(), p.x.max()
    segments, warnings = [], []
    for k, cid in enumerate(survey.ids):
        if not (xmin - reach <= xk[k] <= xmax + reach):
            warnings.append(f"{p.name}: CCR {cid} lies outside the pass (along-track {xk[k]:.1f} m, "
                            f"photons cover {xmin:.1f}–{xmax:.1f} m); ignored")
            continue
        if abs(yk[k]) > reach:
            warnings.append(f"{p.name}: CCR {cid} is {yk[k]:+.1f} m across the track, beyond any footprint; ignored")
            continue
        band = p.coarse & (np.abs(p.x - xk[k]) <= reach) & (np.abs(above - survey.height[k]) <= system.delta_h)
        idx = np.flatnonzero(band)
        idx = idx[np.argsort(p.x[idx], kind="stable")]
        if idx.size:
            runs = np.split(idx, np.flatnonzero(np.diff(p.x[idx]) > gap) + 1)
            idx = max(runs, key=len)
        if idx.size >= 3:
            a, b = np.polyfit(p.x[idx], above[idx], 1)
            idx = idx[np.abs(above[idx] - (a * p.x[idx] + b)) <= 3.0 * system.height_sigma]
        shots = np.unique(p.shot[idx])
        if shots.size < 3:
            warnings.append(f"{p.name}: no CCR photons found for CCR {cid} "
                            f"({shots.size} shots in the {survey.height[k]:.2f} ± {system.delta_h:.2f} m band)")
            continue
        a, b = np.polyfit(p.x[idx] - p.x[idx].mean(), above[idx], 1)
        _, one, counts = np.unique(p.shot[idx], return_index=True, return_counts=True)
        order = np.argsort(p.x[idx][one])
        shot_x = p.x[idx][one][order]  # photons of one shot share its along-track position
        # every photon of the window (not only the run, not only the denoised ones: the sparse tails
        # of the footprint profile carry the diameter) within the count band around the CCR line,
        # and the background rate from an empty band above it
        win = np.flatnonzero(np.abs(p.x - xk[k]) <= reach)
        off = above[win] - (a * (p.x[win] - p.x[idx].mean()) + b)
        half = min(3.0 * system.height_sigma, system.delta_h)
        wshots, wone = np.unique(p.shot[win], return_index=True)
        wcounts = np.bincount(np.searchsorted(wshots, p.shot[win][np.abs(off) <= half]), minlength=wshots.size)
        wx, wcounts = with_silent_shots(p.x[win][wone], wcounts, system.shot_spacing)
        n_ref = np.count_nonzero((off > 3.0 * half) & (off <= 3.0 * half + BACKGROUND_BAND))
        background = n_ref / (wx.size * BACKGROUND_BAND) * 2.0 * half
        segments.append(CCRSegment(p.name, cid, float(xk[k]), float(yk[k]), float(survey.height[k]), idx,
                                   shot_x, float(np.arctan(a)), float(b), counts[order], wx, wcounts, background))
    return segments, warnings


def shot_loss_rate(segments: list[CCRSegment], spacing: float, with_count: bool = False):
    """Fraction of shots lost inside the central half of the segments (where detection is sure);
    with ``with_count`` also the number of shots it was counted over."""
    det = exp = 0
    for s in segments:
        lo, hi = s.midpoint - s.length / 4.0, s.midpoint + s.length / 4.0
        det += int(np.count_nonzero((s.shot_x >= lo) & (s.shot_x <= hi)))
        exp += int(np.floor((hi - s.first) / spacing + 1e-6) - np.ceil((lo - s.first) / spacing - 1e-6) + 1)
    q = float(np.clip(1.0 - det / exp, 0.0, 0.8)) if exp else 0.0
    return (q, exp) if with_count else q


def chords(segments: list[CCRSegment], spacing: float, loss: float) -> np.ndarray:
    """Chord length per segment (m): n_shots·d_l / (1 − q)."""
    return np.array([s.n_shots for s in segments]) * spacing / (1.0 - loss)


@dataclass
class GridResult:
    """The method's grid search: RMS (m) over footprint diameters × cross-track biases."""

    diameters: np.ndarray
    cross_biases: np.ndarray
    rms_cross: np.ndarray  #: (n_diameters, n_biases)
    rms_along: float
    along_bias: float
    cross_bias: float
    diameter: float
    sides: list[int]  #: +1 CCR left of the footprint track, −1 right

    @property
    def total(self) -> np.ndarray:
        return self.rms_cross + self.rms_along

    def to_dict(self) -> dict:
        return {"along_track_bias": self.along_bias, "cross_track_bias": self.cross_bias,
                "footprint_diameter": self.diameter, "rms_along": self.rms_along,
                "rms_cross": float(self.rms_cross.min()), "ccr_sides": self.sides, "unit": "m"}


def grid_search(segments: list[CCRSegment], spacing: float, settings: SearchSettings) -> GridResult:
    """Minimise along-track RMS + cross-track RMS over footprint diameter and cross-track bias."""
    y = np.array([s.y_ccr for s in segments])
    resid_a = np.array([s.x_ccr - s.midpoint for s in segments])
    b_a = float(resid_a.mean())
    rms_a = float(np.sqrt(np.mean((resid_a - b_a) ** 2)))
    diam = np.arange(settings.diameter_min, settings.diameter_max + 1e-9, settings.diameter_step)
    half = settings.diameter_max / 2.0
    biases = np.arange(y.min() - half, y.max() + half + 1e-9, settings.bias_step)
    r = diam[:, None, None] / 2.0
    sq = np.zeros((diam.size, biases.size))
    for s, yi in zip(segments, y):
        n_cand = int(np.ceil(s.missing_shots(spacing) * spacing / settings.length_step)) + 1
        lengths = s.n_shots * spacing + settings.length_step * np.arange(n_cand)
        dist = np.sqrt(np.clip(r**2 - (lengths[None, None, :] / 2.0) ** 2, 0.0, None))  # (nD, 1, nL)
        over = np.clip(lengths[None, None, :] / 2.0 - r, 0.0, None)
        off = np.abs(yi - biases)[None, :, None]
        err = np.hypot(off - dist, over).min(axis=2)
        sq += err**2
    rms_c = np.sqrt(sq / len(segments))
    i, j = np.unravel_index(np.argmin(rms_c + rms_a), rms_c.shape)
    sides = [int(np.sign(yi - biases[j]) or 1) for yi in y]
    return GridResult(diam, biases, rms_c, rms_a, b_a, float(biases[j]), float(diam[i]), sides)


#: Names of the refined parameters: PARAMETERS + the CCR peak photon rate Λ and the shot-loss rate q.
PROFILE_PARAMETERS = (*PARAMETERS, "ccr_peak_photons", "shot_loss_rate")
#: A-priori σ of a detection indicator (0/1) and of a photon count, for the least squares weights.
SIGMA_DETECTION, SIGMA_COUNT = 0.4, 1.0


def mean_ccr_photons(x_shot: np.ndarray, x_ccr: np.ndarray, y_ccr: np.ndarray, v: dict, jitter: float) -> np.ndarray:
    """Mean CCR photons λ̄ per shot (reported along-track x_shot, CCR at x_ccr, y_ccr; m).

    λ = Λ·exp(−2r²/w²) with r the distance from the true footprint centre (reported x + along
    bias, cross bias) to the CCR and w the 1/e² radius giving the 50 %-detection diameter D.
    The shot's pointing jitter (σ_j per axis, Gaussian) blurs it: averaged over the jitter,
    each axis's Gaussian of variance w²/4 becomes one of variance w²/4 + σ_j², so
    λ̄ = Λ·w²/(w² + 4σ_j²)·exp(−2r²/(w² + 4σ_j²)) — exact for the mean; the detection
    probability 1 − e^(−λ̄) then errs by O((σ_j/w)⁴)."""
    w2 = footprint_radius_1e2(v["footprint_diameter"], v["ccr_peak_photons"]) ** 2
    b2 = w2 + 4.0 * jitter**2
    r2 = (x_shot + v["along_track_bias"] - x_ccr) ** 2 + (v["cross_track_bias"] - y_ccr) ** 2
    return v["ccr_peak_photons"] * (w2 / b2) * np.exp(-2.0 * r2 / b2)


def profile_model(x_shot: np.ndarray, x_ccr: np.ndarray, y_ccr: np.ndarray, beta: np.ndarray, detected: np.ndarray,
                  v: dict, system: SystemParameters) -> np.ndarray:
    """Expected observations per shot: the detection indicator 1 − P₀ of every shot, then the
    photon count of each detecting shot given detection, E[k]/(1 − P₀), with
    P₀ = e^(−β)·(q + (1 − q)·e^(−λ̄)) and E[k] = (1 − q)·N·(1 − e^(−λ̄/N)) + β.

    λ̄ from :func:`mean_ccr_photons` (Gaussian footprint, Poisson photons, pointing jitter);
    N detector channels each record ≤ 1 photon of a CCR return (it arrives within the dead
    time); q = rate of shots whose CCR return is lost; β = mean background photons per shot
    in the count band (Poisson). Arrays are per shot (x_ccr, y_ccr, β repeated per shot)."""
    n = system.channels
    lam = mean_ccr_photons(x_shot, x_ccr, y_ccr, v, system.pointing_jitter)
    q = v["shot_loss_rate"]
    p_det = 1.0 - np.exp(-beta) * (q + (1.0 - q) * np.exp(-lam))
    mean = (1.0 - q) * n * -np.expm1(-lam[detected] / n) + beta[detected]
    return np.concatenate([p_det, mean / np.clip(p_det[detected], 1e-12, None)])


def model_sigma(x_shot, x_ccr, y_ccr, beta, detected, v: dict, system: SystemParameters) -> np.ndarray:
    """σ of each observation of :func:`profile_model` under the model ``v``: √(P(1−P)) for the
    detection indicators, √(N·π(1−π)) (π = 1 − e^(−λ̄/N), channels hit) for the counts."""
    n = system.channels
    lam = mean_ccr_photons(x_shot, x_ccr, y_ccr, v, system.pointing_jitter)
    q = v["shot_loss_rate"]
    pdet = 1.0 - np.exp(-beta) * (q + (1.0 - q) * np.exp(-lam))
    pi = -np.expm1(-lam[detected] / n)
    return np.concatenate([np.sqrt(np.clip(pdet * (1 - pdet), 0.02, None)),
                           np.sqrt(np.clip(n * pi * (1 - pi), 0.25, None))])


def _profile_data(segments: list[CCRSegment], pick=None, rng=None):
    """Stacked per-shot data (x_shot, x_ccr, y_ccr, counts), optionally resampled, and the
    observation vector [detected (0/1) per shot, counts of the detecting shots]."""
    parts = []
    for i in (range(len(segments)) if pick is None else pick):
        s = segments[i]
        j = np.arange(s.window_x.size) if rng is None else rng.integers(0, s.window_x.size, s.window_x.size)
        parts.append((s.window_x[j], np.full(j.size, s.x_ccr), np.full(j.size, s.y_ccr), np.full(j.size, s.background),
                      s.window_counts[j]))
    xs, xc, yc, beta, c = (np.concatenate(a) for a in zip(*parts))
    det = c > 0
    obs = np.concatenate([det.astype(float), c[det].astype(float)])
    sigma = np.concatenate([np.full(c.size, SIGMA_DETECTION), np.full(int(det.sum()), SIGMA_COUNT)])
    return xs, xc, yc, beta, det, obs, sigma


def bootstrap(segments: list[CCRSegment], start: dict, system: SystemParameters, replicates: int, seed: int) -> np.ndarray:
    """(n, 5) bootstrap re-estimates of PROFILE_PARAMETERS, resampling the CCR segments and,
    within each, the shots of its window (scipy least_squares from ``start``, weights from
    the model at ``start``)."""
    from scipy.optimize import least_squares

    rng = np.random.default_rng(seed)
    x0 = np.array([start[k] for k in PROFILE_PARAMETERS])
    lo, hi = [-np.inf, -np.inf, 1.0, 1.1, -0.5], [np.inf, np.inf, np.inf, np.inf, 0.99]
    x0 = np.clip(x0, np.array(lo) + 1e-6, np.array(hi) - 1e-6)
    out = []
    for _ in range(replicates):
        pick = rng.integers(0, len(segments), len(segments))
        if np.ptp([segments[i].y_ccr for i in pick]) < 0.5:
            continue
        xs, xc, yc, beta, det, obs, _ = _profile_data(segments, pick, rng)
        sig = model_sigma(xs, xc, yc, beta, det, start, system)
        with catch_warnings():  # trf's step control divides by zero on flat directions
            simplefilter("ignore", RuntimeWarning)
            fit = least_squares(
                lambda q: (profile_model(xs, xc, yc, beta, det, dict(zip(PROFILE_PARAMETERS, q)), system) - obs) / sig,
                x0, bounds=(lo, hi), method="trf")
        if fit.success:
            out.append(fit.x)
    return np.array(out).reshape(-1, len(PROFILE_PARAMETERS))


@dataclass
class CCRResult:
    """Calibration outcome: the Solution (JSON schema of calidar.adjust), grid search, segments."""

    solution: object
    grid: GridResult
    segments: list[CCRSegment]
    passes: list[PassData]
    loss_rate: float
    chords: np.ndarray
    warnings: list[str] = field(default_factory=list)


def calibrate(passes: list[PassData], survey: CCRSurvey, system: SystemParameters | None = None,
              settings: SearchSettings | None = None) -> CCRResult:
    """Solve along/cross-track bias and footprint diameter from the CCR returns of one or more passes."""
    system = system or SystemParameters()
    settings = settings or SearchSettings()
    if survey.lat is None and len(passes) > 1:
        raise InputError(survey.source, "columns", f"x,y are along/cross-track positions in ONE pass's track, but "
                         f"{len(passes)} passes were given; give the CCRs as id,lat,lon,height")
    segments, warnings = [], []
    for p in passes:
        s, w = extract_segments(p, survey, system, settings)
        segments += s
        warnings += w
    if not segments:
        raise CalibrationError("no CCR photons found in any pass: " + "; ".join(warnings))
    ys = np.array([s.y_ccr for s in segments])
    if len(segments) < 2 or np.ptp(ys) < 0.5:
        raise CalibrationError(
            f"{len(segments)} lit CCR segment(s) at cross-track offsets {np.round(ys, 2).tolist()} m: need at least two "
            "CCRs at different cross-track offsets (one chord gives |cross-track offset| only, not its side, "
            "and not the footprint diameter)")
    d_l = system.shot_spacing
    loss, n_loss = shot_loss_rate(segments, d_l, with_count=True)
    chord = chords(segments, d_l, loss)
    grid = grid_search(segments, d_l, settings)
    n = len(segments)
    n_ch = system.channels
    xs, xc, yc, beta, det, obs, sig = _profile_data(segments)
    peak = max(float(np.max([s.central_count for s in segments])), 1.0)
    peak0 = float(-n_ch * np.log1p(-min(peak, n_ch - 0.5) / n_ch))  # λ of the brightest centre

    def residuals(v: dict) -> np.ndarray:
        with np.errstate(over="ignore", invalid="ignore"):  # trial steps far out: non-finite → rejected
            return profile_model(xs, xc, yc, beta, det, v, system) - obs

    params = ParameterSet([
        Parameter("along_track_bias", grid.along_bias, "m"),
        Parameter("cross_track_bias", grid.cross_bias, "m"),
        Parameter("footprint_diameter", grid.diameter, "m"),
        Parameter("ccr_peak_photons", max(peak0, 2.0), "1", step=1e-3),
        # the missing shots counted in the chord centres (stepping d_l) are a binomial prior on q
        Parameter("shot_loss_rate", loss, "1", step=1e-4,
                  prior_sigma=float(np.sqrt(max(loss * (1 - loss), 0.05) / max(n_loss, 1)))),
    ])
    sol = solve(residuals, params, sigma=sig, robust=None)
    # re-weight by the model's own variances (binomial detection, binomial channel hits) and re-solve
    sig = model_sigma(xs, xc, yc, beta, det, sol.values, system)
    sol = solve(residuals, ParameterSet([replace(p, value=sol.values[p.name]) for p in params]), sigma=sig,
                robust=None)
    boot = (bootstrap(segments, sol.values, system, settings.bootstrap, settings.seed)
            if settings.bootstrap else np.zeros((0, len(PROFILE_PARAMETERS))))
    ls_sigma = dict(sol.sigma)
    q = min(max(sol.values["shot_loss_rate"], 0.0), 0.95)
    crb = cramer_rao_sigma(xs, xc, yc, dict(sol.values, shot_loss_rate=q), n_ch, system.pointing_jitter)
    # a few replicates of a 2-CCR pass run off (a wild Λ): drop those outside the searched
    # diameter range or with a bias beyond the searched reach before the covariance
    v = sol.values
    kept = boot[(boot[:, 2] >= settings.diameter_min) & (boot[:, 2] <= settings.diameter_max)
                & (np.abs(boot[:, 0] - v["along_track_bias"]) <= settings.max_bias)
                & (np.abs(boot[:, 1] - v["cross_track_bias"]) <= settings.max_bias)]
    if kept.shape[0] >= 20:
        sol = replace(sol, covariance=np.cov(kept.T))
        sigma_source = (f"bootstrap ({kept.shape[0]} replicates over CCRs and shots"
                        + (f"; {boot.shape[0] - kept.shape[0]} run-off replicates dropped)" if kept.shape[0] < boot.shape[0]
                           else ")"))
    elif settings.bootstrap:
        sigma_source = "least squares (too few CCRs for a bootstrap)"
        warnings.append("σ from least squares only: the bootstrap needs CCRs at ≥ 2 cross-track offsets")
    else:
        sigma_source = "least squares (bootstrap off)"
    if n <= 3:
        warnings.append(f"only {n} CCR segments: few CCR profiles for four footprint parameters; "
                        "treat the footprint diameter with care")
    sol.warnings.extend(warnings)
    sol.extra.update({
        "method": "CCR chord grid search, then least squares on the per-shot CCR photon counts",
        "sigma_source": sigma_source,
        "least_squares_sigma": {k: float(v) for k, v in ls_sigma.items()},
        "cramer_rao_sigma": crb,
        "grid_search": grid.to_dict(),
        "shot_loss_rate": loss,
        "delta_h": system.delta_h,
        "system": {"dead_time_s": system.dead_time, "pulse_width_s": system.pulse_width, "shot_spacing_m": d_l,
                   "channels": system.channels, "pointing_jitter_m": system.pointing_jitter},
        "segments": [dict(s.summary(d_l), chord=float(c)) for s, c in zip(segments, chord)],
        "passes": [p.name for p in passes],
    })
    return CCRResult(sol, grid, segments, passes, loss, chord, warnings)
