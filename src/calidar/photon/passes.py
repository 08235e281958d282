"""One pass of one beam, ready for CCR extraction: the photons near the CCRs, denoised, with the
ground under them.

A granule's pass is thousands of km long; CCRs sit at a few sites. Only the photons within
``SITE_MARGIN`` of a CCR are denoised and ground-modelled, so a 2 000 km pass costs what its
CCR sites cost, and the along-track coordinates around each CCR come from a local track line
(:meth:`calidar.photon.survey.CCRSurvey.in_track`).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from calidar.errors import CalibrationError
from calidar.photon.denoise import denoise_stages
from calidar.photon.ground import ground_profile

SITE_MARGIN = 600.0  #: m of photons kept on either side of each CCR
GROUND_SAMPLE = 1.0  #: m


@dataclass(frozen=True)
class SystemParameters:
    """Instrument constants: dead time t_d (s), RMS pulse width σ (s), along-track shot spacing
    d_l (m), detector channels (a CCR return arrives within the dead time, so each channel records
    ≤ 1 photon), pointing jitter σ_j (m, per axis)."""

    dead_time: float = 3.2e-9
    pulse_width: float = 1.0e-9
    shot_spacing: float = 0.7
    #: None: from the beam's strength (16 strong, 4 weak; 16 when unknown)
    channels: int | None = None
    pointing_jitter: float = 0.3

    @property
    def delta_h(self) -> float:
        """Half-height (m) of the CCR photon band: Δh = min(c·t_d/2, 3·c·σ)."""
        from calidar.photon.parameters import C_LIGHT

        return min(C_LIGHT * self.dead_time / 2.0, 3.0 * C_LIGHT * self.pulse_width)

    @property
    def height_sigma(self) -> float:
        """Range noise of one photon (m): c·σ/2."""
        from calidar.photon.parameters import C_LIGHT

        return C_LIGHT * self.pulse_width / 2.0

    def channels_of(self, beam) -> int:
        return self.channels or beam.channels or 16


@dataclass
class PassData:
    """The photons of one beam of one pass near its CCRs (sorted by along-track x) and its CCRs'
    track positions."""

    name: str
    #: the beam's parameter group: 'spot N' when the laser spot is known, else the ground track
    group_key: str
    label: str  #: e.g. 'gt1l (spot 6, weak)'
    channels: int
    x: np.ndarray  #: m, along track
    h: np.ndarray  #: m
    shot: np.ndarray  #: shot id of each photon
    signal: np.ndarray  #: both denoising stages (surface photons)
    coarse: np.ndarray  #: histogram stage only (CCR photons are taken from these)
    ground: object  #: callable x (m) → ground height (m)
    ccr_x: np.ndarray  #: m, along-track position of every surveyed CCR (NaN: not near this pass)
    ccr_y: np.ndarray  #: m, cross-track position (left positive)
    ccr_distance: np.ndarray  #: m, from each CCR to the nearest photon of the pass
    photons_total: int  #: photons of the whole beam
    group: int = 0  #: parameter group index (set by the calibration)
    above_ground: np.ndarray | None = None  #: h − ground(x)
    #: m, the ground model sampled every GROUND_SAMPLE m (for plots)
    ground_x: np.ndarray | None = None
    ground_h: np.ndarray | None = None


def prepare_pass(beam, survey, system: SystemParameters, name: str | None = None,
                 reach: float = 17.5) -> PassData:
    """Locate the CCRs in the beam's track, keep the photons of their sites, denoise them and
    model the ground."""
    name = name or f"{beam.source}:{beam.beam}"
    if len(beam) == 0:
        raise CalibrationError(f"{name}: no photons")
    x_all = beam.x
    xk, yk, dist = survey.in_track(x_all, beam.lat, beam.lon)
    near = np.isfinite(xk) & (dist <= reach + 1_000.0)
    keep = np.zeros(x_all.size, bool)
    order = np.argsort(x_all, kind="stable") if np.any(np.diff(x_all) < 0) else None
    xs = x_all if order is None else x_all[order]
    for xc in xk[near]:
        lo, hi = np.searchsorted(xs, [xc - SITE_MARGIN, xc + SITE_MARGIN])
        keep[lo:hi] = True
    idx = np.flatnonzero(keep) if order is None else np.sort(order[keep])
    idx = idx[np.argsort(x_all[idx], kind="stable")]
    x, h, shot = x_all[idx], beam.h[idx], beam.shot_index()[idx]
    key = f"spot {beam.spot}" if beam.spot else beam.beam
    beam_of = (name, key, beam.label, system.channels_of(beam))
    ccrs = (np.where(near, xk, np.nan), yk, dist, len(beam))
    if x.size < 10:
        none = np.zeros(x.size, bool)
        return PassData(*beam_of, x, h, shot, none, none.copy(), None, *ccrs)
    coarse, signal = denoise_stages(x, h, system.shot_spacing)
    if signal.sum() < 10:
        raise CalibrationError(f"{name}: denoising kept {signal.sum()} photons near the CCRs; no "
                               "surface found")
    ground = ground_profile(x[signal], h[signal])
    gx = np.unique(np.round(x / GROUND_SAMPLE) * GROUND_SAMPLE)
    return PassData(*beam_of, x, h, shot, signal, coarse, ground, *ccrs,
                    above_ground=h - ground(x), ground_x=gx, ground_h=ground(gx))
