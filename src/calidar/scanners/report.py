"""Report sections of the scanner analyses (they render results; nothing is computed here
beyond formatting)."""

from __future__ import annotations

import numpy as np

from calidar.report.numbers import fixed, signed
from calidar.scanners.analysis import ScannerAnalysis, settings_sources
from calidar.scanners.figures import displacement_figure, pattern_figure, separability_figure
from calidar.scanners.separability import Separability
from calidar.scanners.sources import DEFAULT_ERRORS, MODEL_NAMES, error_sources
from calidar.scanners.verdict import user_value

SEPARABILITY_TEXT = (
    "Separability from the boresight: the Jacobian of the pattern's points with respect to the "
    "boresight angles and each structural component (eccentricity split into ε/r·cos C and "
    "ε/r·sin C). 'Own part' is the fraction of a component's effect on the points that no "
    "boresight rotation reproduces; the best boresight is the rotation (per unit of the error) "
    "that imitates it most closely."
)


def _mm(m: float | None) -> str:
    """Metres as millimetres with sensible digits."""
    if m is None:
        return "—"
    v = m * 1e3
    return f"{v:.1f}" if abs(v) >= 10 else f"{v:.2f}"


def _arcsec(v: float) -> str:
    """Arcseconds with sensible digits."""
    return f"{v:.1f}" if v >= 10 else f"{v:.2f}"


def _maxima_cells(m: dict, spec_arcsec: float) -> list[str]:
    """max |dX|, |dY|, |dZ|, 3-D (mm), worst pointing (″) and pointing / spec of one error's
    maxima."""
    pointing = m["max_pointing_arcsec"]
    return [_mm(m["max_abs_dx_m"]), _mm(m["max_abs_dy_m"]), _mm(m["max_abs_dz_m"]),
            _mm(m["max_3d_m"]), _arcsec(pointing), f"{pointing / spec_arcsec:.2f}"]


def _maxima_rows(a: ScannerAnalysis, s: dict) -> list[list]:
    """The error budget: each error's (and comparison's) maxima, then all together's."""
    spec = s["spec_arcsec"]
    sources = {src.name: src for src in error_sources(a.model)}
    grating = a.settings.grating_radius_mm
    rows = []
    for k, v in list(s["errors"].items()) + list(s.get("comparisons", {}).items()):
        src = sources.get(k) or sources[k.split("_literal")[0]]
        label = src.label if k in sources else f"{src.short} read literally (eq. 13; a comparison)"
        rows.append([label, user_value(src, v["value"], grating), *_maxima_cells(v, spec)])
    if s["combined"]:
        c = s["combined"]
        rows.append(["all together", "", *_maxima_cells(c, spec)])
        rows.append(["root-sum-square of the maxima", "", "", "", "", _mm(c["rss_of_max_3d_m"]),
                     "", ""])
    return rows


def _introduction(a: ScannerAnalysis, s: dict) -> str:
    """The section's first paragraph: the scanner, its geometry and its pattern's extent (m)."""
    ext = s["pattern"]
    geometry = ", ".join(f"{k} = {v:g}" for k, v in s["scanner"].items() if k != "model" and v)
    return (f"{MODEL_NAMES[a.model].capitalize()} scanner ({geometry or 'nominal geometry'}) at a "
            f"range of {a.range_m:g} m: the pattern spans {ext['extent_x_m']:.1f} m along x "
            f"(forward) × {ext['extent_y_m']:.1f} m along y (right). Points are range × beam "
            "direction in the scanner frame (x forward, y right, z down); each error's "
            "displacement is the change of every point of the pattern it causes.")


def _tolerance_table(sec, a: ScannerAnalysis, s: dict) -> None:
    """Each error's largest value alone and with an equal share of the spec."""
    sources = {src.name: src for src in error_sources(a.model)}
    grating = a.settings.grating_radius_mm
    tol_rows = [[sources[k].label, user_value(sources[k], v["max_alone"], grating),
                 user_value(sources[k], v["max_equal_share"], grating)]
                for k, v in s["tolerances"].items()]
    header = ["error", "largest alone", f"largest with an equal share (spec/√{len(tol_rows)})"]
    sec.table(header, tol_rows,
              caption=f"Tolerances keeping the worst pointing error ≤ {s['spec_arcsec']:g}″; "
                      "eccentricity at its worst phase, in µm at the grating radius")


