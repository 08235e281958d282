"""VGICP rows' σ: b's normal's error is in a's scatter along it, not in a's mean (issue 26, twelfth
session).

a's scatter is measured along b's fitted normal about a's mean, so it holds b's normal's error
times a's spread in b's plane, τ_b²·t (:func:`calidar.strips.vgicp_planes._tilt_cofactor`); the
row's residual, a's mean against b's plane, does not. Counted as a's noise it made every row's σ
too wide (on a flat airborne scene at the truth RMS z 0.944; docs/validation.md, "VGICP's σ0 on
airborne surveys"). Pure noise on a plane: the rows' RMS z is 1."""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest
import scipy.sparse as sp

from calidar.strips.vgicp import VgicpSettings, match_pair_vgicp
from calidar.strips.vgicp_planes import _along_normal_variance, _tilt_cofactor, local_planes

NOISE_M = 0.03  #: the points' noise along the vertical, m (the airborne Monte-Carlo's range noise)


def _strip(rng, n: int = 25_000) -> np.ndarray:
    """n points (m) on a tilted plane over 150 m × 150 m, noisy in height."""
    x, y = rng.uniform(-75.0, 75.0, (2, n))
    return np.column_stack([x, y, 0.1 * x + 0.05 * y + rng.normal(0.0, NOISE_M, n)])


def test_rows_on_a_noisy_plane_read_rms_z_one():
    """Two strips of one plane, matched where they lie (the truth): nothing in the residuals but
    the points' noise, so RMS z = 1 (±1 % over ≈ 5 000 rows; before: 0.944)."""
    settings = replace(VgicpSettings(), noise_floor_m=0.0)
    z = []
    for seed in (1, 2, 3):
        rng = np.random.default_rng(seed)
        a, b = _strip(rng), _strip(rng)
        c = match_pair_vgicp(1, a, 2, b, settings)
        z.append(c.residuals(a, b) / c.sigma_m)
    z = np.concatenate(z)
    assert z.size > 4_000
    assert np.sqrt(np.mean(z**2)) == pytest.approx(1.0, abs=0.03)


def test_a_scatter_along_b_normal_holds_b_tilt_times_t():
    """E[s_a²] = τ²·(1 + t) for a's scatter about its mean along b's fitted normal (a and b with
    noise τ): 4 000 draws of one row's noise, a's 10 points spread across b's 12-point disc."""
    rng = np.random.default_rng(5)
    disc = lambda n: np.column_stack([rng.uniform(-1, 1, (n, 2)) * [2.0, 1.0], np.zeros(n)])  # noqa: E731
    a0, b0 = disc(10), disc(12)
    draws, s2, t = 4_000, [], []
    A = sp.csr_matrix(np.full((1, 10), 0.1))
    for _ in range(draws):
        a = a0 + [0, 0, 1] * rng.normal(0.0, NOISE_M, (10, 1))
        b = b0 + [0, 0, 1] * rng.normal(0.0, NOISE_M, (12, 1))
        planes = local_planes(b, b.mean(axis=0)[None], 12, 1)
        mean = A @ a
        s2.append(_along_normal_variance(A, a, mean, planes.normal)[0])
        t.append(_tilt_cofactor(A, a, mean, planes.eigval, planes.eigvec)[0])
    t = float(np.mean(t))
    assert t > 0.1  # a's spread in the plane about b's: t ≈ 2 · (10/9) / 12, not small
    expected = NOISE_M**2 * (1.0 + t)
    assert np.mean(s2) == pytest.approx(expected, rel=0.04)  # ±2.2 % sampling spread
    assert np.mean(s2) > NOISE_M**2 * (1.0 + t / 2)  # not τ² alone


def test_one_point_rows_have_no_tilt_part():
    A = sp.csr_matrix(np.ones((1, 1)))
    p = np.zeros((1, 3))
    vec = np.eye(3)[None]
    assert _tilt_cofactor(A, p, p, np.ones((1, 3)), vec)[0] == 0.0
