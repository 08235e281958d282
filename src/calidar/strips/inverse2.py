"""Inverses of many 2×2 matrices in one numba pass, bit for bit as ``np.linalg.inv``.

``np.linalg.inv`` on a stack of 2×2 matrices solves A X = I per matrix with LAPACK's ``dgesv``
(LU with partial pivoting, then two triangular solves) and pays its per-matrix overhead (≈ 1 µs,
over the hundreds of thousands of cells a swath difference asks for). :func:`inv2` does the same
arithmetic, operation for operation as the OpenBLAS kernels numpy ships with (the pivot's
reciprocal multiplied in, the back substitution's update fused: one rounding), so that results
stay equal to the last bit (``tests/unit/strips/test_inverse2.py`` compares random and covariance
matrices of every scale). Anything LAPACK would call singular, a non-finite entry or another dtype
than float64 goes to ``np.linalg.inv`` itself (its error, its NaNs, its precision). The operations
are those of the kernels OpenBLAS picks on x86-64 (Haswell and later); numpy built with another
LAPACK, or OpenBLAS picking other kernels, may round differently: each process checks the kernel
once against ``np.linalg.inv`` on :data:`PROBES` matrices in its two roundings — the back
substitution's update fused (:data:`FUSED`: Intel x86-64) or multiplied and subtracted apart, as
the OpenBLAS 0.3.31 of numpy 2.4 rounds on an AMD EPYC with AVX-512 (issue 32, thirteenth
session) — and, unless every bit agrees in one of them, leaves all inverses to numpy.
"""

from __future__ import annotations

import numpy as np
from numba import njit, types
from numba.extending import intrinsic


@intrinsic
def _fma(typingctx, a, b, c):  # pragma: no cover - numba
    """a · b + c with one rounding (LLVM's ``llvm.fma.f64``)."""
    sig = types.float64(types.float64, types.float64, types.float64)

    def codegen(context, builder, signature, args):
        return builder.fma(*args)

    return sig, codegen


PROBES = 2000  #: matrices of the once-per-process check that the kernel rounds as numpy does
FUSED, APART = True, False  #: the back substitution's update with one rounding, or two
_AGREES: list[bool] = []  #: the check's answer, once made
_ROUNDING: list[bool] = [FUSED]  #: the rounding that agreed (FUSED or APART)


def inv2(a: np.ndarray) -> np.ndarray:
    """The inverses (K, 2, 2) of matrices ``a`` (K, 2, 2), as ``np.linalg.inv(a)``."""
    a = np.asarray(a)
    if a.ndim != 3 or a.shape[1:] != (2, 2):
        raise ValueError(f"expected (K, 2, 2) matrices, got shape {a.shape}")
    if a.dtype != np.float64 or not agrees():  # numpy's own precision (float32: sgesv), or rounding
        return np.linalg.inv(a)
    a = np.ascontiguousarray(a)
    out = np.empty_like(a)
    if not _inv2_kernel(a, out, _ROUNDING[0]):  # a zero pivot or a non-finite entry: LAPACK's
        return np.linalg.inv(a)
    return out


def agrees() -> bool:
    """Whether the kernel, in one of its roundings (kept for the process: :data:`_ROUNDING`), gives
    ``np.linalg.inv``'s bits on :data:`PROBES` seeded matrices of every scale (random,
    covariance-like, pivots of equal size, zero first entries): checked once."""
    if not _AGREES:
        rng = np.random.default_rng(20261127)
        a = rng.normal(size=(PROBES, 2, 2)) * rng.lognormal(0.0, 4.0, (PROBES, 1, 1))
        a[::4] = a[::4] @ a[::4].transpose(0, 2, 1)  # symmetric positive definite
        a[1::7, 1, 0], a[2::9, 0, 0] = a[1::7, 0, 0], 0.0
        ref = np.linalg.inv(a).view(np.int64)
        for rounding in (FUSED, APART):
            out = np.empty_like(a)
            if _inv2_kernel(a, out, rounding) and np.array_equal(out.view(np.int64), ref):
                _ROUNDING[0] = rounding
                _AGREES.append(True)
                break
        else:
            _AGREES.append(False)
    return _AGREES[0]


@njit(cache=True, nogil=True)
def _inv2_kernel(a, out, fused=True):  # pragma: no cover - numba
    """out[k] = a[k]⁻¹ by dgetrf + dgetrs on the identity, the back substitution's update
    ``b1 − p12 · x2`` with one rounding (``fused``) or two; False (out unfinished) at the first
    zero pivot or non-finite entry."""
    for k in range(a.shape[0]):
        a11, a12, a21, a22 = a[k, 0, 0], a[k, 0, 1], a[k, 1, 0], a[k, 1, 1]
        if not (np.isfinite(a11) and np.isfinite(a12) and np.isfinite(a21)
                and np.isfinite(a22)):
            return False
        swap = abs(a21) > abs(a11)  # idamax: the first of equal magnitudes
        if swap:
            p11, p12, p21, p22 = a21, a22, a11, a12
        else:
            p11, p12, p21, p22 = a11, a12, a21, a22
        if p11 == 0.0:
            return False
        r1 = 1.0 / p11
        low = p21 * r1
        u22 = p22 - low * p12
        if u22 == 0.0:
            return False
        r2 = 1.0 / u22
        for c in range(2):  # the columns of P · I
            b1 = 1.0 if (c == 0) != swap else 0.0
            b2 = 1.0 - b1
            x2 = (b2 - low * b1) * r2
            out[k, 0, c] = (_fma(-p12, x2, b1) if fused else b1 - p12 * x2) * r1
            out[k, 1, c] = x2
    return True
