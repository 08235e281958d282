"""numba kernels of the fit's hot loops: residuals with their partials per observation, and the
normal equations accumulated row by row (each row touches 4 spline coefficients per channel).
The equations are those of :mod:`calidar.trajrec.geometry` (its numpy forms are the reference;
tests/unit/trajrec/test_geometry.py holds these to them)."""

from __future__ import annotations

import contextlib
import math

import numpy as np
from numba import njit

_H_ANG = 1e-5  #: central-difference step of the attitude partials, rad


@njit(cache=True, nogil=True, inline="always")
def _body(de, dn, du, roll, pitch, heading):
    """b = R_nbᵀ · v_ned of an east-north-up vector (the rotation of geometry.body_vectors)."""
    v0, v1, v2 = dn, de, -du
    c, s = math.cos(heading), math.sin(heading)
    v0, v1 = c * v0 + s * v1, -s * v0 + c * v1
    c, s = math.cos(pitch), math.sin(pitch)
    v0, v2 = c * v0 - s * v2, s * v0 + c * v2
    c, s = math.cos(roll), math.sin(roll)
    v1, v2 = c * v1 + s * v2, -s * v1 + c * v2
    return v0, v1, v2


@njit(cache=True, nogil=True, inline="always")
def _scanner(b0, b1, b2, ck, sk, ce, se):
    """The scanner vector s = Ry(ε)ᵀ·Rz(κ)ᵀ·b (ck, sk, ce, se: cos, sin of the scan plane's yaw κ
    and pitch ε in the body)."""
    s0, s1 = ck * b0 + sk * b1, -sk * b0 + ck * b1
    return ce * s0 - se * b2, s1, se * s0 + ce * b2


@njit(cache=True, nogil=True, inline="always")
def _angles(b0, b1, b2, ck, sk, ce, se):
    """(across-track angle of the body vector, along-track angle of the scanner vector)."""
    s0, s1, s2 = _scanner(b0, b1, b2, ck, sk, ce, se)
    return math.atan2(b1, b2), math.atan2(s0, math.hypot(s1, s2))


@njit(cache=True, nogil=True)
def scan_partials(points, state, scan, kappa=0.0, eps=0.0):  # pragma: no cover - numba
    """Residuals (n, 2) (across − scan angle, along) and partials (n, 2, 6): exact for the
    position (b is linear in p − S), central differences of 1e-5 rad for the attitude (their error,
    ~1e-11, stays far below the along-track angle's scatter, whose weight would amplify any more).
    ``kappa``, ``eps``: the scan plane's yaw and pitch in the body (rad; see
    geometry.scan_residuals)."""
    n = points.shape[0]
    ck, sk, ce, se = math.cos(kappa), math.sin(kappa), math.cos(eps), math.sin(eps)
    r = np.empty((n, 2))
    g = np.empty((n, 2, 6))
    att = np.empty(3)
    eye = np.eye(3)
    for k in range(n):
        p, st = points[k], state[k]
        de, dn, du = p[0] - st[0], p[1] - st[1], p[2] - st[2]
        ro, pi, he = state[k, 3], state[k, 4], state[k, 5]
        b0, b1, b2 = _body(de, dn, du, ro, pi, he)
        a0, c0 = _angles(b0, b1, b2, ck, sk, ce, se)
        r[k, 0] = a0 - scan[k]
        r[k, 1] = c0
        s0, s1, s2 = _scanner(b0, b1, b2, ck, sk, ce, se)
        q = b1 * b1 + b2 * b2
        qs = s1 * s1 + s2 * s2
        h = math.sqrt(qs)
        big = qs + s0 * s0
        # ∂across/∂b = (0, b2, −b1)/q; ∂along/∂s = (h, −s0·s1/h, −s0·s2/h)/(s0² + h²);
        # ∂b/∂S_j = −A e_j
        for j in range(3):
            e0, e1, e2 = _body(eye[j, 0], eye[j, 1], eye[j, 2], ro, pi, he)
            f0, f1, f2 = _scanner(e0, e1, e2, ck, sk, ce, se)
            g[k, 0, j] = -(b2 * e1 - b1 * e2) / q
            g[k, 1, j] = -(h * f0 - s0 * (s1 * f1 + s2 * f2) / h) / big
        for j in range(3):
            att[0], att[1], att[2] = ro, pi, he
            att[j] += _H_ANG
            b0j, b1j, b2j = _body(de, dn, du, att[0], att[1], att[2])
            a1, c1 = _angles(b0j, b1j, b2j, ck, sk, ce, se)
            att[j] -= 2 * _H_ANG
            b0j, b1j, b2j = _body(de, dn, du, att[0], att[1], att[2])
            a2, c2 = _angles(b0j, b1j, b2j, ck, sk, ce, se)
            g[k, 0, 3 + j] = (a1 - a2) / (2 * _H_ANG)
            g[k, 1, 3 + j] = (c1 - c2) / (2 * _H_ANG)
    return r, g


