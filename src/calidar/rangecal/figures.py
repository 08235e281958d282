"""Figures of the range calibration: residuals per observation and against distance, and the
two-step method's groups."""

from __future__ import annotations

import numpy as np

from calidar.rangecal import RangeCalibration
from calidar.report.plots import plt

MM = 1e3  #: m → mm for display
MAX_LABELS = 12  #: groups above which points are not labelled one by one


def residual_figure(result: RangeCalibration):
    """Residuals (mm) per observation and against the P→X distance, with ±2σ of each equation."""
    obs, fit = result.observations, result.fit
    fig, (ax1, ax2) = plt.subplots(1, 2, figsize=(11, 3.8))
    many = len(obs.groups) > MAX_LABELS  # one colour per group while a legend can show them
    labels = np.where(obs.kind == "E", "E points", "feature points" if many else obs.group)
    idx = np.arange(len(obs))
    for lab in dict.fromkeys(labels):
        m = (labels == lab) & fit.keep
        kw = dict(fmt="o", ms=4, capsize=2, label=lab)
        ax1.errorbar(idx[m], fit.residuals[m] * MM, yerr=2 * fit.sigma[m] * MM, **kw)
        ax2.errorbar(fit.distance[m], fit.residuals[m] * MM, yerr=2 * fit.sigma[m] * MM, **kw)
    rej = ~fit.keep
    if rej.any():
        for ax, x in ((ax1, idx), (ax2, fit.distance)):
            ax.plot(x[rej], fit.residuals[rej] * MM, "kx", ms=9, mew=2,
                    label="rejected (data snooping)")
        ok = fit.residuals[fit.keep] * MM
        span = max(np.abs(ok).max() + 2 * fit.sigma[fit.keep].max() * MM, 1.0) * 1.3
        # keep the kept ones readable; say where the rest went
        if np.abs(fit.residuals[rej] * MM).max() > 3 * span:
            for ax in (ax1, ax2):
                ax.set_ylim(-span, span)
            largest = np.abs(fit.residuals[rej]).max() * MM
            title = f"rejected residuals up to {largest:.0f} mm lie off the scale"
            ax1.set_title(title, fontsize=8)
    for ax in (ax1, ax2):
        ax.axhline(0, color="k", lw=0.8)
        ax.set_ylabel("model − scanner range [mm]")
        ax.grid(alpha=0.3)
    ax1.set_xlabel("observation (file order)")
    ax2.set_xlabel("distance P→X [m]")
    ax1.legend(fontsize=7, ncol=2, loc="upper right")
    fig.tight_layout()
    return fig


def group_figure(result: RangeCalibration):
    """ΔS_i per group (mm) with the points of each group, ΔS and its 95 % interval."""
    m = result.method
    fig, ax = plt.subplots(figsize=(7, 3.5))
    diff = m.feature_diff * MM
    for i, g in enumerate(m.groups):
        sel = m.feature_group == g
        ax.plot(np.full(sel.sum(), i), diff[sel], ".", color="0.5")
        if len(m.groups) <= MAX_LABELS:
            for y, p in zip(diff[sel], m.feature_point[sel]):
                ax.annotate(p, (i, y), xytext=(4, 0), textcoords="offset points", fontsize=7,
                            color="0.4")
    ax.plot(range(len(m.groups)), m.group_delta_s * MM, "o", color="C0", label="ΔS_i (group mean)")
    ax.axhline(m.delta_s * MM, color="C1", label=f"ΔS = {m.delta_s * MM:.2f} mm")
    lo, hi = m.delta_s - m.delta_s_half_width, m.delta_s + m.delta_s_half_width
    ax.axhspan(lo * MM, hi * MM, color="C1", alpha=0.2, label="95 % interval of ΔS")
    step = max(1, len(m.groups) // MAX_LABELS)
    ax.set_xticks(range(0, len(m.groups), step), m.groups[::step])
    ax.set_ylabel("scanner range − S_PX [mm]")
    ax.set_xlabel("group")
    ax.grid(alpha=0.3)
    ax.legend(fontsize=8, loc="upper right")
    fig.tight_layout()
    return fig
