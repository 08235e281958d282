import laspy
import numpy as np
import pyproj
import pytest

from calidar.errors import InputError, OutputExistsError
from calidar.io import iter_las_chunks, read_las, write_las
from calidar.io.las import (
    adjusted_standard_in_week, adjusted_standard_to_week_seconds, iter_las_times, single_gps_week,
    week_seconds_to_adjusted_standard,
)


def _points(n=1000, seed=0):
    rng = np.random.default_rng(seed)
    xyz = np.c_[rng.uniform(300000, 301000, n), rng.uniform(4.18e6, 4.181e6, n), rng.uniform(2000, 2500, n)]
    return xyz, 400000.0 + np.sort(rng.uniform(0, 10, n)), rng.uniform(-30, 30, n)


@pytest.mark.parametrize("suffix", [".las", ".laz"])
def test_write_read_round_trip(tmp_path, suffix):
    xyz, t, ang = _points()
    path = write_las(tmp_path / f"a{suffix}", xyz, "EPSG:32611", gps_time=t, scan_angle_deg=ang, point_source_id=7,
                     classification=np.full(t.size, 2), intensity=np.arange(t.size))
    p = read_las(path)
    assert len(p) == t.size
    assert np.max(np.abs(p.xyz - xyz)) <= 0.0005 + 1e-9  # 1 mm scale
    assert np.array_equal(p.gps_time, t)
    assert np.max(np.abs(p.scan_angle_deg - ang)) <= 0.003 + 1e-12  # 0.006° steps
    assert np.all(p.point_source_id == 7) and np.all(p.classification == 2)
    assert np.array_equal(p.intensity, np.arange(t.size))
    assert np.all(p.return_number == 1) and np.all(p.number_of_returns == 1)
    assert p.crs.to_epsg() == 32611
    assert p.time_system == "gps_week_seconds"
    with laspy.open(path) as r:
        assert r.header.version.minor == 4 and r.header.point_format.id == 6
        assert r.header.are_points_compressed == (suffix == ".laz")
    with pytest.raises(OutputExistsError):
        write_las(path, xyz, "EPSG:32611", gps_time=t, scan_angle_deg=ang, point_source_id=7)


def test_chunks_cover_the_file(tmp_path):
    xyz, t, ang = _points(2500)
    path = write_las(tmp_path / "c.laz", xyz, "EPSG:32611", gps_time=t, scan_angle_deg=ang, point_source_id=1)
    chunks = list(iter_las_chunks(path, chunk_points=1000, fields=("scan_angle_deg",)))
    assert [len(c) for c in chunks] == [1000, 1000, 500]
    assert np.array_equal(np.concatenate([c.gps_time for c in chunks]), t)
    assert chunks[0].point_source_id is None and chunks[0].crs.to_epsg() == 32611


@pytest.mark.parametrize("suffix", [".las", ".laz"])
def test_a_range_of_points_reads_as_the_same_slice_of_the_file(tmp_path, suffix):
    """start/stop read [start, stop) only (a LAZ seeks by its chunk table, across its 50 000-point chunks)."""
    xyz, t, ang = _points(120_000)
    path = write_las(tmp_path / f"r{suffix}", xyz, "EPSG:32611", gps_time=t, scan_angle_deg=ang, point_source_id=1)
    for start, stop in [(0, 7_000), (49_990, 100_010), (110_000, None), (119_999, 200_000)]:
        chunks = list(iter_las_chunks(path, chunk_points=20_000, start=start, stop=stop))
        want = slice(start, stop)
        assert np.array_equal(np.concatenate([c.gps_time for c in chunks]), t[want])
        assert np.max(np.abs(np.concatenate([c.xyz for c in chunks]) - xyz[want])) <= 0.0005 + 1e-9
        assert max(len(c) for c in chunks) <= 20_000


