"""The range-calibration report section (renders a :class:`RangeCalibration`; computes nothing)."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from calidar.rangecal import RangeCalibration
from calidar.rangecal.figures import group_figure, residual_figure
from calidar.rangecal.verdict import stated_precisions
from calidar.report import Report
from calidar.report.numbers import signed as _f

MM, PPM = 1e3, 1e6  #: m → mm, ratio → ppm for display


def _parameter_rows(result: RangeCalibration, truth: dict | None) -> list[list]:
    sol, fit = result.solution, result.fit
    rows = []
    for name, f, unit, d in (("range_offset", MM, "mm", 2), ("range_scale", PPM, "ppm", 1)):
        if fit.interval(name) is None:
            rows.append([name, f"0 ({unit}, held)", "", "", "", "", ""])
            continue
        lo, hi = fit.interval(name)
        t = truth.get(name) if truth else None
        err = None if t is None else sol.values[name] - t
        rows.append([f"{name} [{unit}]", _f(sol.values[name] * f, d),
                     f"{sol.sigma[name] * f:.{d}f}", f"{_f(lo * f, d)} … {_f(hi * f, d)}",
                     _f(None if t is None else t * f, d), _f(None if err is None else err * f, d),
                     "—" if err is None else f"{abs(err) / sol.sigma[name]:.1f}"])
    return rows


def _method_rows(result: RangeCalibration) -> list[list]:
    m = result.method

    def iv(v, h):
        return f"{_f((v - h) * MM, 2)} … {_f((v + h) * MM, 2)}"

    rows = [[f"ΔS_{g}", _f(v * MM, 2), "", ""] for g, v in zip(m.groups, m.group_delta_s)]
    rows.append(["ΔS (mean of the groups)", _f(m.delta_s * MM, 2), f"{m.delta_s_sigma * MM:.2f}",
                 iv(m.delta_s, m.delta_s_half_width)])
    if m.delta is not None:
        rows.append(["Δ (mean of the E points)", _f(m.delta * MM, 2), f"{m.delta_sigma * MM:.2f}",
                     iv(m.delta, m.delta_half_width)])
    return rows


def _model_text(result: RangeCalibration) -> str:
    """The targets, the model and the stated precisions, in words."""
    obs = result.observations
    n_feature, n_e = int(np.sum(obs.kind == "feature")), int(np.sum(obs.kind == "E"))
    return (f"{len(obs)} targets ({n_feature} feature points in {len(obs.groups)} groups, "
            f"{n_e} E points) from {len(obs.setups)} total-station setup(s). Model: scanner "
            "range = (1 + range_scale)·S_PX + range_offset, S_PX the distance from the scanner's "
            "mirror centre P to the target from the two polar observations; P's observations are "
            "nuisance parameters held by their stated precision. Stated precisions: "
            f"{stated_precisions(result)}.")


def _global_test_text(result: RangeCalibration) -> str:
    """σ0 with its 0.95 range, χ², p and the residuals' RMS, in words."""
    g, after = result.fit.global_test, result.solution.residuals_after
    lo, hi = g["sigma0_range95"]
    return (f"Global test: σ0 = {g['sigma0']:.3f} (0.95 range {lo:.2f}–{hi:.2f}), "
            f"χ² = {g['chi2']:.1f} on {g['dof']:.0f} degrees of freedom, p = {g['p_value']:.3f}; "
            f"RMS of the residuals {after['rms'] * MM:.2f} mm over {after['n']} targets.")


#: the two-step method in words
METHOD_TEXT = ("The prescribed two-step method on the same targets: ΔS_i = mean of (scanner range "
               "− S_PX) over group i's feature points, ΔS their mean; Δ = the range error left at "
               "the E points after ΔS (zero without a scale error). σ propagated from the stated "
               "precisions, 95 % = ±1.96 σ.")


def add_section(report: Report, result: RangeCalibration, truth: dict[str, float] | None = None,
                title: str | None = None) -> None:
    """Add the range-calibration section; ``truth``: SI values by parameter name (a
    simulation's)."""
    obs, fit, sol = result.observations, result.fit, result.solution
    name = Path(obs.source).name
    sec = report.section(title or f"Range calibration against a total station ({name})")
    sec.text(_model_text(result))
    sec.table(["parameter", "value", "σ", "95 % interval", "truth", "error", "|error| / σ"],
              _parameter_rows(result, truth),
              caption="Estimates; 95 % intervals from Student's t with "
                      f"{sol.dof:.0f} degrees of freedom (factor {fit.t_factor:.3f})")
    sec.text(_global_test_text(result))
    sec.text(METHOD_TEXT)
    sec.table(["two-step method", "value [mm]", "σ [mm]", "95 % interval [mm]"],
              _method_rows(result))
    if fit.rejected:
        rows = [[r["line"], r["point"], r["group"] or "—", _f(r["w"], 1),
                 _f(r["residual_m"] * MM, 1)] for r in fit.rejected]
        sec.table(["line", "point", "group", "w (standardized)", "residual [mm]"], rows,
                  caption="Rejected by data snooping (|w| > 3.29)")
    sec.figure(residual_figure(result), "Residuals (model − scanner range) per observation and "
               "against distance; bars ±2σ of each observation equation; crosses: rejected "
               "targets.")
    sec.figure(group_figure(result),
               "Per group: scanner range − S_PX of each feature point, ΔS_i and ΔS.")
    for w in sol.warnings:
        sec.warning(w)
