"""Known answers of ``calidar accuracy``, written from the ASPRS Positional Accuracy Standards,
Edition 2 (2023), as read for this test (not from the code):

- NVA: RMSE_V(data) = sqrt(Σ dz² / n) over the non-vegetated checkpoints; Edition 2 adds the
  checkpoints' survey error: RMSE_V = sqrt(RMSE_V(data)² + RMSE_V(survey)²).
- The product is of the "X-cm" class when RMSE_V ≤ X; the classes tabulated include 5, 10, 15 cm.
- VVA: the 95th percentile of |dz| over the vegetated checkpoints (percentile by linear
  interpolation at rank 0.95·(n − 1) of the sorted values, counted from 0).
- At least 30 NVA checkpoints; the legacy NSSDA 95 % figure is 1.96 × RMSE_V.

The ground is a tilted plane sampled densely (class 2), so its TIN reproduces the plane exactly and
each checkpoint's dz = surface − checkpoint is the offset the test put under it.
"""

from __future__ import annotations

import csv
import json

import numpy as np
import pytest

from calidar.io.las import write_las
from calidar.pipelines.accuracy import AccuracySettings, measure_accuracy, run_accuracy

CRS = "EPSG:32632"
X0, Y0 = 500_000.0, 5_200_000.0


def plane(x, y):
    return 400.0 + 0.05 * (x - X0) - 0.03 * (y - Y0)


def _strips(folder, extent=200.0, spacing=0.5):
    """Two overlapping flight lines of ground points on the plane (plus vegetation 3 m above)."""
    paths = []
    for k, (xa, xb) in enumerate(((0.0, 120.0), (80.0, extent))):
        gx, gy = np.meshgrid(np.arange(xa, xb, spacing), np.arange(0.0, extent, spacing))
        x, y = X0 + gx.ravel(), Y0 + gy.ravel() + 0.1 * k  # the second line's grid offset: a real TIN
        n = x.size
        veg = np.arange(n) % 7 == 0  # some points are canopy, classified 5, 3 m up
        z = plane(x, y) + np.where(veg, 3.0, 0.0)
        paths.append(write_las(folder / f"line_{k + 1}.laz", np.c_[x, y, z], CRS, gps_time=np.arange(n) * 1e-4 + 1e3 * k,
                               scan_angle_deg=np.zeros(n), point_source_id=k + 1,
                               classification=np.where(veg, 5, 2).astype(np.uint8)))
    return paths


#: NVA offsets: 16 checkpoints +7.4 cm, 14 at −7.4 cm → RMSE 7.4 cm, mean (16 − 14)·7.4/30 cm
NVA_OFFSETS = np.r_[np.full(16, 0.074), np.full(14, -0.074)]
#: VVA offsets: 1, −2, 3, ... 20 cm (|dz| = 1..20 cm)
VVA_OFFSETS = np.array([(k + 1) * (-1) ** k for k in range(20)]) / 100.0


def _checkpoints(path, sigma: float | None = 0.02):
    rng = np.random.default_rng(5)
    xy = np.stack(np.meshgrid(np.arange(10.0, 190.0, 18.0), np.arange(10.0, 190.0, 36.0)), -1).reshape(-1, 2)[:50]
    xy = xy + rng.uniform(-2.0, 2.0, xy.shape)
    offsets = np.r_[NVA_OFFSETS, VVA_OFFSETS]
    rows = ["id,x,y,z,class" + (",sigma" if sigma is not None else "")]
    for k, ((x, y), off) in enumerate(zip(xy, offsets)):
        x, y = X0 + x, Y0 + y
        cover = "NVA" if k < NVA_OFFSETS.size else "vegetated"
        rows.append(f"C{k:02d},{x:.3f},{y:.3f},{plane(x, y) - off:.4f},{cover}" + (f",{sigma}" if sigma is not None else ""))
    path.write_text("\n".join(rows) + "\n")
    return path


def test_the_statistics_are_the_standards(tmp_path):
    strips = _strips(tmp_path)
    a = measure_accuracy(strips, _checkpoints(tmp_path / "cp.csv"))
    acc = a.accuracy
    assert a.used.all() and acc.n_nva == 30 and acc.n_vva == 20
    # every residual is the offset put under its checkpoint (a plane's TIN is the plane)
    np.testing.assert_allclose(a.dz, np.r_[NVA_OFFSETS, VVA_OFFSETS], atol=2e-4)
    assert acc.rmse_data_m == pytest.approx(0.074, abs=2e-4)
    assert acc.rmse_survey_m == pytest.approx(0.02)
    assert acc.rmse_m == pytest.approx(np.sqrt(0.074**2 + 0.02**2), abs=2e-4)  # 7.67 cm
    assert acc.mean_m == pytest.approx(2 * 0.074 / 30, abs=2e-4)
    assert acc.legacy95_m == pytest.approx(1.96 * np.sqrt(0.074**2 + 0.02**2), abs=4e-4)
    # sorted |dz| = 1..20 cm; rank 0.95·19 = 18.05 → 19 cm + 0.05·(20 − 19) cm
    assert acc.vva95_m == pytest.approx(0.1905, abs=2e-4)
    assert acc.class_cm == 10.0 and acc.enough
    assert acc.statement().startswith("tested 7.7 cm RMSEz (NVA, 30 checkpoints): meets the 10-cm vertical accuracy class")
    assert acc.outliers == ()


