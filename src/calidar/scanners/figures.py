"""Figures of the structural-error analysis: the pattern, the displacement curves, and the
separability from the boresight."""

from __future__ import annotations

import numpy as np

from calidar.report.numbers import fixed
from calidar.report.plots import plt
from calidar.scanners.analysis import ErrorEffect, ScannerAnalysis
from calidar.scanners.separability import Separability
from calidar.scanners.sources import MODEL_NAMES


def _angle_axis_label(model: str) -> str:
    return "scan angle θ [deg]" if model == "linear" else "encoder angle β [deg]"


def pattern_figure(a: ScannerAnalysis):
    """Top view (x forward up, y right) of the pattern at the range."""
    fig, ax = plt.subplots(figsize=(5.5, 5))
    p = a.points_m
    ax.plot(p[:, 1], p[:, 0], ".", ms=2)
    ax.plot(p[:1, 1], p[:1, 0], "r^", label="β = 0" if a.model != "linear" else "θ = −FOV/2")
    ext = p.max(axis=0) - p.min(axis=0)
    ax.set_aspect("equal", adjustable="datalim")
    ax.set_xlabel("y (right) [m]")
    ax.set_ylabel("x (forward) [m]")
    extent = f"{ext[0]:.1f} m (x) × {ext[1]:.1f} m (y)"
    ax.set_title(f"{MODEL_NAMES[a.model]} pattern at {a.range_m:g} m: {extent}")
    ax.legend(loc="upper right")
    ax.grid(alpha=0.3)
    return fig


def displacement_figure(a: ScannerAnalysis, effect: ErrorEffect, title: str):
    """X/Y/Z displacement (mm) of every pattern point against the encoder/scan angle."""
    fig, ax = plt.subplots(figsize=(7, 3.5))
    deg = np.degrees(a.angles)
    for k, lab in enumerate(("dX (forward)", "dY (right)", "dZ (down)")):
        ax.plot(deg, effect.displacement_m[:, k] * 1e3, label=lab)
    ax.set_xlabel(_angle_axis_label(a.model))
    ax.set_ylabel("displacement [mm]")
    ax.set_title(title, fontsize=9)
    ax.grid(alpha=0.3)
    ax.legend(fontsize=8)
    return fig


def _short(name: str) -> str:
    """A parameter's name short enough for a matrix's axis."""
    return name.replace("boresight_", "bs_").replace("eccentricity", "ecc")


def correlation_axes(ax, names, corr, title: str) -> None:
    """A labelled correlation matrix with its values, white text on dark cells."""
    im = ax.imshow(corr, vmin=-1, vmax=1, cmap="RdBu_r")
    labels = [_short(s) for s in names]
    ax.set_xticks(range(len(names)), labels, rotation=60, ha="right", fontsize=8)
    ax.set_yticks(range(len(names)), labels, fontsize=8)
    for i in range(len(names)):
        for j in range(len(names)):
            v = corr[i, j]
            digits = 3 if 0.99 < abs(v) < 0.9995 else 2  # a third where two would read ±1.00
            ax.text(j, i, fixed(v, digits), ha="center", va="center", fontsize=7,
                    color="white" if abs(v) > 0.6 else "black")
    ax.set_title(title, fontsize=9)
    return im


def separability_figure(sep: Separability, name: str, value_si: float, label: str,
                        unit_value: str, model: str):
    """Left: the error ``name``'s displacements and what the best boresight leaves of them;
    right: the correlations of boresight and structural components (all points known)."""
    n = sep.jacobian.shape[0] // 3
    full = (sep.columns[name] * value_si).reshape(n, 3)
    rest = sep.left_after_boresight(name, value_si)
    x = np.degrees(sep.angles)
    fig, (a1, a2) = plt.subplots(1, 2, figsize=(12, 4.4), gridspec_kw={"width_ratios": [1.3, 1]})
    for i, lab in enumerate("XYZ"):
        a1.plot(x, full[:, i] * 100, color=f"C{i}", label=f"d{lab} from the error")
        a1.plot(x, rest[:, i] * 100, "--", color=f"C{i}",
                label=f"d{lab} left after the best boresight")
    a1.set_xlabel(_angle_axis_label(model))
    a1.set_ylabel("displacement [cm]")
    m = sep.mimic[name]
    mimic = ", ".join(f"{k} {fixed(v, 3)}" for k, v in zip(("roll", "pitch", "yaw"), m)
                      if abs(v) > 5e-4) or "none"
    a1.set_title(f"{label} = {unit_value} at {sep.range_m:g} m: best boresight per unit error: "
                 f"{mimic}; {100 * sep.unexplained[name]:.1f} % left", fontsize=9)
    a1.legend(fontsize=7, ncol=2)
    a1.grid(alpha=0.3)
    im = correlation_axes(a2, sep.names, sep.correlation,
                          "correlation of the estimates (all points known)")
    fig.colorbar(im, ax=a2, fraction=0.046)
    fig.tight_layout()
    return fig
