"""Signal photons by an oriented neighbour count against the local solar background (``calidar
denoise``).

Why not fixed height histograms: on a weak beam in daylight (0.5–1 signal photons a shot against
several MHz of background) over sloping ground, a surface crosses many height bins of an along-track
window, no bin rises above the background's fluctuation, and the ground line breaks into gaps of
100–200 m. Both published families of photon classifiers handle it by following the surface:

- the ATL03 ATBD (Neumann et al., 2019, "ICESat-2 ATL03 Algorithm Theoretical Basis Document",
  §5 signal finding) measures the background rate per along-track interval and histograms photons
  along the surface's slope ("slant histograms"), a bin being signal when it exceeds what the
  background makes likely;
- DRAGANN (Neuenschwander & Pitts, 2019, ATL08 ATBD; Popescu et al., 2018, Remote Sens. Environ.
  219) counts each photon's neighbours within a radius and puts the threshold where the counts stop
  being those of uniformly scattered noise.

Here both ideas in one test. For each photon, the count of other photons in a parallelogram of
half-length ``half_along`` (m) along track and half-height ``half_height`` (m) about the line
through it of slope s, maximised over slopes s in [−``max_slope``, +``max_slope``] (step half_height
/ half_along, so consecutive parallelograms differ by at most their half-height at the ends): a
photon on a surface of any slope up to max_slope sees its surface's photons along the surface, as
the ATBD's slant histograms do. Under background alone the count in one parallelogram is Poisson
with mean μ = ρ · 2·half_along · 2·half_height, ρ the background's density (photons per m along per
m of height) measured in the photon's along-track block (``block`` m: the height histogram's bins of
``bin_height`` m, sigma-clipped so that signal bins drop out, the ATBD's background from the
histogram's lower part). The photon is signal when its largest count reaches k, the least count that
all the slopes tried together (a Bonferroni bound over them) reach by chance with probability ≤
``false_alarm`` (and at least ``min_count``). A second, coarser scale (``coarse`` × the
parallelogram) catches the ground of steep slopes, whose footprint spreads its heights.
"""

from __future__ import annotations

from dataclasses import dataclass

import numba
import numpy as np
from scipy.stats import poisson


MIN_SPAN = 20.0  #: m, the least height a block's background is measured over (see _block_density)


@dataclass(frozen=True)
class DensitySettings:
    """The signal test's settings (m unless stated)."""

    #: (half-length along track, half-height about the slope line) of each scale's parallelogram
    scales: tuple[tuple[float, float], ...] = ((10.0, 0.75), (15.0, 1.125), (25.0, 0.75))
    max_slope: float = 1.0  #: steepest surface followed (m/m, 45°)
    #: chance that a background photon passes (before the surface band's share)
    false_alarm: float = 0.0005
    min_count: int = 2  #: photons needed on each side in any case
    #: and at least this many per m of the side's length (a surface, not a few photons)
    min_rate: float = 0.15
    #: a photon's count must reach this fraction of the largest count within ±relative_height
    relative: float = 0.2
    #: m (the tails beside a dense surface: afterpulses, background at its edge)
    relative_height: float = 2.0
    block: float = 20.0  #: along-track length of the background's blocks
    bin_height: float = 1.0  #: height bins of the background's histogram


