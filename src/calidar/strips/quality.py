"""Strip quality: how well two overlapping strips agree.

Vertical: the swath-overlap difference of the USGS Lidar Base Specification (interswath
relative accuracy): on a grid of ``cell_m`` cells, wherever both strips are smooth (a plane
fits their points within ``max_rms_m``) and gently sloped (< ``max_slope_deg``), the
difference dz = z_a − z_b of the two fitted planes at the cell centre; summarised as
median, RMSDz and max |dz|. Vegetation and edges fail the smoothness test.

Planimetric: on planar cells of all slopes, dz = n · t for the normals n and one
translation t = (dx, dy, dz) of strip a relative to b (least squares with 3·MAD
rejection); dx, dy are reported only when sloped cells face in enough directions.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from calidar.strips.overlap import footprint_area_m2
from calidar.strips.planes import PlaneSettings, fit_patches

#: LAS classes never used for the vertical difference: vegetation (3–5), noise (7, 18), water (9).
EXCLUDED_CLASSES = (3, 4, 5, 7, 9, 18)


@dataclass(frozen=True)
class QualitySettings:
    """Swath-difference settings (metres, degrees where named)."""

    cell_m: float | None = None  #: None → 2 m, larger where too sparse for ≈ min_points per cell
    min_points: int = 6
    max_rms_m: float = 0.08  #: smooth surface: point scatter about the cell's plane
    max_slope_deg: float = 10.0  #: vertical statistics on gentler cells only
    min_sloped_cells: int = 10  #: for planimetric offsets
    min_slope_deg: float = 15.0  #: a cell counts as sloped (planimetric) above this


@dataclass
class PairQuality:
    """Agreement of strips a and b (dz = a − b), metres."""

    a: int
    b: int
    n_cells: int
    median_dz_m: float | None
    rmsdz_m: float | None
    max_abs_dz_m: float | None
    mean_dz_m: float | None
    dx_m: float | None = None  #: planimetric offset of a relative to b (east), sloped planes
    dy_m: float | None = None
    sigma_dxy_m: float | None = None
    n_sloped: int = 0
    cell_m: float = 2.0
    grid: np.ndarray = field(default_factory=lambda: np.zeros((0, 0)), repr=False)  #: (ny, nx) dz, NaN outside, row 0 north
    origin: tuple[float, float] = (0.0, 0.0)  #: (west x, north y) of the grid, m

    def to_dict(self) -> dict:
        keys = ("a", "b", "median_dz_m", "rmsdz_m", "max_abs_dz_m", "mean_dz_m", "n_cells", "dx_m", "dy_m",
                "sigma_dxy_m", "n_sloped", "cell_m")
        return {k: getattr(self, k) for k in keys}


def cell_indices(keys: np.ndarray) -> np.ndarray:
    """Integer grid indices (K, 2) of :func:`calidar.strips.overlap.cell_keys` keys."""
    i = keys >> 32
    j = keys & 0xFFFFFFFF
    j = np.where(j >= 2**31, j - 2**32, j)
    return np.stack([i, j], axis=1)


def _cell_size(points_a, points_b, s: QualitySettings) -> float:
    if s.cell_m:
        return s.cell_m
    dens = [p.shape[0] / max(footprint_area_m2(p), 1e-9) for p in (points_a, points_b)]
    return float(max(2.0, np.ceil(np.sqrt(1.5 * s.min_points / max(min(dens), 1e-9)))))


def swath_difference(a: int, points_a: np.ndarray, b: int, points_b: np.ndarray,
                     settings: QualitySettings | None = None) -> PairQuality:
    """Vertical and planimetric agreement of two strips' points (each (N, 3), metres, z up)."""
    s = settings or QualitySettings()
    cell = _cell_size(points_a, points_b, s)
    ps = PlaneSettings(min_points=s.min_points, max_rms_m=s.max_rms_m, min_spread=0.15)
    pa, pb = fit_patches(np.asarray(points_a, float), cell, ps), fit_patches(np.asarray(points_b, float), cell, ps)
    keys, ia, ib = np.intersect1d(pa.keys, pb.keys, assume_unique=True, return_indices=True)
    ij = cell_indices(keys)
    centre = (ij + 0.5) * cell
    na, nb = pa.normal[ia], pb.normal[ib]

    def z_at(c, n):  # height of the plane through c with normal n at the cell centre
        return c[:, 2] - (n[:, 0] * (centre[:, 0] - c[:, 0]) + n[:, 1] * (centre[:, 1] - c[:, 1])) / n[:, 2]

    flat = (na[:, 2] >= np.cos(np.radians(s.max_slope_deg))) & (nb[:, 2] >= np.cos(np.radians(s.max_slope_deg)))
    dz = z_at(pa.centroid[ia], na) - z_at(pb.centroid[ib], nb)
    q = PairQuality(a, b, int(flat.sum()), None, None, None, None, cell_m=cell)
    if flat.any():
        d = dz[flat]
        q.median_dz_m, q.rmsdz_m = float(np.median(d)), float(np.sqrt(np.mean(d * d)))
        q.max_abs_dz_m, q.mean_dz_m = float(np.max(np.abs(d))), float(np.mean(d))
        lo, hi = ij[flat].min(axis=0), ij[flat].max(axis=0)
        q.grid = np.full((hi[1] - lo[1] + 1, hi[0] - lo[0] + 1), np.nan)
        q.grid[hi[1] - ij[flat, 1], ij[flat, 0] - lo[0]] = d
        q.origin = (float(lo[0] * cell), float((hi[1] + 1) * cell))
    _planimetric(q, pa.centroid[ia] - pb.centroid[ib], nb, s)
    return q


