"""The CCR calibration's parameters, units and the footprint formula — written once, used by the
likelihood, the fit, the report and the simulator.

Conventions: true footprint position = reported + bias; along-track positive in the direction
of travel; cross-track positive to the left of it. ``footprint_diameter`` D is the 50 %-detection
diameter of a CCR: the diameter within which a CCR is detected (≥ 1 photon) on at least half of
the shots. Nuisance parameters: ``ccr_peak_photons`` Λ (mean CCR photons of a shot centred on the
CCR) and ``shot_loss_rate`` q (fraction of shots whose CCR return is lost).
"""

from __future__ import annotations

import numpy as np

C_LIGHT = 299_792_458.0  #: m/s
#: The calibrated geolocation parameters (m).
GEOLOCATION = ("along_track_bias", "cross_track_bias", "footprint_diameter")
#: Nuisance parameters, estimated with them (photons, fraction).
NUISANCE = ("ccr_peak_photons", "shot_loss_rate")
#: Every parameter of one beam, in the order of the likelihood's arrays.
NAMES = GEOLOCATION + NUISANCE
UNITS = {"along_track_bias": "m", "cross_track_bias": "m", "footprint_diameter": "m",
         "ccr_peak_photons": "1", "shot_loss_rate": "1"}
BIASES = GEOLOCATION[:2]
LN2 = float(np.log(2.0))


def footprint_radius_1e2(diameter, peak_photons):
    """1/e² radius w (m) of a Gaussian footprint whose 50 %-detection diameter is ``diameter`` (m)
    for a CCR returning ``peak_photons`` Λ (mean, at the centre): Λ·exp(−2(D/2)²/w²) = ln 2, so
    w = (D/2)·√(2 / ln(Λ / ln 2)). Arrays or scalars; NaN for Λ ≤ ln 2 (never detected at 50 %)."""
    with np.errstate(invalid="ignore", divide="ignore"):
        log_ratio = np.log(np.asarray(peak_photons, float) / LN2)  # ln(Λ / ln 2)
        return 0.5 * np.asarray(diameter, float) * np.sqrt(2.0 / log_ratio)


def parameter_name(base: str, group: str | None) -> str:
    """The solution's name of a parameter: ``base`` for one beam (or a shared bias), else
    ``base[group]`` (group: the beam's key, e.g. 'gt1l' or 'spot 3')."""
    return base if group is None else f"{base}[{group}]"
