"""Heights above a geoid (docs/conventions.md, Heights): without the PROJ grid a clear error naming
it (never PROJ's "ballpark" fallback, which takes them as ellipsoidal); with the grid installed a
proper transformation; --geoid-undulation N as the documented escape."""

from __future__ import annotations

import numpy as np
import pyproj
import pytest

from calidar import crs as crs_module
from calidar import georef
from calidar.errors import InputError

GEOID_CRS = "EPSG:32632+3855"  # UTM 32N + EGM2008 height
N_M = 47.0


@pytest.fixture
def points():
    """Three points near 45° N, 9° E (UTM 32N) at 100 m above the geoid."""
    x, y = pyproj.Transformer.from_crs("EPSG:4326", "EPSG:32632", always_xy=True).transform([8.9, 9.0, 9.1],
                                                                                            [44.9, 45.0, 45.1])
    return np.c_[x, y, [100.0, 100.0, 100.0]]


def _heights(ecef):
    return pyproj.Transformer.from_crs("EPSG:4978", "EPSG:4979", always_xy=True).transform(*ecef.T)[2]


def test_without_the_grid_a_clear_error(points):
    with pytest.raises(InputError) as e:
        georef.from_crs(points, GEOID_CRS, source="pts.las")
    msg = str(e.value)
    assert msg.startswith("pts.las: crs: WGS 84 / UTM zone 32N + EGM2008 height has heights above a geoid")
    assert "us_nga_egm08_25.tif" in msg and "--geoid-undulation" in msg
    with pytest.raises(InputError, match="us_nga_egm08_25.tif"):
        georef.to_crs(georef.from_crs(points, "EPSG:32632"), GEOID_CRS)


def test_undulation_escape(points):
    e = georef.from_crs(points, GEOID_CRS, geoid_undulation_m=N_M)
    assert _heights(e) == pytest.approx(100.0 + N_M, abs=1e-6)
    assert np.allclose(georef.to_crs(e, GEOID_CRS, geoid_undulation_m=N_M), points, atol=1e-6)
    with pytest.raises(InputError, match="--geoid-undulation: given .* has ellipsoidal heights"):
        georef.from_crs(points, "EPSG:32632", geoid_undulation_m=N_M)


@pytest.fixture
def installed_grid(tmp_path):
    """A stand-in for PROJ's EGM2008 grid (constant N = 47 m over 44–46° N, 8–10° E), installed in a
    PROJ data folder for the test only."""
    import rasterio
    from rasterio.transform import from_origin

    path = tmp_path / "us_nga_egm08_25.tif"
    with rasterio.open(path, "w", driver="GTiff", height=21, width=21, count=1, dtype="float32", crs="EPSG:4326",
                       transform=from_origin(7.95, 46.05, 0.1, 0.1)) as d:
        d.write(np.full((1, 21, 21), N_M, np.float32))
    before = pyproj.datadir.get_data_dir()
    pyproj.datadir.append_data_dir(str(tmp_path))
    crs_module._cached_transformer.cache_clear()
    try:
        yield path
    finally:
        pyproj.datadir.set_data_dir(before)
        crs_module._cached_transformer.cache_clear()


def test_with_the_grid_a_proper_transformation(points, installed_grid):
    e = georef.from_crs(points, GEOID_CRS)
    assert _heights(e) == pytest.approx(100.0 + N_M, abs=1e-3)
    assert np.allclose(e, georef.from_crs(points, GEOID_CRS, geoid_undulation_m=N_M), atol=1e-3)
    assert np.allclose(georef.to_crs(e, GEOID_CRS), points, atol=1e-3)
