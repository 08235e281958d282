"""A tie plane's normal as the adjustment's regressor: its tilt replaced by the expected true tilt
given the fit (issue 26, the outer loop's crawl).

A tie-plane row r = n_b · (â − c_b) (:mod:`calidar.strips.planes`) moves, in the adjustment's
linear model, by n_b · δ when the strips move apart horizontally by δ: on flat ground by b's
fitted tilt times δ. After the next matching, however, â is a's plane again at b's centroid and
the row has moved by *a's* fitted tilt times δ. On flat ground both tilts are the fits' noise,
independent of each other: the model's regressor (b's noise) says nothing of how the re-matched row
moves, yet it weighs in the normal equations as if it did. Every flat row then acts as a prior that
holds the strips' horizontal offsets where the last matching found them — re-centred at every
matching, so the outer loop becomes a proximal iteration that crawls wherever the flat rows outweigh
what parts the mounting from the trajectory corrections (the 10⁹ run's kept cells: ≈ 20 % of the
pitch's error removed an outer iteration; docs/validation.md, seventh session). It also counts as
information the angles' σ took in.

The remedy is regression calibration (Carroll, Ruppert, Stefanski & Crainiceanu 2006, *Measurement
Error in Nonlinear Models*, ch. 4): the noisy regressor replaced by its expectation given the data.
The fitted normal's tilt from the vertical along its in-plane axes e_j, τ_j = z · e_j, has noise
variance v_j = σ² / (m λ_j) (the least-squares slope's: σ² the points' scatter about the plane,
m points, λ_j their variance along e_j). The true tilts of one pair's patches get a prior fitted to
those patches — a mixture of zero-mean normals on a fixed grid of variances, zero included (flat
ground), its weights by EM (the adaptive shrinkage of Stephens 2017, *Biostatistics* 18:275) — and
each row's normal takes the posterior mean of its tilt: flat patches' rows no longer couple to
horizontal moves, sloped ones keep their normals. The tilt is taken along east and north, each
component with its own prior (tenth session): a prior on the tilt's magnitude left a sloped
patch's tilt across its slope — the fit's noise there, as on flat ground — whole, and those rows
held the loop alike along the lines (the 10⁹ run's kept cells: 8 outer iterations → 3).
E[t_j | τ_j] is a regression calibration whatever the slopes' directions (only each component's
distribution is modelled); it shrinks most where the slopes run east or north. Only b's fit is
used, which the row's residual does not hold (its noise is a's and b's centroid's): the regressor
stays independent of the residual's noise and the outer loop's fixed point unbiased.
"""

from __future__ import annotations

import numpy as np
from numba import njit

#: the prior's variances of a true tilt (rad²): flat, then 3·10⁻⁴ rad to 1 rad (walls are steeper:
#: their tilts are far beyond the fits' noise and kept whatever the prior)
PRIOR_VARIANCES = np.r_[0.0, np.logspace(-7.0, 0.0, 15)]
#: normals' vertical component below this (slopes over 60°, walls): the fitted normal kept
STEEP_NZ = 0.5
EM_ITERATIONS = 60


def expected_tilt(tau: np.ndarray, var: np.ndarray) -> np.ndarray:
    """The posterior mean (R, 2) of true tilts given fitted ones ``tau`` (R, 2) with noise
    variances ``var`` (R, 2), under a prior fitted to them (mixture of normals N(0, s²) over
    :data:`PRIOR_VARIANCES`, weights by EM)."""
    if tau.shape[0] == 0:
        return tau.copy()
    s2 = PRIOR_VARIANCES[None, :, None]
    total = var[:, None, :] + s2  # (R, K, 2)
    loglik = -0.5 * np.sum(np.log(total) + tau[:, None, :] ** 2 / total, axis=2)  # (R, K)
    loglik -= loglik.max(axis=1, keepdims=True)
    lik = np.exp(loglik)
    weight = mixture_weights(lik, EM_ITERATIONS)
    post = lik * weight
    post /= post.sum(axis=1, keepdims=True)
    return np.einsum("rk,rkj->rj", post, s2 / total) * tau


