"""Correspondences between two strips: the one interface every matching method produces.

A correspondence set links observations to the points of strip a and strip b through
sparse averaging matrices, so the same residual serves point pairs (one point each side)
and tie planes (a patch centroid on each side):

    c_a = A · P_a(θ),   c_b = B · P_b(θ)               (n_obs, 3)
    point_to_plane:  r = Σ normal · (c_a − c_b)         (n_obs,)  m
    point_to_point:  r = (c_a − c_b).ravel()            (3·n_obs,) m

P_a(θ), P_b(θ) are the strips' points re-georeferenced with the current parameters, in a
local Cartesian frame (metres). ``normal`` is a unit vector per observation (the plane's
normal in strip b); it is held fixed during one solve.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np

if TYPE_CHECKING:  # the matrices' type only: `calidar quality` imports no scipy
    import scipy.sparse as sp


@dataclass(frozen=True)
class Correspondences:
    strip_a: int  #: point_source_id (flight line) of strip a
    strip_b: int
    A: sp.csr_matrix  #: (n_obs, n_points_a) averaging weights, rows sum to 1
    B: sp.csr_matrix  #: (n_obs, n_points_b)
    #: (n_obs, 3) unit normals for point_to_plane, None for point_to_point
    normal: np.ndarray | None
    sigma_m: np.ndarray | float = 0.05  #: a-priori σ of each residual, m
    method: str = "planes"  #: "planes" | "vgicp"
    #: degrees of freedom of each row's σ² when it is estimated from its points' scatter
    #: (residual/σ then follows Student's t; inf: σ taken as known) — the global test's
    #: consistency for the robust weights (issue 26)
    dof: np.ndarray | float = np.inf
    #: (n_obs, 2) each side's share of the row's variance (m², a then b) and (n_obs, 2) their
    #: degrees of freedom, when the matcher knows them (tie planes): a patch that several pairs'
    #: rows use is then counted once (:mod:`calidar.strips.shared_patches`, issue 26)
    side_variance: np.ndarray | None = None
    side_dof: np.ndarray | None = None
    #: VGICP's unevenness ℓ, σ_u, σ_e read from the pair's points, when estimated
    #: (:meth:`calidar.strips.unevenness_length.UnevennessFit.to_dict`)
    unevenness: dict | None = None
    #: … and the log L surface it was read from, for the survey's pooled ℓ
    #: (:class:`calidar.strips.unevenness_length.Surface`; :mod:`calidar.strips.outer_loop`)
    unevenness_surface: object | None = None

    def __post_init__(self):
        if self.A.shape[0] != self.B.shape[0]:
            raise ValueError(f"A has {self.A.shape[0]} rows, B has {self.B.shape[0]}")
        if self.normal is not None and self.normal.shape != (self.A.shape[0], 3):
            raise ValueError(f"normal must be ({self.A.shape[0]}, 3), got {self.normal.shape}")

    @property
    def n_obs(self) -> int:
        return self.A.shape[0]

    @property
    def kind(self) -> str:
        return "point_to_point" if self.normal is None else "point_to_plane"

    def residuals(self, points_a: np.ndarray, points_b: np.ndarray) -> np.ndarray:
        """Residuals (m) for the strips' current points (local metres)."""
        d = self.A @ points_a - self.B @ points_b
        if self.normal is None:
            return d.ravel()
        return np.einsum("ij,ij->i", d, self.normal)


#: prior degrees of freedom of :func:`moderated_variance` (a row's own scatter counts ν = n − 3)
SCATTER_PRIOR_DOF = 20.0


def moderated_variance(variance_m2: np.ndarray, dof: np.ndarray | float,
                       prior_dof: float = SCATTER_PRIOR_DOF) -> np.ndarray:
    """Each plane's scatter variance (m², from ``dof`` degrees of freedom) shrunk toward the
    mean of all of them: (ν·s² + ν0·s̄²) / (ν + ν0) (empirical Bayes moderated variances,
    Smyth 2004, *Stat. Appl. Genet. Mol. Biol.* 3:3).

    A 12-point plane's own s² (ν = 9) scatters by ±47 %; weighting each row by 1/s² favours
    the rows that look quiet by chance, and the data's part of the angles' error came out
    1.16× its σ (yaw, 22 airborne surveys) — with ν0 = 20, 0.86×, and that part itself 17 %
    smaller (see docs/validation.md)."""
    s2 = np.asarray(variance_m2, float)
    if s2.size == 0:
        return s2
    nu = np.broadcast_to(np.asarray(dof, float), s2.shape)
    return (nu * s2 + prior_dof * float(np.mean(s2))) / (nu + prior_dof)