@numba.njit(cache=True)
def _oriented_max(x: np.ndarray, h: np.ndarray, a: float, b: float, s0: float, ds: float,
                  ns: int) -> tuple[np.ndarray, np.ndarray]:  # pragma: no cover - numba
    """For photons sorted by x: over the slopes s0 + k·ds (k < ns), the largest of min(left,
    right), the counts of other photons with |dh − s·dx| ≤ b behind (−a ≤ dx < 0) and ahead (0 < dx
    ≤ a) of it; photons of its own shot (dx = 0) within ±b count on both sides. A neighbour at dx ≠
    0 lies in the parallelograms of the slopes in [(dh − b)/dx, (dh + b)/dx]: it adds 1 to that run
    of slopes (a difference array per side), so a photon costs its neighbours plus ns.

    Where the data end (or pause) on one side — no photon at all in its far half, a/2 … a — only
    the other side is counted, and ``one_sided`` says so: the test there is on that side's count
    alone."""
    n = x.size
    out = np.zeros(n, np.int32)
    one_sided = np.zeros(n, np.bool_)
    left = np.zeros(ns + 1, np.int32)
    right = np.zeros(ns + 1, np.int32)
    lo = 0
    for i in range(n):
        while x[lo] < x[i] - a:
            lo += 1
        left[:] = 0
        right[:] = 0
        level = 0
        j = lo
        while j < n and x[j] <= x[i] + a:
            if j != i:
                dx = x[j] - x[i]
                dh = h[j] - h[i]
                if abs(dx) < 1e-6:
                    if abs(dh) <= b:
                        level += 1
                elif abs(dh) <= b - s0 * abs(dx):  # else in no parallelogram (s0 = −max_slope)
                    s1 = (dh - b) / dx
                    s2 = (dh + b) / dx
                    if s1 > s2:
                        s1, s2 = s2, s1
                    k1 = max(int(np.ceil((s1 - s0) / ds - 1e-9)), 0)
                    k2 = min(int(np.floor((s2 - s0) / ds + 1e-9)), ns - 1)
                    if k1 <= k2:
                        side = left if dx < 0 else right
                        side[k1] += 1
                        side[k2 + 1] -= 1
            j += 1
        open_behind = x[lo] > x[i] - 0.5 * a
        open_ahead = x[j - 1] < x[i] + 0.5 * a
        one_sided[i] = open_behind != open_ahead
        run_l, run_r, best = 0, 0, 0
        for k in range(ns):
            run_l += left[k]
            run_r += right[k]
            m = min(run_l, run_r)
            if open_behind and not open_ahead:
                m = run_r
            elif open_ahead and not open_behind:
                m = run_l
            if m > best:
                best = m
        out[i] = best + level
    return out, one_sided


@numba.njit(cache=True)
def _local_max(x: np.ndarray, h: np.ndarray, v: np.ndarray, a: float,
               dh: float) -> np.ndarray:  # pragma: no cover
    """For photons sorted by x: the largest v among the photons within |Δx| ≤ a, |Δh| ≤ dh (itself
    included)."""
    n = x.size
    out = np.zeros(n, v.dtype)
    lo = 0
    for i in range(n):
        while x[lo] < x[i] - a:
            lo += 1
        best = v[i]
        j = lo
        while j < n and x[j] <= x[i] + a:
            if abs(h[j] - h[i]) <= dh and v[j] > best:
                best = v[j]
            j += 1
        out[i] = best
    return out


@numba.njit(cache=True)
def _clipped_mean(counts: np.ndarray) -> float:  # pragma: no cover - numba
    """Mean of the counts after dropping, four times over, those above mean + 3·√mean + 1 (signal
    bins) and their neighbours (a surface's edges spill into them)."""
    m = np.median(counts)
    for _ in range(4):
        high = counts > m + 3.0 * np.sqrt(m) + 1.0
        keep = ~high
        keep[1:] &= ~high[:-1]
        keep[:-1] &= ~high[1:]
        if not keep.any():
            break
        m = counts[keep].mean()
    return m


@numba.njit(cache=True)
def _block_density(x: np.ndarray, h: np.ndarray, block: np.ndarray, nblock: int, bin_h: float,
                   spacing: float, min_span: float) -> np.ndarray:  # pragma: no cover - numba
    """Background density (photons per m along per m height) of each block; photons sorted by
    block.

    The block's along-track length is the span of its photons, or the shot cells they occupy × the
    shot spacing when under half of that span is occupied (a clipped file's gap); its heights span
    its lowest to highest photon, at least ``min_span``: a photon cloud less tall than ATLAS's
    telemetry band (≥ 30 m; 33–63 m on the real sea-ice granule here) had an empty band around it,
    i.e. hardly any background, which the empty bins added say (without them a block of signal
    alone would take its signal for background)."""
    rho = np.zeros(nblock)
    start = 0
    n = x.size
    while start < n:
        stop = start
        while stop < n and block[stop] == block[start]:
            stop += 1
        hb = h[start:stop]
        lo, hi = hb.min(), hb.max()
        nb = max(int(np.ceil((hi - lo) / bin_h)), int(np.ceil(min_span / bin_h)))
        counts = np.zeros(nb)
        for v in hb:
            counts[min(int((v - lo) / bin_h), nb - 1)] += 1.0
        occupied = np.unique(np.floor(x[start:stop] / spacing)).size * spacing
        spanned = x[start:stop].max() - x[start:stop].min() + spacing
        # the span, unless the data pause inside it (then the shots seen): empty shots are not gaps
        length = spanned if occupied > 0.5 * spanned else occupied
        rho[block[start]] = _clipped_mean(counts) / (bin_h * length)
        start = stop
    return rho


