import numpy as np
import pytest

from calidar import frames, georef
from calidar.errors import InputError
from calidar.io import read_trajectory, read_trajectory_text

HOUSTON = "houston_trajectory/sbet_047_IGS08-UTM15N-Ellipsoid-trim.txt"


def _truth(n=100):
    t = 1000.0 + np.arange(n) * 0.01
    lat = np.radians(45.0) + np.linspace(0, 1e-4, n)
    lon = np.radians(-119.0) + np.linspace(0, 2e-4, n)
    return t, lat, lon, np.linspace(1000, 1010, n), np.radians(np.linspace(-2, 2, n)), np.full(n, 0.03), np.radians(np.linspace(10, 30, n))


def test_houston_reads_14600_records(real_data):
    tr = read_trajectory(real_data / HOUSTON, crs="EPSG:32615")
    assert len(tr) == 14600
    assert tr.rate_hz == pytest.approx(200.0, rel=1e-6)
    assert tr.time[-1] - tr.time[0] == pytest.approx(73.0, abs=0.01)
    assert np.degrees(tr.roll).min() == pytest.approx(-18.5, abs=0.1)
    # flying west: the azimuth column is a true heading (the track differs from it by < 1°,
    # while the meridian convergence there is −1.15°)
    v = np.gradient(tr.ecef, tr.time, axis=0)
    ned = np.einsum("nji,nj->ni", frames.r_en(tr.lat, tr.lon), v)
    crab = np.angle(np.exp(1j * (np.arctan2(ned[:, 1], ned[:, 0]) - tr.heading)))
    assert abs(np.degrees(np.median(crab[:10000]))) < 0.5
    assert np.degrees(tr.heading[0]) == pytest.approx(-90.494178, abs=1e-9)  # first record, as in the file


def test_houston_without_crs_is_a_clear_error(real_data):
    with pytest.raises(InputError, match="projected x/y columns; give their projected CRS"):
        read_trajectory(real_data / HOUSTON)


def test_projected_grid_heading_round_trip(tmp_path):
    t, lat, lon, h, r, p, hd = _truth()
    crs = "EPSG:32611"
    xyz = georef.to_crs(frames.geodetic_to_ecef(lat, lon, h), crs)
    gamma = frames.grid_factors(crs, lon, lat)[0]
    grid = np.degrees(hd - gamma)
    path = tmp_path / "traj.txt"
    rows = np.c_[t, xyz[:, 0], xyz[:, 1], xyz[:, 2], np.degrees(r), np.degrees(p), grid]
    np.savetxt(path, rows, fmt="%.9f", header="Time Easting Northing Height Roll(deg) Pitch(deg) Heading(deg)", comments="")
    tr = read_trajectory_text(path, crs=crs, heading_reference="grid")
    assert np.allclose(tr.lat, lat, atol=1e-11) and np.allclose(tr.lon, lon, atol=1e-11)
    assert np.allclose(tr.height, h, atol=1e-6)
    assert np.allclose(tr.heading, hd, atol=1e-9)
    assert np.degrees(np.abs(gamma).max()) > 1.0  # the correction mattered
    as_true = read_trajectory_text(path, crs=crs)
    assert np.allclose(as_true.heading, np.radians(grid), atol=1e-9)


def test_geographic_radians_headerless(tmp_path):
    t, lat, lon, h, r, p, hd = _truth()
    path = tmp_path / "traj.csv"
    np.savetxt(path, np.c_[lon, lat, t, h, r, p, hd], fmt="%.12f", delimiter=",")
    cols = ["lon", "lat", "time", "height", "roll", "pitch", "heading"]
    tr = read_trajectory(path, columns=cols, angles="rad")
    assert np.allclose(tr.lat, lat, atol=1e-12) and np.allclose(tr.heading, hd, atol=1e-12)
    with pytest.raises(InputError, match="no header line"):
        read_trajectory(path)


