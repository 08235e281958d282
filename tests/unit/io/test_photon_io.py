"""ATL03 reader/writer: the real ICESat-2 subset, round trips, clear errors."""

from __future__ import annotations

import dataclasses
import json

import h5py
import numpy as np
import pytest

from calidar.errors import InputError
from calidar.io.atl03 import read_atl03, write_atl03
from calidar.sim.photons import PhotonSimConfig, simulate_pass


def test_reads_real_atl03_subset(real_data):
    b = read_atl03(real_data / "atl03_arctic" / "ATL03_gt1l.h5", "gt1l")
    assert len(b) == 2909
    assert b.signal_conf.shape == (2909, 5)
    assert np.degrees(b.lat).min() > 87.2 and np.degrees(b.lat).max() < 87.4
    x = b.x
    # along-track distance = segment_dist_x + dist_ph_along: non-decreasing, ~0.7 m between shots
    assert np.all(np.diff(x) > -0.05)  # photons of one shot differ by centimetres
    steps = np.diff(np.unique(np.round(x, 1)))
    assert 0.6 < np.median(steps) < 0.8
    assert b.shot_index().max() + 1 < len(b)  # several photons per shot


def test_missing_beam_and_group_are_named(real_data, tmp_path):
    path = real_data / "atl03_arctic" / "ATL03_gt1l.h5"
    with pytest.raises(InputError, match="gt2r: beam group missing; the file has gt1l"):
        read_atl03(path, "gt2r")
    with pytest.raises(InputError, match="--beam"):
        read_atl03(path, "gt9x")
    broken = tmp_path / "broken.h5"
    with h5py.File(broken, "w") as f:
        f.create_group("gt1l/heights")
    with pytest.raises(InputError, match=r"broken.h5: gt1l/geolocation: group missing"):
        read_atl03(broken, "gt1l")


def test_write_read_round_trip(tmp_path):
    sim = simulate_pass(PhotonSimConfig(seed=3, length=300.0, n_ccr=2, ccr_spacing=60.0))
    path = write_atl03(tmp_path / "a.h5", [sim.beam])
    b = read_atl03(path, "gt1l")
    assert len(b) == len(sim.beam)
    np.testing.assert_allclose(b.x, sim.beam.x, atol=1e-3)  # float32 dist_ph_along
    np.testing.assert_allclose(b.lat, sim.beam.lat, atol=1e-12)
    np.testing.assert_array_equal(b.signal_conf, sim.beam.signal_conf)


REAL = "atl03_arctic/ATL03_gt1l.h5"


def clip_like_a_subsetter(src, dst, lat_lo, lat_hi):
    """Keep the photons with lat_lo ≤ lat_ph ≤ lat_hi and every other beam attribute, but the
    geolocation (segment) arrays of the whole granule, as clipping tools do. Returns the kept mask."""
    with h5py.File(src) as f, h5py.File(dst, "w") as g:
        keep = (f["gt1l/heights/lat_ph"][()] >= lat_lo) & (f["gt1l/heights/lat_ph"][()] <= lat_hi)
        grp = g.create_group("gt1l")
        grp.attrs.update(dict(f["gt1l"].attrs))
        for name in f["gt1l/heights"]:
            grp.create_dataset(f"heights/{name}", data=f[f"gt1l/heights/{name}"][()][keep])
        f.copy(f["gt1l/geolocation"], grp, "geolocation")
    return keep


@pytest.fixture
def clipped(real_data, tmp_path):
    """The real subset clipped to 87.2950–87.2970° N (1 167 of 2 909 photons; 40 segments kept)."""
    keep = clip_like_a_subsetter(real_data / REAL, tmp_path / "clipped.h5", 87.2950, 87.2970)
    return tmp_path / "clipped.h5", keep


def test_clipped_file_photons_placed_on_their_segments_by_time(real_data, clipped):
    path, keep = clipped
    full, b = read_atl03(real_data / REAL, "gt1l"), read_atl03(path, "gt1l")
    assert len(b) == keep.sum() == 1167 and b.segment_id.size == 40
    assert full.along_track_source == "segments" and b.along_track_source.startswith("photon times")
    np.testing.assert_allclose(b.x, full.x[keep], atol=1e-6)  # the same distances as the whole subset's
    assert (b.strength, b.spot, b.channels) == ("weak", 6, 4)  # gt1l in the forward orientation


def test_clipped_file_denoises_and_keeps_atl03_high_confidence(clipped, cli, tmp_path):
    """Issue 17: a clipped real file denoises; ATL03's high-confidence (sea ice = 4) photons are kept ≥ 95 %."""
    path, _ = clipped
    code, out, err = cli("denoise", path, "--out", tmp_path / "d.csv")
    assert code == 0, err
    assert "along-track distance from the photon times" in err  # said, not hidden
    rows = np.genfromtxt(tmp_path / "d.csv", delimiter=",", names=True, dtype=None, encoding="utf-8")
    with h5py.File(path) as f:
        high = f["gt1l/heights/signal_conf_ph"][()][:, 2] == 4
    assert high.sum() > 1000 and rows.size == high.size
    assert rows["signal"][high].mean() >= 0.95  # measured 0.996
    assert rows["signal"][~high].mean() < 0.6
    assert set(rows["beam"]) == {"gt1l"} and set(rows["strength"]) == {"weak"}
    assert rows["dist_ph_along"].max() < 21 and rows["along_track_m"].min() > 1e7  # named for what they hold
    code, out, _ = cli("info", path, "--json")
    assert code == 0 and "photon times" in json.loads(out)["warning"]


def test_strength_from_sc_orient_and_beam_choice(tmp_path):
    from calidar.io.atl03 import select_beams

    sim = simulate_pass(PhotonSimConfig(seed=3, length=300.0, n_ccr=2, ccr_spacing=60.0))
    beams = [dataclasses.replace(sim.beam, beam=n, strength=None, spot=None) for n in ("gt1l", "gt1r")]
    path = write_atl03(tmp_path / "a.h5", beams)
    for orient, strong in ((0, "gt1l"), (1, "gt1r")):
        with h5py.File(path, "a") as f:
            if "orbit_info" in f:
                del f["orbit_info"]
            f["orbit_info/sc_orient"] = np.array([orient], np.int8)
        got = {n: read_atl03(path, n).strength for n in ("gt1l", "gt1r")}
        assert got[strong] == "strong" and list(got.values()).count("weak") == 1
    assert select_beams(path, None) == ["gt1l", "gt1r"] and select_beams(path, ("gt1r", "gt1l")) == ["gt1r", "gt1l"]
    with pytest.raises(InputError, match="--beam: expected all, one of gt1l"):
        select_beams(path, ("gt7x",))
    with pytest.raises(InputError, match="a.h5: gt2l: beam group missing; the file has gt1l, gt1r"):
        select_beams(path, ("gt2l",))


def test_bad_photon_values_are_named(tmp_path):
    sim = simulate_pass(PhotonSimConfig(seed=3, length=300.0, n_ccr=2, ccr_spacing=60.0))
    lat = sim.beam.lat.copy()
    lat[5] = np.nan
    path = write_atl03(tmp_path / "nan.h5", [dataclasses.replace(sim.beam, lat=lat)])
    with pytest.raises(InputError, match=r"nan.h5: gt1l/heights/lat_ph: expected finite values in \[-90, 90\] deg, "
                                         r"got nan \(1 of \d+ values, first at photon 5\)"):
        read_atl03(path, "gt1l")