@njit(cache=True, nogil=True)
def mount_partials(points, state, kappa, eps):  # pragma: no cover - numba
    """Partials (n, 2) of the along-track angle by the scan plane's yaw κ and pitch ε in the body
    (central differences of 1e-5 rad, as the attitude's)."""
    n = points.shape[0]
    out = np.empty((n, 2))
    for k in range(n):
        p, st = points[k], state[k]
        b0, b1, b2 = _body(p[0] - st[0], p[1] - st[1], p[2] - st[2], st[3], st[4], st[5])
        for j in range(2):
            ka, ea = (kappa + _H_ANG, eps) if j == 0 else (kappa, eps + _H_ANG)
            kb, eb = (kappa - _H_ANG, eps) if j == 0 else (kappa, eps - _H_ANG)
            c1 = _angles(b0, b1, b2, math.cos(ka), math.sin(ka), math.cos(ea), math.sin(ea))[1]
            c2 = _angles(b0, b1, b2, math.cos(kb), math.sin(kb), math.cos(eb), math.sin(eb))[1]
            out[k, j] = (c1 - c2) / (2 * _H_ANG)
    return out


@njit(cache=True, nogil=True)
def ray_partials(sensor, last, u1, u2):  # pragma: no cover - numba
    """Residuals (n, 2) of the sensor against each ray and their exact partials (n, 2, 6)."""
    n = sensor.shape[0]
    r = np.empty((n, 2))
    g = np.zeros((n, 2, 6))
    for k in range(n):
        w0, w1, w2 = sensor[k, 0] - last[k, 0], sensor[k, 1] - last[k, 1], sensor[k, 2] - last[k, 2]
        rho = math.sqrt(w0 * w0 + w1 * w1 + w2 * w2)
        e1 = (w0 * u1[k, 0] + w1 * u1[k, 1] + w2 * u1[k, 2]) / rho
        e2 = (w0 * u2[k, 0] + w1 * u2[k, 1] + w2 * u2[k, 2]) / rho
        r[k, 0], r[k, 1] = e1, e2
        for c in range(3):
            wc = (w0, w1, w2)[c] / rho
            g[k, 0, c] = u1[k, c] / rho - e1 * wc / rho
            g[k, 1, c] = u2[k, c] / rho - e2 * wc / rho
    return r, g


@njit(cache=True, nogil=True)
def accumulate(n_mat, rhs, first, w, g, r, weight, k_coef):  # pragma: no cover - numba
    """Upper triangle of n_mat += Σ weight·a aᵀ, and rhs −= Σ weight·a·r, with a = g ⊗ (spline
    weights), row by row over a's nonzero entries (see :func:`symmetrize`)."""
    a = np.empty(24)
    cols = np.empty(24, np.int64)
    for k in range(r.shape[0]):
        wk = weight[k]
        if wk == 0.0:
            continue
        m = 0
        for c in range(6):
            if g[k, c] == 0.0:
                continue
            for j in range(4):
                a[m] = g[k, c] * w[k, j]
                cols[m] = c * k_coef + first[k] + j
                m += 1
        for p in range(m):
            ap = wk * a[p]
            rhs[cols[p]] -= ap * r[k]
            cp = cols[p]
            for q in range(m):
                if cols[q] >= cp:
                    n_mat[cp, cols[q]] += ap * a[q]


