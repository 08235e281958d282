"""The ground's height at a control point from one strip's points around it (issue 28): a
quadratic surface, not a plane.

A plane fitted to the points within 2 m of a control point and read at the point is off by the
terrain's curvature there: for z = ½κ·x² over a disc of radius R the plane sits κR²/8 above the
ground at its centre. On the simulator's smooth ground (checkpoints where the terrain departs from
a plane by ≤ 1.5 cm RMS) that error was 9 mm RMS at 2 m, shared by every strip that sees the point
(correlation 0.97 between strips), five times the plane's noise σ and absent from it: the vertical
trajectory bias's σ came out 1.3× too small (docs/validation.md, ground control). A least-squares
quadric z = a + b·dx + c·dy + d·dx² + e·dx·dy + f·dy² about the control point (dx, dy from it)
follows the curvature; its height there, a, is a linear combination Σ wᵢ·zᵢ of the points'
heights (w the first row of (XᵀX)⁻¹Xᵀ: Σw = 1, Σw·dx = Σw·dy = 0), so the row keeps the
correspondences' form (weights w in place of 1/n) and its noise σ² = s²·Σw² (s² the scatter about
the quadric, n − 6 degrees of freedom). For points spread evenly over a disc Σw² ≈ 4/n (the
price of the curvature terms: the plane's is 1/n)."""

from __future__ import annotations

import numpy as np

MIN_POINTS = 15  #: the quadric's 6 coefficients with 9 degrees of freedom for its scatter
#: n·Σw² above this: the points do not surround the control point (it lies near a strip's edge or
#: in a gap) and the quadric would be extrapolated; the row is left out
MAX_SPREAD = 16.0


def local_surface(points: np.ndarray,
                  at: np.ndarray) -> tuple[np.ndarray, np.ndarray, float] | None:
    """For a strip's ``points`` (m, 3) around the control point ``at`` (3,), local m: the weights
    w (m,) whose Σ wᵢ·pᵢ is the quadric's point above/below ``at``, the surface's unit normal there
    (up), and the noise variance of that height (m²); None when the points cannot tell it."""
    p = np.asarray(points, float)
    m = len(p)
    if m < MIN_POINTS:
        return None
    d = p[:, :2] - np.asarray(at, float)[:2]
    scale = max(float(np.sqrt(np.mean(np.sum(d * d, axis=1)))), 1e-3)
    u = d / scale  # unit-free coordinates for a well-conditioned normal matrix
    X = np.c_[np.ones(m), u[:, 0], u[:, 1], u[:, 0] ** 2, u[:, 0] * u[:, 1], u[:, 1] ** 2]
    try:
        N_inv = np.linalg.inv(X.T @ X)
    except np.linalg.LinAlgError:
        return None
    if not np.all(np.isfinite(N_inv)):
        return None
    H = N_inv @ X.T  # (6, m): coefficients = H · z
    w = H[0]
    if m * float(w @ w) > MAX_SPREAD:
        return None
    coef = H @ p[:, 2]
    rss = float(np.sum((X @ coef - p[:, 2]) ** 2))
    gx, gy = coef[1] / scale, coef[2] / scale
    normal = np.array([-gx, -gy, 1.0]) / np.sqrt(1.0 + gx * gx + gy * gy)
    return w, normal, rss / (m - 6) * float(w @ w)
