"""The scanner's own calibration as parameters of a segment's fit: the scan-angle encoder's offset
and scale, and the scan plane's yaw and pitch in the body (issue #30).

Points alone cannot tell these from the trajectory: an encoder offset is a roll, its scale a
height (the fan's opening; "roll and mirror scale are directly related and can be perceived as the
same thing", bloglidar 2010, "Mission calibration"), the scan plane's yaw a heading and its pitch a
pitch.
Calibrations find them per installation (the boresight flights of NERC-ARF's Leica ALS50-II
procedure; leeward's scanner: offset −0.09°, scale +0.25 %, scan plane yawed 13.96° and pitched
0.07° against its SBET). Each is a parameter with a prior (0 ± σ). Where the points determine it
(posterior σ below half the prior's, judged in the coarse iterations) it is estimated with the
trajectory (the bordered normal equations, solved by the Schur complement):

    [N   B      ] [dx]   [r_c]      cov(x) = N⁻¹ + X·S⁻¹·Xᵀ,  X = N⁻¹·B,  S = C + P − Bᵀ·X
    [Bᵀ  C + P  ] [dg] = [r_g]

N the banded normal matrix of the spline coefficients, B its border with the (few) parameters, P
their prior precision. Where they do not, the parameter is held at its prior mean and its prior σ
passed into the trajectory's covariance through the estimate's sensitivity to it (Schmidt's
"consider" covariance, as navigation filters carry unestimated biases): the estimate is that of
the fit without it, only its σ is wider. Estimating an undetermined one instead would let the weak
plausibility priors on roll and pitch split it from the attitude.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from calidar.trajrec.kernels import accumulate_border

#: the parameters, in order: scan-angle offset (rad), scan-angle scale (1), scan-plane yaw, pitch
#: (rad), the encoder's curvature (its error's quadratic term, as the angle it reaches at 30°, rad)
#: and the scan's cone (the beams' constant angle out of the scan plane, rad: a scanner whose beams
#: sweep a flat cone, not a plane)
NAMES = ("scan_offset", "scan_scale", "scan_plane_yaw", "scan_plane_pitch", "scan_curvature",
         "scan_cone")
LABELS = {"scan_offset": "scan-angle offset", "scan_scale": "scan-angle scale",
          "scan_plane_yaw": "scan-plane yaw", "scan_plane_pitch": "scan-plane pitch",
          "scan_curvature": "scan-angle curvature (at 30°)", "scan_cone": "scan cone"}
#: which parameters the scan-angle field carries (the others: the planar scan lines)
OF_SCAN_ANGLES = (True, True, False, False, True, False)
CURVATURE_AT = float(np.radians(30.0))  #: the angle at which the curvature term is stated
#: ``calidar trajectory``'s default prior σ: offset 0.1°, scale 0.3 %, yaw and pitch 0.1°,
#: curvature 0.2° at 30°, cone 0.02°: the order of what a real scanner shows against its SBET and
#: of the boresight errors a calibration flight removes (docs/validation.md, "Lines of at most 100
#: characters … fifth session", has the figures). Datasheets state the encoder's resolution, not its
#: calibration against the trajectory; a user who knows them gives 0
DEFAULT_SIGMA = (float(np.radians(0.1)), 0.003, float(np.radians(0.1)), float(np.radians(0.1)),
                 float(np.radians(0.2)), float(np.radians(0.02)))


def notes(mount: dict) -> list[str]:
    """In words: the parameters estimated (value ± σ) where the points determine them (posterior σ
    below half the prior's), and those held, whose prior σ is in the σ columns. ``mount``: name →
    (value, posterior σ, prior σ), SI."""
    est, held = [], []
    for name, (v, s, prior) in mount.items():
        scale, unit = (100.0, " %") if name == "scan_scale" else (float(np.degrees(1.0)), "°")
        label = LABELS[name]
        if s < 0.5 * prior:
            est.append(f"{label} {v * scale:+.2g} ± {s * scale:.2g}{unit}")
        else:
            held.append(f"{label} {prior * scale:.2g}{unit}")
    out = [f"estimated from the points: {', '.join(est)}"] if est else []
    if held:
        out.append("not determined by the points, their prior σ in the σ columns: "
                   + ", ".join(held))
    return out


def active(sigmas) -> np.ndarray:
    """Indices of the parameters with a prior σ > 0 (the others are held at their given values)."""
    return np.flatnonzero(np.asarray(sigmas, float) > 0)


def design(name: str, n: int, scan=None, along_partials=None, idx=(), scale: float = 0.0,
           angle=None) -> np.ndarray:
    """Partials (n, m) of one residual type by the active parameters ``idx``: the across-track
    residual ((angle − offset − curvature·(angle/30°)²)/(1 + scale) − stored angle; ``scan``: the
    model's reading, the first term; ``angle``: the geometry's angle) by offset, scale and
    curvature, the along-track one (angle − cone) by the scan plane's yaw and pitch
    (``along_partials`` (n, 2)) and the cone; rays by none.

    The stored angle is the observation, not a regressor: written as angle − (1 + scale)·stored −
    offset, the scale's partial −stored would carry the angle's noise e, and Σ stored·r its E[e²]
    per point, a bias of about −σ_scale²·Σ 1/σ_e²·σ_e² = −n·σ_scale² (errors in variables; the
    scale is nearly collinear with the height, so σ_scale is large)."""
    full = np.zeros((n, len(NAMES)))
    if name == "across":
        f = 1.0 / (1.0 + scale)
        full[:, 0], full[:, 1] = -f, -scan * f
        if angle is not None:
            full[:, 4] = -f * (angle / CURVATURE_AT) ** 2
    elif name == "along":
        if along_partials is not None:
            full[:, 2:4] = along_partials
        full[:, 5] = -1.0
    return full[:, idx]


def border(basis, g: np.ndarray, gm: np.ndarray, weight: np.ndarray, k: int,
           r: np.ndarray | None = None) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """B (6K, m) = Σ w·a·gmᵀ, C (m, m) = Σ w·gm·gmᵀ and −Σ w·gm·r, a the row's partials by the
    spline coefficients (channel-major: channel c, coefficient j → c·K + j)."""
    first, bw = basis
    m = gm.shape[1]
    b, c, r_g = np.zeros((6 * k, m)), np.zeros((m, m)), np.zeros(m)
    if m and weight.size:
        residuals = np.zeros(weight.size) if r is None else r
        accumulate_border(b, c, r_g, first, bw, np.ascontiguousarray(g),
                          np.ascontiguousarray(gm), residuals, weight, k)
    return b, c, r_g


@dataclass
class MountStep:
    """A Gauss–Newton step with the mounting: the coefficients' step (channel-major), the estimated
    parameters' step, and L with L·Lᵀ what the mounting adds to the coefficients' covariance."""

    dx: np.ndarray
    dg: np.ndarray
    low_rank: np.ndarray
    sigma: np.ndarray  #: posterior σ of each parameter (the prior's where it is held)
    est: np.ndarray  #: which were estimated (mask)


def determined(b: np.ndarray, c: np.ndarray, x_b: np.ndarray, sigma: np.ndarray,
               data_scale: float = 1.0) -> np.ndarray:
    """Which parameters the points determine: posterior σ (all estimated together, the data's
    information scaled by ``data_scale``) below half the prior's."""
    s = np.diag(1.0 / sigma**2) + data_scale * (c - b.T @ x_b)
    post = np.sqrt(np.maximum(np.diag(np.linalg.inv(s)), 0.0))
    return post < 0.5 * sigma


def mount_step(x_rhs: np.ndarray, x_b: np.ndarray, b: np.ndarray, c: np.ndarray, r_g: np.ndarray,
               sigma: np.ndarray, value: np.ndarray, est: np.ndarray) -> MountStep:
    """The bordered solve above for the parameters ``est`` (mask) estimated, the others held at
    ``value`` and considered (Schmidt's consider covariance: their prior σ passed through the
    sensitivity of the estimate to them). ``x_rhs`` = N⁻¹·r_c and ``x_b`` = N⁻¹·B from the banded
    solve."""
    prec = 1.0 / sigma**2
    s_all = np.diag(prec) + c - b.T @ x_b
    r_gp = r_g - prec * value
    e, h = np.flatnonzero(est), np.flatnonzero(~est)
    dx, dg, post = x_rhs, np.zeros(e.size), sigma.copy()
    factors = []
    s_e_inv = np.zeros((0, 0))
    if e.size:
        s_e_inv = np.linalg.inv(s_all[np.ix_(e, e)])
        s_e_inv = 0.5 * (s_e_inv + s_e_inv.T)
        dg = s_e_inv @ (r_gp[e] - b[:, e].T @ x_rhs)
        dx = x_rhs - x_b[:, e] @ dg
        factors.append(x_b[:, e] @ np.linalg.cholesky(s_e_inv))
        post[e] = np.sqrt(np.diag(s_e_inv))
    if h.size:
        z = x_b[:, h] - (x_b[:, e] @ s_e_inv @ s_all[np.ix_(e, h)] if e.size else 0.0)
        factors.append(z * sigma[h])
        # the held ones move the estimated ones too: −S_e⁻¹·S_eh per unit, their prior σ passed on
        if e.size:
            moved = s_e_inv @ s_all[np.ix_(e, h)] * sigma[h]
            post[e] = np.sqrt(post[e] ** 2 + np.sum(moved**2, axis=1))
    low_rank = np.hstack(factors) if factors else np.zeros((x_rhs.size, 0))
    return MountStep(dx, dg, low_rank, post, est)
