"""The 2×2 inverses of :mod:`calidar.strips.inverse2` equal ``np.linalg.inv``'s bit for bit."""

import numpy as np
import pytest

from calidar.strips import inverse2
from calidar.strips.inverse2 import inv2
from calidar.strips.planimetric import gradient_noise


def _same(a):
    ref = np.linalg.inv(a)
    got = inv2(a)
    assert got.shape == ref.shape
    np.testing.assert_array_equal(got.view(np.int64), ref.view(np.int64))  # every bit
    if inverse2.agrees():  # the kernel itself, not numpy standing in for it
        out = np.empty_like(ref)
        assert inverse2._inv2_kernel(np.ascontiguousarray(a), out, inverse2._ROUNDING[0])
        np.testing.assert_array_equal(out.view(np.int64), ref.view(np.int64))


def test_the_kernel_does_the_inverses_where_the_check_agrees(monkeypatch):
    """Where the once-per-process check finds every bit equal, the kernel does the finite float64
    inverses and numpy is not called; a zero pivot still goes to numpy. (Whether the check agrees is
    the machine's: the kernel mirrors the OpenBLAS kernels of the x86-64 CPUs it was written on; on
    an AMD EPYC with the same OpenBLAS core type, 'Haswell', the fused rounding differs in 388 of
    the 2 000 probes and the rounding apart agrees — docs/validation.md, ninth and thirteenth
    sessions.)"""
    monkeypatch.setattr(inverse2, "_AGREES", [True])
    a = np.random.default_rng(6).normal(size=(1000, 2, 2))
    calls = []
    real = np.linalg.inv
    monkeypatch.setattr(np.linalg, "inv", lambda x: calls.append(1) or real(x))
    assert np.allclose(inv2(a), real(a), rtol=1e-12, atol=0) and calls == []
    a[5, 0, 0] = a[5, 1, 0] = 0.0  # singular: LAPACK's own error
    with pytest.raises(np.linalg.LinAlgError):
        inv2(a)
    assert calls == [1]


def test_numpy_does_every_inverse_when_the_check_disagrees(monkeypatch):
    monkeypatch.setattr(inverse2, "_AGREES", [False])
    a = np.random.default_rng(6).normal(size=(1000, 2, 2))
    calls = []
    real = np.linalg.inv
    monkeypatch.setattr(np.linalg, "inv", lambda x: calls.append(1) or real(x))
    np.testing.assert_array_equal(inv2(a), real(a))
    assert calls == [1]


def test_random_matrices_of_every_scale_bit_for_bit():
    rng = np.random.default_rng(3)
    a = rng.normal(size=(400_000, 2, 2)) * rng.lognormal(0, 5, size=(400_000, 1, 1))
    a[::7, 1, 0] = a[::7, 0, 0]  # equal magnitudes in the pivot column: no swap
    a[::11, 1, 0] = -a[::11, 0, 0]
    a[::13, 0, 0] = 0.0  # a zero first entry: the rows swap
    _same(a)


def test_covariances_and_strided_input_bit_for_bit():
    rng = np.random.default_rng(4)
    s = rng.normal(size=(200_000, 3, 5))
    cov = s @ s.transpose(0, 2, 1) * rng.lognormal(-6, 2, size=(200_000, 1, 1))
    _same(cov[:, :2, :2])  # a strided view, as gradient_noise passes it
    single = cov[:, :2, :2].astype(np.float32)
    assert inv2(single).dtype == np.float32
    np.testing.assert_array_equal(inv2(single), np.linalg.inv(single))


def test_singular_and_non_finite_as_numpy():
    with pytest.raises(np.linalg.LinAlgError):
        inv2(np.array([[[1.0, 0.0], [0.0, 1.0]], [[1.0, 2.0], [2.0, 4.0]]]))
    with pytest.raises(np.linalg.LinAlgError):
        inv2(np.zeros((1, 2, 2)))
    a = np.array([[[1.0, np.nan], [0.5, 2.0]], [[2.0, 1.0], [1.0, 3.0]]])
    np.testing.assert_array_equal(inv2(a), np.linalg.inv(a))  # NaN where numpy's are
    assert inv2(np.zeros((0, 2, 2))).shape == (0, 2, 2)
    with pytest.raises(ValueError, match="2, 2"):
        inv2(np.zeros((3, 3, 3)))


def test_gradient_noise_as_with_numpy_inverse():
    rng = np.random.default_rng(5)
    pts = rng.normal(size=(5000, 12, 3)) * [1.0, 0.7, 0.05]
    cov = np.einsum("kni,knj->kij", pts - pts.mean(1, keepdims=True),
                    pts - pts.mean(1, keepdims=True)) / 12
    normal = np.linalg.eigh(cov)[1][:, :, 0]
    normal *= np.sign(normal[:, 2:3])
    count = rng.integers(6, 40, 5000).astype(float)
    lam = np.einsum("ki,kij,kj->k", normal, cov, normal)
    var_z = lam / normal[:, 2] ** 2 * count / np.maximum(count - 3, 1)
    ref = var_z[:, None, None] * np.linalg.inv(cov[:, :2, :2]) / count[:, None, None]
    np.testing.assert_array_equal(gradient_noise(cov, count, normal), ref)


def test_the_two_roundings_differ_and_each_is_checked(monkeypatch):
    """The kernel's two roundings of the back substitution (fused, apart) give different bits on
    the probes (so the check tells them apart), and the check keeps the one that gives numpy's:
    with numpy standing in as each in turn, the check agrees and keeps that one."""
    rng = np.random.default_rng(20261127)
    a = rng.normal(size=(2000, 2, 2)) * rng.lognormal(0.0, 4.0, (2000, 1, 1))
    got = {}
    for rounding in (inverse2.FUSED, inverse2.APART):
        got[rounding] = np.empty_like(a)
        assert inverse2._inv2_kernel(a, got[rounding], rounding)
    assert not np.array_equal(got[True].view(np.int64), got[False].view(np.int64))
    for rounding in (inverse2.FUSED, inverse2.APART):
        def as_kernel(x, rounding=rounding):
            out = np.empty_like(x)
            inverse2._inv2_kernel(np.ascontiguousarray(x), out, rounding)
            return out
        monkeypatch.setattr(inverse2, "_AGREES", [])
        monkeypatch.setattr(inverse2, "_ROUNDING", [not rounding])
        monkeypatch.setattr(np.linalg, "inv", as_kernel)
        assert inverse2.agrees() and inverse2._ROUNDING == [rounding]