def test_adjusted_standard_time(tmp_path):
    week = 2200
    t_week = 345600.0 + np.linspace(0, 100, 50)
    t_adj = week_seconds_to_adjusted_standard(t_week, week)
    back, w = adjusted_standard_to_week_seconds(t_adj)
    assert w == week and np.allclose(back, t_week, atol=1e-6)
    xyz, _, ang = _points(50)
    path = write_las(tmp_path / "s.las", xyz, "EPSG:32611", gps_time=t_adj, scan_angle_deg=ang, point_source_id=1,
                     time_system="gps_adjusted_standard")
    p = read_las(path)
    assert p.time_system == "gps_adjusted_standard"
    assert np.allclose(p.gps_week_seconds(), t_week, atol=1e-6)
    with pytest.raises(InputError, match="span GPS weeks"):
        adjusted_standard_to_week_seconds(week_seconds_to_adjusted_standard([604790.0, 604810.0], week))


def test_real_las_12_geotiff_keys(real_data):
    p = read_las(real_data / "leeward_sierra" / "points.las")
    assert len(p) == 1325
    # user-defined GeoTIFF keys: UTM zone 11N conversion (16011) on WGS 84 parameters
    assert p.crs.to_epsg() == 32611
    assert p.scan_angle_deg.min() == -30 and p.scan_angle_deg.max() == 29
    assert np.all(p.point_source_id == 36)
    assert p.gps_time.min() == pytest.approx(400825.106, abs=1e-3)
    assert read_las(real_data / "leeward_sierra" / "points.las", crs="EPSG:32612").crs.to_epsg() == 32612


def test_real_laz_lambert93(real_data):
    p = read_las(real_data / "ign_two_strips" / "faceraster_numerical_imprecision.laz")
    assert p.crs.to_epsg() == 2154
    ids, counts = np.unique(p.point_source_id, return_counts=True)
    assert dict(zip(ids.tolist(), counts.tolist())) == {305: 10020, 306: 8054}


@pytest.mark.parametrize("fmt", [0, 2])
def test_point_format_without_gps_time(tmp_path, fmt):
    las = laspy.create(point_format=fmt, file_version="1.2")
    las.x = np.arange(3.0)
    las.y = np.arange(3.0)
    las.z = np.arange(3.0)
    path = tmp_path / "nogps.las"
    las.write(path)
    with pytest.raises(InputError, match=f"nogps.las: point_format: point format {fmt} has no GPS time"):
        read_las(path)


def test_no_crs_and_not_las(tmp_path):
    las = laspy.create(point_format=1, file_version="1.2")
    las.x = las.y = las.z = np.arange(3.0)
    las.gps_time = np.arange(3.0)
    las.write(tmp_path / "nocrs.las")
    assert read_las(tmp_path / "nocrs.las").crs is None
    assert read_las(tmp_path / "nocrs.las", crs="EPSG:2154").crs == pyproj.CRS("EPSG:2154")
    (tmp_path / "x.las").write_text("hello")
    with pytest.raises(InputError, match="not a readable LAS/LAZ"):
        read_las(tmp_path / "x.las")


