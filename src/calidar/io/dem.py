"""A DEM GeoTIFF for ``calidar plan --terrain``: heights on a north-up grid in projected metres."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from calidar.errors import InputError

MAX_CELLS = 50_000_000  #: a larger DEM: crop it to the planned block


def read_dem(path: Path) -> tuple[np.ndarray, float, float, float, float]:
    """Band 1 of a GeoTIFF → (heights (ny, nx) m with no-data as NaN, x and y of node (0, 0), dx,
    dy) for a north-up grid; node (i, j) at (x0 + j·dx, y0 − i·dy), the pixel centres."""
    import rasterio
    from rasterio.errors import RasterioIOError

    path = Path(path)
    if not path.is_file():
        raise InputError(path, "--terrain", "not found; expected flat, flat:HEIGHT, "
                         "scene[:PRESET[:SEED]] or a DEM GeoTIFF")
    try:
        with rasterio.open(path) as src:
            if src.width * src.height > MAX_CELLS:
                raise InputError(path, "size", f"{src.width} × {src.height} cells; expected at "
                                 f"most {MAX_CELLS:,} (crop the DEM to the block)")
            t = src.transform
            if t.b != 0 or t.d != 0 or t.a <= 0 or t.e >= 0:
                raise InputError(path, "transform", "expected a north-up grid (no rotation, "
                                 "positive x and negative y pixel size)")
            if src.crs is not None and src.crs.is_geographic:
                raise InputError(path, "crs", f"{src.crs} is geographic; expected a projected CRS "
                                 "in metres (the flight lines are in its metres)")
            z = src.read(1, masked=True).astype(float).filled(np.nan)
    except RasterioIOError as e:
        first_line = str(e).splitlines()[0][:120]
        raise InputError(path, "file", f"not a readable GeoTIFF ({first_line})") from None
    if not np.any(np.isfinite(z)):
        raise InputError(path, "heights", "no valid height; expected a DEM with data")
    if np.nanmax(np.abs(z)) > 10_000:
        raise InputError(path, "heights", f"heights up to {np.nanmax(np.abs(z)):.0f}; expected "
                         "metres within ±10 000")
    return z, t.c + t.a / 2, t.f + t.e / 2, t.a, -t.e
