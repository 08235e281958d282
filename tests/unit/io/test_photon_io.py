"""ATL03 reader/writer: the real ICESat-2 subset, round trips, clear errors."""

from __future__ import annotations

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
