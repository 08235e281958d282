"""Structural-error analysis of scanners: how each error moves points around the scan pattern.

For a scanner model, a range R and a set of structural errors this module computes

* the scan pattern at R: points p(β) = R · u(β) in the scanner frame s (x forward, y right,
  z down), β the encoder angle over one revolution (or the scan angle over the FOV);
* per error, the displacement R · (u_err(β) − u(β)) of every point (X/Y/Z curves) and its maxima;
* a combined budget (all errors at once, and the root-sum-square of the individual maxima);
* a tolerance allocation: the largest value of each error whose pointing error (the angle
  between u_err and u, worst point of the pattern) stays within a spec, alone and with an
  equal share spec/√k of a k-error RSS budget.

Reproduces the published Palmer figures at 500 m (A = 45°, B = 7.5°): pattern 258.8 m × 184.6 m;
ε/r = 15 µm / 75 mm → ≤ 26 mm in X, 9 mm in Y; δ_R = 0.02° → ≤ 34 cm in X, 25 cm in Y;
δ_L = 0.02° → ≤ 34 cm in X with the laser fixed in frame s (17 cm with the literal reading
of the paper's eq. (13); see :mod:`calidar.scanners.palmer`).
"""

from __future__ import annotations

import csv
import json
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from calidar.errors import InputError
from calidar.scanners import LinearScanner, PalmerScanner, Scanner, WedgeScanner
from calidar.scanners.palmer import palmer_directions

ARCSEC = np.pi / (180.0 * 3600.0)  #: one arcsecond in rad


@dataclass(frozen=True)
class ErrorSource:
    """One structural error: its user unit and how a magnitude (SI) maps to model parameters."""

    name: str  #: key in the JSON summary
    label: str
    unit: str  #: user unit: "deg", "ratio" or "ppm"
    apply: Callable[[float], dict[str, float]]  #: magnitude (SI) → scanner parameters

    def to_user(self, value_si: float) -> float:
        return float({"deg": np.degrees(value_si), "ppm": value_si * 1e6}.get(self.unit, value_si))

    def to_si(self, value_user: float) -> float:
        return float({"deg": np.radians(value_user), "ppm": value_user * 1e-6}.get(self.unit, value_user))


def error_sources(model: str, eccentricity_phase_rad: float = 0.0, axis_tilt_azimuth_rad: float = 0.0) -> list[ErrorSource]:
    """The structural errors of a model (``palmer``, ``wedge`` or ``linear``)."""
    ecc = ErrorSource("eccentricity", "encoder eccentricity ε/r", "ratio",
                      lambda e: {"eccentricity_ratio": e, "eccentricity_phase": eccentricity_phase_rad})
    if model == "palmer":
        return [ecc, ErrorSource("delta_l", "laser–axis angle error δ_L", "deg", lambda d: {"delta_l": d}),
                ErrorSource("delta_r", "mirror-normal–axis angle error δ_R", "deg", lambda d: {"delta_r": d})]
    if model == "wedge":
        ca, sa = np.cos(axis_tilt_azimuth_rad), np.sin(axis_tilt_azimuth_rad)
        return [ecc, ErrorSource("wedge_angle_error", "wedge angle error Δα", "deg", lambda d: {"wedge_angle_error": d}),
                ErrorSource("axis_tilt", "rotation-axis tilt", "deg",
                            lambda t: {"wedge_axis_tilt_x": t * ca, "wedge_axis_tilt_y": t * sa})]
    if model == "linear":
        return [ErrorSource("scan_angle_offset", "scan-angle offset", "deg", lambda d: {"scan_angle_offset": d}),
                ErrorSource("scan_angle_scale", "scan-angle scale", "ppm", lambda s: {"scan_angle_scale": s})]
    raise InputError(None, "--model", f"expected one of palmer, wedge, linear, got {model!r}")


#: Example magnitudes (SI) analysed when none is given: the published Palmer example values.
DEFAULT_ERRORS = {
    "palmer": {"eccentricity": 15e-6 / 0.075, "delta_l": np.radians(0.02), "delta_r": np.radians(0.02)},
    "wedge": {"eccentricity": 15e-6 / 0.075, "wedge_angle_error": np.radians(0.02), "axis_tilt": np.radians(0.02)},
    "linear": {"scan_angle_offset": np.radians(0.02), "scan_angle_scale": 100e-6},
}


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


