"""Control surfaces as observations of the strip adjustment (issue 28): surveyed planar patches,
such as roof facets, beside or instead of control points.

A plane is known from ≥ 3 surveyed points on it (:mod:`calidar.io.control_planes`): the weighted
least-squares plane z = a + b·dx + c·dy about their centroid, with its covariance C from the
points' σ. A strip observes it by its points inside the patch (the polygon the surveyed points span,
less ``INSET_M`` from its edges where eaves and walls mix in, and within ``GATE_M`` of the
points' median distance from the plane: chimneys, vents, overhanging crowns left out): the row is
their centroid p̄'s distance from the plane along its surveyed normal n, r = n · (p̄ − c) (c the
plane's centroid: the control pseudo-strip's point, as for control points,
:mod:`calidar.strips.control`), > 0 when the strip lies above. Its σ² = s²/m (s the points'
scatter about their own plane, m − 3 degrees of freedom) + the plane's survey variance at p̄,
n_z²·gᵀCg with g = (1, dx, dy) of p̄ from the centroid; its part at the centroid
(:attr:`ControlPlanes.sigma_m`) and its slopes', shared by every strip that sees the plane, are the
plane's own nuisance parameters in the adjustment: its height and two slopes with their survey
covariance (:mod:`calidar.strips.control_survey`).

A plane tells the height only along its normal, and a sloped roof's normal also leans
horizontally: roof facets facing several ways observe a horizontal shift as well.

:class:`ControlPlanes` answers what :class:`calidar.strips.control.ControlPoints` answers
(``ids``, ``local``, ``sigma_m``, :meth:`keep_xy`, :meth:`rows`): the calibrator takes either
(:data:`calidar.strips.config.CONTROL_KINDS` names them).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import ClassVar

import numpy as np
import scipy.sparse as sp

from calidar.adjust import Parameter
from calidar.io.control_planes import is_plane_file, read_control_planes
from calidar.strips.control import rows_to_correspondences
from calidar.strips.control_survey import PREFIX as SURVEY
from calidar.strips.correspond import Correspondences

INSET_M = 0.5  #: a strip's points this far inside the patch's edges (eaves, walls, gutters)
GATE_M = 0.2  #: and this close to the points' median distance from the plane (m)
MIN_POINTS = 10  #: a strip's points on a plane for a row
KEEP_SPACING_M = 2.0  #: places over each patch whose surroundings the ingest keeps


@dataclass(frozen=True, eq=False)
class ControlPlanes:
    """Control planes in the strips' local frame (m)."""

    kind: ClassVar[str] = "surfaces"
    label: ClassVar[str] = "control planes"
    words: ClassVar[str] = "control planes"
    row_noun: ClassVar[str] = "control plane"
    dz_meaning: ClassVar[str] = ("(dz: the strip's points on the patch minus the surveyed plane, "
                                 "vertically; σ: the plane's survey σ there and the points' "
                                 "scatter)")
    how_to_give: ClassVar[str] = "surveyed planes: plane, x, y, z, sigma"
    reaches_beyond_strips: ClassVar[bool] = False
    accepts: ClassVar = staticmethod(is_plane_file)  #: a CSV whose header names a plane column
    reader: ClassVar = staticmethod(read_control_planes)
    takes_sigma: ClassVar[bool] = False

    ids: np.ndarray  #: (n,) str
    local: np.ndarray  #: (n, 3) each plane's centroid (the control pseudo-strip's points)
    coef: np.ndarray  #: (n, 3) a, b, c of z = a + b·dx + c·dy about the centroid (a = its height)
    cov: np.ndarray  #: (n, 3, 3) their covariance, m²
    hulls: tuple[np.ndarray, ...]  #: per plane, the patch's corners (k, 2), counter-clockwise

    @classmethod
    def notes(cls, f, targets) -> tuple[str, ...]:
        """What the run's notes say of the file read (none)."""
        return ()

    @classmethod
    def from_file(cls, f, local: np.ndarray) -> ControlPlanes:
        """The planes of a :class:`calidar.io.control_planes.ControlPlaneFile` whose points are at
        ``local`` (N, 3) m in the strips' frame; each checked there (an error naming plane and
        line)."""
        from scipy.spatial import ConvexHull

        from calidar.io.control_planes import check_plane, fit_plane

        ids, cents, coefs, covs, hulls = [], [], [], [], []
        for name in f.planes():
            k = np.flatnonzero(f.plane == name)
            check_plane(f, k, local[k])
            c, coef, cov = fit_plane(local[k], f.sigma_m[k])
            xy = local[k, :2]
            hull = xy[ConvexHull(xy).vertices] if k.size > 3 else xy[_ccw(xy)]
            for found, value in zip((ids, cents, coefs, covs, hulls), (name, c, coef, cov, hull)):
                found.append(value)
        return cls(np.asarray(ids, str), np.asarray(cents), np.asarray(coefs), np.asarray(covs),
                   tuple(hulls))

    @property
    def normal(self) -> np.ndarray:
        """(n, 3) unit normals, up."""
        n = np.c_[-self.coef[:, 1], -self.coef[:, 2], np.ones(len(self.ids))]
        return n / np.linalg.norm(n, axis=1, keepdims=True)

    @property
    def sigma_m(self) -> np.ndarray:
        """(n,) each plane's survey σ along its normal at its centroid (m)."""
        return self.normal[:, 2] * np.sqrt(self.cov[:, 0, 0])

    def keep_xy(self) -> np.ndarray:
        """(K, 2) places over every patch, ≤ ``KEEP_SPACING_M`` apart, whose points are kept."""
        out = []
        for hull in self.hulls:
            lo, hi = hull.min(axis=0), hull.max(axis=0)
            gx, gy = np.meshgrid(np.arange(lo[0], hi[0] + KEEP_SPACING_M, KEEP_SPACING_M),
                                 np.arange(lo[1], hi[1] + KEEP_SPACING_M, KEEP_SPACING_M))
            grid = np.c_[gx.ravel(), gy.ravel()]
            out += [hull, grid[inside(grid, hull, 0.0)]]
        return np.vstack(out)

    def rows(self, strip_id: int, index: np.ndarray, points: np.ndarray,
             n_strip_points: int) -> Correspondences | None:
        """Rows between strip ``strip_id`` (its points ``index`` at local ``points`` (M, 3), of
        ``n_strip_points`` in all) and the planes it covers; None when it covers none."""
        points = np.asarray(points, float)
        index = np.asarray(index)
        rows, cols, weights, normals, sigmas, targets = [], [], [], [], [], []
        for k in range(len(self.ids)):
            sel = self._on_plane(points, k)
            if sel.size < MIN_POINTS:
                continue
            # height → along n
            noise = self.normal[k, 2] ** 2 * _scatter_variance(points[sel]) / sel.size
            g = np.r_[1.0, points[sel, :2].mean(axis=0) - self.local[k, :2]]
            survey = self.normal[k, 2] ** 2 * float(g @ self.cov[k] @ g)
            r = len(normals)
            rows += [r] * sel.size
            cols += list(index[sel])
            weights += [1.0 / sel.size] * sel.size
            normals.append(self.normal[k])
            sigmas.append(np.sqrt(noise + survey))
            targets.append(k)
        return rows_to_correspondences(strip_id, (rows, cols, weights), normals, sigmas, targets,
                                       (n_strip_points, len(self.ids)), "control planes")

    def _survey_names(self, k: int) -> tuple[str, str, str]:
        return f"{SURVEY}{k}", f"{SURVEY}{k}_slope_x", f"{SURVEY}{k}_slope_y"

    def survey_parameters(self) -> list:
        """Each plane's survey error as nuisance parameters (:mod:`calidar.strips.control_survey`):
        its height at the centroid and its two slopes, priors 0 ± √diag(C) (correlated:
        :meth:`survey_correlation`)."""
        out = []
        for k in range(len(self.ids)):
            s = np.sqrt(np.diag(self.cov[k]))
            out += [Parameter(n, 0.0, u, prior_sigma=float(v))
                    for n, u, v in zip(self._survey_names(k), ("m", "1", "1"), s)]
        return out

    def survey_correlation(self) -> list:
        """Per plane (its three survey parameters, their correlation from C)."""
        out = []
        for k in range(len(self.ids)):
            s = np.sqrt(np.diag(self.cov[k]))
            out.append((self._survey_names(k), self.cov[k] / np.outer(s, s)))
        return out

    def survey_design(self, k: np.ndarray, normals: np.ndarray, at: np.ndarray):
        """Rows of planes ``k`` at places ``at`` (n, 3): the plane's height and slopes' errors move
        a row by −n_z·(1, dx, dy) (dx, dy from its centroid); the row's own σ holds all of their
        variance, n_z²·gᵀCg, taken out."""
        nz = np.asarray(normals, float)[:, 2]
        g = np.c_[np.ones(len(k)), np.asarray(at, float)[:, :2] - self.local[k, :2]]
        rows = np.repeat(np.arange(len(k)), 3)
        M = sp.csr_matrix(((nz[:, None] * g).ravel(),
                           (rows, (3 * k[:, None] + np.arange(3)).ravel())),
                          shape=(len(k), 3 * len(self.ids)))
        return M, nz**2 * np.einsum("ni,nij,nj->n", g, self.cov[k], g)

    def _on_plane(self, points: np.ndarray, k: int) -> np.ndarray:
        """Indices of ``points`` inside patch ``k`` (``INSET_M`` from its edges) near its plane."""
        hull = self.hulls[k]
        lo, hi = hull.min(axis=0), hull.max(axis=0)
        box = np.flatnonzero(np.all((points[:, :2] >= lo) & (points[:, :2] <= hi), axis=1))
        box = box[inside(points[box, :2], hull, INSET_M)]
        if box.size < MIN_POINTS:
            return box
        d = (points[box] - self.local[k]) @ self.normal[k]
        return box[np.abs(d - np.median(d)) < GATE_M]


