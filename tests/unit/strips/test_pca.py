"""The closed-form 3×3 eigen-decomposition against LAPACK, on the neighbourhoods it meets."""

import numpy as np
import pytest

from calidar.strips.pca import eigh3


def _rotations(rng, m):
    return np.linalg.qr(rng.normal(size=(m, 3, 3)))[0]


def _cases():
    rng = np.random.default_rng(7)
    m = 20000
    x = rng.normal(size=(m, 3, 3))
    R = _rotations(rng, m)

    def scatter(sd):  # 12-point neighbourhoods with these standard deviations, rotated
        p = np.einsum("mij,mkj->mki", R, rng.normal(size=(m, 12, 3)) * sd)
        p -= p.mean(axis=1, keepdims=True)
        return np.einsum("mki,mkj->mij", p, p) / 12

    def spectrum(d):  # R diag(d) Rᵀ
        return np.einsum("mij,mj,mkj->mik", R, np.broadcast_to(d, (m, 3)), R)

    return {
        "random": x + x.transpose(0, 2, 1),
        "roof patch": scatter([2.0, 1.5, 0.03]),
        "square patch": scatter([1.0, 1.0, 0.01]),
        "double eigenvalue": spectrum(np.stack([np.ones(m), np.ones(m), rng.uniform(0, 2, m)], axis=1)),
        "line": spectrum([4.0, 1e-6, 1e-6]),
        "identity": np.repeat(2.0 * np.eye(3)[None], 10, axis=0),
        "zero": np.zeros((10, 3, 3)),
    }


@pytest.mark.parametrize("name", list(_cases()))
def test_eigh3_matches_lapack(name):
    a = _cases()[name]
    lam, vec = eigh3(a)
    ref, ref_vec = np.linalg.eigh(a)
    scale = np.maximum(np.abs(ref).max(axis=1, keepdims=True), 1e-300)
    assert np.max(np.abs(lam - ref) / scale) < 1e-13
    assert np.all(np.diff(lam, axis=1) >= -1e-13 * scale)  # ascending
    assert np.max(np.abs(np.einsum("mji,mjk->mik", vec, vec) - np.eye(3))) < 1e-13  # orthonormal
    residual = np.einsum("mij,mjk->mik", a, vec) - vec * lam[:, None, :]
    assert np.max(np.linalg.norm(residual, axis=1) / scale) < 1e-13  # A v = λ v
    separated = (ref[:, 1] - ref[:, 0]) > 1e-3 * scale[:, 0]  # the normal is defined: same as LAPACK's
    cosine = np.abs(np.einsum("mi,mi->m", vec[separated, :, 0], ref_vec[separated, :, 0]))
    assert np.all(cosine > 1 - 1e-10)


def test_eigh3_refuses_other_shapes():
    with pytest.raises(ValueError, match=r"\(M, 3, 3\)"):
        eigh3(np.zeros((4, 2, 2)))