def test_without_survey_sigma_the_data_term_alone_and_a_warning(tmp_path):
    a = measure_accuracy(_strips(tmp_path), _checkpoints(tmp_path / "cp.csv", sigma=None))
    assert a.accuracy.rmse_m == pytest.approx(0.074, abs=2e-4) and a.accuracy.rmse_survey_m is None
    assert a.accuracy.statement().startswith("tested 7.4 cm RMSEz (NVA, 30 checkpoints): meets the 10-cm")
    a = measure_accuracy(sorted(tmp_path.glob("line_*.laz")), tmp_path / "cp.csv", AccuracySettings(survey_sigma_m=0.05))
    assert a.accuracy.rmse_m == pytest.approx(np.hypot(0.074, 0.05), abs=2e-4)  # 8.9 cm: still 10-cm


def test_outputs_class_not_met_outliers_and_unused(tmp_path, cli):
    strips = _strips(tmp_path)
    cp = _checkpoints(tmp_path / "cp.csv")
    lines = cp.read_text().splitlines()
    lines[1] = f"C00,{lines[1].split(',')[1]},{lines[1].split(',')[2]},{float(lines[1].split(',')[3]) - 0.5:.4f},NVA,0.02"
    x, y = X0 + 50.0, Y0 + 199.55  # inside the files' bounds, beyond line 1's last row: no triangle holds it
    lines.append(f"GAP,{x:.3f},{y:.3f},{plane(x, y):.3f},NVA,0.02")
    cp.write_text("\n".join(lines) + "\n")
    code, out, err = cli("accuracy", *strips, "--checkpoints", cp, "--out", tmp_path / "out", "--class", "5")
    assert code == 3, err  # class 5 cm asked for, not met
    assert "NOT met" in out and "outliers" in out and "GAP" in out
    doc = json.loads((tmp_path / "out" / "accuracy.json").read_text())
    assert doc["outliers"][0]["id"] == "C00" and doc["outliers"][0]["dz_m"] == pytest.approx(0.574, abs=1e-3)
    assert doc["not_used"][0]["id"] == "GAP" and "outside the TIN" in doc["not_used"][0]["reason"]
    assert doc["accuracy"]["n_nva"] == 30 and doc["verdict"]["status"] == "fail"
    rows = list(csv.DictReader((tmp_path / "out" / "checkpoints.csv").open()))
    assert len(rows) == 51 and rows[0]["outlier"] == "yes" and rows[-1]["not_used"]
    assert float(rows[5]["dz_m"]) == pytest.approx(NVA_OFFSETS[5], abs=2e-4)
    html = (tmp_path / "out" / "report.html").read_text()
    assert "Residual map" in html and "Where the error is" in html and "GAP" in html


def test_run_accuracy_writes_its_three_files(tmp_path):
    strips = _strips(tmp_path)
    out = tmp_path / "out"
    out.mkdir()
    run = run_accuracy(strips, _checkpoints(tmp_path / "cp.csv"), out, argv=["calidar", "accuracy"])
    assert sorted(p.name for p in out.iterdir()) == ["accuracy.json", "checkpoints.csv", "report.html"]
    assert run.verdict.status == "pass"


def test_points_in_a_geographic_crs(tmp_path):
    """Points and checkpoints in lon/lat/ellipsoidal height (EPSG:4979): the TIN in a local metric
    frame, the same residuals as in UTM (the plane is the same surface)."""
    import pyproj

    to_geo = pyproj.Transformer.from_crs(CRS, "EPSG:4979", always_xy=True)
    paths = []
    for k, p in enumerate(_strips(tmp_path / "utm")):
        from calidar.io.las import read_las

        pts = read_las(p)
        lon, lat, h = to_geo.transform(*pts.xyz.T)
        paths.append(write_las(tmp_path / f"geo_{k}.laz", np.c_[lon, lat, h], "EPSG:4979", gps_time=pts.gps_time,
                               scan_angle_deg=pts.scan_angle_deg, point_source_id=k + 1,
                               classification=pts.classification))
    utm = _checkpoints(tmp_path / "cp_utm.csv")
    rows = utm.read_text().splitlines()
    out = [rows[0]]
    for r in rows[1:]:
        f = r.split(",")
        lon, lat, h = to_geo.transform(float(f[1]), float(f[2]), float(f[3]))
        out.append(",".join([f[0], f"{lon:.10f}", f"{lat:.10f}", f"{h:.4f}", *f[4:]]))
    (tmp_path / "cp_geo.csv").write_text("\n".join(out) + "\n")
    a = measure_accuracy(paths, tmp_path / "cp_geo.csv")
    np.testing.assert_allclose(a.dz, np.r_[NVA_OFFSETS, VVA_OFFSETS], atol=1e-3)  # 1e-9° storage ≈ 0.1 mm
    assert a.accuracy.class_cm == 10.0


def test_nothing_tested_is_a_failure_with_the_reason(tmp_path):
    strips = _strips(tmp_path)
    x, y = X0 + 50.0, Y0 + 199.55
    (tmp_path / "cp.csv").write_text(f"id,x,y,z,class\nGAP,{x},{y},{plane(x, y)},NVA\n")
    (tmp_path / "out").mkdir()
    run = run_accuracy(strips, tmp_path / "cp.csv", tmp_path / "out")
    assert run.verdict.status == "fail" and run.assessment.accuracy.rmse_m is None
    assert [f.check for f in run.verdict.findings] == ["NVA accuracy class", "checkpoint count", "checkpoints not tested",
                                                         "USGS swath checks"]
    assert (tmp_path / "out" / "report.html").is_file()
