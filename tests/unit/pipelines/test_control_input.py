"""The control file of ``calidar boresight --control`` (calidar.pipelines.control): read as a
checkpoint CSV with the land cover optional and σ required, vegetated points left out with a
note, another CRS transformed, clear errors naming the file and the field."""

from __future__ import annotations

from dataclasses import replace
from types import SimpleNamespace

import numpy as np
import pytest

from calidar.crs import from_crs, to_crs
from calidar.errors import InputError
from calidar.io.las import write_las
from calidar.pipelines.control import _strips_crs, control_points, read_control
from calidar.pipelines.inputs import PointOptions
from calidar.strips.strip import LocalFrame

CRS = "EPSG:32632"
X0, Y0 = 500_000.0, 5_200_000.0
SENSOR = SimpleNamespace(crs=None)


@pytest.fixture(scope="module")
def strip(tmp_path_factory):
    x, y = np.meshgrid(np.arange(0.0, 50.0, 5.0), np.arange(0.0, 50.0, 5.0))
    n = x.size
    return write_las(tmp_path_factory.mktemp("control") / "line.laz", np.c_[X0 + x.ravel(), Y0 + y.ravel(), np.full(n, 400.0)],
                     CRS, gps_time=np.arange(n) * 1e-3, scan_angle_deg=np.zeros(n), point_source_id=1)


def _write(tmp_path, text):
    p = tmp_path / "control.csv"
    p.write_text(text)
    return p


def test_sigma_is_required_and_the_land_cover_optional(strip, tmp_path):
    ok = read_control(_write(tmp_path, f"id,x,y,z,sigma\nG1,{X0 + 10},{Y0 + 10},400.02,0.01\n"), None,
                      _strips_crs(strip, PointOptions(), SENSOR))
    expected = from_crs(np.array([[X0 + 10, Y0 + 10, 400.02]]), CRS)
    np.testing.assert_allclose(ok.ecef, expected, atol=1e-6)
    assert ok.notes == ()
    with pytest.raises(InputError) as e:
        read_control(_write(tmp_path, f"id,x,y,z\nG1,{X0},{Y0},400.0\n"), None, _strips_crs(strip, PointOptions(), SENSOR))
    assert "control.csv" in str(e.value) and "sigma" in str(e.value)


def test_vegetated_points_are_left_out_with_a_note(strip, tmp_path):
    text = (f"id,x,y,z,class,sigma\nG1,{X0 + 10},{Y0 + 10},400,open,0.01\nG2,{X0 + 20},{Y0 + 20},400,trees,0.01\n")
    c = read_control(_write(tmp_path, text), None, _strips_crs(strip, PointOptions(), SENSOR))
    assert list(c.checkpoints.ids) == ["G1"] and len(c.ecef) == 1
    assert "1 control points marked vegetated left out" in c.notes[0] and "G2" in c.notes[0]
    with pytest.raises(InputError, match="every control point is marked vegetated"):
        read_control(_write(tmp_path, f"id,x,y,z,class,sigma\nG2,{X0},{Y0},400,trees,0.01\n"), None,
                     _strips_crs(strip, PointOptions(), SENSOR))


def test_another_crs_is_transformed_and_bad_crs_named(strip, tmp_path):
    utm = np.array([[X0 + 12.0, Y0 + 31.0, 400.5]])
    lonlat = to_crs(from_crs(utm, CRS), "EPSG:4979")
    text = f"id,lat,lon,h,sigma\nG1,{lonlat[0, 1]:.10f},{lonlat[0, 0]:.10f},{lonlat[0, 2]:.4f},0.01\n"
    text = text.replace("lat,lon,h", "y,x,z")
    c = read_control(_write(tmp_path, text), "EPSG:4979", _strips_crs(strip, PointOptions(), SENSOR))
    np.testing.assert_allclose(c.ecef, from_crs(utm, CRS), atol=2e-3)
    with pytest.raises(InputError, match="--control-crs"):
        read_control(_write(tmp_path, text), "EPSG:nonsense", _strips_crs(strip, PointOptions(), SENSOR))


def test_two_points_at_one_place_are_named(strip, tmp_path):
    text = f"id,x,y,z,sigma\nG1,{X0 + 10},{Y0 + 10},400,0.01\nG2,{X0 + 10},{Y0 + 10},400.1,0.01\n"
    c = read_control(_write(tmp_path, text), None, _strips_crs(strip, PointOptions(), SENSOR))
    with pytest.raises(InputError, match="'G2' is at the place of 'G1'"):
        control_points(c, LocalFrame.at(c.ecef))


def test_checkpoints_for_the_boresight_need_no_sigma_and_join_the_kept_points(strip, tmp_path):
    """--checkpoints: σ optional (0: not given), vegetated ones left out of the ground check with a
    note, their places added to the control's for the ingest; --checkpoints-crs, --class and
    --control-crs need their file."""
    from calidar.pipelines.control import checked_checkpoints, read_ground
    from calidar.pipelines.strip_config import StripConfig

    text = f"id,x,y,z,class\nC1,{X0 + 10},{Y0 + 10},400.02,open\nC2,{X0 + 20},{Y0 + 20},400,vegetated\n"
    control = _write(tmp_path, f"id,x,y,z,sigma\nG1,{X0 + 5},{Y0 + 5},400.0,0.01\n")
    checkpoints = tmp_path / "checkpoints.csv"
    checkpoints.write_text(text)
    config = StripConfig()
    ground = read_ground(control, checkpoints, config, [strip], SENSOR)
    cp = ground.checkpoints
    assert list(cp.checkpoints.ids) == ["C1"] and cp.checkpoints.sigma_m is None
    assert "left out of the check against the ground" in cp.notes[0] and "C2" in cp.notes[0]
    np.testing.assert_allclose(ground.near, np.vstack([ground.control.ecef, cp.ecef]))
    frame = LocalFrame.at(cp.ecef)
    points, notes = checked_checkpoints(cp, frame, ["before"])
    assert points.sigma_m.tolist() == [0.0] and notes == ["before", *cp.notes]
    none = read_ground(None, None, config, [strip], SENSOR)
    assert none.control is None and none.checkpoints is None and none.near is None
    for change, option in (({"checkpoints_crs": "EPSG:4326"}, "--checkpoints-crs"), ({"checkpoint_class_cm": 5.0}, "--class"),
                           ({"control_crs": "EPSG:4326"}, "--control-crs")):
        with pytest.raises(InputError, match=option):
            read_ground(None, None, replace(config, **change), [strip], SENSOR)
