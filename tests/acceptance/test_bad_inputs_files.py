"""The bad-input corpus (issue 27), files checked for what they claim and geometry that must hold:
LAZ files whose header under- or over-counts their points, a chunk decoding outside the header's
bounds, damaged scale factors, a wrong UTM zone, two files with one point source id, heights in a
CRS without a vertical part (issue 26), ATL03 fields of the wrong shape, trajectory glitches.

Every case runs ``python -m calidar`` in a subprocess on files written here (from the corpus's
simulated survey and the real data) and checks the exit code, the one-line message and that
nothing was left behind.
"""

from __future__ import annotations

import json

import os
import re
import shutil
import struct
import subprocess
import sys
from pathlib import Path

import laspy
import numpy as np
import pyproj
import pytest

SBET_FIELDS = 17


def run(*args) -> tuple[int, str, str]:
    """``calidar *args`` in a subprocess: (exit code, stdout, stderr)."""
    env = {**os.environ, "COLUMNS": "200"}
    p = subprocess.run([sys.executable, "-m", "calidar", *map(str, args)], capture_output=True, text=True, env=env,
                       timeout=600)
    return p.returncode, p.stdout, p.stderr


def one_error(code: int, err: str, *needles: str) -> str:
    """Exit 1, one "error:" line on stderr holding every needle, no traceback."""
    assert code == 1, err
    assert "Traceback" not in err and "internal error" not in err, err
    errors = [line for line in err.splitlines() if line.startswith("error: ")]
    assert len(errors) == 1, err
    for n in needles:
        assert n in errors[0], (n, errors[0])
    return errors[0]


def _patch(src: Path, dst: Path, *edits: tuple[int, str, float]) -> Path:
    """A copy of ``src`` with header bytes replaced: (offset, struct format, value)."""
    b = bytearray(src.read_bytes())
    for offset, fmt, value in edits:
        struct.pack_into(fmt, b, offset, value)
    dst.write_bytes(bytes(b))
    return dst


#: LAS header offsets (LAS 1.4, ASPRS R15 Table 3): x scale factor, x offset, max/min z, the 64-bit point count
X_SCALE, X_OFFSET, MAX_Z, MIN_Z, POINT_COUNT_64 = 131, 155, 211, 219, 247


