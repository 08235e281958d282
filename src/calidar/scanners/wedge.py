"""Rotating refracting wedge (single Risley prism): the beam sweeps a cone, a circle on the ground.

Frame s: x forward, y right, z down; the laser travels along +z through a glass wedge of
apex angle α (``wedge_angle``) and refractive index n (``wedge_refractive_index``) that
rotates about the laser axis. The entry face is normal to the axis, the exit face tilted by
α. Refraction is computed exactly with the vector form of Snell's law at both faces,
t = η d + (η cos θᵢ − √(1 − η² sin² θᵢ)) N, so the cone (deviation) angle of the perfect
wedge is δ = asin(n sin α) − α; the thin-prism approximation δ ≈ (n − 1) α is within 1 % of it
only for α below a few degrees (:func:`deviation_angle`).

Encoder angle β = 0 deviates the beam towards +x; β grows towards +y. Structural errors:
``wedge_angle_error`` (α → α + Δα), a tilt of the rotation axis relative to the laser
(``wedge_axis_tilt_x``: towards +x, a rotation about y; ``wedge_axis_tilt_y``: towards +y),
and encoder eccentricity (``eccentricity_ratio`` ε/r, ``eccentricity_phase`` C, see
:mod:`calidar.scanners.rotating`). Observations: β (N,) in rad.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import ClassVar

import numpy as np

from calidar.frames import rot_x, rot_y, rot_z
from calidar.scanners.named import NamedParameters
from calidar.scanners.rotating import (as_encoder_angles, check_toml_keys, encoder_angle,
                                       refine_angles, toml_number, true_angle)


def deviation_angle(wedge_angle_rad: float, refractive_index: float, exact: bool = True) -> float:
    """Cone angle (rad) of a beam entering the wedge normal to its first face.

    Exact: asin(n sin α) − α; thin prism: (n − 1) α.
    """
    if not exact:
        return (refractive_index - 1.0) * wedge_angle_rad
    return float(np.arcsin(refractive_index * np.sin(wedge_angle_rad)) - wedge_angle_rad)


def refract(d: np.ndarray, normal: np.ndarray, eta: float) -> np.ndarray:
    """Snell's law: unit directions d (N, 3) through a surface with unit normals (N, 3) pointing
    back towards the incident side, η = n_incident / n_transmitted. NaN on total reflection."""
    cos_i = -np.einsum("ij,ij->i", normal, d)
    k = 1.0 - eta**2 * (1.0 - cos_i**2)
    with np.errstate(invalid="ignore"):
        return eta * d + (eta * cos_i - np.sqrt(k))[:, None] * normal


@dataclass(frozen=True)
class WedgeScanner(NamedParameters):
    """Rotating refracting wedge; observations are the encoder angle β (N,) in rad."""

    wedge_angle: float = np.radians(20.0)  #: rad, apex angle α
    wedge_refractive_index: float = 1.5168  #: n (ratio; BK7 at 1064 nm ≈ 1.507, at 532 nm ≈ 1.519)
    wedge_angle_error: float = 0.0  #: rad, Δα
    wedge_axis_tilt_x: float = 0.0  #: rad, rotation axis tilted towards +x
    wedge_axis_tilt_y: float = 0.0  #: rad, rotation axis tilted towards +y
    eccentricity_ratio: float = 0.0  #: ε/r (ratio)
    eccentricity_phase: float = 0.0  #: rad, C
    model: str = "wedge"
    units: ClassVar[dict[str, str]] = {"wedge_angle": "rad", "wedge_refractive_index": "1",
                                       "wedge_angle_error": "rad", "wedge_axis_tilt_x": "rad",
                                       "wedge_axis_tilt_y": "rad", "eccentricity_ratio": "1",
                                       "eccentricity_phase": "rad"}

    def __post_init__(self):
        check_wedge(self.wedge_angle, self.wedge_refractive_index, self.eccentricity_ratio)

    @property
    def cone_angle(self) -> float:
        """Exact deviation of the error-free wedge, rad."""
        return deviation_angle(self.wedge_angle, self.wedge_refractive_index)

    def directions(self, angles) -> np.ndarray:
        """Encoder angles β (N,) rad → unit beam vectors (N, 3) in frame s (exact refraction)."""
        b = true_angle(as_encoder_angles(angles), self.eccentricity_ratio, self.eccentricity_phase)
        alpha = self.wedge_angle + self.wedge_angle_error
        r = rot_x(-self.wedge_axis_tilt_y) @ rot_y(self.wedge_axis_tilt_x) @ rot_z(b)  # (N, 3, 3)
        n_in = r @ np.array([0.0, 0.0, -1.0])  # entry face, towards the laser
        n_out = r @ np.array([-np.sin(alpha), 0.0, np.cos(alpha)])  # exit face, outward
        d = np.broadcast_to(np.array([0.0, 0.0, 1.0]), n_in.shape)
        n = self.wedge_refractive_index
        d = refract(d, n_in, 1.0 / n)
        d = refract(d, -n_out, n)
        return d / np.linalg.norm(d, axis=1, keepdims=True)

    def angles(self, directions) -> np.ndarray:
        """Unit vectors (N, 3) in frame s → encoder angles β (N,) in rad, in (−π, π].

        Starts from the azimuth of u (exact for an untilted axis), inverts the eccentricity and
        refines by Gauss–Newton: exact on the pattern, the closest pattern direction off it.
        """
        u = np.asarray(directions, float)
        u = u / np.linalg.norm(u, axis=1, keepdims=True)
        azimuth = np.arctan2(u[:, 1], u[:, 0])
        b = encoder_angle(azimuth, self.eccentricity_ratio, self.eccentricity_phase)
        b = refine_angles(self.directions, u, b)
        return np.angle(np.exp(1j * b))

    def to_toml(self) -> dict:
        return {
            "model": self.model,
            "wedge_angle_deg": float(np.degrees(self.wedge_angle)),
            "refractive_index": float(self.wedge_refractive_index),
            "wedge_angle_error_deg": float(np.degrees(self.wedge_angle_error)),
            "axis_tilt_x_deg": float(np.degrees(self.wedge_axis_tilt_x)),
            "axis_tilt_y_deg": float(np.degrees(self.wedge_axis_tilt_y)),
            "eccentricity_ratio": float(self.eccentricity_ratio),
            "eccentricity_phase_deg": float(np.degrees(self.eccentricity_phase)),
        }

    @classmethod
    def from_toml(cls, table: dict, source: str = "sensor.toml") -> "WedgeScanner":
        angle_keys = ("wedge_angle_error_deg", "axis_tilt_x_deg", "axis_tilt_y_deg",
                      "eccentricity_phase_deg")
        keys = {"model", "wedge_angle_deg", "refractive_index", "eccentricity_ratio", *angle_keys}
        check_toml_keys(table, keys, source)
        alpha = np.radians(toml_number(table, "wedge_angle_deg", 20.0, source))
        n = toml_number(table, "refractive_index", 1.5168, source)
        e = toml_number(table, "eccentricity_ratio", 0.0, source)
        check_wedge(alpha, n, e, source, prefix="scanner.")
        rad = {k: np.radians(toml_number(table, k, 0.0, source)) for k in angle_keys}
        return cls(alpha, n, rad["wedge_angle_error_deg"], rad["axis_tilt_x_deg"],
                   rad["axis_tilt_y_deg"], e, rad["eccentricity_phase_deg"])


def check_wedge(wedge_angle: float, refractive_index: float, eccentricity_ratio: float,
                source: str | None = None, prefix: str = "") -> None:
    """Reject non-physical wedges (angle rad) with a clear :class:`InputError`."""
    from calidar.errors import InputError

    n_sin_alpha = refractive_index * np.sin(wedge_angle)
    if not refractive_index > 1.0:
        raise InputError(source, f"{prefix}refractive_index",
                         f"expected n > 1 (glass ≈ 1.5), got {refractive_index:g}")
    if not 0.0 < wedge_angle < np.pi / 2:
        raise InputError(source, f"{prefix}wedge_angle_deg",
                         f"expected 0 < α < 90°, got {np.degrees(wedge_angle):g}°")
    if not n_sin_alpha < 1.0:
        raise InputError(source, f"{prefix}wedge_angle_deg",
                         f"n·sin α = {n_sin_alpha:.3f} ≥ 1: the beam is totally reflected")
    if not abs(eccentricity_ratio) < 1.0:
        raise InputError(source, f"{prefix}eccentricity_ratio",
                         f"expected |ε/r| < 1, got {eccentricity_ratio:g}")
