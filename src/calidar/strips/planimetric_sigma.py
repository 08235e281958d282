"""The σ of a least-squares fit over blocks of cells (:mod:`calidar.strips.planimetric`): the
cluster-robust covariance with the blocks correlated out to a distance (Conley 1999), the
delete-a-group jackknife over stretches of the overlap (Künsch 1989), and the random-effects mean
of the stretches' estimates (DerSimonian & Laird 1986, Hartung & Knapp 2001). docs/validation.md
measures how honest the planimetric σ are.
"""

from __future__ import annotations

import numpy as np


def groups_along(blocks: np.ndarray, centre: np.ndarray, k: int, across: int = 1) -> np.ndarray:
    """Group (K,) 0…k·across−1 of each cell: whole blocks cut into ``k`` stretches of equal count
    along the overlap's long axis (its cells' principal direction), each cut into ``across`` parts
    of equal count across it."""
    u = centre - centre.mean(axis=0)
    axes = np.linalg.eigh(u.T @ u)[1]
    _, inv = np.unique(blocks, return_inverse=True)
    count = np.bincount(inv)
    along = np.bincount(inv, u @ axes[:, -1]) / count  # each block's place along the overlap
    side = np.bincount(inv, u @ axes[:, 0]) / count
    stretch = np.searchsorted(np.quantile(along, np.linspace(0, 1, k + 1)[1:-1]), along)
    group = stretch * across
    for g in range(k) if across > 1 else ():
        mine = stretch == g
        if mine.any():
            cuts = np.quantile(side[mine], np.linspace(0, 1, across + 1)[1:-1])
            group[mine] += np.searchsorted(cuts, side[mine])
    return group[inv]


def formal_fit(a: np.ndarray, y: np.ndarray, m: np.ndarray,
               blocks: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Least squares a·t = y with the noise moments ``m`` out: t and its formal covariance (the
    residuals' variance with a free offset per block counted in the degrees of freedom)."""
    n_mat = a.T @ a - m.sum(axis=0)
    t = np.linalg.solve(n_mat, a.T @ y)
    r = y - a @ t
    dof = max(len(y) - a.shape[1] - np.unique(blocks).size, 1)
    return t, np.linalg.inv(n_mat) * (r @ r) / dof


def random_effects_mean(est: np.ndarray, var: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The random-effects mean of ``est`` (k, m) with variances ``var`` (k, m), per column, and its
    σ: τ² by DerSimonian & Laird (1986) from Cochran's Q about the fixed-effect mean, weights
    1/(var + τ²), the variance 1/Σ weights times the Hartung–Knapp factor Σw(est − mean)²/(k − 1)
    (Hartung & Knapp 2001, Stat. Med. 20:3875–3889) when it exceeds 1 (Röver, Knapp & Friede 2015,
    BMC Med. Res. Methodol. 15:99): with a few stretches τ² from Q is often 0 by chance; and
    widened by √((k−1)/(k−3)), the RMS of Student's t with k − 1 degrees of freedom (k ≥ 4)."""
    est, var = np.asarray(est, float), np.maximum(np.asarray(var, float), 1e-12)
    k = len(est)
    w = 1.0 / var
    fixed = (w * est).sum(axis=0) / w.sum(axis=0)
    q = (w * (est - fixed) ** 2).sum(axis=0)
    tau2 = np.maximum(0.0, (q - (k - 1)) / (w.sum(axis=0) - (w**2).sum(axis=0) / w.sum(axis=0)))
    w = 1.0 / (var + tau2)
    mean = (w * est).sum(axis=0) / w.sum(axis=0)
    q_hk = np.maximum(1.0, (w * (est - mean) ** 2).sum(axis=0) / (k - 1))
    # (mean − μ)/σ then follows Student's t with k − 1 degrees of freedom, whose RMS is
    # √((k−1)/(k−3)): σ widened by it, so that error/σ has RMS 1 as every σ of calidar is read
    return mean, np.sqrt(q_hk / w.sum(axis=0) * (k - 1) / max(k - 3, 1))


def jackknife_cov(a: np.ndarray, y: np.ndarray, m: np.ndarray, blocks: np.ndarray,
                  centre: np.ndarray, k: int) -> np.ndarray | None:
    """Delete-a-group jackknife covariance of the (noise-corrected) least squares a·t = y over ``k``
    groups of whole blocks cut along the overlap's long axis (Künsch 1989, Ann. Statist.
    17:1217–1241, for dependent data): a displacement that varies along the strips by more than the
    cells' scatter says makes the groups disagree, and widens the σ where the blocks' covariance,
    with few independent stretches of overlap, cannot."""
    if k < 2:
        return None
    group = groups_along(blocks, centre, k)
    n_mat, rhs = a.T @ a - m.sum(axis=0), a.T @ y
    ts = []
    for i in range(k):
        out = group == i
        if not out.any():
            continue
        ai = a[out]
        n_left = n_mat - ai.T @ ai + m[out].sum(axis=0)
        ts.append(np.linalg.lstsq(n_left, rhs - ai.T @ y[out], rcond=None)[0])
    if len(ts) < 2:
        return None
    ts = np.array(ts)
    d = ts - ts.mean(axis=0)
    return (len(ts) - 1) / len(ts) * d.T @ d


def cluster_cov(a: np.ndarray, r: np.ndarray, blocks: np.ndarray, centre: np.ndarray, hac_m: float,
                m: np.ndarray | None = None,
                t: np.ndarray | None = None) -> tuple[np.ndarray, int]:
    """Robust covariance of least squares with design ``a`` and residuals ``r``: the rows'
    estimating functions (a·r, plus m·t with the per-row noise moments ``m`` (K, p, p) taken out of
    the normal equations at the solution ``t``) summed per block, and the blocks' sums correlated
    with product-Bartlett weights (1 − |Δx|/L)(1 − |Δy|/L) of their centres' distance, L = ``hac_m``
    (Conley 1999, J. Econometrics 92:1–45; L = 0: the cluster-robust CR1 of Liang & Zeger 1986),
    small-sample factor G/(G−1)·(N−1)/(N−p); never below the formal one. Also how many blocks
    hold cells."""
    n, p = a.shape
    used, blocks = np.unique(blocks, return_inverse=True)
    g = used.size
    psi = a * r[:, None]
    if m is not None:
        psi = psi + m @ t
    bread = np.linalg.pinv(a.T @ a - (0.0 if m is None else m.sum(axis=0)))
    score = np.zeros((g, p))
    np.add.at(score, blocks, psi)
    formal = bread * (r @ r) / max(n - p - g, 1)
    if g < 2:
        return formal, g
    sums = np.stack([np.bincount(blocks, centre[:, k]) for k in range(2)], axis=1)
    at = sums / np.bincount(blocks)[:, None]  # the blocks' mean centres
    meat = score.T @ score
    # the block pairs closer than hac_m on both axes (a k-d tree: memory grows with g, not g²)
    if hac_m > 0:
        from scipy.spatial import cKDTree

        i, j = cKDTree(at).query_pairs(hac_m, p=np.inf, output_type="ndarray").T
        w = np.prod(np.clip(1.0 - np.abs(at[i] - at[j]) / hac_m, 0.0, 1.0), axis=1)
        cross = (score[i] * w[:, None]).T @ score[j]
        meat += cross + cross.T
    cov = g / (g - 1) * (n - 1) / max(n - p, 1) * bread @ meat @ bread
    return (cov if np.trace(cov) >= np.trace(formal) else formal), g