@pytest.fixture(scope="module")
def files(corpus, tmp_path_factory):
    """The corpus survey (strips, sbet.out, sensor.toml) and the damaged files made from it."""
    s = corpus.root / "survey"
    d = tmp_path_factory.mktemp("files")
    line1 = s / "strips" / "line_001.laz"
    n = laspy.open(line1).header.point_count
    _patch(line1, d / "undercount.laz", (POINT_COUNT_64, "<Q", n // 2))
    _patch(line1, d / "overcount.laz", (POINT_COUNT_64, "<Q", n + 500))
    _patch(line1, d / "xscale0.laz", (X_SCALE, "<d", 0.0))
    _patch(line1, d / "xscale_negative.laz", (X_SCALE, "<d", -0.001))
    _patch(line1, d / "xscale_nan.laz", (X_SCALE, "<d", float("nan")))
    _patch(line1, d / "xoffset_1e300.laz", (X_OFFSET, "<d", 1e300))
    las = laspy.read(line1)
    lo, hi = float(las.header.mins[2]), float(las.header.maxs[2])
    z = np.array(las.z)
    z[1000:1100] = 2.0e6  # what a corrupted chunk decodes to (±2 000 km) ...
    las.z = z
    las.write(d / "z2000km.laz")
    _patch(d / "z2000km.laz", d / "z2000km.laz", (MAX_Z, "<d", hi), (MIN_Z, "<d", lo))  # ... with the header's bounds
    b = bytearray(line1.read_bytes())  # bytes of the compressed chunk flipped
    start = laspy.open(line1).header.offset_to_point_data + 8
    for k in range(start + 2000, start + 2064):
        b[k] ^= 0x5A
    (d / "flipped.laz").write_bytes(bytes(b))
    tagged = laspy.read(line1)  # the points of UTM 32N tagged 33N
    tagged.header.vlrs = [v for v in tagged.header.vlrs if v.record_id not in (2112, 34735, 34736, 34737)]
    tagged.header.add_crs(pyproj.CRS.from_epsg(32633))
    tagged.write(d / "zone33.laz")
    up = laspy.read(line1)  # heights 30 m up: a geoid height taken as ellipsoidal
    up.z = np.array(up.z) + 30.0
    up.write(d / "up30.laz")
    same = laspy.read(s / "strips" / "line_002.laz")  # line 2 delivered with line 1's point source id
    same.point_source_id[:] = np.asarray(las.point_source_id)[0]
    same.write(d / "line_002_as_1.laz")
    far = laspy.read(s / "strips" / "line_004.laz")  # far from the others and with line 1's id
    far.x = np.array(far.x) + 5000.0
    far.point_source_id[:] = np.asarray(las.point_source_id)[0]
    far.write(d / "far_as_1.laz")
    late = laspy.read(line1)  # GPS times 18 s late (UTC taken for GPS time, or the leap seconds twice)
    late.gps_time = np.array(late.gps_time) + 18.0
    late.write(d / "late18s.laz")
    sbet = np.fromfile(s / "sbet.out", "<f8").reshape(-1, SBET_FIELDS)
    jump = sbet.copy()
    jump[len(jump) // 2, 1] += 1e-3  # one record 6 km north (1e-3 rad of latitude)
    jump.tofile(d / "sbet_jump.out")
    flip = sbet.copy()
    flip[len(flip) // 2, 7] += 1.0  # one record's roll 57° off
    flip.tofile(d / "sbet_roll_glitch.out")
    return s, d


def test_undercounting_header_is_an_error_everywhere(files, tmp_path):
    """A LAZ whose header counts half its points: never read at the header's count (half a strip)."""
    s, d = files
    f = d / "undercount.laz"
    for args in (["info", f], ["inverse", f, "-t", s / "sbet.out", "--out", tmp_path / "v.csv"],
                 ["regeoref", f, "-t", s / "sbet.out", "--from", s / "sensor.toml", "--to", s / "sensor.toml",
                  "--out", tmp_path / "r"],
                 ["quality", f, s / "strips" / "line_002.laz", "--out", tmp_path / "q"]):
        one_error(*run(*args)[::2], "undercount.laz", "point_count", "the header says", "fewer points than the file holds")
    assert list(tmp_path.iterdir()) == []


def test_overcounting_header_is_an_error(files, tmp_path):
    s, d = files
    one_error(*run("inverse", d / "overcount.laz", "-t", s / "sbet.out", "--out", tmp_path / "v.csv")[::2],
              "overcount.laz", "point_count", "more points than the file holds")
    assert not (tmp_path / "v.csv").exists()


@pytest.mark.parametrize("command", ["inverse", "regeoref", "boresight"])
def test_chunk_outside_the_header_bounds_is_named(files, tmp_path, command):
    """z of ±2 000 km where the header says 440–468 m: the points, their LAZ chunk and the field named."""
    s, d = files
    f = d / "z2000km.laz"
    args = {"inverse": [f, "-t", s / "sbet.out", "--out", tmp_path / "v.csv"],
            "regeoref": [f, "-t", s / "sbet.out", "--from", s / "sensor.toml", "--to", s / "sensor.toml",
                         "--out", tmp_path / "r"],
            "boresight": [s / "strips" / "line_002.laz", f, "--trajectory", s / "sbet.out", "--sensor",
                          s / "sensor.toml", "--out", tmp_path / "c"]}[command]
    one_error(*run(command, *args)[::2], "z2000km.laz: z: 100 points (1000–1099, LAZ chunk 0)",
              "outside the header's bounds")
    assert list(tmp_path.iterdir()) == []


def test_flipped_bytes_in_a_chunk(files, tmp_path):
    """Corrupted compressed bytes: one clear line naming the file and the chunk, whatever they decode to."""
    s, d = files
    one_error(*run("inverse", d / "flipped.laz", "-t", s / "sbet.out", "--out", tmp_path / "v.csv")[::2],
              "flipped.laz", "chunk")


@pytest.mark.parametrize("name, field", [("xscale0", "x scale factor"), ("xscale_negative", "x scale factor"),
                                         ("xscale_nan", "x scale factor"), ("xoffset_1e300", "x offset")])
def test_damaged_scale_or_offset(files, tmp_path, name, field):
    """A zero, negative or NaN scale (x all at the offset: ranges 20 m off, regeoref crashed), an absurd offset."""
    s, d = files
    f = d / f"{name}.laz"
    one_error(*run("info", f)[::2], f"{name}.laz: {field}: expected")
    one_error(*run("regeoref", f, "-t", s / "sbet.out", "--from", s / "sensor.toml", "--to", s / "sensor.toml",
                   "--out", tmp_path / "r")[::2], f"{name}.laz: {field}")
    assert not (tmp_path / "r").exists()


def test_wrong_utm_zone_is_an_error(files, tmp_path):
    """Points of UTM 32N tagged 33N (456 km off): inverse and regeoref stop with the likely cause
    (they gave ranges of 456 km and moved points by 896 m with exit 0); boresight too, via --crs."""
    s, d = files
    f = d / "zone33.laz"
    for args in (["inverse", f, "-t", s / "sbet.out", "--out", tmp_path / "v.csv"],
                 ["regeoref", f, "-t", s / "sbet.out", "--from", s / "sensor.toml", "--to", s / "sensor.toml",
                  "--out", tmp_path / "r"],
                 ["inverse", s / "strips" / "line_001.laz", "--crs", "EPSG:32633", "-t", s / "sbet.out",
                  "--out", tmp_path / "v.csv"]):
        one_error(*run(*args)[::2], "sideways from the trajectory", "wrong CRS or UTM zone")
    one_error(*run("boresight", s / "strips" / "line_001.laz", s / "strips" / "line_002.laz", "--crs", "EPSG:32633",
                   "--trajectory", s / "sbet.out", "--sensor", s / "sensor.toml", "--out", tmp_path / "c")[::2],
              "line_001.laz: xyz", "wrong CRS or UTM zone")
    assert list(tmp_path.iterdir()) == []


def test_points_18_s_late_are_a_time_error(files, tmp_path):
    """Times 18 s off: the points lie behind the UAV; the error names the offset it implies."""
    s, d = files
    msg = one_error(*run("inverse", d / "late18s.laz", "-t", s / "sbet.out", "--out", tmp_path / "v.csv")[::2],
                    "late18s.laz: gps_time", "behind the sensor", "UTC against GPS")
    offset = float(msg.split("a time offset of about ")[1].split(" s")[0])
    assert abs(offset + 18.0) < 2.0, msg
    one_error(*run("boresight", s / "strips" / "line_002.laz", d / "late18s.laz", "--trajectory", s / "sbet.out",
                   "--sensor", s / "sensor.toml", "--out", tmp_path / "c")[::2], "late18s.laz: gps_time", "time offset")
    assert list(tmp_path.iterdir()) == []


def test_boresight_names_a_strip_whose_heights_are_off(files, tmp_path):
    s, d = files
    code, out, err = run("boresight", d / "up30.laz", *[s / "strips" / f"line_00{k}.laz" for k in (2, 3)],
                         "--trajectory", s / "sbet.out", "--sensor", s / "sensor.toml", "--out", tmp_path / "c")
    assert code in (0, 3), err
    assert "up30.laz: the heights are +" in out + err and "vertical-datum mismatch" in out + err
    assert "line_002.laz: the heights are" not in out + err


def test_heights_off_the_scan_angles(files, tmp_path):
    """Heights 30 m up (a geoid height taken as ellipsoidal): the inverse states its vertical
    reference, warns that EPSG:32632 has none and names the +30 m the scan angles show."""
    s, d = files
    code, out, err = run("inverse", d / "up30.laz", "-t", s / "sbet.out", "--out", tmp_path / "v.csv")
    assert code == 0, err
    assert "EPSG:32632 has no vertical part: the heights are taken as ellipsoidal" in out
    assert "--geoid-undulation" in out and "vertical-datum mismatch" in out
    delta = float(out.split("the heights are ")[2].split(" ±")[0])
    assert abs(delta - 30.0) < 1.5, out
    code, out, err = run("inverse", s / "strips" / "line_001.laz", "-t", s / "sbet.out", "--out", tmp_path / "w.csv")
    assert code == 0, err
    assert ("heights: ellipsoidal (assumed: EPSG:32632 has no vertical part), confirmed by the file's "
            "scan angles (the heights agree with them to ") in out
    assert "vertical-datum mismatch" not in out


def test_heights_above_a_geoid_with_the_wrong_undulation(corpus, tmp_path):
    """The corpus's geoid.laz (ellipsoidal heights tagged EGM2008) with N = 47 m puts the points 3 m
    below the UAV: the scan angles disagree and the message names a vertical datum among the causes."""
    b, s = corpus.root / "bad", corpus.root / "survey"
    one_error(*run("inverse", b / "geoid.laz", "-t", s / "sbet.out", "--out", tmp_path / "v.csv",
                   "--geoid-undulation", "47")[::2], "geoid.laz: scan_angle", "vertical datum")


def test_files_sharing_a_point_source_id_are_kept_apart(files, tmp_path):
    """Line 2 delivered with line 1's id: the same pairs as with the true ids (none lost, none
    mislabelled), and a note saying so."""
    s, d = files
    strips = [s / "strips" / f"line_00{k}.laz" for k in range(1, 5)]
    code, out0, err = run("quality", *strips, "--out", tmp_path / "q0")
    assert code == 0, err
    code, out1, err = run("quality", strips[0], d / "line_002_as_1.laz", *strips[2:], "--out", tmp_path / "q1")
    assert code == 0, err
    assert "point_source_id 1 is held by 2 files whose GPS times do not interleave: kept apart" in out1
    pairs = [json.loads((tmp_path / q / "quality.json").read_text())["pairs"] for q in ("q0", "q1")]
    rows = [sorted((p["n_cells"], *sorted((p["n_points_a"], p["n_points_b"]))) for p in found) for found in pairs]
    assert len(rows[0]) == len(rows[1]) >= 3
    assert rows[0] == rows[1]  # cells and both point counts of every pair (a line's new id may swap a and b)


def test_far_strip_sharing_an_id_is_named(files, tmp_path):
    """A strip 5 km away with line 1's id: quality keeps it apart from line 1 and names it as
    overlapping nothing; boresight, whose trajectory never flew there, stops on its geometry."""
    s, d = files
    strips = [s / "strips" / f"line_00{k}.laz" for k in range(1, 4)]
    code, out, err = run("quality", *strips, d / "far_as_1.laz", "--out", tmp_path / "q")
    assert code == 0, err
    assert "far_as_1.laz) overlaps no other strip" in out and "kept apart" in out
    code, _, err = run("boresight", *strips, d / "far_as_1.laz", "--trajectory", s / "sbet.out", "--sensor",
                       s / "sensor.toml", "--out", tmp_path / "c")
    line = one_error(code, err, "far_as_1.laz: xyz", " m across")
    # the 5 000 m shift across the north–south line, to within the swath's own few metres
    across = int(re.search(r"(\d+) m across", line).group(1))
    assert abs(across - 5000) <= 10, err


def test_lidar_hd_heights_stated(real_data, tmp_path):
    """French LiDAR HD (EPSG:2154, orthometric heights): quality says how it took the heights."""
    laz = real_data / "ign_two_strips" / "faceraster_numerical_imprecision.laz"
    if not laz.exists():
        pytest.skip(f"real data not found at {real_data}")
    code, out, err = run("quality", laz, "--out", tmp_path / "q")
    assert code == 0, err
    assert "heights: ellipsoidal (assumed: EPSG:2154 has no vertical part)" in out


def test_leeward_checks(real_data, tmp_path):
    """The real leeward strip: consistent as delivered; 30 m up → the vertical warning; retagged
    UTM 12N → the zone error."""
    src = real_data / "leeward_sierra" / "points.las"
    if not src.exists():
        pytest.skip(f"real data not found at {real_data}")
    sbet = real_data / "leeward_sierra" / "sbet.out"
    code, out, err = run("inverse", src, "-t", sbet, "--out", tmp_path / "a.csv")
    assert code == 0 and "vertical-datum mismatch" not in out, out + err
    las = laspy.read(src)
    las.z = np.array(las.z) + 30.0
    las.write(tmp_path / "up30.las")
    code, out, err = run("inverse", tmp_path / "up30.las", "-t", sbet, "--out", tmp_path / "b.csv")
    assert code == 0 and "vertical-datum mismatch" in out, out + err
    one_error(*run("inverse", src, "--crs", "EPSG:32612", "-t", sbet, "--out", tmp_path / "c.csv")[::2],
              "points.las", "wrong CRS or UTM zone")


@pytest.mark.parametrize("name, needles", [("sbet_jump.out", ("position", "m/s", "a position glitch")),
                                           ("sbet_roll_glitch.out", ("roll", "°/s", "an attitude glitch"))])
def test_trajectory_glitches(files, tmp_path, name, needles):
    s, d = files
    one_error(*run("inverse", s / "strips" / "line_001.laz", "-t", d / name, "--out", tmp_path / "v.csv")[::2],
              name, *needles)


def test_atl03_2d_height_names_h_ph(corpus, tmp_path):
    """A 2-D h_ph is blamed on h_ph, not on delta_time."""
    import h5py

    src = next((corpus.root / "photons").glob("*.h5"))
    f = tmp_path / "h_ph_2d.h5"
    shutil.copy(src, f)
    with h5py.File(f, "r+") as h:
        beam = next(k for k in h if k.startswith("gt") and "heights" in h[k])
        hp = h[beam]["heights"]["h_ph"][()]
        del h[beam]["heights"]["h_ph"]
        h[beam]["heights"].create_dataset("h_ph", data=np.stack([hp, hp], axis=1))
    one_error(*run("info", f)[::2], f"{beam}/heights/h_ph", "one value per photon (1-D)")
