"""Distances P→X from two polar total-station observations, and their derivatives.

A polar observation from the total station O is (slope distance S in m, vertical angle β
in rad, up positive, horizontal direction Hz in rad). In the station's local frame
(x east-ish, y north-ish, z up; the zero of Hz is arbitrary):
X = S·(cos β sin Hz, cos β cos Hz, sin β).

The distance between P and X follows from the 3-D law of cosines with α = Hz_X − Hz_P:
S_PX² = S_OP² + S_OX² − 2·S_OP·S_OX·(cos β_P cos β_X cos α + sin β_P sin β_X).
For A and B, level with P (S_OP sin β_P = S_OX sin β_X), it reduces to the plane law of
cosines of the horizontal distances D = S cos β, since the general formula equals
D_P² + D_X² − 2·D_P·D_X·cos α + (S_OP sin β_P − S_OX sin β_X)².
"""

from __future__ import annotations

import numpy as np


def polar_to_local(slope, va, hz) -> np.ndarray:
    """Local coordinates (…, 3) in m of polar observations (m, rad, rad)."""
    slope, va, hz = np.broadcast_arrays(*(np.asarray(a, float) for a in (slope, va, hz)))
    c = np.cos(va)
    return np.stack([slope * c * np.sin(hz), slope * c * np.cos(hz), slope * np.sin(va)], axis=-1)


def distance_law_of_cosines(s_p, va_p, hz_p, s_x, va_x, hz_x) -> np.ndarray:
    """3-D distance P→X (m) from the polar observations of P and X (m, rad)."""
    alpha = np.asarray(hz_x) - hz_p
    cos_g = np.cos(va_p) * np.cos(va_x) * np.cos(alpha) + np.sin(va_p) * np.sin(va_x)
    d2 = np.asarray(s_p) ** 2 + np.asarray(s_x) ** 2 - 2.0 * np.asarray(s_p) * s_x * cos_g
    return np.sqrt(np.clip(d2, 0.0, None))


def distance_level(s_p, va_p, hz_p, s_x, va_x, hz_x) -> np.ndarray:
    """Special case for A/B (level with P): plane law of cosines of horizontal distances (m)."""
    d_p, d_x = np.asarray(s_p) * np.cos(va_p), np.asarray(s_x) * np.cos(va_x)
    d2 = d_p**2 + d_x**2 - 2.0 * d_p * d_x * np.cos(np.asarray(hz_x) - hz_p)
    return np.sqrt(np.clip(d2, 0.0, None))


def distance_partials(s_p, va_p, hz_p, s_x, va_x, hz_x) -> tuple[np.ndarray, np.ndarray]:
    """Distance P→X (m) and its partial derivatives (…, 6) with respect to
    (S_P [m/m], β_P [m/rad], Hz_P [m/rad], S_X, β_X, Hz_X)."""
    p = polar_to_local(s_p, va_p, hz_p)
    x = polar_to_local(s_x, va_x, hz_x)
    diff = x - p
    d = np.linalg.norm(diff, axis=-1)
    u = diff / np.maximum(d, 1e-300)[..., None]

    def frame(s, va, hz):
        s, va, hz = np.broadcast_arrays(*(np.asarray(a, float) for a in (s, va, hz)))
        cv, sv, ch, sh = np.cos(va), np.sin(va), np.cos(hz), np.sin(hz)
        d_s = np.stack([cv * sh, cv * ch, sv], -1)
        d_va = s[..., None] * np.stack([-sv * sh, -sv * ch, cv], -1)
        d_hz = s[..., None] * np.stack([cv * ch, -cv * sh, np.zeros_like(cv)], -1)
        return d_s, d_va, d_hz

    fp = frame(s_p, va_p, hz_p)
    fx = frame(s_x, va_x, hz_x)
    parts = [-np.sum(u * f, -1) for f in fp] + [np.sum(u * f, -1) for f in fx]
    return d, np.stack(parts, axis=-1)
