"""Plot helpers shared by the report sections (matplotlib, Agg backend)."""

from __future__ import annotations

import matplotlib

matplotlib.use("Agg")

import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402


def residual_histogram(before: np.ndarray, after: np.ndarray, unit: str = "m",
                       title: str = "Residuals"):
    """Overlaid histograms of residuals before and after a calibration (in ``unit``)."""
    fig, ax = plt.subplots(figsize=(7, 3.5))
    lim = np.percentile(np.abs(np.r_[before, after]), 99) if before.size + after.size else 1.0
    bins = np.linspace(-lim, lim, 81)
    rms_before, rms_after = np.sqrt(np.mean(before**2)), np.sqrt(np.mean(after**2))
    ax.hist(before, bins=bins, alpha=0.5, label=f"before (RMS {rms_before:.4g} {unit})")
    ax.hist(after, bins=bins, alpha=0.5, label=f"after (RMS {rms_after:.4g} {unit})")
    ax.set_xlabel(f"residual [{unit}]")
    ax.set_ylabel("count")
    ax.set_title(title)
    ax.legend()
    return fig


def correlation_figure(corr: np.ndarray, names: list[str]):
    """A correlation matrix as a heat map with every value written in its cell (white on dark
    cells), full labels on both axes."""
    n = len(names)
    size = 1.2 + 0.75 * n
    fig, ax = plt.subplots(figsize=(size + 2.2, size))
    im = ax.imshow(corr, vmin=-1, vmax=1, cmap="RdBu_r")
    ax.set_xticks(range(n), names, rotation=35, ha="right", fontsize=9)
    ax.set_yticks(range(n), names, fontsize=9)
    for i in range(n):
        for j in range(n):
            v = corr[i, j]
            text = _correlation_text(v)
            ax.text(j, i, text, ha="center", va="center", fontsize=9,
                    color="white" if np.isfinite(v) and abs(v) > 0.55 else "black")
    fig.colorbar(im, ax=ax, label="correlation ρ", shrink=0.8)
    fig.tight_layout()
    return fig


def _correlation_text(v: float) -> str:
    """A correlation as its cell shows it: two decimals, signed, zero unsigned; "—" when
    undefined."""
    if not np.isfinite(v):
        return "—"
    return f"{v:+.2f}".replace("+0.00", "0.00").replace("-0.00", "0.00")


def _map_size(nx: int, ny: int) -> tuple[float, float]:
    """Figure width and height (inches) of a map of ny × nx cells: 9 wide when the grid is wide,
    7.5 high when it is tall, the other side following the grid's aspect up to 6:1."""
    aspect = min(max(ny, nx) / max(min(ny, nx), 1), 6)
    if nx >= ny:
        return 9.0, max(2.6, 9.0 / aspect + 1.2)
    return max(4.0, 7.5 / aspect + 2.5), 7.5


def dz_map(grid: np.ndarray, origin: tuple[float, float], cell_m: float, title: str,
           label: str = "dz [mm]", factor: float = 1e3):
    """A map of a difference grid (row 0 north; ``origin`` its north-west corner, m) × ``factor``,
    diverging colours centred on 0 on its own scale (98th percentile of |value|); the figure
    follows the grid's shape, long strips included."""
    ny, nx = grid.shape
    values = grid * factor
    lim = float(np.nanpercentile(np.abs(values), 98)) if np.isfinite(values).any() else 1.0
    wide = nx >= ny
    fig, ax = plt.subplots(figsize=_map_size(nx, ny))
    extent = (origin[0], origin[0] + nx * cell_m, origin[1] - ny * cell_m, origin[1])
    im = ax.imshow(values, cmap="RdBu_r", vmin=-lim, vmax=lim, extent=extent,
                   interpolation="nearest", aspect="equal")
    fig.colorbar(im, ax=ax, label=label, shrink=0.9,
                 orientation="horizontal" if wide else "vertical", pad=0.18 if wide else 0.04)
    ax.ticklabel_format(useOffset=False, style="plain")
    ax.set_title(title, fontsize=10)
    ax.set_xlabel("easting [m]")
    ax.set_ylabel("northing [m]")
    return fig