@dataclass
class ScannerAnalysis:
    model: str
    scanner: Scanner
    range_m: float
    spec_rad: float
    angles: np.ndarray  #: observations around the pattern, rad
    points_m: np.ndarray  #: pattern points (N, 3) in frame s, m
    effects: dict[str, ErrorEffect]
    combined: ErrorEffect | None
    tolerances: dict[str, dict]
    comparisons: dict[str, ErrorEffect] = field(default_factory=dict)
    notes: list[str] = field(default_factory=list)

    def summary(self) -> dict:
        """The JSON summary (SI metres; error values in their user units)."""
        ext = self.points_m.max(axis=0) - self.points_m.min(axis=0)
        out = {
            "model": self.model,
            "scanner": self.scanner.to_toml(),
            "range_m": self.range_m,
            "spec_arcsec": self.spec_rad / ARCSEC,
            "spec_m_at_range": self.spec_rad * self.range_m,
            "pattern": {"extent_x_m": float(ext[0]), "extent_y_m": float(ext[1]), "extent_z_m": float(ext[2]),
                        "n_points": int(len(self.points_m))},
            "errors": {k: e.maxima() for k, e in self.effects.items()},
            "combined": None if self.combined is None else {
                **self.combined.maxima(),
                "rss_of_max_3d_m": float(np.sqrt(sum(e.maxima()["max_3d_m"] ** 2 for e in self.effects.values())))},
            "tolerances": self.tolerances,
            "notes": self.notes,
        }
        if self.comparisons:
            out["comparisons"] = {k: e.maxima() for k, e in self.comparisons.items()}
        return out


def build_scanner(model: str, *, axis_angle_deg: float = 45.0, mirror_tilt_deg: float = 7.5,
                  wedge_angle_deg: float = 20.0, refractive_index: float = 1.5168) -> Scanner:
    """The error-free scanner of a model with the given design geometry (degrees at this edge)."""
    if model == "palmer":
        return PalmerScanner(np.radians(axis_angle_deg), np.radians(mirror_tilt_deg))
    if model == "wedge":
        return WedgeScanner(np.radians(wedge_angle_deg), refractive_index)
    if model == "linear":
        return LinearScanner()
    raise InputError(None, "--model", f"expected one of palmer, wedge, linear, got {model!r}")


def _tolerance(scanner: Scanner, source: ErrorSource, angles: np.ndarray, spec_rad: float) -> float:
    """Largest magnitude (SI) of one error whose worst pointing error is ≤ spec_rad (bisection)."""
    u0 = scanner.directions(angles)

    def worst(x: float) -> float:
        return float(pointing_error(scanner.with_parameters(**source.apply(x)).directions(angles), u0).max())

    probe = 1e-6
    hi = 2.0 * spec_rad * probe / max(worst(probe), 1e-300)
    lo = 0.0
    while worst(hi) <= spec_rad:
        lo, hi = hi, 2.0 * hi
    for _ in range(50):
        mid = 0.5 * (lo + hi)
        lo, hi = (mid, hi) if worst(mid) <= spec_rad else (lo, mid)
    return lo


