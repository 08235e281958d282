"""Strip quality (swath-overlap differences) and the ``calidar quality`` command."""

from __future__ import annotations

import json

import numpy as np
import pytest

from calidar.io.las import write_las
from calidar.strips.lines import line_ids
from calidar.strips.quality import QualitySettings, swath_difference


def _surface(rng, n, shift=(0.0, 0.0, 0.0), noise=0.02):
    """Gable roofs (±30° slopes facing four ways) on flat ground, 120 m square."""
    xy = rng.uniform(0, 120, (n, 2))
    u = np.mod(xy, 30.0)
    roof = np.where((u[:, 0] > 10) & (u[:, 1] > 10), 3.0 + 0.6 * np.minimum(np.abs(u[:, 0] - 20), np.abs(u[:, 1] - 20)), 0.0)
    z = roof + rng.normal(0, noise, n)
    p = np.column_stack([xy, z])
    # the strip's displacement: the same surface seen shifted by ``shift``
    return p + np.asarray(shift)


def test_vertical_offset_and_planimetric_shift_are_measured():
    rng = np.random.default_rng(0)
    a = _surface(rng, 200_000, shift=(0.15, -0.10, 0.04))
    b = _surface(rng, 200_000)
    q = swath_difference(1, a, 2, b, QualitySettings(cell_m=2.0))
    assert q.median_dz_m == pytest.approx(0.04, abs=0.004)
    assert q.rmsdz_m == pytest.approx(0.04, abs=0.01)
    assert q.n_cells > 1500
    assert q.dx_m == pytest.approx(0.15, abs=0.03) and q.dy_m == pytest.approx(-0.10, abs=0.03)
    assert q.grid.shape == (60, 60) and np.nanmedian(q.grid) == pytest.approx(q.median_dz_m)


def test_flat_only_overlap_gives_no_planimetric_offsets():
    rng = np.random.default_rng(1)
    a = np.column_stack([rng.uniform(0, 50, (20000, 2)), rng.normal(0.0, 0.02, 20000)])
    b = np.column_stack([rng.uniform(0, 50, (20000, 2)), rng.normal(-0.03, 0.02, 20000)])
    q = swath_difference(1, a, 2, b)
    assert q.median_dz_m == pytest.approx(0.03, abs=0.005)
    assert q.dx_m is None and q.dy_m is None


def test_lines_from_time_gaps_when_ids_are_missing():
    t = np.r_[np.linspace(0, 30, 50), np.linspace(200, 230, 40)]
    ids, how = line_ids(np.zeros(90, int), t[::-1])
    assert how == "gps_time_gaps"
    assert np.all(ids[::-1][:50] == 1) and np.all(ids[::-1][50:] == 2)


def test_real_ign_lines_305_306(cli, real_data, tmp_path):
    laz = real_data / "ign_two_strips" / "faceraster_numerical_imprecision.laz"
    code, out, err = cli("quality", laz, "--json", "--out", tmp_path / "q")
    assert code == 0, err
    doc = json.loads(out)
    (pair,) = doc["pairs"]
    assert (pair["a"], pair["b"]) == (305, 306) and doc["lines_from"] == "point_source_id"
    assert pair["median_dz_m"] == pytest.approx(-0.025, abs=0.004)
    assert pair["n_cells"] > 50 and pair["rmsdz_m"] < 0.05
    assert {p.name for p in (tmp_path / "q").iterdir()} == {"quality.json", "config.toml", "dz_305_306.tif", "dz_305_306.png"}
    import rasterio

    with rasterio.open(tmp_path / "q" / "dz_305_306.tif") as src:
        assert src.crs.to_epsg() == 2154
        assert np.nanmedian(src.read(1)) == pytest.approx(pair["median_dz_m"], abs=1e-6)
    code, out, err = cli("quality", laz, "--out", tmp_path / "q")
    assert code == 1 and "not empty; pass --force" in err


def test_quality_errors_are_one_line(cli, tmp_path):
    rng = np.random.default_rng(2)
    xyz = np.column_stack([rng.uniform(0, 50, (2000, 2)) + [500000, 5000000], rng.normal(0, 0.02, 2000)])
    one = write_las(tmp_path / "one.laz", xyz, "EPSG:32632", gps_time=np.linspace(0, 10, 2000),
                    scan_angle_deg=np.zeros(2000), point_source_id=1)
    far = write_las(tmp_path / "far.laz", xyz + [5000, 0, 0], "EPSG:32632", gps_time=np.linspace(100, 110, 2000),
                    scan_angle_deg=np.zeros(2000), point_source_id=2)
    code, out, err = cli("quality", one)
    assert code == 1 and "found one flight line" in err and "Traceback" not in err
    code, out, err = cli("quality", one, far)
    assert code == 1 and "none of the 2 flight lines (1 (one.laz), 2 (far.laz)) overlap another" in err
    code, out, err = cli("quality", tmp_path / "missing.laz", one)
    assert code == 1 and "missing.laz" in err
