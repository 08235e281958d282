"""Scan patterns: the encoder/scan angles a scanner model reports at each shot time.

``SCAN_PATTERNS`` maps a scanner ``model`` name (see :data:`calidar.scanners.SCANNERS`) to a
function ``pattern(t_s, rate_hz, half_fov_rad, kind) -> angles`` (rad, the shape that
model's ``directions`` accepts). Models without an entry are taken to be rotating
(Palmer, wedge, …): encoder angle β = 2π·f·t, wrapped to [0, 2π).
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np

from calidar.errors import InputError

LINEAR_KINDS = ("oscillating", "polygon")


def linear_pattern(t_s, rate_hz: float, half_fov_rad: float,
                   kind: str = "oscillating") -> np.ndarray:
    """Across-track scan angles θ (N,) rad, negative left: triangle wave (oscillating mirror,
    two scan lines per period) or sawtooth (rotating polygon, one line per period)."""
    phase = np.mod(np.asarray(t_s, float) * rate_hz, 1.0)
    if kind == "oscillating":
        return half_fov_rad * (1.0 - 4.0 * np.abs(phase - 0.5))
    if kind == "polygon":
        return half_fov_rad * (2.0 * phase - 1.0)
    raise InputError(None, "scan_pattern", f"expected one of {LINEAR_KINDS}, got {kind!r}")


def rotating_pattern(t_s, rate_hz: float, half_fov_rad: float = 0.0, kind: str = "") -> np.ndarray:
    """Encoder angles β = 2π·f·t (N,) rad in [0, 2π) of a continuously rotating scanner."""
    return np.mod(2.0 * np.pi * rate_hz * np.asarray(t_s, float), 2.0 * np.pi)


SCAN_PATTERNS: dict[str, Callable[..., np.ndarray]] = {"linear": linear_pattern}


def scan_angles(scanner, t_s, rate_hz: float, half_fov_rad: float,
                kind: str = "oscillating") -> np.ndarray:
    """Encoder angles of ``scanner`` (any :class:`calidar.scanners.Scanner`) at shot times
    ``t_s``."""
    return SCAN_PATTERNS.get(scanner.model, rotating_pattern)(t_s, rate_hz, half_fov_rad, kind)


def half_field_of_view(scanner, rate_hz: float, half_fov_rad: float,
                       kind: str = "oscillating") -> float:
    """Largest across-track angle (rad) of the beams the scanner produces over one period."""
    t = np.linspace(0.0, 1.0 / rate_hz, 721)
    u = scanner.directions(scan_angles(scanner, t, rate_hz, half_fov_rad, kind))
    return float(np.max(np.abs(np.arctan2(u[:, 1], u[:, 2]))))
