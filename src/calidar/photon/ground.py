"""Ground profile under a photon pass: a smoothing spline through robust per-bin ground heights.

Objects above the ground (CCRs on poles, vegetation) can outnumber ground photons in a bin,
so the ground is found from below: the bin's low percentile locates the surface, the median
of the photons within [-0.5, +1.0] m of it is the bin's ground height, and a cubic smoothing
spline (scipy ``make_smoothing_spline``, fixed smoothing length: cross-validating the
penalty costs minutes on a long pass) joins the bins.
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np

from calidar.errors import CalibrationError


def _per_bin(ix: np.ndarray, h: np.ndarray, q: float, nbin: int) -> tuple[np.ndarray, np.ndarray]:
    """The q-quantile of h in every bin (NaN when empty) and the bin counts."""
    order = np.lexsort((h, ix))
    cnt = np.bincount(ix, minlength=nbin)
    first = np.cumsum(cnt) - cnt
    out = np.full(nbin, np.nan)
    has = cnt > 0
    out[has] = h[order[first[has] + np.floor(q * (cnt[has] - 1)).astype(np.int64)]]
    return out, cnt


def ground_profile(x_m: np.ndarray, h_m: np.ndarray, bin_m: float = 5.0, min_photons: int = 3,
                   low_quantile: float = 0.1,
                   smoothing_m: float = 10.0) -> Callable[[np.ndarray], np.ndarray]:
    """Ground height (m) as a function of along-track distance (m), from signal photons.

    ``smoothing_m``: length scale of the spline (its penalty λ = smoothing_m⁴ / bin_m, so
    features shorter than about that length are smoothed away)."""
    from scipy.interpolate import make_smoothing_spline

    x, h = np.asarray(x_m, float), np.asarray(h_m, float)
    if x.size < min_photons:
        raise CalibrationError("too few signal photons to model the ground")
    x0 = x.min()
    ix = ((x - x0) // bin_m).astype(np.int64)
    nbin = int(ix.max()) + 1
    low, _ = _per_bin(ix, h, low_quantile, nbin)
    near = (h >= low[ix] - 0.5) & (h <= low[ix] + 1.0)
    med, cnt = _per_bin(ix[near], h[near], 0.5, nbin)
    ok = cnt >= min_photons
    xc = np.bincount(ix[near], weights=x[near], minlength=nbin)[ok] / cnt[ok]
    hc = med[ok]
    if xc.size < 5:
        raise CalibrationError(f"only {xc.size} along-track bins with ground photons; need 5 to "
                               "model the ground")
    spline = make_smoothing_spline(xc, hc, lam=smoothing_m**4 / bin_m)
    return lambda xq: spline(np.asarray(xq, float))