def inside(xy: np.ndarray, hull: np.ndarray, inset_m: float) -> np.ndarray:
    """Whether each of ``xy`` (M, 2) lies inside the convex polygon ``hull`` (k, 2,
    counter-clockwise), at least ``inset_m`` from each of its edges."""
    e = np.roll(hull, -1, axis=0) - hull
    inward = np.c_[-e[:, 1], e[:, 0]] / np.maximum(np.linalg.norm(e, axis=1), 1e-12)[:, None]
    dist = np.einsum("mkj,kj->mk", xy[:, None, :] - hull[None], inward)
    return np.all(dist >= inset_m, axis=1)


def _ccw(xy: np.ndarray) -> np.ndarray:
    """The order of three points that runs counter-clockwise."""
    a, b, c = xy
    cross = (b[0] - a[0]) * (c[1] - a[1]) - (b[1] - a[1]) * (c[0] - a[0])
    return np.array([0, 1, 2] if cross > 0 else [0, 2, 1])


def _scatter_variance(p: np.ndarray) -> float:
    """The variance of points ``p`` (m, 3) about their own least-squares plane z = a + b·x + c·y
    (m − 3 degrees of freedom), m²."""
    d = p - p.mean(axis=0)
    X = np.c_[np.ones(len(d)), d[:, 0], d[:, 1]]
    coef, *_ = np.linalg.lstsq(X, d[:, 2], rcond=None)
    return float(np.sum((X @ coef - d[:, 2]) ** 2) / max(len(d) - 3, 1))