def add_section(report, a: ScannerAnalysis, sep: Separability | None = None,
                title: str | None = None) -> None:
    """A report section: pattern, maxima, displacement curves, tolerances, separability."""
    s = a.summary()
    model = MODEL_NAMES[a.model]
    sec = report.section(title or f"Structural errors of a {model} scanner at {a.range_m:g} m")
    sec.text(_introduction(a, s))
    sec.figure(pattern_figure(a), "Scan pattern at the range (top view).")
    header = ["error", "value", "max |dX| [mm]", "max |dY| [mm]", "max |dZ| [mm]", "max 3-D [mm]",
              "worst pointing [″]", "pointing / spec"]
    sec.table(header, _maxima_rows(a, s),
              caption=f"Largest displacement of a pattern point per error (error budget); spec "
                      f"{s['spec_arcsec']:g}″ = {_mm(s['spec_m_at_range'])} mm at {a.range_m:g} m")
    for name, e in list(a.effects.items()) + list(a.comparisons.items()):
        figure = displacement_figure(a, e, e.title(name, a.range_m))
        sec.figure(figure, f"Displacements for {name}.")
    _tolerance_table(sec, a, s)
    for note in a.notes:
        sec.text(note)
    if sep is not None:
        add_separability(sec, a, sep)


def add_separability(sec, a: ScannerAnalysis, sep: Separability) -> None:
    """The separability table and figure (the least separable error) inside section ``sec``."""
    sources = settings_sources(a.settings)
    rows = []
    for src in sources:
        for name in dict.fromkeys([c for c, _ in src.parts()]):
            mimic = [signed(v, 3) for v in sep.mimic[name]]
            rows.append([name, f"{100 * sep.unexplained[name]:.1f}", *mimic])
    sec.text(SEPARABILITY_TEXT)
    sec.table(["component", "own part [%]", "best roll [rad/unit]", "best pitch [rad/unit]",
               "best yaw [rad/unit]"], rows)
    worst = min(sources, key=lambda src: sep.unexplained[src.name])
    if worst.name in a.effects:
        value = a.effects[worst.name].value_si
    else:
        value = worst.to_si(DEFAULT_ERRORS[a.model][worst.name])
    shown = user_value(worst, worst.to_user(value))
    sec.figure(separability_figure(sep, worst.name, value, worst.label, shown, a.model),
               f"{worst.label}, the error least separable from the boresight: its displacements "
               "(solid) and what the best boresight rotation leaves of them (dashed); right, the "
               "correlations of a joint estimate.")


def _control_rows(solution, truth: dict[str, float]) -> list[list]:
    """Free parameters in the units people use: angles in degrees with σ and error in arcseconds,
    the eccentricity ratio in parts per million."""
    rows = []
    for name, sigma in solution.sigma.items():
        p = solution.parameters[name]
        v, t = solution.values[name], truth.get(name)
        if p.unit == "rad":  # σ and error in arcseconds while they are small, else degrees
            f, unit, d = np.degrees(1.0), "°", 4
            sf, sunit = (f * 3600, "″") if np.degrees(sigma) < 0.05 else (f, "°")
        else:
            f, unit, sf, sunit, d = 1e6, " ppm", 1e6, " ppm", 1
        err = None if t is None else v - t
        if name == "eccentricity_phase" and err is not None:
            err = (err + np.pi) % (2 * np.pi) - np.pi
        truth_text = "—" if t is None else f"{fixed(t * f, d)}{unit}"
        error_text = "—" if err is None else f"{signed(err * sf, 2)}{sunit}"
        ratio_text = "—" if err is None else f"{abs(err) / sigma:.1f}"
        rows.append([name, f"{fixed(v * f, d)}{unit}", f"{sigma * sf:.2f}{sunit}", truth_text,
                     error_text, ratio_text])
    return rows


def add_control_section(report, solution, truth: dict[str, float]) -> None:
    """The Palmer control-point adjustment (boresight + structural parameters from noisy points)."""
    sec = report.section("Palmer self-calibration from control points (adjustment engine)")
    sec.text("Boresight and every Palmer parameter estimated together from noisy simulated control "
             "points of one revolution: the separable parameters come back; δ_L and the boresight "
             "pitch share their information.")
    sec.table(["parameter", "estimate", "σ", "truth", "error", "|error| / σ"],
              _control_rows(solution, truth))
    ra, rb = solution.residuals_after, solution.residuals_before
    sec.text(f"RMS of the coordinate residuals {ra['rms'] * 1e3:.1f} mm after, "
             f"{rb['rms'] * 1e3:.1f} mm before, over {ra['n']} coordinates; "
             f"σ0 = {solution.sigma0:.3f}; {len(solution.history) - 1} iterations"
             f"{'' if solution.converged else ', NOT converged'}.")
    for w in solution.warnings:
        sec.warning(w)


def add_selfcal_section(report, truth: dict[str, float], results: dict, title: str) -> None:
    """Report section comparing boresight-only and boresight + Palmer strip calibrations."""
    sec = report.section(title)
    for est, r in results.items():
        sec.text(f"Estimated: {' + '.join(est)}.")
        sec.solution(r.solution, truth)