@njit(cache=True, nogil=True)
def mixture_weights(lik, iterations):  # pragma: no cover - numba
    """The mixture's weights (K,) after ``iterations`` EM steps from uniform, given each row's
    likelihood under each component ``lik`` (R, K): per step post = lik·weight normalised per row,
    weight = post's mean over the rows. One pass over the rows per step, without temporaries, in
    the order of operations of numpy's ``post /= post.sum(axis=1, keepdims=True); weight =
    post.mean(axis=0)`` (the same bits, tests/unit/strips/test_tilt.py; ≈ 5× fewer CPU seconds):
    each row's sum as numpy's pairwise sum of 8 ≤ K ≤ 128 numbers (eight running sums, a tree,
    then the rest), the rows' posteriors summed in row order, the weight that sum over R."""
    n_rows, n = lik.shape
    assert 8 <= n <= 128
    weight = np.full(n, 1.0 / n)
    post, acc, part = np.empty(n), np.empty(n), np.empty(8)
    for _ in range(iterations):
        for r in range(n_rows):
            for k in range(n):
                post[k] = lik[r, k] * weight[k]
            for j in range(8):
                part[j] = post[j]
            i = 8
            while i < n - n % 8:
                for j in range(8):
                    part[j] += post[i + j]
                i += 8
            total = ((part[0] + part[1]) + (part[2] + part[3])) + ((part[4] + part[5])
                                                                   + (part[6] + part[7]))
            while i < n:
                total += post[i]
                i += 1
            for k in range(n):
                acc[k] = post[k] / total if r == 0 else acc[k] + post[k] / total
        for k in range(n):
            weight[k] = acc[k] / n_rows
    return weight


def calibrated_normals(normal: np.ndarray, axes: np.ndarray, spread_m2: np.ndarray,
                       rms_m: np.ndarray, count: np.ndarray) -> np.ndarray:
    """Unit normals (R, 3) pointing up whose tilt from the vertical is the expected true tilt
    (:func:`expected_tilt`) of the fitted ``normal`` (R, 3), from each patch's in-plane axes
    (``axes`` (R, 3, 2)), its points' variances along them (``spread_m2`` (R, 2), m²), its
    scatter about the plane (``rms_m``, m) and its points (``count``).

    The tilt is taken along east and north (in-plane axes f_1 ⟂ north, f_2 = n × f_1), each with
    its own prior (issue 26, tenth session): a slope along one axis says nothing of the tilt
    along the other, whose fitted value there is noise that a prior on the tilt's magnitude kept
    whole (a sloped patch's cross tilt then coupled the rows to moves along it). Patches steeper
    than :data:`STEEP_NZ` (walls) keep their fitted normals: their tilts are far beyond a fit's
    noise, and along east and north they are no tilts."""
    normal = np.asarray(normal, float)
    out = normal.copy()
    gentle = normal[:, 2] >= STEEP_NZ
    if gentle.any():
        out[gentle] = _along_east_north(normal[gentle], axes[gentle], spread_m2[gentle],
                                        rms_m[gentle], count[gentle])
    return out


def _along_east_north(normal: np.ndarray, axes: np.ndarray, spread_m2: np.ndarray,
                      rms_m: np.ndarray, count: np.ndarray) -> np.ndarray:
    """:func:`calibrated_normals` of patches no steeper than :data:`STEEP_NZ`."""
    f1 = np.cross(np.array([0.0, 1.0, 0.0]), normal)  # in-plane, ⟂ north: ≈ east
    f1 /= np.linalg.norm(f1, axis=1)[:, None]
    frame = np.stack([f1, np.cross(normal, f1)], axis=2)  # (R, 3, 2): ≈ east, ≈ north
    tau = frame[:, 2, :]  # z · f_j: the tilt along each axis (rad, small angles)
    var_e = np.clip(rms_m, 1e-6, None)[:, None] ** 2 / (count[:, None] * spread_m2)
    rot = np.einsum("rij,rik->rjk", frame, axes)  # f_j · e_k
    var = np.einsum("rjk,rk->rj", rot**2, var_e)  # the tilts' noise variances along f_j
    shrunk = np.column_stack([expected_tilt(tau[:, j:j + 1], var[:, j:j + 1])[:, 0]
                              for j in range(2)])
    # z = (z·n) n + Σ_j τ_j f_j, so n ≈ z − Σ_j τ_j f_j: the tilt τ_j replaced by its expectation
    out = normal + np.einsum("rij,rj->ri", frame, tau - shrunk)
    return out / np.linalg.norm(out, axis=1)[:, None]
