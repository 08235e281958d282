"""Eigen-decomposition of many symmetric 3×3 matrices: the PCA of local point neighbourhoods
(tie-plane patches, VGICP's local planes, the swath-difference cells).

``np.linalg.eigh`` on a stack of 3×3 matrices pays LAPACK's per-matrix overhead (≈ 1 µs,
over tens of thousands of cells per strip pair); here each matrix takes a closed form
(≈ 0.2 µs): the eigenvalues from the trigonometric solution of the characteristic cubic
(Smith 1961, *Eigenvalues of a symmetric 3×3 matrix*, CACM 4(4)), the eigenvector of the
eigenvalue farther from the middle one as the largest cross product of two rows of A − λI,
and the other two from the exact 2×2 problem in the plane orthogonal to it (one Jacobi
rotation), so nearly equal eigenvalues still get an orthonormal basis. Eigenvalues come
from Rayleigh quotients of the final vectors.
"""

from __future__ import annotations

import numpy as np
from numba import njit


def eigh3(a: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Eigenvalues (M, 3) ascending and unit eigenvectors (M, 3, 3) in columns of symmetric
    a (M, 3, 3), as ``np.linalg.eigh`` (each vector's sign is arbitrary)."""
    a = np.ascontiguousarray(a, dtype=np.float64)
    if a.ndim != 3 or a.shape[1:] != (3, 3):
        raise ValueError(f"expected (M, 3, 3) symmetric matrices, got shape {a.shape}")
    lam, vec = np.empty((a.shape[0], 3)), np.empty((a.shape[0], 3, 3))
    _eigh3_kernel(a, lam, vec)
    return lam, vec


@njit(cache=True, nogil=True, inline="always")
def _null_vector(a00, a01, a02, a11, a12, a22, lam):  # pragma: no cover - numba
    """Unit vector v with (A − lam·I) v ≈ 0: the largest cross product of two rows."""
    r00, r11, r22 = a00 - lam, a11 - lam, a22 - lam
    # rows (r00, a01, a02), (a01, r11, a12), (a02, a12, r22) and their pairwise cross products
    x0, x1, x2 = a01 * a12 - a02 * r11, a02 * a01 - r00 * a12, r00 * r11 - a01 * a01
    y0, y1, y2 = a01 * r22 - a02 * a12, a02 * a02 - r00 * r22, r00 * a12 - a01 * a02
    z0, z1, z2 = r11 * r22 - a12 * a12, a12 * a02 - a01 * r22, a01 * a12 - r11 * a02
    nx = x0 * x0 + x1 * x1 + x2 * x2
    ny = y0 * y0 + y1 * y1 + y2 * y2
    nz = z0 * z0 + z1 * z1 + z2 * z2
    if nx >= ny and nx >= nz:
        c0, c1, c2, n2 = x0, x1, x2, nx
    elif ny >= nz:
        c0, c1, c2, n2 = y0, y1, y2, ny
    else:
        c0, c1, c2, n2 = z0, z1, z2, nz
    if not n2 > 0.0:
        return 0.0, 0.0, 1.0
    f = 1.0 / np.sqrt(n2)
    return c0 * f, c1 * f, c2 * f


@njit(cache=True, nogil=True)
def _eigh3_kernel(a, lam, vec):  # pragma: no cover - numba
    for m in range(a.shape[0]):
        a00, a01, a02 = a[m, 0, 0], a[m, 0, 1], a[m, 0, 2]
        a11, a12, a22 = a[m, 1, 1], a[m, 1, 2], a[m, 2, 2]
        q = (a00 + a11 + a22) / 3.0
        b00, b11, b22 = a00 - q, a11 - q, a22 - q
        off_diagonal = a01 * a01 + a02 * a02 + a12 * a12
        p = np.sqrt((b00 * b00 + b11 * b11 + b22 * b22 + 2.0 * off_diagonal) / 6.0)
        if p == 0.0:  # a multiple of the identity
            for i in range(3):
                lam[m, i] = q
                for j in range(3):
                    vec[m, i, j] = 1.0 if i == j else 0.0
            continue
        # det(A − q·I) by cofactors along the first row
        det = (b00 * (b11 * b22 - a12 * a12) - a01 * (a01 * b22 - a12 * a02)
               + a02 * (a01 * a12 - b11 * a02))
        phi = np.arccos(min(max(det / (2.0 * p * p * p), -1.0), 1.0)) / 3.0
        hi = q + 2.0 * p * np.cos(phi)
        lo = q + 2.0 * p * np.cos(phi + 2.0 * np.pi / 3.0)
        mid = 3.0 * q - hi - lo
        low_end = mid - lo >= hi - mid  # the better separated end first
        v0, v1, v2 = _null_vector(a00, a01, a02, a11, a12, a22, lo if low_end else hi)
        # u ⟂ v: v crossed with the axis it is least aligned with; w = v × u
        if abs(v0) <= abs(v1) and abs(v0) <= abs(v2):
            u0, u1, u2 = 0.0, -v2, v1  # e_x × v
        elif abs(v1) <= abs(v2):
            u0, u1, u2 = v2, 0.0, -v0  # e_y × v
        else:
            u0, u1, u2 = -v1, v0, 0.0  # e_z × v
        f = 1.0 / np.sqrt(u0 * u0 + u1 * u1 + u2 * u2)
        u0, u1, u2 = u0 * f, u1 * f, u2 * f
        w0, w1, w2 = v1 * u2 - v2 * u1, v2 * u0 - v0 * u2, v0 * u1 - v1 * u0
        # the 2×2 problem in the (u, w) plane, solved by one rotation
        au0 = a00 * u0 + a01 * u1 + a02 * u2
        au1 = a01 * u0 + a11 * u1 + a12 * u2
        au2 = a02 * u0 + a12 * u1 + a22 * u2
        aw0 = a00 * w0 + a01 * w1 + a02 * w2
        aw1 = a01 * w0 + a11 * w1 + a12 * w2
        aw2 = a02 * w0 + a12 * w1 + a22 * w2
        suu = u0 * au0 + u1 * au1 + u2 * au2
        suw = u0 * aw0 + u1 * aw1 + u2 * aw2
        sww = w0 * aw0 + w1 * aw1 + w2 * aw2
        t = 0.5 * np.arctan2(2.0 * suw, suu - sww)
        c, s = np.cos(t), np.sin(t)
        l_big = c * c * suu + 2.0 * c * s * suw + s * s * sww
        l_small = s * s * suu - 2.0 * c * s * suw + c * c * sww
        l_v = (v0 * (a00 * v0 + a01 * v1 + a02 * v2) + v1 * (a01 * v0 + a11 * v1 + a12 * v2)
               + v2 * (a02 * v0 + a12 * v1 + a22 * v2))
        iv, ism, ibg = (0, 1, 2) if low_end else (2, 0, 1)
        lam[m, iv], lam[m, ism], lam[m, ibg] = l_v, l_small, l_big
        vec[m, 0, iv], vec[m, 1, iv], vec[m, 2, iv] = v0, v1, v2
        vec[m, 0, ism], vec[m, 0, ibg] = -s * u0 + c * w0, c * u0 + s * w0
        vec[m, 1, ism], vec[m, 1, ibg] = -s * u1 + c * w1, c * u1 + s * w1
        vec[m, 2, ism], vec[m, 2, ibg] = -s * u2 + c * w2, c * u2 + s * w2
