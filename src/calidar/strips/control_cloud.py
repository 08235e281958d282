"""A reference point cloud as control of the strip adjustment (issue 28; OPALS matches strips to a
control point cloud): ``calidar boresight --control reference.laz --control-sigma 0.02``.

The reference cloud (a denser, more precise survey of part of the area: terrestrial or mobile
scans, a calibrated earlier flight) is cut into square cells of ``CELL_M``; a cell whose points
fill it and scatter about their least-squares plane by ≤ ``MAX_SCATTER_M`` (open ground, a road,
a roof facet; not trees, walls or edges), not steeper than ``MAX_SLOPE_DEG``, is one local plane
— a control plane as :class:`calidar.strips.control_planes.ControlPlanes` holds them: fitted to
its points ≥ 0.5 m inside (the square a strip's points are taken from, so that both sides average
the ground's curvature alike), z = a + b·dx + c·dy about their centroid with covariance
s²·(XᵀX)⁻¹ from their own scatter s, the cell's square as the patch. A strip observes it as it
observes a surveyed plane (its points inside the cell, their centroid's distance from the plane
along the normal); the row's σ² is the strip points' scatter over their number plus the reference
plane's variance at their centroid: both sides' scatter, as the VGICP rows take both clouds'
(:mod:`calidar.strips.vgicp_planes`). The cells are taken evenly over the cloud, at most
``MAX_TARGETS`` (each a control row per strip over it; thousands add rows, not information on six
sensor parameters).

What the reference cloud does not tell is its own datum: a user states its vertical accuracy
(``--control-sigma``, m), and the cloud's height offset is ONE nuisance parameter of the
adjustment with that prior (:mod:`calidar.strips.control_survey`): a cell's rows move by −n_z per
metre of it (a row's own σ, the dz/σ solution.json shows against the cloud as it is, holds that
part too; the adjustment weighs the row without it). Each cell's own plane noise, shared by the
strips over it, stays in their rows' σ (with the cells' hundreds of reference points it is a few
tenths of a millimetre).
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path
from typing import ClassVar

import numpy as np
import scipy.sparse as sp

from calidar.adjust import Parameter
from calidar.cells import grid_indices
from calidar.errors import InputError
from calidar.io.control_cloud import is_cloud_file, read_reference_cloud
from calidar.strips.control_planes import INSET_M, ControlPlanes
from calidar.strips.control_survey import PREFIX

#: the reference cloud's cells (m): a strip's points inside one less the patch inset (0.5 m a side)
CELL_M = 3.0
MIN_REFERENCE_POINTS = 30  #: reference points ≥ INSET_M inside a cell for its plane
FILL = 0.8  #: the points must span this share of the cell along x and y
#: RMS of a cell's points about their plane (m): above it the cell is not one surface
MAX_SCATTER_M = 0.02
MAX_SLOPE_DEG = 30.0
MAX_TARGETS = 300  #: cells taken at most, evenly over the cloud
DATUM = f"{PREFIX}datum"  #: the reference cloud's height offset (m, up), a nuisance parameter


@dataclass(frozen=True, eq=False)
class ControlCloud(ControlPlanes):
    """A reference cloud's planar cells as control planes, with the cloud's stated datum σ."""

    kind: ClassVar[str] = "cloud"
    label: ClassVar[str] = "reference-cloud cells"
    words: ClassVar[str] = "reference-cloud cells"
    row_noun: ClassVar[str] = "control plane"
    dz_meaning: ClassVar[str] = ("(dz: the strip's points in a planar cell of the reference cloud "
                                 "minus the cell's plane, vertically; σ: both clouds' scatter "
                                 "there; the reference cloud's datum is a parameter of its own, "
                                 "held to its stated σ)")
    how_to_give: ClassVar[str] = "a reference point cloud: --control ref.laz --control-sigma M"
    reaches_beyond_strips: ClassVar[bool] = True  #: a reference cloud may reach beyond the strips
    accepts: ClassVar = staticmethod(is_cloud_file)  #: a LAS/LAZ file
    reader: ClassVar = staticmethod(read_reference_cloud)
    takes_sigma: ClassVar[bool] = True  #: --control-sigma: the σ of its heights' datum

    datum_sigma_m: float = 0.0  #: the cloud's stated vertical accuracy (σ of its height datum), m
    source: str = ""  #: the file it came from
    n_points: int = 0  #: the reference points read

    @classmethod
    def notes(cls, f, targets) -> tuple[str, ...]:
        """The run's note on the cloud read: its points, the planar cells taken, its datum's σ."""
        return (f"reference cloud {Path(f.path).name}: {len(f.xyz):,} points, "
                f"{len(targets.ids)} planar cells as control (σ of its datum "
                f"{100 * f.sigma_m:g} cm)",)

    @classmethod
    def from_file(cls, f, local: np.ndarray) -> "ControlCloud":
        """The cells of a :class:`calidar.io.control_cloud.ReferenceCloud` whose points are at
        ``local`` (N, 3) m; an error naming the file when no cell is smooth and full."""
        return cls.from_points(local, f.sigma_m, str(f.path))

    @classmethod
    def from_points(cls, local: np.ndarray, datum_sigma_m: float, source: str = "<memory>",
                    cell_m: float = CELL_M, max_targets: int = MAX_TARGETS) -> "ControlCloud":
        p = np.asarray(local, float)
        cells = planar_cells(p, cell_m)
        if cells is None:
            raise InputError(source, "points",
                             f"no {cell_m:g} m cell of the reference cloud holds ≥ "
                             f"{MIN_REFERENCE_POINTS} points on one smooth surface (scatter ≤ "
                             f"{100 * MAX_SCATTER_M:g} cm, slope ≤ {MAX_SLOPE_DEG:g}°); expected "
                             "a dense cloud of open ground, roads or roofs")
        key, cent, coef, cov = cells
        if key.size > max_targets:  # evenly over the cloud, in the cells' order
            pick = np.unique(np.linspace(0, key.size - 1, max_targets).round().astype(int))
            key, cent, coef, cov = key[pick], cent[pick], coef[pick], cov[pick]
        ij = np.c_[key // (1 << 31), key % (1 << 31)] - (1 << 30)
        hulls = tuple(cell_m * (np.array([[0, 0], [1, 0], [1, 1], [0, 1]], float) + ij_k[::-1])
                      for ij_k in ij)
        ids = np.array([f"R{k + 1:03d}" for k in range(key.size)])
        return cls(ids, cent, coef, cov, hulls, float(datum_sigma_m), source, len(p))

    @property
    def sigma_m(self) -> np.ndarray:
        """(n,) each cell's survey σ shared by the strips over it: the cloud's datum σ (its own
        plane noise stays in its rows)."""
        return np.full(len(self.ids), self.datum_sigma_m)

    def rows(self, strip_id: int, index: np.ndarray, points: np.ndarray, n_strip_points: int):
        """:meth:`ControlPlanes.rows` with each row's own σ holding the datum's part (n_z·σ_datum)²,
        as a control point's holds its survey σ: dz/σ of the rows against the cloud as it is."""
        from dataclasses import replace

        c = super().rows(strip_id, index, points, n_strip_points)
        if c is None:
            return None
        return replace(c, sigma_m=np.sqrt(np.asarray(c.sigma_m) ** 2
                                          + (c.normal[:, 2] * self.datum_sigma_m) ** 2))

    def survey_parameters(self) -> list[Parameter]:
        """The cloud's height offset, prior 0 ± its stated σ (none at σ 0: it is the datum)."""
        if self.datum_sigma_m <= 0:
            return []
        return [Parameter(DATUM, 0.0, "m", prior_sigma=self.datum_sigma_m)]

    def survey_correlation(self) -> tuple:
        """No correlated survey parameters (the datum is one)."""
        return ()

    def survey_design(self, k: np.ndarray, normals: np.ndarray, at: np.ndarray | None = None):
        """Every row on the datum column, moved by −n_z per metre of it; its part (n_z·σ_datum)²
        taken out of the row's σ."""
        n, nz = len(k), np.asarray(normals, float)[:, 2]
        if self.datum_sigma_m <= 0:
            return sp.csr_matrix((n, 0)), np.zeros(n)
        return sp.csr_matrix(nz[:, None]), (nz * self.datum_sigma_m) ** 2


