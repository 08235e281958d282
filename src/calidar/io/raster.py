"""Raster and picture outputs: a single-band float32 GeoTIFF of a north-up grid and a
matplotlib figure as PNG, each written atomically (:func:`calidar.outputs.atomic_path`)."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from calidar.outputs import atomic_path


def write_geotiff(path: str | Path, grid: np.ndarray, cell_m: float, origin: tuple[float, float],
                  crs=None, force: bool = False) -> Path:
    """``grid`` (ny, nx; row 0 north, NaN no data) as a float32 GeoTIFF with pixel corners at
    ``origin`` (west x, north y) and square cells of ``cell_m``; ``crs`` a rasterio-readable CRS or
    None.

    Built in memory and written as bytes: a full disk is one OSError, not libtiff's lines on
    stderr."""
    import rasterio
    from affine import Affine

    path = Path(path)
    transform = Affine(cell_m, 0.0, origin[0], 0.0, -cell_m, origin[1])
    with atomic_path(path, force) as tmp, rasterio.MemoryFile() as mem:
        with mem.open(driver="GTiff", height=grid.shape[0], width=grid.shape[1], count=1,
                      dtype="float32", crs=crs, nodata=np.nan, transform=transform) as dst:
            dst.write(grid.astype(np.float32), 1)
        tmp.write_bytes(mem.read())
    return path


def write_png(path: str | Path, fig, force: bool = False, dpi: int = 110) -> Path:
    """A matplotlib figure as PNG (tight bounding box); the figure is closed afterwards."""
    import matplotlib.pyplot as plt

    path = Path(path)
    try:
        with atomic_path(path, force) as tmp:
            fig.savefig(tmp, format="png", dpi=dpi, bbox_inches="tight")
    finally:
        plt.close(fig)
    return path
