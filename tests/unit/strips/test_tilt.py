"""The tie planes' calibrated normals (:mod:`calidar.strips.tilt`, issue 26): a sloped patch's tilt
across its slope is the fit's noise and is shrunk like a flat patch's; its slope is kept; walls
(normals near horizontal, facing any way) keep their normals."""

from __future__ import annotations

import numpy as np

from calidar.strips.tilt import EM_ITERATIONS, calibrated_normals, mixture_weights

NOISE_RAD = 0.03  #: the fitted tilt's noise per axis (σ 1 cm, 12 points, spread 0.1 m)


def _patches(rng: np.random.Generator, true_tilt: np.ndarray):
    """Fitted normals and their fits' summaries for true tilts (R, 2) along east and north."""
    r = true_tilt.shape[0]
    tilt = true_tilt + rng.normal(0.0, NOISE_RAD, (r, 2))
    normal = np.column_stack([-tilt, np.ones(r)])
    normal /= np.linalg.norm(normal, axis=1)[:, None]
    axes = np.stack([np.linalg.svd(n[None, :])[2][1:].T for n in normal])  # any in-plane basis
    spread = np.full((r, 2), 0.01)  # (0.1 m)²
    rms, count = np.full(r, 0.01), np.full(r, 12)  # 0.01² / (12 · 0.01) = 0.03² per axis
    return normal, axes, spread, rms, count


def _tilts(normal: np.ndarray) -> np.ndarray:
    return -normal[:, :2] / normal[:, 2:3]


def test_cross_tilt_of_sloped_patches_is_shrunk_and_their_slope_kept():
    """Half the patches slope 0.3 east, half are flat. Before (a prior on the tilt's magnitude)
    the sloped ones kept their north tilt's noise whole (RMS 0.029 rad); now it is shrunk (RMS 0.002 rad)
    as the flat patches' are (RMS 0.010), and the east slope stays within its noise of 0.3."""
    rng = np.random.default_rng(3)
    true = np.zeros((2000, 2))
    true[:1000, 0] = 0.3
    got = _tilts(calibrated_normals(*_patches(rng, true)))
    sloped, flat = got[:1000], got[1000:]
    assert np.sqrt(np.mean(sloped[:, 1] ** 2)) < 0.01, np.sqrt(np.mean(sloped[:, 1] ** 2))
    assert np.sqrt(np.mean(flat ** 2)) < 0.015
    assert abs(np.mean(sloped[:, 0]) - 0.3) < 0.005
    assert 0.8 * NOISE_RAD < np.std(sloped[:, 0]) < 1.2 * NOISE_RAD  # the slope itself not shrunk


def test_walls_keep_their_normals():
    """Normals within a few degrees of horizontal, facing north, south, east and between."""
    rng = np.random.default_rng(4)
    face = np.radians([90.0, -90.0, 0.0, 45.0, 180.0])
    normal = np.column_stack([np.cos(face), np.sin(face), np.full(5, 0.02)])
    normal /= np.linalg.norm(normal, axis=1)[:, None]
    axes = np.stack([np.linalg.svd(n[None, :])[2][1:].T for n in normal])
    flat = _patches(rng, np.zeros((200, 2)))
    out = calibrated_normals(np.vstack([normal, flat[0]]), np.vstack([axes, flat[1]]),
                             np.vstack([np.full((5, 2), 0.01), flat[2]]),
                             np.r_[np.full(5, 0.01), flat[3]], np.r_[np.full(5, 12), flat[4]])
    assert np.all(np.isfinite(out))
    assert np.all(np.einsum("ij,ij->i", out[:5], normal) > np.cos(np.radians(0.5)))


def _weights_numpy(lik: np.ndarray, iterations: int) -> np.ndarray:
    """The EM steps of the mixture's weights as numpy writes them (the code before the kernel)."""
    weight = np.full(lik.shape[1], 1.0 / lik.shape[1])
    for _ in range(iterations):
        post = lik * weight
        post /= post.sum(axis=1, keepdims=True)
        weight = post.mean(axis=0)
    return weight


def test_mixture_weights_kernel_has_numpy_bits():
    """The numba kernel of the EM steps gives numpy's weights bit for bit (the calibration's
    results stay identical: issue 32, eleventh session), for likelihoods as expected_tilt's
    (each row's largest 1, the rest spread over decades), row counts 1 to 20 000, and the
    component counts 8 ≤ K ≤ 128 its pairwise sum follows (16: PRIOR_VARIANCES)."""
    rng = np.random.default_rng(11)
    for rows, k in [(1, 16), (2, 16), (7, 16), (333, 16), (4099, 16), (20_000, 16), (500, 8),
                    (500, 13), (500, 27), (500, 128)]:
        lik = np.exp(-rng.exponential(5.0, (rows, k)) * rng.random((rows, 1)) * 3.0)
        lik[np.arange(rows), rng.integers(0, k, rows)] = 1.0
        want = _weights_numpy(lik, EM_ITERATIONS)
        got = mixture_weights(lik, EM_ITERATIONS)
        assert np.array_equal(got, want), (rows, k, np.max(np.abs(got - want)))
