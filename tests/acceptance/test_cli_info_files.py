"""``calidar info`` on every kind of file: ATL03 photons, and every file of the real-data folder."""

from __future__ import annotations

import dataclasses
import json

import h5py
import numpy as np
import pytest

from calidar.io.atl03 import PhotonBeam, segment_photons, write_atl03


def _beam(name, n, t0, seed):
    """n photons of one beam, 4 per shot at 10 kHz, 0.7 m apart along track."""
    rng = np.random.default_rng(seed)
    shot = np.arange(n) // 4
    x = 0.7 * shot + np.sort(rng.uniform(0, 0.01, n))
    seg_id, beg, cnt, dist_x, along = segment_photons(x)
    return PhotonBeam(beam=name, delta_time=t0 + 1e-4 * shot, lat=np.radians(87.3 + 1e-7 * x),
                      lon=np.radians(np.full(n, 100.0)), h=rng.normal(0, 2, n), dist_along=along,
                      dist_across=np.zeros(n), signal_conf=np.full((n, 5), 4, np.int8), quality=np.zeros(n, np.int8),
                      segment_id=seg_id, ph_index_beg=beg, segment_ph_cnt=cnt, segment_dist_x=dist_x)


def test_info_atl03_beams(tmp_path, cli):
    a, b = _beam("gt1l", 1000, 1000.0, 1), _beam("gt3r", 402, 1000.5, 2)
    path = write_atl03(tmp_path / "two.h5", [a, b])
    code, out, err = cli("info", path, "--json")
    assert code == 0, err
    d = json.loads(out)
    assert d["kind"] == "photons (ICESat-2 ATL03)" and d["photons"] == 1402
    assert [(r["beam"], r["photons"], r["shots"]) for r in d["beams"]] == [("gt1l", 1000, 250), ("gt3r", 402, 101)]
    assert d["beams"][0]["delta_time"] == pytest.approx([1000.0, 1000.0 + 249e-4], abs=1e-9)
    assert d["beams"][1]["segments"] == b.segment_id.size
    assert d["beams"][0]["lat_deg"][0] == pytest.approx(87.3, abs=1e-6)
    code, out, _ = cli("info", path)
    assert code == 0 and "beam gt3r:        402 photons, 101 shots" in out
    empty = write_atl03(tmp_path / "empty.h5", [dataclasses.replace(
        a, beam="gt2l", delta_time=a.delta_time[:0], lat=a.lat[:0], lon=a.lon[:0], h=a.h[:0], dist_along=a.h[:0],
        dist_across=a.h[:0], signal_conf=a.signal_conf[:0], quality=a.quality[:0], segment_id=a.segment_id[:0],
        ph_index_beg=a.ph_index_beg[:0], segment_ph_cnt=a.segment_ph_cnt[:0], segment_dist_x=a.segment_dist_x[:0])])
    code, out, err = cli("info", empty)
    assert code == 0 and "beam gt2l:          0 photons" in out, err


def test_info_hdf5_that_is_not_atl03(tmp_path, cli):
    with h5py.File(tmp_path / "other.h5", "w") as f:
        f.create_dataset("x", data=np.arange(3))
    code, _, err = cli("info", tmp_path / "other.h5")
    assert code == 1 and err.strip().count("\n") == 0 and "Traceback" not in err
    assert "other.h5: an HDF5 file without ATL03 beam groups" in err


def test_info_every_real_file(real_data, cli):
    """Every file there gives a summary, or (README, leeward's config) one clear line, exit 1."""
    files = sorted(p for p in real_data.rglob("*") if p.is_file())
    assert len(files) >= 8
    expected_errors = {"README.md": "not a trajectory?", "config.toml": "not a trajectory?",
                       "sbet_047_IGS08-UTM15N-Ellipsoid-trim.txt": "give their projected CRS"}
    summaries = {}
    for p in files:
        code, out, err = cli("info", p, "--json")
        if p.name in expected_errors:
            assert code == 1 and err.strip().count("\n") == 0 and expected_errors[p.name] in err, err
            assert str(p) in err
        else:
            assert code == 0, err
            summaries[p.name] = json.loads(out)
    houston = real_data / "houston_trajectory" / "sbet_047_IGS08-UTM15N-Ellipsoid-trim.txt"
    code, out, _ = cli("info", houston, "--crs", "EPSG:32615", "--json")
    assert code == 0 and json.loads(out)["records"] == 14600
    atl03 = summaries["ATL03_gt1l.h5"]
    assert [(r["beam"], r["photons"]) for r in atl03["beams"]] == [("gt1l", 2909)]
    t0, t1 = atl03["beams"][0]["delta_time"]
    assert 56 < t1 - t0 < 58  # "2,909 photons over 57 s"
    assert 87.2 < atl03["beams"][0]["lat_deg"][0] < 87.4
    assert summaries["faceraster_numerical_imprecision.laz"]["points"] == 18074
    assert summaries["points_ecef.las"]["crs_epsg"] == 4978 and summaries["points.las"]["crs_epsg"] == 32611
    assert summaries["sbet.out"]["records"] == 200
    assert summaries["smrmsg.smrmsg"]["records"] == 21902  # README: 21,902 records, 1 Hz over 21,901 s
    csd = summaries["sample.csd"]  # numbers of the real-data README
    assert csd["kind"] == "raw pulses (Optech CSD)" and csd["pulses"] == 1000 and csd["returns"] == 1000
    assert csd["gps_week"] == 1660 and csd["format_version"] == pytest.approx(5.201)
    assert csd["gps_time"] == pytest.approx([575644.744846, 575644.758832], abs=1e-6)
    assert csd["range_m"] == pytest.approx([794.6, 829.3], abs=0.05)
    assert csd["lon_deg"][0] == pytest.approx(-82.552, abs=1e-3)  # −442.55° as stored