def _planimetric(q: PairQuality, diff: np.ndarray, normal: np.ndarray, s: QualitySettings) -> None:
    """Translation (dx, dy, dz) of a relative to b from n · t = n · (c_a − c_b), robustly."""
    sloped = normal[:, 2] <= np.cos(np.radians(s.min_slope_deg))
    q.n_sloped = int(sloped.sum())
    if q.n_sloped < s.min_sloped_cells:
        return
    h = normal[sloped, :2]
    if np.linalg.eigvalsh(h.T @ h / q.n_sloped)[0] < 0.01:  # all slopes face one way: dx, dy not separable
        return
    y = np.einsum("ij,ij->i", diff, normal)
    keep = np.ones(y.size, bool)
    for _ in range(3):
        t, *_ = np.linalg.lstsq(normal[keep], y[keep], rcond=None)
        r = y - normal @ t
        mad = 1.4826 * np.median(np.abs(r[keep] - np.median(r[keep])))
        keep = np.abs(r) <= 3.0 * max(mad, 1e-6)
    cov = np.linalg.inv(normal[keep].T @ normal[keep]) * np.mean(r[keep] ** 2)
    q.dx_m, q.dy_m = float(t[0]), float(t[1])
    q.sigma_dxy_m = float(np.sqrt(max(cov[0, 0], cov[1, 1])))


def write_rasters(q: PairQuality, out_dir: str | Path, crs=None, force: bool = False) -> list[Path]:
    """dz grid as GeoTIFF (``dz_<a>_<b>.tif``, float32 m, NaN nodata) and a PNG picture."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    import rasterio
    from affine import Affine

    from calidar.outputs import atomic_path

    out_dir = Path(out_dir)
    paths = []
    if q.grid.size == 0:
        return paths
    tif = out_dir / f"dz_{q.a}_{q.b}.tif"
    with atomic_path(tif, force) as tmp:
        with rasterio.open(tmp, "w", driver="GTiff", height=q.grid.shape[0], width=q.grid.shape[1], count=1,
                           dtype="float32", crs=crs, nodata=np.nan,
                           transform=Affine(q.cell_m, 0.0, q.origin[0], 0.0, -q.cell_m, q.origin[1])) as dst:
            dst.write(q.grid.astype(np.float32), 1)
    paths.append(tif)
    fig = dz_figure(q)
    png = out_dir / f"dz_{q.a}_{q.b}.png"
    with atomic_path(png, force) as tmp:
        fig.savefig(tmp, format="png", dpi=110, bbox_inches="tight")
    plt.close(fig)
    paths.append(png)
    return paths


def dz_figure(q: PairQuality, vmax: float | None = None):
    """A map of dz (m) for one pair, diverging colours centred on 0."""
    import matplotlib.pyplot as plt

    fig, ax = plt.subplots(figsize=(5.5, 4.5))
    lim = vmax or (float(np.nanpercentile(np.abs(q.grid), 98)) if np.isfinite(q.grid).any() else 1.0)
    ny, nx = q.grid.shape
    extent = (q.origin[0], q.origin[0] + nx * q.cell_m, q.origin[1] - ny * q.cell_m, q.origin[1])
    im = ax.imshow(q.grid, cmap="RdBu_r", vmin=-lim, vmax=lim, extent=extent, interpolation="nearest")
    fig.colorbar(im, ax=ax, label=f"dz = z({q.a}) − z({q.b}) [m]")
    ax.set_title(f"strips {q.a} − {q.b}: median {q.median_dz_m or 0:+.3f} m, RMSDz {q.rmsdz_m or 0:.3f} m")
    ax.set_xlabel("x [m]")
    ax.set_ylabel("y [m]")
    return fig
