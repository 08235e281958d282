"""Shared pieces of rotating scanners (Palmer mirror, refracting wedge).

Encoder eccentricity: a grating of radius r mounted with its centre ε off the rotation axis
makes the read head report β while the optics sit at the true angle

    β_true = β + (ε/r) · sin(β − C)

(ε/r is the ``eccentricity_ratio``, C the ``eccentricity_phase``, both from the Palmer
error analysis this package reproduces). Everything here is in radians.
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np


def true_angle(encoder_rad, ratio: float, phase_rad: float) -> np.ndarray:
    """Optical (true) rotation angle from the encoder reading, rad."""
    b = np.asarray(encoder_rad, float)
    return b + ratio * np.sin(b - phase_rad)


def encoder_angle(true_rad, ratio: float, phase_rad: float, iterations: int = 6) -> np.ndarray:
    """Inverse of :func:`true_angle` by Newton's method (|ratio| < 1 keeps it monotonic), rad."""
    t = np.asarray(true_rad, float)
    b = t - ratio * np.sin(t - phase_rad)
    for _ in range(iterations):
        b = b - (b + ratio * np.sin(b - phase_rad) - t) / (1.0 + ratio * np.cos(b - phase_rad))
    return b


def canonical_eccentricity(solution) -> None:
    """Report an estimated encoder eccentricity as ε/r ≥ 0 with C in (−π, π], in place.

    (−ε/r, C) and (ε/r, C + π) are the same encoder error (sin(β − C − π) = −sin(β − C)), and a
    solve may land on either; a negative ε/r is flipped (the covariance row and column of ε/r
    change sign). ``solution``: a :class:`calidar.adjust.Solution` with both parameters free;
    anything else is left as it is.
    """
    names = solution.parameters.free_names
    if "eccentricity_ratio" not in names or "eccentricity_phase" not in names:
        return
    i, j = names.index("eccentricity_ratio"), names.index("eccentricity_phase")
    x = solution.parameters.x()
    if x[i] < 0:
        x[i], x[j] = -x[i], x[j] + np.pi
        sign = np.ones(x.size)
        sign[i] = -1.0
        solution.covariance = solution.covariance * np.outer(sign, sign)
    x[j] = np.pi - (np.pi - x[j]) % (2.0 * np.pi)
    solution.parameters = solution.parameters.updated(x)


def refine_angles(directions: Callable[[np.ndarray], np.ndarray], u: np.ndarray, beta0: np.ndarray,
                  iterations: int = 4, step_rad: float = 1e-6) -> np.ndarray:
    """Encoder angles (N,) minimising |directions(β) − u| by Gauss–Newton from β0, rad.

    For u on the scan pattern this converges to the exact β; for u off the pattern it returns the
    angle of the closest pattern direction near β0 (the "best β").
    """
    b = np.asarray(beta0, float).copy()
    for _ in range(iterations):
        f = directions(b) - u
        j = (directions(b + step_rad) - directions(b - step_rad)) / (2.0 * step_rad)
        jj = np.einsum("ij,ij->i", j, j)
        b = b - np.einsum("ij,ij->i", j, f) / np.where(jj > 0, jj, 1.0)
    return b


def as_encoder_angles(angles) -> np.ndarray:
    """Encoder observations (N,) or (N, 1) rad → (N,) array."""
    a = np.asarray(angles, float)
    if a.ndim == 2 and a.shape[1] == 1:
        a = a[:, 0]
    if a.ndim != 1:
        raise ValueError("rotating scanners take one encoder angle per shot, shape (N,); "
                         f"got {a.shape}")
    return a


def check_toml_keys(table: dict, known: set[str], source: str) -> None:
    """Unknown keys in a ``[scanner]`` table are a clear error."""
    from calidar.errors import InputError

    unknown = set(table) - known
    if unknown:
        raise InputError(source, "scanner",
                         f"unknown key(s) {sorted(unknown)}; expected {sorted(known)}")


def toml_number(table: dict, key: str, default: float, source: str) -> float:
    """A number from a ``[scanner]`` table (booleans and strings are errors)."""
    from calidar.errors import InputError

    v = table.get(key, default)
    if isinstance(v, bool) or not isinstance(v, (int, float)):
        raise InputError(source, f"scanner.{key}", f"expected a number, got {v!r}")
    return float(v)
