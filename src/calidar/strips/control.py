"""Ground control as observations of the strip adjustment (issue 28): the building block.

A control point (surveyed x, y, z with σ) observes a strip's local surface: the residual is the
distance of the control point from the plane of the strip's points around it, along that plane's
normal, r = n · (c − p) (c the points' centroid, p the control point; > 0 when the strip's
surface lies above it, as ``calidar accuracy``'s dz), with σ² = σ_control² + s²/n (s the points'
scatter about the plane). The rows are :class:`~calidar.strips.correspond.Correspondences`
between the strip and a *control pseudo-strip* (id :data:`CONTROL_ID`) whose :class:`Pose`
(:func:`control_pose`) puts each "point" at its control point with a zero rotation: the lidar
equation then returns the control point itself whatever the sensor, with no derivative and no
trajectory correction (the pseudo-strip has no time span), so :class:`~calidar.strips.problem.StripProblem`
and its analytic Jacobian take control rows unchanged, beside the tie planes. Range offset,
vertical lever arm and vertical trajectory biases, which the overlaps cannot see, are then
observed (tests/unit/strips/test_control.py).

Not yet wired into ``calidar boresight`` (see the issue): the ingest must keep the points near
control points, the outer loop must add :func:`control_correspondences` to each matching, and
the clusters/geometry warnings must skip the pseudo-strip.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import scipy.sparse as sp
from scipy.spatial import cKDTree

from calidar.strips.correspond import Correspondences
from calidar.strips.strip import Pose

CONTROL_ID = -1  #: the id of the control pseudo-strip
RADIUS_M = 2.0  #: a strip's points within this (x, y) of a control point form its plane
MIN_POINTS = 8


@dataclass(frozen=True)
class ControlPoints:
    """Control points in the strips' local frame (m)."""

    ids: np.ndarray  #: (n,) str
    local: np.ndarray  #: (n, 3) m
    sigma_m: np.ndarray  #: (n,) survey σ of each, m


def control_pose(control: ControlPoints, template: Pose) -> Pose:
    """The control pseudo-strip's poses: position = the control point, rotation zero, so that
    p = r + R·(…) = r for every sensor (``template``: a real strip's poses, for the angles' shape)."""
    n = len(control.ids)
    angles = np.zeros((n, *template.angles.shape[1:]))
    return Pose(np.arange(n), np.asarray(control.local, float), np.zeros((n, 3, 3)), np.zeros(n), angles)


def control_correspondences(strip_id: int, index: np.ndarray, points: np.ndarray, n_strip_points: int,
                            control: ControlPoints, radius_m: float = RADIUS_M,
                            min_points: int = MIN_POINTS) -> Correspondences | None:
    """Rows between strip ``strip_id`` (its points ``index`` at local ``points`` (M, 3), of
    ``n_strip_points`` in all) and the control points it covers; None when it covers none."""
    tree = cKDTree(np.asarray(points)[:, :2])
    rows, cols, weights, normals, sigmas, targets = [], [], [], [], [], []
    for k, near in enumerate(tree.query_ball_point(control.local[:, :2], radius_m)):
        if len(near) < min_points:
            continue
        p = points[near]
        c = p.mean(axis=0)
        lam, vec = np.linalg.eigh(np.cov((p - c).T))
        normal = vec[:, 0] if vec[2, 0] >= 0 else -vec[:, 0]
        scatter2 = lam[0] * (len(near) - 1) / max(len(near) - 3, 1)
        r = len(normals)
        rows += [r] * len(near)
        cols += list(np.asarray(index)[near])
        weights += [1.0 / len(near)] * len(near)
        normals.append(normal)
        sigmas.append(np.sqrt(control.sigma_m[k] ** 2 + scatter2 / len(near)))
        targets.append(k)
    if not normals:
        return None
    n = len(normals)
    A = sp.csr_matrix((weights, (rows, cols)), shape=(n, n_strip_points))
    B = sp.csr_matrix((np.ones(n), (np.arange(n), targets)), shape=(n, len(control.ids)))
    return Correspondences(strip_id, CONTROL_ID, A, B, np.array(normals), np.array(sigmas), "control")