def analyze(model: str, range_m: float, errors_si: dict[str, float] | None = None, *, spec_arcsec: float = 10.0,
            eccentricity_phase_rad: float = 0.0, axis_tilt_azimuth_rad: float = 0.0, grating_radius_m: float = 0.075,
            fov_deg: float = 60.0, n: int = 720, **geometry) -> ScannerAnalysis:
    """Analyse a model at ``range_m`` (m) for errors {name: magnitude in SI}; None → the defaults."""
    if not (np.isfinite(range_m) and range_m > 0):
        raise InputError(None, "--range", f"expected a range > 0 m, got {range_m:g}")
    if not (np.isfinite(spec_arcsec) and spec_arcsec > 0):
        raise InputError(None, "--spec-arcsec", f"expected a pointing spec > 0 arcsec, got {spec_arcsec:g}")
    if not grating_radius_m > 0:
        raise InputError(None, "--grating-radius-mm", f"expected a radius > 0, got {grating_radius_m * 1e3:g} mm")
    scanner = build_scanner(model, **geometry)
    sources = {s.name: s for s in error_sources(model, eccentricity_phase_rad, axis_tilt_azimuth_rad)}
    notes = []
    if not errors_si:
        errors_si = DEFAULT_ERRORS[model]
        notes.append("no error given: the example magnitudes were analysed")
    unknown = set(errors_si) - set(sources)
    if unknown:
        raise InputError(None, "errors", f"{sorted(unknown)} do not apply to the {model} scanner; expected {sorted(sources)}")
    angles = pattern_angles(scanner, n, np.radians(fov_deg))
    u0 = scanner.directions(angles)

    def effect(src, value, sc):
        u = sc.directions(angles)
        return ErrorEffect(src, value, range_m * (u - u0), pointing_error(u, u0))

    effects, params = {}, {}
    for name, value in errors_si.items():
        p = sources[name].apply(value)
        params.update(p)
        effects[name] = effect(sources[name], value, scanner.with_parameters(**p))
    combined = effect(None, None, scanner.with_parameters(**params)) if len(effects) > 1 else None

    spec = spec_arcsec * ARCSEC
    tolerances = {}
    for name, src in sources.items():
        variants = [src]
        if name == "eccentricity":  # the phase is unknown at design time: worst case over C
            variants = [ErrorSource(name, src.label, src.unit,
                                    lambda e, c=c: {"eccentricity_ratio": e, "eccentricity_phase": c})
                        for c in np.linspace(0.0, np.pi, 13)]
        alone, share = (min(_tolerance(scanner, v, angles, lim) for v in variants)
                        for lim in (spec, spec / np.sqrt(len(sources))))
        tolerances[name] = {"unit": src.unit, "max_alone": src.to_user(alone), "max_equal_share": src.to_user(share)}
        if name == "eccentricity":
            tolerances[name]["max_alone_um_at_grating_radius"] = alone * grating_radius_m * 1e6
            tolerances[name]["grating_radius_mm"] = grating_radius_m * 1e3
    comparisons = {}
    if model == "palmer" and "delta_l" in errors_si:
        u = palmer_directions(angles, scanner.palmer_axis_angle, scanner.palmer_mirror_tilt,
                              delta_l=errors_si["delta_l"], reference="motor")
        comparisons["delta_l_literal_eq13"] = ErrorEffect(sources["delta_l"], errors_si["delta_l"],
                                                          range_m * (u - u0), pointing_error(u, u0))
        notes.append("delta_l: calidar keeps the laser fixed in frame s (the motor axis tilts, the beam moves by ≈2·δ_L); "
                     "comparisons.delta_l_literal_eq13 keeps the motor fixed (beam moves by ≈δ_L). They differ by a rigid "
                     "rotation R_y(δ_L), i.e. a boresight pitch.")
    return ScannerAnalysis(model, scanner, float(range_m), spec, angles, range_m * u0, effects, combined, tolerances,
                           comparisons, notes)


def _angle_axis_label(a: ScannerAnalysis) -> str:
    return "scan angle θ [deg]" if a.model == "linear" else "encoder angle β [deg]"


def pattern_figure(a: ScannerAnalysis):
    """Top view (x forward up, y right) of the pattern at the range."""
    import matplotlib.pyplot as plt

    from calidar.report import plots  # noqa: F401  (selects the Agg backend)

    fig, ax = plt.subplots(figsize=(5.5, 5))
    p = a.points_m
    ax.plot(p[:, 1], p[:, 0], ".", ms=2)
    ax.plot(p[:1, 1], p[:1, 0], "r^", label="β = 0" if a.model != "linear" else "θ = −FOV/2")
    ext = p.max(axis=0) - p.min(axis=0)
    ax.set_aspect("equal", adjustable="datalim")
    ax.set_xlabel("y (right) [m]")
    ax.set_ylabel("x (forward) [m]")
    ax.set_title(f"{a.model} pattern at {a.range_m:g} m: {ext[0]:.1f} m (x) × {ext[1]:.1f} m (y)")
    ax.legend(loc="upper right")
    ax.grid(alpha=0.3)
    return fig


def displacement_figure(a: ScannerAnalysis, effect: ErrorEffect, title: str):
    """X/Y/Z displacement (mm) of every pattern point against the encoder/scan angle."""
    import matplotlib.pyplot as plt

    from calidar.report import plots  # noqa: F401

    fig, ax = plt.subplots(figsize=(7, 3.5))
    deg = np.degrees(a.angles)
    for k, lab in enumerate(("dX (forward)", "dY (right)", "dZ (down)")):
        ax.plot(deg, effect.displacement_m[:, k] * 1e3, label=lab)
    ax.set_xlabel(_angle_axis_label(a))
    ax.set_ylabel("displacement [mm]")
    ax.set_title(title)
    ax.grid(alpha=0.3)
    ax.legend()
    return fig


def _effect_title(name: str, e: ErrorEffect, range_m: float) -> str:
    if e.source is None:
        return f"all errors together at {range_m:g} m"
    return f"{e.source.label} = {e.source.to_user(e.value_si):.6g} {e.source.unit} at {range_m:g} m ({name})"


