"""LAS/LAZ files checked for what their header claims (calidar.io.las_checks, issue 27)."""

import struct

import laspy
import numpy as np
import pytest

from calidar.errors import InputError
from calidar.io import iter_las_chunks, read_las

POINT_COUNT_12 = 107  #: LAS 1.2: the uint32 point count (ASPRS LAS 1.2, Table 4)


def _laz12(path, n, seed=0):
    """A LAS 1.2 format 3 LAZ (not layered: chunks of 50 000 points without their own counts)."""
    h = laspy.LasHeader(point_format=3, version="1.2")
    h.scales, h.offsets = [0.01] * 3, [500000.0, 5200000.0, 0.0]
    las = laspy.LasData(h)
    rng = np.random.default_rng(seed)
    las.x, las.y = 500000 + rng.uniform(0, 500, n), 5200000 + rng.uniform(0, 500, n)
    las.z, las.gps_time = 440 + rng.uniform(0, 25, n), np.linspace(1000.0, 1100.0, n)
    las.write(path)
    return path


def _count(src, dst, n):
    b = bytearray(src.read_bytes())
    struct.pack_into("<I", b, POINT_COUNT_12, n)
    dst.write_bytes(bytes(b))
    return dst


@pytest.mark.parametrize("n, claimed, problem", [
    (40_000, 20_000, "fewer points than the file holds"),  # one chunk: half its bytes unused
    (120_000, 110_000, "fewer points than the file holds"),  # within the last chunk
    (120_000, 60_000, "the LAZ chunk table 3 chunks of 50000"),  # fewer chunks than the table has
    (40_000, 45_000, "more points than it holds"),
])
def test_laz12_counts_against_the_chunks(tmp_path, n, claimed, problem):
    bad = _count(_laz12(tmp_path / "a.laz", n), tmp_path / "b.laz", claimed)
    with pytest.raises(InputError, match=f"b.laz: point_count: .*{problem}"):
        read_las(bad, fields=())
    assert len(read_las(tmp_path / "a.laz", fields=())) == n  # the true file reads whole


def test_real_laz_files_pass(real_data):
    for path, n in (("ign_two_strips/faceraster_numerical_imprecision.laz", 18074),
                    ("pdal_autzen/autzen_trim.laz", 110000), ("lidr_topography/Topography.laz", 73403)):
        if (real_data / path).exists():
            assert len(read_las(real_data / path, fields=())) == n


def test_points_outside_the_bounds_name_their_chunk(tmp_path):
    src = _laz12(tmp_path / "a.laz", 120_000)
    las = laspy.read(src)
    z = np.array(las.z)
    z[60_000:60_010] = -2.0e6
    las.z = z
    las.write(tmp_path / "b.laz")
    b = bytearray((tmp_path / "b.laz").read_bytes())
    struct.pack_into("<d", b, 219, 440.0)  # min z as the good file's
    (tmp_path / "b.laz").write_bytes(bytes(b))
    with pytest.raises(InputError, match=r"b.laz: z: 10 points \(60000–60009, LAZ chunk 1\) have z from -2e\+06"):
        for _ in iter_las_chunks(tmp_path / "b.laz", 30_000, fields=()):
            pass


def test_bounds_tolerate_their_own_extent(tmp_path):
    """Header bounds a little stale (points up to one extent beyond) are no corruption."""
    src = _laz12(tmp_path / "a.laz", 1000)
    b = bytearray(src.read_bytes())
    struct.pack_into("<d", b, 211, 460.0)  # max z 460 while points reach 465
    (tmp_path / "b.laz").write_bytes(bytes(b))
    assert len(read_las(tmp_path / "b.laz", fields=())) == 1000


@pytest.mark.parametrize("offset, value, field", [(131, 0.0, "x scale factor"), (139, -0.01, "y scale factor"),
                                                  (147, float("nan"), "z scale factor"), (155, 1e300, "x offset")])
def test_scales_and_offsets(tmp_path, offset, value, field):
    src = _laz12(tmp_path / "a.laz", 100)
    b = bytearray(src.read_bytes())
    struct.pack_into("<d", b, offset, value)
    (tmp_path / "b.laz").write_bytes(bytes(b))
    with pytest.raises(InputError, match=f"b.laz: {field}: expected"):
        read_las(tmp_path / "b.laz")
