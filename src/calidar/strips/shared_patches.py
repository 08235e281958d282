"""A patch that several pairs' rows use, counted once (issue 26, seventh session).

Where s strips cover one spot (cross lines: about 4), each strip's patch there enters the rows of
the s − 1 pairs it makes with the others, and each pair's row holds that patch's noise: the rows
are correlated, and taken as independent they count each patch's noise s − 1 times. On UAV cross
lines the tie planes' pitch came out with RMS z 1.6 (docs/validation.md).

The rows of all s(s − 1)/2 pairs over one spot, r_ij = e_i − e_j + (J_i − J_j)·δ (e_i strip i's
patch noise, variance v, J_i its move by a parameter δ), give the same estimate as the least
squares on the s patches against one common plane (the generalised least squares under their
real covariance), since Σ_{i<j} (J_i − J_j)(e_i − e_j) = s · Σ_i (J_i − J̄) e_i; but the
information they claim, Σ_{i<j} (J_i − J_j)² / 2v = s · Σ_i (J_i − J̄)² / 2v, is s/2 times the
real one, Σ_i (J_i − J̄)² / v. Each row's variance times s/2 = (k + 1)/2, k = s − 1 the number of
rows using each patch, makes it exact, for any J; with one pair (k = 1, opposite lines) nothing
changes. So each side's variance share is raised by (k + 1)/2, k the number of rows that use its
points (the mean over its points, weighted as the side's variance is: Σ h² k / Σ h²), and the row
counts as 2/(k + 1) of an observation in the redundancy: the s(s − 1)/2 rows hold s − 1
independent differences, and Σ r²/σ² over them then has expectation s − 1 (the global test's σ0
stays 1 for honest rows).
"""

from __future__ import annotations

from dataclasses import replace

import numpy as np

from calidar.strips.correspond import Correspondences
from calidar.strips.row_variance import satterthwaite


def _carries(c: Correspondences) -> bool:
    """Whether ``c`` carries its rows' sides' variances (a matcher that picks rows without
    carrying them along leaves them unused)."""
    shape = (c.n_obs, 2)
    return (c.n_obs > 0 and c.side_variance is not None and c.side_dof is not None
            and np.shape(c.side_variance) == shape and np.shape(c.side_dof) == shape)


def _uses(corrs: list[Correspondences]) -> dict[int, np.ndarray]:
    """Per strip, how many rows of the sets that carry their sides' variances use each point."""
    count: dict[int, np.ndarray] = {}
    for c in corrs:
        if not _carries(c):
            continue
        for sid, m in ((c.strip_a, c.A), (c.strip_b, c.B)):
            n = count.setdefault(sid, np.zeros(0))
            add = np.bincount(m.indices[m.data != 0], minlength=m.shape[1])
            if n.size < add.size:
                n = count[sid] = np.r_[n, np.zeros(add.size - n.size)]
            n[: add.size] += add
    return count


def side_factor(m, uses: np.ndarray) -> np.ndarray:
    """(k + 1)/2 per row of the averaging matrix ``m`` (CSR), k the number of rows using each of
    its points (``uses``), weighted by the squares of the row's weights."""
    rows = np.repeat(np.arange(m.shape[0]), np.diff(m.indptr))
    w2 = m.data**2
    k = uses[m.indices]
    total = np.bincount(rows, w2, m.shape[0])
    return np.where(total > 0, 0.5 * (1.0 + np.bincount(rows, w2 * k, m.shape[0])
                                      / np.maximum(total, 1e-300)), 1.0)


def counted_once(corrs: list[Correspondences]) -> tuple[list[Correspondences], list[np.ndarray]]:
    """The correspondence sets with each row's σ (and the degrees of freedom of σ²) raised for the
    patches its sides share with other pairs' rows, and per set each row's share of an
    observation (1 where nothing is shared, or the set carries no sides' variances: VGICP,
    control). The sets' columns must be whole strips' points (the same for every pair)."""
    uses = _uses(corrs)
    out, shares = [], []
    for c in corrs:
        if not _carries(c):
            out.append(c)
            shares.append(np.ones(c.n_obs * (3 if c.normal is None else 1)))
            continue
        f = np.stack([side_factor(c.A, uses[c.strip_a]), side_factor(c.B, uses[c.strip_b])], 1)
        parts = c.side_variance * f
        sigma2 = np.broadcast_to(np.asarray(c.sigma_m, float), (c.n_obs,)) ** 2
        rest = np.clip(sigma2 - c.side_variance.sum(axis=1), 0.0, None)  # e.g. a noise floor
        sigma = np.sqrt(parts.sum(axis=1) + rest)
        dof = satterthwaite([parts[:, 0], parts[:, 1], rest],
                            [c.side_dof[:, 0], c.side_dof[:, 1], np.full(c.n_obs, np.inf)])
        scale = (parts.sum(axis=1) + rest) / np.maximum(sigma2, 1e-300)
        # counted: a second pass leaves the set as it is
        out.append(replace(c, sigma_m=sigma, dof=dof, side_variance=None, side_dof=None))
        shares.append(1.0 / np.maximum(scale, 1.0))
    return out, shares