def add_section(report, a: ScannerAnalysis, title: str | None = None) -> None:
    """A report section: pattern, displacement curves, maxima, budget, tolerances."""
    s = a.summary()
    sec = report.section(title or f"Scanner structural-error analysis ({a.model})")
    ext = s["pattern"]
    sec.text(f"Scanner {json.dumps(s['scanner'])}; range {a.range_m:g} m; pattern {ext['extent_x_m']:.2f} m (x, forward) × "
             f"{ext['extent_y_m']:.2f} m (y, right). Points are range × beam direction in the scanner frame "
             f"(x forward, y right, z down).")
    sec.figure(pattern_figure(a), "Scan pattern at the range (top view).")
    rows = [[k, v.get("value"), v.get("unit"), v["max_abs_dx_m"] * 1e3, v["max_abs_dy_m"] * 1e3, v["max_abs_dz_m"] * 1e3,
             v["max_3d_m"] * 1e3, v["max_pointing_arcsec"]] for k, v in s["errors"].items()]
    for k, v in s.get("comparisons", {}).items():
        rows.append([k, v["value"], v["unit"], v["max_abs_dx_m"] * 1e3, v["max_abs_dy_m"] * 1e3, v["max_abs_dz_m"] * 1e3,
                     v["max_3d_m"] * 1e3, v["max_pointing_arcsec"]])
    if s["combined"]:
        c = s["combined"]
        rows.append(["all together", None, None, c["max_abs_dx_m"] * 1e3, c["max_abs_dy_m"] * 1e3, c["max_abs_dz_m"] * 1e3,
                     c["max_3d_m"] * 1e3, c["max_pointing_arcsec"]])
        rows.append(["RSS of the maxima", None, None, None, None, None, c["rss_of_max_3d_m"] * 1e3, None])
    sec.table(["error", "value", "unit", "max |dX| mm", "max |dY| mm", "max |dZ| mm", "max 3D mm", "max pointing ″"], rows,
              caption="Largest displacement of a pattern point per error (error budget)")
    for name, e in list(a.effects.items()) + list(a.comparisons.items()):
        sec.figure(displacement_figure(a, e, _effect_title(name, e, a.range_m)), f"Displacements for {name}.")
    tol_rows = [[k, v["unit"], v["max_alone"], v["max_equal_share"], v.get("max_alone_um_at_grating_radius")]
                for k, v in s["tolerances"].items()]
    sec.table(["error", "unit", "max alone", "max with equal RSS share", "ε alone [µm]"], tol_rows,
              caption=f"Tolerances keeping the pointing error ≤ {s['spec_arcsec']:g}″ "
                      f"({s['spec_m_at_range'] * 100:.2f} cm at {a.range_m:g} m); eccentricity: worst phase")
    for note in a.notes:
        sec.text(note)


def write_outputs(a: ScannerAnalysis, out_dir: Path) -> dict:
    """pattern.csv/.png, displacement_<error>.csv/.png, summary.json and report.html in out_dir."""
    from calidar.outputs import atomic_path, write_text_atomic
    from calidar.report import Report

    out_dir = Path(out_dir)
    lab = "scan_angle_deg" if a.model == "linear" else "encoder_angle_deg"
    deg = np.degrees(a.angles)

    def write_csv(name, header, rows):
        with atomic_path(out_dir / name) as tmp, open(tmp, "w", newline="") as f:
            w = csv.writer(f)
            w.writerow(header)
            w.writerows(rows)

    write_csv("pattern.csv", [lab, "x_m", "y_m", "z_m"], [[f"{b:.6f}", *(f"{v:.6f}" for v in p)]
                                                           for b, p in zip(deg, a.points_m)])
    figs = {"pattern.png": pattern_figure(a)}
    effects = dict(a.effects, **a.comparisons)
    if a.combined is not None:
        effects["combined"] = a.combined
    for name, e in effects.items():
        write_csv(f"displacement_{name}.csv", [lab, "dx_m", "dy_m", "dz_m", "pointing_arcsec"],
                  [[f"{b:.6f}", *(f"{v:.9f}" for v in d), f"{p / ARCSEC:.6f}"]
                   for b, d, p in zip(deg, e.displacement_m, e.pointing_rad)])
        figs[f"displacement_{name}.png"] = displacement_figure(a, e, _effect_title(name, e, a.range_m))
    import matplotlib.pyplot as plt

    for name, fig in figs.items():
        with atomic_path(out_dir / name) as tmp:
            fig.savefig(tmp, format="png", dpi=110, bbox_inches="tight")
        plt.close(fig)
    summary = a.summary()
    write_text_atomic(out_dir / "summary.json", json.dumps(summary, indent=2) + "\n")
    rep = Report(f"calidar scanner analysis ({a.model})")
    add_section(rep, a)
    rep.write(out_dir / "report.html")
    return summary
