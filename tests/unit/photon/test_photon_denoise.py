"""Photon denoising on the real ATL03 subset and on a simulated pass with known photon classes."""

from __future__ import annotations

from calidar.io.atl03 import read_atl03
from calidar.photon.denoise import denoise
from calidar.sim.photons import PhotonSimConfig, simulate_pass


def test_real_sea_ice_high_confidence_photons_are_kept(real_data):
    b = read_atl03(real_data / "atl03_arctic" / "ATL03_gt1l.h5", "gt1l")
    signal = denoise(b.x, b.h)
    high = b.signal_conf[:, 2] == 4  # sea-ice column
    assert high.sum() > 2000
    assert signal[high].mean() >= 0.95
    # and it is not "keep everything": some low-confidence photons are dropped
    assert signal[~high].mean() < 0.6


def test_simulated_signal_kept_and_background_rejected():
    sim = simulate_pass(PhotonSimConfig(seed=11, n_ccr=4))
    signal = denoise(sim.beam.x, sim.beam.h)
    cls = sim.photon_class
    assert signal[cls == 1].mean() > 0.98  # ground
    assert signal[cls == 2].mean() > 0.95  # CCR returns
    assert signal[cls == 0].mean() < 0.15  # solar background (those left lie inside the surface band)


def test_fine_stage_equals_sklearn_dbscan_noise_labels():
    import numpy as np
    from sklearn.cluster import DBSCAN

    from calidar.photon.denoise import fine_dbscan

    sim = simulate_pass(PhotonSimConfig(seed=12, n_ccr=3, length=500.0, ccr_spacing=60.0))
    x, h = sim.beam.x, sim.beam.h
    for ra, rh, k in [(2.45, 0.6, 4), (1.0, 0.3, 3)]:
        ref = DBSCAN(eps=1.0, min_samples=k).fit(np.column_stack([x / ra, h / rh])).labels_ >= 0
        np.testing.assert_array_equal(fine_dbscan(x, h, ra, rh, k), ref)
