"""What a structural-error analysis is asked for (``calidar scanner analyze``), in the units
people give it, with every number checked against its physical range (one table, :data:`LIMITS`).
"""

from __future__ import annotations

from dataclasses import dataclass, field, fields

import numpy as np

from calidar.errors import InputError
from calidar.scanners.sources import MODELS, error_sources
from calidar.validate import integer, number

#: Largest ``--points``: the curves are smooth (720 points resolve their maxima to 1e-5), and the
#: displacement arrays, CSV files and plots grow with the count (≈ 1 kB per point over all outputs).
MAX_POINTS = 100_000
MIN_POINTS = 8

#: field → (option, low, high, unit, low excluded, high excluded)
LIMITS: dict[str, tuple[str, float, float, str, bool, bool]] = {
    "range_m": ("--range", 0.0, 1e6, "m", True, False),
    "spec_arcsec": ("--spec-arcsec", 0.0, 36000.0, "arcsec", True, False),
    "phase_deg": ("--phase", -360.0, 360.0, "deg", False, False),
    "axis_tilt_azimuth_deg": ("--axis-tilt-azimuth", -360.0, 360.0, "deg", False, False),
    "grating_radius_mm": ("--grating-radius-mm", 0.0, 1000.0, "mm", True, False),
    "fov_deg": ("--fov", 0.0, 360.0, "deg", True, False),
    "axis_angle_deg": ("--axis-angle", 0.0, 90.0, "deg", True, True),
    "mirror_tilt_deg": ("--mirror-tilt", 0.0, 90.0, "deg", True, True),
    "wedge_angle_deg": ("--wedge-angle", 0.0, 90.0, "deg", True, True),
    "refractive_index": ("--refractive-index", 1.0, 4.0, "", True, False),
}


@dataclass(frozen=True)
class AnalysisSettings:
    """A structural-error analysis: model, range, error magnitudes (user units: deg, ratio, ppm by
    error name; empty: the published example values) and the design geometry. :meth:`checked`
    validates every field."""

    model: str
    range_m: float
    errors: dict[str, float] = field(default_factory=dict)
    spec_arcsec: float = 10.0  #: pointing spec for the verdict and the tolerances
    phase_deg: float = 0.0  #: eccentricity phase C
    axis_tilt_azimuth_deg: float = 0.0  #: direction of a wedge axis tilt from x
    grating_radius_mm: float = 75.0  #: encoder grating radius (turns ε/r into µm)
    fov_deg: float = 60.0  #: linear scanner field of view
    points: int = 720  #: points around the pattern
    axis_angle_deg: float = 45.0  #: Palmer A
    mirror_tilt_deg: float = 7.5  #: Palmer B
    wedge_angle_deg: float = 20.0  #: wedge apex angle α
    refractive_index: float = 1.5168  #: wedge n

    def checked(self) -> "AnalysisSettings":
        """Self when every number is finite and within its range, else an :class:`InputError`
        naming the option, the range and the value."""
        if self.model not in MODELS:
            raise InputError(None, "--model",
                             f"expected one of {', '.join(MODELS)}, got {self.model!r}")
        for f in fields(self):
            if f.name in LIMITS:
                option, lo, hi, unit, open_lo, open_hi = LIMITS[f.name]
                number(getattr(self, f.name), option, lo, hi, unit, open_lo=open_lo,
                       open_hi=open_hi)
        integer(self.points, "--points", MIN_POINTS, MAX_POINTS,
                why="more only costs memory and time: 720 points resolve the curves' maxima "
                    "to 1e-5")
        self._check_errors()
        self._check_geometry()
        return self

    def _check_errors(self) -> None:
        """Each error known to the model and within its limits (user units)."""
        sources = {s.name: s for s in error_sources(self.model)}
        for name, value in self.errors.items():
            src = sources.get(name)
            if src is None:
                self._wrong_error(name, sources)
            low = -src.limit if src.low is None else src.low
            unit = src.unit if src.unit != "ratio" else "(ratio)"
            number(value, src.option, low, src.limit, unit)

    def _wrong_error(self, name: str, sources: dict) -> None:
        """Raise the error of an error ``name`` this model does not have: the models that have
        it, or the ones it has."""
        owners = [(m, s) for m in MODELS for s in error_sources(m) if s.name == name]
        if not owners:
            raise InputError(None, "errors",
                             f"unknown error {name!r}; expected one of {', '.join(sources)}")
        models = " or ".join(m for m, _ in owners)
        raise InputError(None, owners[0][1].option,
                         f"applies to --model {models}, not {self.model}")

    def _check_geometry(self) -> None:
        """Palmer: B < A; wedge: no total reflection inside the wedge (n·sin α < 1)."""
        if self.model == "palmer" and not self.mirror_tilt_deg < self.axis_angle_deg:
            raise InputError(None, "--mirror-tilt",
                             f"expected B < A = {self.axis_angle_deg:g}° (--axis-angle), "
                             f"got {self.mirror_tilt_deg:g}°")
        if self.model == "wedge":
            alpha = self.wedge_angle_deg + self.errors.get("wedge_angle_error", 0.0)
            if not self.refractive_index * np.sin(np.radians(alpha)) < 1.0:
                raise InputError(None, "--wedge-angle",
                                 f"n·sin α = {self.refractive_index:g}·sin {alpha:g}° ≥ 1: the "
                                 "beam is totally reflected inside the wedge; expected a smaller "
                                 "angle or refractive index")

    def options(self) -> dict:
        """The settings as the run record's options (user units)."""
        return {f.name: getattr(self, f.name) for f in fields(self)}
