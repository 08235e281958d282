"""Plot helpers shared by the report sections (matplotlib, Agg backend)."""

from __future__ import annotations

import matplotlib

matplotlib.use("Agg")

import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402


def residual_histogram(before: np.ndarray, after: np.ndarray, unit: str = "m", title: str = "Residuals"):
    """Overlaid histograms of residuals before and after a calibration."""
    fig, ax = plt.subplots(figsize=(7, 3.5))
    lim = np.percentile(np.abs(np.r_[before, after]), 99) if before.size + after.size else 1.0
    bins = np.linspace(-lim, lim, 81)
    ax.hist(before, bins=bins, alpha=0.5, label=f"before (RMS {np.sqrt(np.mean(before**2)):.4g} {unit})")
    ax.hist(after, bins=bins, alpha=0.5, label=f"after (RMS {np.sqrt(np.mean(after**2)):.4g} {unit})")
    ax.set_xlabel(f"residual [{unit}]")
    ax.set_ylabel("count")
    ax.set_title(title)
    ax.legend()
    return fig
