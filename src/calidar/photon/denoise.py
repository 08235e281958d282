"""Photon denoising. :func:`denoise` (``calidar denoise``) is the slope-following neighbour count
against the measured solar background of :mod:`calidar.photon.density`; :func:`denoise_stages`,
the two-stage method below, stays what the CCR calibration uses on its sites (flat, strong returns;
its Monte-Carlo figures in docs/validation.md were measured with it).

Two-stage method: a coarse along-track height histogram (waveform) test, then DBSCAN's noise test
in scaled (along-track, height) space.

Coarse stage: photons are binned in along-track windows (``bin_along`` m) and height bins
(``bin_height`` m above the window's lowest photon); the solar background per window is the
median bin count over the occupied height range; bins exceeding background + k·√background
(and at least ``min_count``) are signal, dilated by one bin in height. Fine stage: DBSCAN
(Ester et al. 1996) on the coarse survivors with distances scaled so that ``eps`` = 1 is an
ellipse of ``radius_along`` × ``radius_height`` m; noise points are dropped.
"""

from __future__ import annotations

import numba
import numpy as np

def coarse_histogram(x_m: np.ndarray, h_m: np.ndarray, bin_along: float = 20.0,
                     bin_height: float = 0.5, k_sigma: float = 3.0, min_count: int = 3,
                     half_window: float = 20.0) -> np.ndarray:
    """Boolean mask of photons in signal bins of the along-track height histogram.

    Each ``bin_along`` window is histogrammed over ±``half_window`` m around its median
    height (photons outside are not signal); the background is the median bin count."""
    x, h = np.asarray(x_m, float), np.asarray(h_m, float)
    if x.size == 0:
        return np.zeros(0, bool)
    ix = ((x - x.min()) // bin_along).astype(np.int64)
    nx = int(ix.max()) + 1
    order = np.lexsort((h, ix))
    cnt = np.bincount(ix, minlength=nx)
    first = np.cumsum(cnt) - cnt
    hmid = np.zeros(nx)
    has = cnt > 0
    hmid[has] = h[order[first[has] + cnt[has] // 2]]
    nz = 2 * int(np.ceil(half_window / bin_height))
    iz = np.floor((h - hmid[ix]) / bin_height).astype(np.int64) + nz // 2
    inside = (iz >= 0) & (iz < nz)
    iz = np.clip(iz, 0, nz - 1)
    counts = np.bincount(ix * nz + iz, weights=inside, minlength=nx * nz).reshape(nx, nz)
    bg = np.median(counts, axis=1)
    thresh = np.maximum(bg + k_sigma * np.sqrt(np.maximum(bg, 1.0)), min_count - 0.5)
    sig = counts > thresh[:, None]
    sig[:, 1:] |= sig[:, :-1]
    sig[:, :-1] |= sig[:, 1:].copy()
    return sig[ix, iz] & inside


@numba.njit(cache=True)
def _dbscan_keep(x: np.ndarray, h: np.ndarray,
                 min_samples: int) -> np.ndarray:  # pragma: no cover - numba
    """DBSCAN noise test on points sorted by x, unit radius: keep = core or within 1 of a core."""
    n = x.size
    core = np.zeros(n, np.bool_)
    lo = 0
    for i in range(n):
        while x[lo] < x[i] - 1.0:
            lo += 1
        cnt = 0
        j = lo
        while j < n and x[j] <= x[i] + 1.0:
            if (x[j] - x[i]) ** 2 + (h[j] - h[i]) ** 2 <= 1.0:
                cnt += 1
            j += 1
        core[i] = cnt >= min_samples
    keep = core.copy()
    lo = 0
    for i in range(n):
        while x[lo] < x[i] - 1.0:
            lo += 1
        if keep[i]:
            continue
        j = lo
        while j < n and x[j] <= x[i] + 1.0:
            if core[j] and (x[j] - x[i]) ** 2 + (h[j] - h[i]) ** 2 <= 1.0:
                keep[i] = True
                break
            j += 1
    return keep


def fine_dbscan(x_m: np.ndarray, h_m: np.ndarray, radius_along: float = 2.5,
                radius_height: float = 0.6, min_samples: int = 4) -> np.ndarray:
    """Boolean mask of photons DBSCAN keeps (core or border points) in scaled (x/ra, h/rh) space.

    Only DBSCAN's noise decision is needed, not the cluster labels, so it is computed directly
    (numba, a sliding window over photons sorted along track): a core point has ≥ min_samples
    points (itself included) within eps = 1; a border point lies within eps of a core point.
    Identical to ``sklearn.cluster.DBSCAN(eps=1, min_samples).labels_ >= 0``, in O(N·k)."""
    x, h = np.asarray(x_m, float), np.asarray(h_m, float)
    keep = np.zeros(x.size, bool)
    if x.size == 0:
        return keep
    order = np.argsort(x, kind="stable")
    keep[order] = _dbscan_keep(x[order] / radius_along, h[order] / radius_height, min_samples)
    return keep


def denoise_stages(x_m: np.ndarray, h_m: np.ndarray, shot_spacing: float = 0.7,
                   min_samples: int = 4) -> tuple[np.ndarray, np.ndarray]:
    """(coarse, signal) masks: the histogram stage, then DBSCAN on its survivors.

    Two histograms offset by half a window are OR-ed, so no run of returns is cut by a bin
    edge. The DBSCAN along-track radius is 3.5 shot spacings (m), the height radius 0.6 m."""
    x, h = np.asarray(x_m, float), np.asarray(h_m, float)
    coarse = coarse_histogram(x, h) | coarse_histogram(np.concatenate([[x.min() - 10.0], x]),
                                                       np.concatenate([[h[0]], h]))[1:]
    signal = np.zeros(x.size, bool)
    idx = np.flatnonzero(coarse)
    signal[idx] = fine_dbscan(x[idx], h[idx], radius_along=3.5 * shot_spacing,
                              min_samples=min_samples)
    return coarse, signal


def denoise(x_m: np.ndarray, h_m: np.ndarray, shot_spacing: float = 0.7,
            settings=None) -> np.ndarray:
    """Signal mask of every photon: :func:`calidar.photon.density.signal_photons` (slope-following
    neighbour counts tested against the local background; robust on weak beams in daylight over
    sloping ground, where the fixed histograms of :func:`denoise_stages` break the ground line)."""
    from calidar.photon.density import DensitySettings, signal_photons

    return signal_photons(x_m, h_m, shot_spacing, settings or DensitySettings())
