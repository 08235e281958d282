"""The range-calibration report section and the ``calidar demo`` step."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from calidar.report import Report
from calidar.report.plots import plt
from calidar.rangecal import RangeCalibration, truth_parameters
from calidar.rangecal.fit import target_distances

MM = 1e3  #: m → mm for display


def residual_figure(result: RangeCalibration):
    """Residuals (mm) per observation and against the P→X distance, with ±2σ of each equation."""
    obs, fit = result.observations, result.fit
    fig, (ax1, ax2) = plt.subplots(1, 2, figsize=(11, 3.8))
    labels = np.where(obs.kind == "E", "E points", obs.group)
    idx = np.arange(len(obs))
    for lab in dict.fromkeys(labels):
        m = (labels == lab) & fit.keep
        kw = dict(fmt="o", ms=4, capsize=2, label=lab)
        ax1.errorbar(idx[m], fit.residuals[m] * MM, yerr=2 * fit.sigma[m] * MM, **kw)
        ax2.errorbar(fit.distance[m], fit.residuals[m] * MM, yerr=2 * fit.sigma[m] * MM, **kw)
    rej = ~fit.keep
    if rej.any():
        for ax, x in ((ax1, idx), (ax2, fit.distance)):
            ax.plot(x[rej], fit.residuals[rej] * MM, "kx", ms=9, mew=2, label="rejected (data snooping)")
    for ax in (ax1, ax2):
        ax.axhline(0, color="k", lw=0.8)
        ax.set_ylabel("model − scanner range [mm]")
    ax1.set_xlabel("observation (file order)")
    ax2.set_xlabel("distance P→X [m]")
    ax1.legend(fontsize=7, ncol=2)
    fig.tight_layout()
    return fig


def group_figure(result: RangeCalibration):
    """ΔS_i per group (mm) with the points of each group, ΔS and its 95 % interval."""
    obs, fit, m = result.observations, result.fit, result.method
    fig, ax = plt.subplots(figsize=(7, 3.5))
    keep = fit.keep & (obs.kind == "feature")
    diff = (obs.scanner - target_distances(obs)[0]) * MM
    for i, g in enumerate(m.groups):
        sel = keep & (obs.group == g)
        ax.plot(np.full(sel.sum(), i), diff[sel], ".", color="0.5")
        for x, y, p in zip(np.full(sel.sum(), i), diff[sel], obs.point[sel]):
            ax.annotate(p, (x, y), xytext=(4, 0), textcoords="offset points", fontsize=7, color="0.4")
    ax.plot(range(len(m.groups)), m.group_delta_s * MM, "o", color="C0", label="ΔS_i (group mean)")
    ax.axhline(m.delta_s * MM, color="C1", label=f"ΔS = {m.delta_s * MM:.2f} mm")
    if m.delta_s_half_width is not None:
        ax.axhspan((m.delta_s - m.delta_s_half_width) * MM, (m.delta_s + m.delta_s_half_width) * MM, color="C1",
                   alpha=0.2, label="95 % interval of ΔS")
    ax.set_xticks(range(len(m.groups)), m.groups)
    ax.set_ylabel("scanner range − S_PX [mm]")
    ax.set_xlabel("group")
    ax.legend(fontsize=8)
    fig.tight_layout()
    return fig


def add_section(report: Report, result: RangeCalibration, truth: dict | None = None, title: str | None = None) -> None:
    """Add the range-calibration section; ``truth`` is a simulator's truth.json document."""
    obs, fit, m, sol = result.observations, result.fit, result.method, result.solution
    tp = truth_parameters(truth) if truth else None
    sec = report.section(title or f"Range calibration against a total station ({Path(obs.source).name})")
    sec.text(f"{len(obs)} targets ({int(np.sum(obs.kind == 'feature'))} feature points in {len(obs.groups)} groups, "
             f"{int(np.sum(obs.kind == 'E'))} E points) from {len(obs.setups)} total-station setups. Model: scanner "
             "range = (1 + range_scale)·S_PX + range_offset, σ propagated from the total station's stated precision "
             f"and the scanner noise ({obs.scanner_sigma * MM:g} mm); P's polar observations are nuisance parameters.")
    sec.solution(sol, tp)
    rows = []
    for name, f, unit in (("range_offset", MM, "mm"), ("range_scale", 1e6, "ppm")):
        if fit.interval(name) is None:
            continue
        lo, hi = fit.interval(name)
        t = tp[name] if tp else None
        rows.append([name, sol.values[name] * f, sol.sigma[name] * f, lo * f, hi * f, unit,
                     None if t is None else t * f, None if t is None else ("yes" if lo <= t <= hi else "NO")])
    sec.table(["parameter", "value", "σ", "95 % low", "95 % high", "unit", "truth", "truth inside"], rows,
              caption=f"95 % intervals: Student t with {sol.dof:.0f} dof (factor {fit.t_factor:.3f})")
    g = fit.global_test
    sec.text(f"Global test: σ0 = {g['sigma0']:.3f}, χ² = {g['chi2']:.1f} on {g['dof']:.0f} dof, p = {g['p_value']:.3f} "
             f"({'passed' if g['passed'] else 'FAILED: the stated precisions do not match the residuals'}).")

    def iv(v, h):
        return f"{(v - h) * MM:.2f} … {(v + h) * MM:.2f}"

    method_rows = [[f"ΔS_{gname}", v * MM, "", ""] for gname, v in zip(m.groups, m.group_delta_s)]
    method_rows.append(["ΔS (mean of groups)", m.delta_s * MM, m.delta_s_sigma * MM, iv(m.delta_s, m.delta_s_half_width)])
    if m.delta is not None:
        method_rows.append(["Δ (mean of E points)", m.delta * MM, m.delta_sigma * MM, iv(m.delta, m.delta_half_width)])
    sec.table(["two-step method", "value [mm]", "σ [mm]", "95 % interval [mm]"], method_rows,
              caption="The prescribed method: ΔS from the scan-circle groups, Δ = range error at the E points after ΔS; "
              "σ propagated from the stated precisions, 95 % = ±1.96 σ")
    lv = result.level
    if not lv["level"]:
        sec.warning(f"A/B are not level with P (height offset up to {lv['max_abs_height_m'] * MM:.1f} mm, "
                    f"{lv['max_abs_z']:.1f} σ, line {lv['worst_line']}): the scanner was not set level, so the points "
                    "are not the prescribed ones; the fit uses the general 3-D distances and stays valid.")
    if fit.rejected:
        sec.table(["line", "point", "group", "w", "residual [mm]"],
                  [[r["line"], r["point"], r["group"] or "—", r["w"], r["residual_m"] * MM] for r in fit.rejected],
                  caption="Rejected by data snooping (|w| > 3.29)")
        sec.warning(f"{len(fit.rejected)} observation(s) rejected as outliers; check them in the field notes.")
    if result.acceptance is not None:
        a = result.acceptance
        verdict = "PASS" if a["passed"] else "FAIL"
        msg = (f"Acceptance: {verdict} — the 95 % bound of the raw range error over {a['distance_range_m'][0]:.1f}–"
               f"{a['distance_range_m'][1]:.1f} m is {a['max_bound95_m'] * MM:.2f} mm against a tolerance of "
               f"{a['tolerance_m'] * MM:.2f} mm.")
        (sec.text if a["passed"] else sec.warning)(msg)
    sec.figure(residual_figure(result), "Residuals (model − scanner range) per observation and against distance; "
               "bars ±2σ of each observation equation.")
    sec.figure(group_figure(result), "Per group: scanner range − S_PX of each feature point, ΔS_i and ΔS.")
