"""Bad checkpoint files: one clear line naming the file, the line and the field, exit 1, nothing
written (missing columns, NaN, duplicates, unknown land cover, another CRS, points outside the data)."""

from __future__ import annotations

import numpy as np
import pytest
from test_accuracy_known_answer import X0, Y0, _checkpoints, _strips, plane

from calidar.errors import InputError
from calidar.io.checkpoints import read_checkpoints, write_checkpoints


@pytest.fixture(scope="module")
def strips(tmp_path_factory):
    return _strips(tmp_path_factory.mktemp("strips"))


def _write(tmp_path, text: str):
    p = tmp_path / "cp.csv"
    p.write_text(text)
    return p


GOOD = f"id,x,y,z,class\nA,{X0 + 20:.3f},{Y0 + 20:.3f},{plane(X0 + 20, Y0 + 20):.3f},open\n"

BAD = {  # file text → what the one-line error must contain
    "id,x,y,class\nA,1,2,open\n": ["cp.csv: z: line 1", "no z column", "expected a header"],
    f"id,x,y,z,class\nA,{X0 + 20},{Y0 + 20},nan,open\n": ["cp.csv: z: line 2", "expected a finite number", "'nan'"],
    f"id,x,y,z,class\nA,{X0 + 20},{Y0 + 20},400,open\nA,{X0 + 30},{Y0 + 30},400,open\n":
        ["cp.csv: id: line 3", "'A' is used again (first on line 2)"],
    f"# survey\nid,x,y,z,class\nA,{X0 + 20},{Y0 + 20},400,open\nB,{X0 + 20},{Y0 + 20.0004},401,open\n":
        ["cp.csv: x/y: line 4", "'B' is at the place of 'A' (line 3"],
    f"id,x,y,z,class\nA,{X0 + 20},{Y0 + 20},400,grass\n": ["cp.csv: class: line 2", "non-vegetated", "'grass'"],
    f"id,x,y,z,class,sigma\nA,{X0 + 20},{Y0 + 20},400,vva,-0.01\n": ["cp.csv: sigma: line 2", "σ ≥ 0"],
    f"id,x,y,z,class\nA,{X0 + 20},{Y0 + 20},400\n": ["cp.csv: class: line 2", "4 values, expected 5"],
    "id,x,y,z,class\n": ["cp.csv", "no checkpoints"],
    # geographic coordinates given for UTM points: outside the data, with the hint
    "id,x,y,z,class\nA,8.5,47.1,400,open\n": ["cp.csv: x/y: line 2", "'A'", "outside the points", "another CRS"],
    f"id,x,y,z,class\nA,{X0 + 20},{Y0 + 20},400,open\nB,{X0 + 500},{Y0 + 20},400,open\n":
        ["cp.csv: x/y: line 3", "'B'", "outside the points"],
}


@pytest.mark.parametrize("text", list(BAD))
def test_bad_checkpoint_files_are_named(cli, strips, tmp_path, text):
    cp = _write(tmp_path, text)
    before = cp.read_bytes()
    code, out, err = cli("accuracy", *strips, "--checkpoints", cp, "--out", tmp_path / "out")
    assert code == 1, (out, err)
    line = err.strip()
    assert "\n" not in line and "Traceback" not in line and "internal error" not in line
    for part in BAD[text]:
        assert part in line, (part, line)
    assert not (tmp_path / "out").exists() and cp.read_bytes() == before


def test_another_crs_is_transformed_when_named(cli, strips, tmp_path):
    """Checkpoints in geographic WGS 84 (ellipsoidal heights, as the points' UTM 32N here) with
    --checkpoints-crs EPSG:4979: transformed to the points' CRS, same residuals as in UTM."""
    import pyproj

    utm = read_checkpoints(_checkpoints(tmp_path / "utm.csv"))
    lon, lat, h = pyproj.Transformer.from_crs("EPSG:32632", "EPSG:4979", always_xy=True).transform(*utm.xyz.T)
    geo = tmp_path / "geo.csv"
    geo.write_text("id,lon,lat,h,class,sigma\n".replace("lon", "x").replace("lat", "y") + "".join(
        f"{i},{a:.10f},{b:.10f},{c:.4f},{'vegetated' if v else 'NVA'},0.02\n"
        for i, a, b, c, v in zip(utm.ids, lon, lat, h, utm.vegetated)))
    code, out, err = cli("accuracy", *strips, "--checkpoints", geo, "--checkpoints-crs", "EPSG:4979", "--out",
                         tmp_path / "out")
    assert code == 0, err
    assert "tested 7.7 cm RMSEz" in out.replace("\n", " ")
    code, out, err = cli("accuracy", *strips, "--checkpoints", geo, "--out", tmp_path / "out2")
    assert code == 1 and "outside the points" in err and "another CRS" in err


def test_synonyms_and_round_trip(tmp_path):
    p = write_checkpoints(tmp_path / "c.csv", ["P1", "P2"], np.array([[1.0, 2.0, 3.0], [4.0, 5.0, 6.0]]),
                          [False, True], [0.01, 0.02], "a comment")
    cp = read_checkpoints(p)
    assert list(cp.ids) == ["P1", "P2"] and list(cp.vegetated) == [False, True] and list(cp.sigma_m) == [0.01, 0.02]
    q = _write(tmp_path, "Name;Easting;Northing;Elevation;Land Cover\nP1;1;2;3;Non-Vegetated\nP2;4;5;6;forest\n")
    cp = read_checkpoints(q)
    assert cp.sigma_m is None and list(cp.vegetated) == [False, True] and list(cp.lines) == [2, 3]
    with pytest.raises(InputError, match="columns 'x', 'easting' all name the x column"):
        read_checkpoints(_write(tmp_path, "id,x,easting,y,z,class\n"))