def test_unknown_crs_and_truncated_file(tmp_path):
    xyz, t, ang = _points(200)
    path = write_las(tmp_path / "a.las", xyz, "EPSG:32611", gps_time=t, scan_angle_deg=ang, point_source_id=1)
    with pytest.raises(InputError, match="a.las: crs: expected a CRS pyproj knows"):
        read_las(path, crs="EPSG:999999")
    cut = tmp_path / "cut.las"
    cut.write_bytes(path.read_bytes()[:-1000])
    with pytest.raises(InputError, match="cut.las"):
        read_las(cut)
    laz = write_las(tmp_path / "a.laz", xyz, "EPSG:32611", gps_time=t, scan_angle_deg=ang, point_source_id=1)
    (tmp_path / "cut.laz").write_bytes(laz.read_bytes()[:-len(laz.read_bytes()) // 2])
    with pytest.raises(InputError, match="cut.laz: cannot read the points"):
        read_las(tmp_path / "cut.laz")
    with pytest.raises(InputError, match="cut.laz: cannot read the points"):
        list(iter_las_times(tmp_path / "cut.laz"))


def _geokeys(*keys):
    """A GeoKeyDirectoryVlr with (id, value) short keys."""
    from laspy.vlrs.known import GeoKeyDirectoryVlr, GeoKeyEntryStruct

    vlr = GeoKeyDirectoryVlr()
    vlr.geo_keys_header.key_directory_version = vlr.geo_keys_header.key_revision = 1
    vlr.geo_keys = []
    for key_id, value in keys:
        k = GeoKeyEntryStruct()
        k.id, k.tiff_tag_location, k.count, k.value_offset = key_id, 0, 1, value
        vlr.geo_keys.append(k)
    vlr.geo_keys_header.number_of_keys = len(keys)
    return vlr


@pytest.mark.parametrize("model_type, epsg", [(3, 4978), (2, 4326)])
def test_geotiff_model_type_geocentric_is_ecef(tmp_path, model_type, epsg):
    """GTModelTypeGeoKey = 3 (geocentric) with GeographicTypeGeoKey 4326 is WGS 84 ECEF, not lat/lon."""
    las = laspy.create(point_format=1, file_version="1.2")
    las.x, las.y, las.z = [-2450000.0, -2450001.0], [-4416000.0, -4416001.0], [3886100.0, 3886101.0]
    las.gps_time = [1.0, 2.0]
    las.header.vlrs.append(_geokeys((1024, model_type), (2048, 4326)))
    las.write(tmp_path / "e.las")
    assert read_las(tmp_path / "e.las").crs.to_epsg() == epsg


@pytest.mark.parametrize("suffix", [".las", ".laz"])
def test_iter_las_times_streams_only_times(tmp_path, suffix):
    xyz, t, ang = _points(2500)
    path = write_las(tmp_path / f"t{suffix}", xyz, "EPSG:32611", gps_time=t, scan_angle_deg=ang, point_source_id=1)
    chunks = list(iter_las_times(path, chunk_points=1000))
    assert [c.size for c in chunks] == [1000, 1000, 500]
    assert np.array_equal(np.concatenate(chunks), t)


def test_single_gps_week(tmp_path):
    week = 2300
    t = week_seconds_to_adjusted_standard(np.array([604799.0, 604800.0]), week)
    assert single_gps_week(t[0], t[0]) == week and single_gps_week(t[1], t[1]) == week + 1
    with pytest.raises(InputError, match="f.las: gps_time: .* span GPS weeks 2300–2301"):
        single_gps_week(t[0], t[1], tmp_path / "f.las")
    assert np.allclose(adjusted_standard_in_week(t, week), [604799.0, 604800.0], atol=1e-6)
    back, w = adjusted_standard_to_week_seconds(np.r_[t[0], np.nan])
    assert w == week and back[0] == pytest.approx(604799.0, abs=1e-6) and np.isnan(back[1])


def _with_point_count(src, dst, count):
    """A copy of an uncompressed LAS 1.4 file whose header claims ``count`` points."""
    b = bytearray(src.read_bytes())
    b[247:255] = np.uint64(count).tobytes()  # LAS 1.4 number of point records (uint64 at byte 247)
    dst.write_bytes(bytes(b))
    return dst


@pytest.mark.parametrize("claimed", [990, 1010])
def test_header_point_count_must_match_the_records(tmp_path, claimed):
    xyz, t, ang = _points()
    las = write_las(tmp_path / "a.las", xyz, "EPSG:32611", gps_time=t, scan_angle_deg=ang, point_source_id=1)
    bad = _with_point_count(las, tmp_path / "bad.las", claimed)
    with pytest.raises(InputError) as e:
        read_las(bad)
    assert str(e.value) == (f"{bad}: point_count: the header says {claimed} points, the file holds 1000 point "
                            "records: truncated or a damaged header")


def test_laz_with_fewer_records_than_its_header(tmp_path):
    xyz, t, ang = _points()
    src = laspy.read(write_las(tmp_path / "a.las", xyz, "EPSG:32611", gps_time=t, scan_angle_deg=ang, point_source_id=1))
    src.header.point_count = 1000
    head = laspy.LasHeader(point_format=6, version="1.4")
    head.scales, head.offsets = src.header.scales, src.header.offsets
    with laspy.open(tmp_path / "b.laz", mode="w", header=head, do_compress=True) as w:
        w.write_points(src.points[:600])
    b = bytearray((tmp_path / "b.laz").read_bytes())
    b[247:255] = np.uint64(1000).tobytes()
    (tmp_path / "b.laz").write_bytes(bytes(b))
    with pytest.raises(InputError, match="b.laz: point_count: the header says 1000 points, the LAZ chunks hold 600: "
                       "a header counting more points"):  # checked when opened (LAZ 1.4: the chunks' own counts)
        list(iter_las_chunks(tmp_path / "b.laz", 250))


def test_absurd_coordinates_are_an_error(tmp_path):
    xyz, t, ang = _points()
    b = bytearray(write_las(tmp_path / "a.las", xyz, "EPSG:32611", gps_time=t, scan_angle_deg=ang,
                            point_source_id=1).read_bytes())
    b[131:139] = np.float64(1e295).tobytes()  # the x scale factor: x = 1e295 × integer ≈ 1e300
    (tmp_path / "huge.las").write_bytes(bytes(b))
    with pytest.raises(InputError, match=r"huge.las: x scale factor: expected a positive scale ≤ 1 .*got 1e\+295"):
        read_las(tmp_path / "huge.las")


def test_point_options_override_the_time_system(tmp_path):
    """--time-system: the global-encoding bit says week seconds, the times are adjusted standard."""
    from calidar.io.las import PointOptions, las_time_system

    xyz, t, ang = _points()
    path = write_las(tmp_path / "a.las", xyz, "EPSG:32611", gps_time=t + 3.07e8, scan_angle_deg=ang, point_source_id=1)
    assert read_las(path).time_system == "gps_week_seconds"
    opts = PointOptions(time_system="adjusted")
    p = read_las(path, options=opts)
    assert p.time_system == "gps_adjusted_standard" and las_time_system(path, opts.time_system) == p.time_system
    assert [c.time_system for c in iter_las_chunks(path, 400, options=opts)] == ["gps_adjusted_standard"] * 3
    assert PointOptions(time_system="gps_week_seconds").time_system == "gps_week_seconds"
    with pytest.raises(InputError, match="--time-system: expected one of week, adjusted, got 'gps'"):
        PointOptions(time_system="gps")
    with pytest.raises(InputError, match=r"--geoid-undulation: expected a finite number in \[-150, 150\] m, got nan"):
        PointOptions(geoid_undulation_m=float("nan"))
    with pytest.raises(ValueError, match="not both"):
        read_las(path, crs="EPSG:32611", options=opts)


@pytest.mark.parametrize("suffix", [".las", ".laz"])
def test_coordinates_are_laspys_scaled_values_bit_for_bit(tmp_path, suffix):
    # the (N, 3) coordinates written in place (issue 32) equal laspy's own x, y, z arrays stacked
    from calidar.io.las import iter_las_fields

    xyz, t, ang = _points(5000, seed=3)
    path = write_las(tmp_path / f"b{suffix}", xyz, "EPSG:32611", gps_time=t, scan_angle_deg=ang,
                     point_source_id=2)
    with laspy.open(path) as r:
        rec = r.read_points(5000)
    expected = np.stack([np.asarray(rec.x, float), np.asarray(rec.y, float),
                         np.asarray(rec.z, float)], axis=1)
    assert np.array_equal(read_las(path).xyz, expected)
    chunks = list(iter_las_fields(path, ("x", "y", "z", "gps_time"), 1700))
    assert np.array_equal(np.concatenate([c["xyz"] for c in chunks]), expected)
    assert np.array_equal(np.concatenate([c["x"] for c in chunks]), expected[:, 0])