@pytest.mark.parametrize(
    "text, options, message",
    [
        ("time,lat,lon,height,roll,pitch\n1,45,7,100,0,0\n2,45,7,100,0,0\n", {}, "columns: missing \\['heading'\\]"),
        ("time,lat,lon,h,roll,pitch,heading\n1,45,7,100,0,0,0\n2,45,7,abc,0,0,0\n", {}, "line 3: expected numbers"),
        ("time,lat,lon,h,roll,pitch,heading\n2,45,7,100,0,0,0\n1,45,7,100,0,0,0\n", {}, "strictly increasing"),
        ("time,lat,lon,h,roll,pitch,heading\n1,45,7,100,0,0,0\n2,45,7,100,0,0,0\n", {"angles": "grad"}, "angles"),
        ("", {}, "empty"),
    ],
)
def test_bad_text_trajectories(tmp_path, text, options, message):
    path = tmp_path / "bad.txt"
    path.write_text(text)
    with pytest.raises(InputError, match=message) as e:
        read_trajectory(path, **options)
    assert str(path) in str(e.value)


def test_sbet_rejects_text_options(real_data):
    with pytest.raises(InputError, match="binary SBET"):
        read_trajectory(real_data / "leeward_sierra" / "sbet.out", crs="EPSG:32611")


def test_houston_through_the_shared_trajectory_options(real_data):
    """The options boresight, quality, inverse and regeoref share (pipelines.inputs.TrajectoryOptions,
    --trajectory-crs …): the real projected Houston export loads; grid heading differs by γ."""
    from calidar.pipelines.inputs import TrajectoryOptions, load_trajectory

    true = load_trajectory(real_data / HOUSTON, TrajectoryOptions(crs="EPSG:32615"))
    grid = load_trajectory(real_data / HOUSTON, TrajectoryOptions(crs="EPSG:32615", heading="grid"))
    assert len(true) == len(grid) == 14600
    gamma = frames.grid_factors("EPSG:32615", true.lon, true.lat)[0]
    assert np.allclose(np.angle(np.exp(1j * (grid.heading - true.heading - gamma))), 0.0, atol=1e-12)
    assert np.degrees(gamma).mean() == pytest.approx(-1.15, abs=0.01)
    with pytest.raises(InputError, match="give their projected CRS"):
        load_trajectory(real_data / HOUSTON)


def test_not_utf8_and_out_of_range_columns(tmp_path):
    t, lat, lon, h, roll, pitch, hd = _truth(5)
    rows = np.c_[t, np.degrees(lat), np.degrees(lon), h, np.degrees(roll), np.degrees(pitch), np.degrees(hd)]
    text = "time,lat,lon,height,roll,pitch,heading\n" + "\n".join(",".join(f"{v:.9f}" for v in r) for r in rows)
    (tmp_path / "latin.csv").write_bytes(("# trajectoire étalonnée\n" + text).encode("latin-1"))
    with pytest.raises(InputError, match="latin.csv: encoding: expected UTF-8 text, got byte 0xe9"):
        read_trajectory(tmp_path / "latin.csv")
    for column, value, message in (("roll", 500.0, "roll: expected finite values in [-180, 180] deg, got 500"),
                                   ("height", 1e9, "height: expected finite values in [-1000, 100000] m, got 1e+09"),
                                   ("lat", 95.0, "lat: expected finite values in [-90, 90] deg, got 95")):
        bad = rows.copy()
        bad[2, ["time", "lat", "lon", "height", "roll", "pitch", "heading"].index(column)] = value
        path = tmp_path / f"{column}.csv"
        path.write_text("time,lat,lon,height,roll,pitch,heading\n" + "\n".join(",".join(map(str, r)) for r in bad))
        with pytest.raises(InputError) as e:
            read_trajectory(path)
        assert str(e.value).startswith(f"{path}: {message} (1 of 5 values, first at line 4)")
