"""Flight-line files of ``calidar plan``: CSV and GeoJSON read alike; errors name file, row and field."""

from __future__ import annotations

import json

import numpy as np
import pytest

from calidar.errors import InputError
from calidar.io.flight_lines import flight_lines_csv, read_flight_lines


def test_csv_and_geojson_give_the_same_lines(tmp_path):
    csv = tmp_path / "lines.csv"
    csv.write_text("# plan\nspeed_mps,height_agl_m,start_x,start_y,end_x,end_y,line\n8,80,-30,-60,-30,60,7\n"
                   "9,120,30,60,30,-60,3\n")
    geo = tmp_path / "lines.geojson"
    geo.write_text(json.dumps({"type": "FeatureCollection", "features": [
        {"type": "Feature", "geometry": {"type": "LineString", "coordinates": [[-30, -60], [0, 0], [-30, 60]]},
         "properties": {"line": 7, "height_agl_m": 80, "speed_mps": 8}},
        {"type": "Feature", "geometry": {"type": "LineString", "coordinates": [[30, 60], [30, -60]]},
         "properties": {"line": 3, "height_agl_m": 120, "speed_mps": 9}}]}))
    a, b = read_flight_lines(csv), read_flight_lines(geo)
    assert [ln.to_dict() for ln in a] == [ln.to_dict() for ln in b]
    assert a[0].number == 7 and a[0].azimuth == pytest.approx(0.0) and a[1].azimuth == pytest.approx(np.pi)
    back = tmp_path / "back.csv"
    back.write_text(flight_lines_csv(a))
    assert [ln.to_dict() for ln in read_flight_lines(back)] == [ln.to_dict() for ln in a]


@pytest.mark.parametrize("row, field", [("1,0,0,0,100,0,8", "height_agl_m"), ("1,0,0,0,100,80,-1", "speed_mps"),
                                        ("1,0,0,0,1,80,8", "end_x/end_y"), ("x,0,0,0,100,80,8", "line"),
                                        ("1,0,0,0,inf,80,8", "end_y")])
def test_bad_rows_are_named(tmp_path, row, field):
    p = tmp_path / "bad.csv"
    p.write_text("line,start_x,start_y,end_x,end_y,height_agl_m,speed_mps\n" + row + "\n")
    with pytest.raises(InputError) as e:
        read_flight_lines(p)
    assert f"row 1 {field}" in str(e.value) and "bad.csv" in str(e.value)