def planar_cells(p: np.ndarray, cell_m: float, inset_m: float = INSET_M):
    """The cells of ``cell_m`` of points ``p`` (N, 3) that hold one smooth surface: their keys (row,
    column packed), the centroids (K, 3) of their points ≥ ``inset_m`` inside (where a strip's
    points are taken, :meth:`ControlPlanes.rows`: both sides averaged over the same square, the
    ground's curvature cancels), plane coefficients a, b, c of z = a + b·dx + c·dy about them (K, 3)
    and those coefficients' covariance (K, 3, 3) from the points' scatter; None when there is none.
    Per cell from sums of moments (one pass over the points, any size); the points must span
    ``FILL`` of the cell both ways."""
    if len(p) == 0:
        return None
    ij = grid_indices(p, cell_m)
    # not cells.cell_keys_of: this key sorts the cells by j, then i, and the rows built from them
    # follow that order; another key would reorder them (and the sums over them)
    keys = ((ij[:, 1] + (1 << 30)) << 31) + (ij[:, 0] + (1 << 30))
    key, inv = np.unique(keys, return_inverse=True)
    lo = np.full((key.size, 2), np.inf)
    hi = np.full((key.size, 2), -np.inf)
    np.minimum.at(lo, inv, p[:, :2])
    np.maximum.at(hi, inv, p[:, :2])
    full = np.all(hi - lo >= FILL * cell_m, axis=1)
    u = p[:, :2] - ij * cell_m  # within the cell
    inner = np.all((u >= inset_m) & (u <= cell_m - inset_m), axis=1)
    p, inv = p[inner], inv[inner]
    m = np.bincount(inv, minlength=key.size)
    s = lambda v: np.bincount(inv, weights=v, minlength=key.size)  # noqa: E731 (a per-cell sum)
    c = np.stack([s(p[:, a]) for a in range(3)], axis=1) / np.maximum(m, 1)[:, None]
    d = p - c[inv]
    Sxx, Sxy, Syy = s(d[:, 0] ** 2), s(d[:, 0] * d[:, 1]), s(d[:, 1] ** 2)
    Sxz, Syz, Szz = s(d[:, 0] * d[:, 2]), s(d[:, 1] * d[:, 2]), s(d[:, 2] ** 2)
    det = Sxx * Syy - Sxy**2
    ok = (m >= MIN_REFERENCE_POINTS) & full & (det > 1e-12)
    det = np.where(ok, det, 1.0)
    b, cc = (Syy * Sxz - Sxy * Syz) / det, (Sxx * Syz - Sxy * Sxz) / det
    rss = np.maximum(Szz - b * Sxz - cc * Syz, 0.0)
    s2 = rss / np.maximum(m - 3, 1)
    slope = np.degrees(np.arctan(np.hypot(b, cc)))
    ok &= (np.sqrt(s2) <= MAX_SCATTER_M) & (slope <= MAX_SLOPE_DEG)
    if not ok.any():
        return None
    k = np.flatnonzero(ok)
    cov = np.zeros((k.size, 3, 3))
    cov[:, 0, 0] = s2[k] / m[k]
    adjugate = np.stack([np.stack([Syy[k], -Sxy[k]], 1), np.stack([-Sxy[k], Sxx[k]], 1)], 1)
    inv2 = adjugate / det[k, None, None]
    cov[:, 1:, 1:] = s2[k, None, None] * inv2
    # about the centroid: a its height (as calidar.io.control_planes.fit_plane)
    coef = np.c_[c[k, 2], b[k], cc[k]]
    return key[k], c[k], coef, cov
