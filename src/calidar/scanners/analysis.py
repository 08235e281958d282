"""Structural-error analysis of scanners: how each error moves points around the scan pattern.

For a scanner model, a range R and a set of structural errors (:class:`AnalysisSettings`)
:func:`analyze` computes

* the scan pattern at R: points p(β) = R · u(β) in the scanner frame s (x forward, y right,
  z down), β the encoder angle over one revolution (or the scan angle over the FOV);
* per error, the displacement R · (u_err(β) − u(β)) of every point (X/Y/Z curves), its maxima
  and the pointing error (angle between u_err and u);
* a combined budget (all errors at once, and the root-sum-square of the individual maxima);
* a tolerance allocation: the largest value of each error whose worst pointing error stays
  within the spec, alone and with an equal share spec/√k of a k-error RSS budget.

Reproduces the published Palmer figures at 500 m (A = 45°, B = 7.5°): pattern 258.8 m × 184.6 m;
ε/r = 15 µm / 75 mm → ≤ 26 mm in X, 9 mm in Y; δ_R = 0.02° → ≤ 34 cm in X, 25 cm in Y;
δ_L = 0.02° → ≤ 34 cm in X with the laser fixed in frame s (17 cm with the literal reading
of the paper's eq. (13); see :mod:`calidar.scanners.palmer`).
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from calidar.scanners import LinearScanner, Scanner
from calidar.scanners.palmer import palmer_directions
from calidar.scanners.settings import AnalysisSettings
from calidar.scanners.sources import (ARCSEC, DEFAULT_ERRORS, ErrorSource, build_scanner,
                                     error_sources)

#: angles over the pattern on which the tolerances are searched (max error to ~1e-6)
TOLERANCE_SAMPLES = 3600
DELTA_L_NOTE = (
    "delta_l: calidar keeps the laser fixed in frame s (the motor axis tilts, the beam moves by "
    "≈2·δ_L); comparisons.delta_l_literal_eq13 keeps the motor fixed (beam moves by ≈δ_L). They "
    "differ by a rigid rotation R_y(δ_L), i.e. a boresight pitch."
)


def settings_sources(s: AnalysisSettings) -> list[ErrorSource]:
    """The model's error sources at the settings' eccentricity phase and axis-tilt azimuth."""
    return error_sources(s.model, np.radians(s.phase_deg), np.radians(s.axis_tilt_azimuth_deg))


def pattern_angles(scanner: Scanner, n: int = 720, fov_rad: float = np.radians(60.0)) -> np.ndarray:
    """Observations covering the pattern: one revolution (rotating) or the FOV (linear), rad."""
    if isinstance(scanner, LinearScanner):
        return np.linspace(-fov_rad / 2, fov_rad / 2, n)
    return np.linspace(0.0, 2 * np.pi, n, endpoint=False)


def pointing_error(u_a: np.ndarray, u_b: np.ndarray) -> np.ndarray:
    """Angle (N,) in rad between unit vectors, accurate for tiny angles."""
    return 2.0 * np.arcsin(np.clip(np.linalg.norm(u_a - u_b, axis=1) / 2.0, 0.0, 1.0))


@dataclass
class ErrorEffect:
    """Displacements (N, 3) m of the pattern points for one error (or the combination)."""

    source: ErrorSource | None
    value_si: float | None
    displacement_m: np.ndarray
    pointing_rad: np.ndarray

    def maxima(self) -> dict[str, float]:
        d = np.abs(self.displacement_m)
        out = {"max_abs_dx_m": float(d[:, 0].max()), "max_abs_dy_m": float(d[:, 1].max()),
               "max_abs_dz_m": float(d[:, 2].max()),
               "max_3d_m": float(np.linalg.norm(self.displacement_m, axis=1).max()),
               "max_pointing_arcsec": float(self.pointing_rad.max() / ARCSEC)}
        if self.source is not None:
            out = {"value": self.source.to_user(self.value_si), "unit": self.source.unit, **out}
        return out

    def title(self, name: str, range_m: float) -> str:
        """A plot title: the error, its value and the range."""
        if self.source is None:
            return f"all errors together at {range_m:g} m"
        value = self.source.to_user(self.value_si)
        return f"{self.source.label} = {value:.6g} {self.source.unit} at {range_m:g} m ({name})"


@dataclass
class ScannerAnalysis:
    """The result of :func:`analyze` (SI inside)."""

    settings: AnalysisSettings
    scanner: Scanner
    spec_rad: float
    angles: np.ndarray  #: observations around the pattern, rad
    points_m: np.ndarray  #: pattern points (N, 3) in frame s, m
    effects: dict[str, ErrorEffect]
    combined: ErrorEffect | None
    tolerances: dict[str, dict]
    comparisons: dict[str, ErrorEffect] = field(default_factory=dict)
    notes: list[str] = field(default_factory=list)
    defaults_used: bool = False  #: no error was given: the example magnitudes were analysed

    @property
    def model(self) -> str:
        return self.settings.model

    @property
    def range_m(self) -> float:
        return float(self.settings.range_m)

    def summary(self) -> dict:
        """The JSON summary (SI metres; error values in their user units)."""
        ext = self.points_m.max(axis=0) - self.points_m.min(axis=0)
        pattern = {"extent_x_m": float(ext[0]), "extent_y_m": float(ext[1]),
                   "extent_z_m": float(ext[2]), "n_points": int(len(self.points_m))}
        combined = None
        if self.combined is not None:
            rss = np.sqrt(sum(e.maxima()["max_3d_m"] ** 2 for e in self.effects.values()))
            combined = {**self.combined.maxima(), "rss_of_max_3d_m": float(rss)}
        out = {
            "model": self.model,
            "scanner": self.scanner.to_toml(),
            "range_m": self.range_m,
            "spec_arcsec": self.spec_rad / ARCSEC,
            "spec_m_at_range": self.spec_rad * self.range_m,
            "pattern": pattern,
            "errors": {k: e.maxima() for k, e in self.effects.items()},
            "combined": combined,
            "tolerances": self.tolerances,
            "notes": self.notes,
        }
        if self.comparisons:
            out["comparisons"] = {k: e.maxima() for k, e in self.comparisons.items()}
        return out


def tolerance(scanner: Scanner, source: ErrorSource, angles: np.ndarray, spec_rad: float) -> float:
    """Largest magnitude (SI) of one error whose worst pointing error is ≤ spec_rad (bisection)."""
    u0 = scanner.directions(angles)

    def worst(x: float) -> float:
        u = scanner.with_parameters(**source.apply(x)).directions(angles)
        return float(pointing_error(u, u0).max())

    probe = 1e-6
    hi = 2.0 * spec_rad * probe / max(worst(probe), 1e-300)
    lo = 0.0
    while worst(hi) <= spec_rad:
        lo, hi = hi, 2.0 * hi
    for _ in range(50):
        mid = 0.5 * (lo + hi)
        lo, hi = (mid, hi) if worst(mid) <= spec_rad else (lo, mid)
    return lo


def _at_every_phase(src: ErrorSource) -> list[ErrorSource]:
    """The eccentricity ``src`` at 13 phases over [0, π] (its sign covers the other half)."""
    return [ErrorSource(src.name, src.label, src.unit, src.option, src.limit,
                        lambda e, c=c: {"eccentricity_ratio": e, "eccentricity_phase": c})
            for c in np.linspace(0.0, np.pi, 13)]


def tolerances(scanner: Scanner, sources: dict[str, ErrorSource], angles: np.ndarray,
               spec_rad: float, grating_radius_m: float) -> dict[str, dict]:
    """Per error (user units): the largest value alone and with an equal RSS share of the spec;
    the eccentricity at its worst phase (unknown at design time), also in µm at the grating
    radius."""
    out = {}
    for name, src in sources.items():
        variants = _at_every_phase(src) if name == "eccentricity" else [src]
        alone, share = (min(tolerance(scanner, v, angles, lim) for v in variants)
                        for lim in (spec_rad, spec_rad / np.sqrt(len(sources))))
        out[name] = {"unit": src.unit, "max_alone": src.to_user(alone),
                     "max_equal_share": src.to_user(share)}
        if name == "eccentricity":
            out[name]["max_alone_um_at_grating_radius"] = alone * grating_radius_m * 1e6
            out[name]["grating_radius_mm"] = grating_radius_m * 1e3
    return out


def analyze(settings: AnalysisSettings, progress=None) -> ScannerAnalysis:
    """Analyse ``settings`` (checked here; see :class:`AnalysisSettings`)."""
    s = settings.checked()
    scanner = build_scanner(s.model, axis_angle_deg=s.axis_angle_deg,
                            mirror_tilt_deg=s.mirror_tilt_deg, wedge_angle_deg=s.wedge_angle_deg,
                            refractive_index=s.refractive_index)
    sources = {e.name: e for e in settings_sources(s)}
    errors = dict(s.errors) or dict(DEFAULT_ERRORS[s.model])
    notes = []
    if not s.errors:
        notes.append("no error was given: the published example magnitudes were analysed")
    errors_si = {k: sources[k].to_si(v) for k, v in errors.items()}
    angles = pattern_angles(scanner, s.points, np.radians(s.fov_deg))
    u0 = scanner.directions(angles)

    def effect(src, value, u):
        return ErrorEffect(src, value, s.range_m * (u - u0), pointing_error(u, u0))

    effects, params = {}, {}
    for name, value in errors_si.items():
        p = sources[name].apply(value)
        params.update(p)
        u = scanner.with_parameters(**p).directions(angles)
        effects[name] = effect(sources[name], value, u)
    combined = None
    if len(effects) > 1:
        combined = effect(None, None, scanner.with_parameters(**params).directions(angles))
    spec = s.spec_arcsec * ARCSEC
    if progress:
        progress("tolerances", 0, 1)
    tolerance_angles = pattern_angles(scanner, TOLERANCE_SAMPLES, np.radians(s.fov_deg))
    tol = tolerances(scanner, sources, tolerance_angles, spec, s.grating_radius_mm * 1e-3)
    if progress:
        progress("tolerances", 1, 1)
    comparisons = {}
    if s.model == "palmer" and "delta_l" in errors_si:
        delta_l = errors_si["delta_l"]
        # the paper's eq. (13) read literally: the motor fixed, the laser tilted (module notes)
        u = palmer_directions(angles, scanner.palmer_axis_angle, scanner.palmer_mirror_tilt,
                              delta_l=delta_l, reference="motor")
        comparisons["delta_l_literal_eq13"] = effect(sources["delta_l"], delta_l, u)
        notes.append(DELTA_L_NOTE)
    return ScannerAnalysis(s, scanner, spec, angles, s.range_m * u0, effects, combined, tol,
                           comparisons, notes, defaults_used=not s.errors)

