"""The a-posteriori standard deviation of unit weight σ0 that a robust adjustment's global test and its variance
factor take: consistent over heavy-tailed residuals, robust to gross ones (issue 26).

The engine's own σ0² of a robust fit, Σ w r²/σ² over the effective redundancy with IRLS weights w on z / MAD-scale,
reads what the rows' σ are only for the distribution its consistency factor assumes (normal: Cauchy 0.794; a t
mixture for rows whose σ come from a few points). Rows whose σ are right in the mean (E[z²] = 1) but wrong row by row
— VGICP's roughest quarter, RMS z 1.22 at the truth — give z a tail heavier than any such model, which the weights
cut: at the truth (``benchmarks/strips_row_sigma.py``) VGICP's σ0 read 0.92–0.95 where its rows' RMS z was 0.99–1.02,
and an M-estimator of scale for the Cauchy loss, made consistent for the rows' own t mixture (Maronna, Martin &
Yohai 2006 §2.5), read 0.93–0.96 and moved by +12 % when 1 % of the rows were 10σ errors.

Here σ0 is the root mean square of the standardised residuals z = r/σ over the redundancy (the priors' squared
standardised deviations and their count included: the unbiased estimate of the variance of unit weight, eᵀPe over
n − u, Koch 1999, *Parameter Estimation and Hypothesis Testing in Linear Models*), with the rows beyond
:data:`GROSS_Z` σ0 skipped as gross (iterated from the MAD scale: a skipped, or hard-rejection, estimator, Hampel,
Ronchetti, Rousseeuw & Stahel 1986, with its rejection point far out in the tail). No consistency factor is needed:
under the models the rows assume (normal, or Student t with ν ≥ 8 scaled to unit variance; the strips' rows have a
median ν of 26–77) fewer than 5·10⁻⁵ of the rows and 0.3 % of E[z²] lie beyond :data:`GROSS_Z` (σ0 0.14 % low; ν = 5:
2.3 %, 1.2 % low), while a 10σ error is rejected whatever its noise.
"""

from __future__ import annotations

import numpy as np

#: a standardised residual beyond this many σ0 is gross (skipped): far beyond the tail of any model the rows' σ assume
#: (t with ν ≥ 8 at unit variance: P(|z| > 7) < 5·10⁻⁵), near enough that a 10σ error is rejected with its noise
GROSS_Z = 7.0
#: fixed-point iterations of the rejection at most (it settles in 2–4)
ITERATIONS = 30


def skipped_sigma0(z: np.ndarray, prior_sq: float = 0.0, n_prior: int = 0, n_free: int = 0,
                   gross_z: float | None = GROSS_Z) -> tuple[float, int]:
    """(σ0, rows skipped) of standardised residuals ``z`` (r/σ): √((Σ z² over |z| ≤ gross_z·σ0 + prior_sq) /
    (rows kept + n_prior − n_free)), iterated from the MAD scale; ``prior_sq``: the priors' Σ (x − centre)ᵀ P
    (x − centre) over ``n_prior`` priors; ``gross_z`` None: no row skipped (the least-squares σ0)."""
    z = np.asarray(z, float).ravel()
    a = np.abs(z)
    keep = np.ones(a.size, bool)
    s = 1.4826 * float(np.median(a)) if a.size else 0.0
    for _ in range(ITERATIONS if gross_z is not None and s > 0 else 1):
        keep = a <= gross_z * s if gross_z is not None and s > 0 else keep
        n = int(np.sum(keep))
        new = float(np.sqrt((np.sum(a[keep] ** 2) + prior_sq) / max(n + n_prior - n_free, 1)))
        if new == s:
            break
        s = new
    return s, int(a.size - np.sum(keep))