def background_density(x_m: np.ndarray, h_m: np.ndarray, block: float = 60.0,
                       bin_height: float = 1.0, shot_spacing: float = 0.7) -> np.ndarray:
    """Per photon, the solar background's density (photons per m along per m of height) in its
    block."""
    x, h = np.asarray(x_m, float), np.asarray(h_m, float)
    if x.size == 0:
        return np.zeros(0)
    ib = ((x - x.min()) // block).astype(np.int64)
    order = np.argsort(ib, kind="stable")
    rho = _block_density(x[order], h[order], ib[order], int(ib.max()) + 1, bin_height,
                         shot_spacing, MIN_SPAN)
    return rho[ib]


def thresholds(mu: np.ndarray, tests: int, false_alarm: float, min_count: int,
               sides: int = 2) -> np.ndarray:
    """The least k with tests · P(Poisson(mu) ≥ k)^sides ≤ false_alarm (and ≥ min_count), per mean
    mu of one side: both sides reach k by chance with the square of one side's chance."""
    # one μ per block: isf once each
    levels, inverse = np.unique(np.asarray(mu, float), return_inverse=True)
    chance = (false_alarm / tests) ** (1.0 / sides)
    k = np.asarray(poisson.isf(chance, np.maximum(levels, 1e-12)), float) + 1.0
    return np.maximum(k, min_count).astype(np.int64)[inverse.reshape(np.shape(mu))]


def oriented_counts(x_m: np.ndarray, h_m: np.ndarray, half_along: float, half_height: float,
                    max_slope: float) -> tuple[np.ndarray, np.ndarray]:
    """Per photon the largest two-sided neighbour count over the slope-following parallelograms and
    whether it is one-sided (the data end on one side; see the module docstring)."""
    x, h = np.asarray(x_m, float), np.asarray(h_m, float)
    ds = half_height / half_along
    ns = 2 * int(np.ceil(max_slope / ds)) + 1
    order = np.argsort(x, kind="stable")
    out, one = np.zeros(x.size, np.int64), np.zeros(x.size, bool)
    if x.size:
        s0 = -ds * (ns // 2)  # the steepest descending slope tried
        out[order], one[order] = _oriented_max(x[order], h[order], half_along, half_height, s0,
                                               ds, ns)
    return out, one


def local_max(x_m: np.ndarray, h_m: np.ndarray, values: np.ndarray, half_along: float,
              half_height: float) -> np.ndarray:
    """Per photon, the largest of ``values`` among the photons within ±half_along m along and
    ±half_height m in height of it."""
    x, h = np.asarray(x_m, float), np.asarray(h_m, float)
    order = np.argsort(x, kind="stable")
    out = np.zeros(x.size, np.asarray(values).dtype)
    if x.size:
        v = np.asarray(values)[order]
        out[order] = _local_max(x[order], h[order], v, half_along, half_height)
    return out


def slope_count(half_along: float, half_height: float, max_slope: float) -> int:
    """How many slopes a parallelogram tries: steps of half_height / half_along up to ±max_slope."""
    return 2 * int(np.ceil(max_slope * half_along / half_height)) + 1


def signal_photons(x_m: np.ndarray, h_m: np.ndarray, shot_spacing: float = 0.7,
                   settings: DensitySettings = DensitySettings()) -> np.ndarray:
    """Boolean mask of the signal photons (see the module docstring)."""
    x, h = np.asarray(x_m, float), np.asarray(h_m, float)
    s = settings
    signal = np.zeros(x.size, bool)
    if x.size == 0:
        return signal
    rho = background_density(x, h, s.block, s.bin_height, shot_spacing)
    tests = sum(slope_count(a, b, s.max_slope) for a, b in s.scales)
    for a, b in s.scales:
        mu = rho * 2.0 * a * b  # one side's background mean
        count, one_sided = oriented_counts(x, h, a, b, s.max_slope)
        least = max(s.min_count, int(np.ceil(s.min_rate * a)))
        k = np.where(one_sided, thresholds(mu, tests, s.false_alarm, 2 * least, sides=1),
                     thresholds(mu, tests, s.false_alarm, least))
        nearby = local_max(x, h, count, a, s.relative_height)
        signal |= (count >= k) & (count >= s.relative * nearby)
    return signal