def symmetrize(n_mat: np.ndarray) -> np.ndarray:
    """The full normal matrix from the upper triangle :func:`accumulate` fills (its lower triangle
    zero): N + Nᵀ with the diagonal once (cheaper than np.triu's masks)."""
    out = n_mat + n_mat.T
    np.fill_diagonal(out, np.diagonal(n_mat))
    return out


#: threadpoolctl's controller, made once (finding the BLAS libraries costs a few ms a call)
_CONTROLLER = []


def one_blas_thread():
    """BLAS on one thread while solving (these matrices are a few hundred wide: a second thread
    gains nothing and, on a busy machine, costs 10×; as ``calidar.adjust.solver``)."""
    try:
        from threadpoolctl import ThreadpoolController
    except ImportError:  # pragma: no cover - a dependency of scikit-learn
        return contextlib.nullcontext()
    if not _CONTROLLER:
        # the controller sees only the libraries loaded when it is made: scipy.linalg's own
        # OpenBLAS (the banded solves) must be loaded first, or its threads stay unlimited and spin
        # (docs/validation.md, "Lines of at most 100 characters … fifth session")
        import scipy.linalg  # noqa: F401

        _CONTROLLER.append(ThreadpoolController())
    return _CONTROLLER[0].limit(limits=1, user_api="blas")


@njit(cache=True, nogil=True)
def accumulate_border(b, c_mat, r_g, first, w, g, gm, r, weight,
                      k_coef):  # pragma: no cover - numba
    """b += Σ weight·a·gmᵀ (a: the row's partials by the spline coefficients, as
    :func:`accumulate`), c_mat += Σ weight·gm·gmᵀ, r_g −= Σ weight·gm·r: the normal matrix's border
    with a few global parameters (calidar.trajrec.mounting)."""
    m = gm.shape[1]
    for k in range(r.shape[0]):
        wk = weight[k]
        if wk == 0.0:
            continue
        for p in range(m):
            gp = wk * gm[k, p]
            if gp == 0.0:
                continue
            r_g[p] -= gp * r[k]
            for q in range(m):
                c_mat[p, q] += gp * gm[k, q]
            for c in range(6):
                if g[k, c] == 0.0:
                    continue
                for j in range(4):
                    b[c * k_coef + first[k] + j, p] += gp * g[k, c] * w[k, j]


@njit(cache=True, nogil=True)
def band_of_inverse(ub):  # pragma: no cover - numba
    """The band of N⁻¹ from the banded Cholesky factor N = UᵀU (``ub``: upper form, ub[u + i − j,
    j] = U[i, j]), in the same form: Z = U⁻¹U⁻ᵀ row by row upwards,
    Z_ij = (δ_ij/U_ii − Σ_{k=i+1}^{i+u} U_ik·Z_kj)/U_ii, which needs only Z's band (Takahashi,
    Fagan & Chin 1973; Rue & Held 2005, §2.4.1): O(n·u²) against O(n²·u) for the whole inverse,
    which a segment's σ (values 4 coefficients apart at most) never use."""
    u, n = ub.shape[0] - 1, ub.shape[1]
    z = np.zeros((u + 1, n))
    for i in range(n - 1, -1, -1):
        uii = ub[u, i]
        top = min(n - 1, i + u)
        for j in range(top, i - 1, -1):
            s = 0.0
            for k in range(i + 1, top + 1):
                zkj = z[u + k - j, j] if k <= j else z[u + j - k, k]
                s += ub[u + i - k, k] * zkj
            z[u + i - j, j] = ((1.0 / uii if i == j else 0.0) - s) / uii
    return z
