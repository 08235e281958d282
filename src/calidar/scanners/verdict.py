"""The verdict of a structural-error analysis: which errors break the pointing spec and by how
much, and which cannot be told apart from the boresight."""

from __future__ import annotations

import numpy as np

from calidar.scanners.analysis import ScannerAnalysis, settings_sources
from calidar.scanners.separability import Separability
from calidar.scanners.sources import ARCSEC, MODEL_NAMES, ErrorSource
from calidar.report.numbers import fixed
from calidar.verdict import Finding, Verdict

#: an error whose own part (not a boresight rotation) is below this fraction is not separable
NOT_SEPARABLE = 0.15
ROTATION_NAMES = ("roll", "pitch", "yaw")


def user_value(src: ErrorSource, value_user: float, grating_radius_mm: float | None = None) -> str:
    """An error's magnitude as people write it: 0.02° (72″), ε/r 2e-4 (15 µm at 75 mm), 100 ppm."""
    if src.unit == "deg":
        return f"{value_user:.4g}° ({value_user * 3600:.3g}″)"
    if src.unit == "ppm":
        return f"{value_user:.4g} ppm"
    um = ""
    if grating_radius_mm:
        um = f" ({value_user * grating_radius_mm * 1e3:.3g} µm at {grating_radius_mm:g} mm)"
    return f"{value_user:.3g}{um}"


def length(m: float) -> str:
    """A length in the unit that reads best: mm below 10 cm, cm below 10 m, else m."""
    if abs(m) < 0.1:
        return f"{m * 1e3:.3g} mm"
    return f"{m * 1e2:.3g} cm" if abs(m) < 10 else f"{m:.4g} m"


def _error_finding(a: ScannerAnalysis, name: str, e) -> Finding:
    """One error's worst pointing against the spec; when it breaks it, its tolerances."""
    spec = a.spec_rad / ARCSEC
    grating = a.settings.grating_radius_mm
    m, src = e.maxima(), e.source
    worst_arcsec = m["max_pointing_arcsec"]
    what = f"{src.short} = {user_value(src, m['value'], grating)}"
    moved = f"worst pointing {worst_arcsec:.3g}″ ({length(m['max_3d_m'])} at {a.range_m:g} m)"
    if worst_arcsec <= spec:
        return Finding("pass", src.label,
                       f"{what}: {moved}, {worst_arcsec / spec:.0%} of the {spec:g}″ spec")
    tol = a.tolerances[name]
    alone = user_value(src, tol["max_alone"], grating)
    share = user_value(src, tol["max_equal_share"], grating)
    over = f"{worst_arcsec / spec:.1f}× the {spec:g}″ spec"
    return Finding("fail", src.label, f"{what}: {moved}, {over}",
                   f"keep {src.short} within {alone} alone, or {share} as an equal share of the "
                   "budget — or calibrate it")


def _pointing_findings(a: ScannerAnalysis) -> list[Finding]:
    """Each error's finding, then all errors together's (when there are several)."""
    out = [_error_finding(a, name, e) for name, e in a.effects.items()]
    if a.combined is not None:
        spec = a.spec_rad / ARCSEC
        m = a.combined.maxima()
        ok = m["max_pointing_arcsec"] <= spec
        largest = max(a.effects, key=lambda k: a.effects[k].pointing_rad.max())
        worst = a.effects[largest].source.short
        moved = f"{length(m['max_3d_m'])} at {a.range_m:g} m"
        out.append(Finding("pass" if ok else "fail", "all errors together",
                           f"worst pointing {m['max_pointing_arcsec']:.3g}″ ({moved}) against the "
                           f"{spec:g}″ spec",
                           "" if ok else f"reduce the largest contributor first ({worst})"))
    return out


def _mimic_text(sep: Separability, src: ErrorSource) -> str:
    """"a boresight pitch of −2.00 × δ_L" (the rotation that best imitates the error)."""
    parts = [f"{r} of {fixed(v, 2)} × {src.short}"
             for r, v in zip(ROTATION_NAMES, sep.mimic[src.name]) if abs(v) > 5e-3]
    return "a boresight " + (" plus ".join(parts) if parts else "rotation")


def _entangled_finding(a: ScannerAnalysis, sep: Separability, src: ErrorSource,
                       own: float) -> Finding:
    """An error the boresight imitates (its own part ``own`` < NOT_SEPARABLE): exactly, or
    nearly, with what the boresight leaves of the analysed value."""
    if own < 1e-6:
        return Finding("warn", f"{src.short} vs the boresight",
                       f"{src.label} is {_mimic_text(sep, src)} exactly: no data can tell them "
                       "apart",
                       f"do not estimate {src.short} with the boresight; the boresight calibration "
                       "takes it whole")
    left = ""
    if src.name in a.effects:
        e = a.effects[src.name]
        d = np.linalg.norm(sep.left_after_boresight(src.name, e.value_si), axis=1).max()
        analysed = user_value(src, src.to_user(e.value_si))
        left = f"; what the boresight cannot take of the analysed {analysed}: ≤ {length(d)}"
    return Finding("warn", f"{src.short} vs the boresight",
                   f"{src.label} acts as {_mimic_text(sep, src)}; only {own:.1%} of its effect on "
                   f"the points is its own{left}",
                   f"a strip or control-point calibration barely separates {src.short} from the "
                   "boresight: hold it at its lab value and let the boresight absorb it, or "
                   "estimate it only from many precise points (an exact trajectory)")


def _separability_findings(a: ScannerAnalysis, sep: Separability) -> list[Finding]:
    """The errors a self-calibration can estimate with the boresight (one pass), and a warning
    for each it cannot."""
    separable, out = [], []
    for src in settings_sources(a.settings):
        own = min(sep.unexplained[n] for n in [src.name] + [c for c, _ in src.parts()])
        if own >= NOT_SEPARABLE:
            separable.append(f"{src.short} ({own:.0%} of its effect is its own)")
        else:
            out.append(_entangled_finding(a, sep, src, own))
    if separable:
        out.insert(0, Finding("pass", "separable from the boresight",
                              f"{'; '.join(separable)}: no boresight rotation reproduces them, a "
                              "self-calibration can estimate them with the boresight"))
    return out


def analysis_verdict(a: ScannerAnalysis, sep: Separability | None) -> Verdict:
    """Pointing against the spec per error and together; separability from the boresight."""
    spec = a.spec_rad / ARCSEC
    n_ok = sum(e.pointing_rad.max() <= a.spec_rad for e in a.effects.values())
    summary = (f"{MODEL_NAMES[a.model]} scanner at {a.range_m:g} m against a {spec:g}″ pointing "
               f"spec ({length(a.spec_rad * a.range_m)} at that range): {n_ok} of "
               f"{len(a.effects)} analysed errors within it")
    if a.defaults_used:
        summary += " (no error given: the published example magnitudes)"
    findings = _pointing_findings(a) + (_separability_findings(a, sep) if sep is not None else [])
    return Verdict(summary, findings)
