"""The structural errors of each scanner model, in the units people give them, and the
error-free scanner they perturb.

An :class:`ErrorSource` names one error (``delta_r``), its user unit (deg, ratio, ppm), the
``calidar scanner analyze`` option that sets it, the range of magnitudes accepted there, and
how a magnitude (SI) maps onto the scanner's parameters — whole (``apply``) and, for the
separability analysis, linearised into independent components (the eccentricity's phase C is
undefined at ε = 0, so it is split into ε/r·cos C and ε/r·sin C; a wedge axis tilt into its x
and y parts).
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from calidar.errors import InputError
from calidar.scanners import LinearScanner, PalmerScanner, Scanner, WedgeScanner

ARCSEC = np.pi / (180.0 * 3600.0)  #: one arcsecond in rad
MODELS = ("palmer", "wedge", "linear")
MODEL_NAMES = {"palmer": "Palmer", "wedge": "rotating-wedge", "linear": "linear"}  #: in sentences


@dataclass(frozen=True)
class ErrorSource:
    """One structural error: its user unit and how a magnitude (SI) maps to model parameters."""

    name: str  #: key in the JSON summary
    label: str
    unit: str  #: user unit: "deg", "ratio" or "ppm"
    option: str  #: the ``calidar scanner analyze`` option giving it (user unit)
    limit: float  #: largest magnitude accepted, user unit (structural errors are small)
    apply: Callable[[float], dict[str, float]]  #: magnitude (SI) → scanner parameters
    #: linearised parts (SI)
    components: tuple[tuple[str, Callable[[float], dict[str, float]]], ...] = ()
    low: float | None = None  #: smallest magnitude accepted (None: −limit)
    symbol: str = ""  #: short name in sentences (δ_L); default: the label

    @property
    def short(self) -> str:
        return self.symbol or self.label

    def to_user(self, value_si: float) -> float:
        return float({"deg": np.degrees(value_si), "ppm": value_si * 1e6}.get(self.unit, value_si))

    def to_si(self, value_user: float) -> float:
        si = {"deg": np.radians(value_user), "ppm": value_user * 1e-6}
        return float(si.get(self.unit, value_user))

    def parts(self) -> tuple[tuple[str, Callable[[float], dict[str, float]]], ...]:
        """The linearised components (name, magnitude SI → parameters); the error itself when
        it has none."""
        return self.components or ((self.name, self.apply),)


def _eccentricity(phase_rad: float) -> ErrorSource:
    """Encoder eccentricity ε/r at phase C; linearised as ε/r·cos C (C = 0) and ε/r·sin C
    (C = 90°)."""
    def at(c):
        return lambda e: {"eccentricity_ratio": e, "eccentricity_phase": c}

    linearised = (("eccentricity_cos", at(0.0)), ("eccentricity_sin", at(np.pi / 2)))
    return ErrorSource("eccentricity", "encoder eccentricity ε/r", "ratio", "--eccentricity", 0.1,
                       at(phase_rad), linearised, low=0.0, symbol="ε/r")


def _palmer_sources() -> list[ErrorSource]:
    """δ_L and δ_R of a Palmer scanner (degrees at the edge)."""
    return [ErrorSource("delta_l", "laser–axis angle error δ_L", "deg", "--delta-l", 10.0,
                        lambda d: {"delta_l": d}, symbol="δ_L"),
            ErrorSource("delta_r", "mirror-normal–axis angle error δ_R", "deg", "--delta-r", 10.0,
                        lambda d: {"delta_r": d}, symbol="δ_R")]


def _wedge_sources(axis_tilt_azimuth_rad: float) -> list[ErrorSource]:
    """The wedge angle error and the rotation-axis tilt (toward ``axis_tilt_azimuth_rad``,
    linearised along x and y) of a wedge scanner."""
    ca, sa = np.cos(axis_tilt_azimuth_rad), np.sin(axis_tilt_azimuth_rad)
    tilt_parts = (("axis_tilt_x", lambda t: {"wedge_axis_tilt_x": t}),
                  ("axis_tilt_y", lambda t: {"wedge_axis_tilt_y": t}))
    return [ErrorSource("wedge_angle_error", "wedge angle error Δα", "deg", "--wedge-angle-error",
                        10.0, lambda d: {"wedge_angle_error": d}, symbol="Δα"),
            ErrorSource("axis_tilt", "rotation-axis tilt", "deg", "--axis-tilt", 10.0,
                        lambda t: {"wedge_axis_tilt_x": t * ca, "wedge_axis_tilt_y": t * sa},
                        tilt_parts, low=0.0)]


def _linear_sources() -> list[ErrorSource]:
    """The scan-angle offset (deg) and scale (ppm) of a linear scanner."""
    return [ErrorSource("scan_angle_offset", "scan-angle offset", "deg", "--scan-angle-offset",
                        10.0, lambda d: {"scan_angle_offset": d}),
            ErrorSource("scan_angle_scale", "scan-angle scale", "ppm", "--scan-angle-scale", 1e5,
                        lambda s: {"scan_angle_scale": s})]


def error_sources(model: str, eccentricity_phase_rad: float = 0.0,
                  axis_tilt_azimuth_rad: float = 0.0) -> list[ErrorSource]:
    """The structural errors of a model (``palmer``, ``wedge`` or ``linear``)."""
    if model == "palmer":
        return [_eccentricity(eccentricity_phase_rad), *_palmer_sources()]
    if model == "wedge":
        return [_eccentricity(eccentricity_phase_rad), *_wedge_sources(axis_tilt_azimuth_rad)]
    if model == "linear":
        return _linear_sources()
    raise InputError(None, "--model", f"expected one of {', '.join(MODELS)}, got {model!r}")


#: Example magnitudes (user units) analysed when none is given: the published Palmer example values.
DEFAULT_ERRORS = {
    "palmer": {"eccentricity": 15e-6 / 0.075, "delta_l": 0.02, "delta_r": 0.02},
    "wedge": {"eccentricity": 15e-6 / 0.075, "wedge_angle_error": 0.02, "axis_tilt": 0.02},
    "linear": {"scan_angle_offset": 0.02, "scan_angle_scale": 100.0},
}


def build_scanner(model: str, *, axis_angle_deg: float = 45.0, mirror_tilt_deg: float = 7.5,
                  wedge_angle_deg: float = 20.0, refractive_index: float = 1.5168) -> Scanner:
    """The error-free scanner of a model with the given design geometry (degrees at this edge)."""
    if model == "palmer":
        return PalmerScanner(np.radians(axis_angle_deg), np.radians(mirror_tilt_deg))
    if model == "wedge":
        return WedgeScanner(np.radians(wedge_angle_deg), refractive_index)
    if model == "linear":
        return LinearScanner()
    raise InputError(None, "--model", f"expected one of {', '.join(MODELS)}, got {model!r}")
