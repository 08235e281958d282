"""σ0, the a-posteriori standard deviation of unit weight, of a robust adjustment: consistent over
heavy-tailed standardised residuals and robust to gross ones (issue 26).

σ0 here is the root mean square of the standardised residuals z = r/σ over the redundancy, the
priors' squared standardised deviations and their count included (eᵀPe / (n − u): Koch 1999,
*Parameter Estimation and Hypothesis Testing in Linear Models*), with rows beyond :data:`GROSS_Z` σ0
skipped as gross, iterated from the MAD scale (a skipped, hard-rejection estimator: Hampel,
Ronchetti, Rousseeuw & Stahel 1986). It needs no consistency factor: under normal rows, or Student t
rows with ν ≥ 8 at unit variance, fewer than 5·10⁻⁵ of the rows and 0.3 % of E[z²] lie beyond
:data:`GROSS_Z`, while a 10σ error is rejected whatever its noise. What it reads against the
engine's Cauchy-weighted σ0 and an M-scale, at the truth and on the Monte-Carlo: docs/validation.md,
"VGICP's σ0 over its heavy tail … (issue 26, 27 Nov, fifth session)".
"""

from __future__ import annotations

import numpy as np

#: a standardised residual beyond this many σ0 is gross (skipped): far beyond the tail of any model
#: the rows' σ assume (t with ν ≥ 8 at unit variance: P(|z| > 7) < 5·10⁻⁵), near enough that a 10σ
#: error is rejected with its noise
GROSS_Z = 7.0
#: fixed-point iterations of the rejection at most (it settles in 2–4)
ITERATIONS = 30


def skipped_sigma0(z: np.ndarray, prior_sq: float = 0.0, n_prior: int = 0, n_free: int = 0,
                   gross_z: float | None = GROSS_Z,
                   share: np.ndarray | None = None) -> tuple[float, int]:
    """(σ0, rows skipped) of standardised residuals ``z`` (r/σ), iterated from the MAD scale:

        σ0 = √((Σ z² over |z| ≤ gross_z·σ0 + prior_sq) / (rows kept + n_prior − n_free))

    ``prior_sq``: the priors' Σ (x − centre)ᵀ P (x − centre) over ``n_prior`` priors; ``gross_z``
    None: no row skipped (the least-squares σ0); ``share``: each row's share of an observation in
    the rows kept (1 each without)."""
    z = np.asarray(z, float).ravel()
    a = np.abs(z)
    keep = np.ones(a.size, bool)
    s = 1.4826 * float(np.median(a)) if a.size else 0.0
    for _ in range(ITERATIONS if gross_z is not None and s > 0 else 1):
        keep = a <= gross_z * s if gross_z is not None and s > 0 else keep
        n = float(np.sum(keep) if share is None else np.sum(np.ravel(share)[keep]))
        new = float(np.sqrt((np.sum(a[keep] ** 2) + prior_sq) / max(n + n_prior - n_free, 1)))
        if new == s:
            break
        s = new
    return s, int(a.size - np.sum(keep))
