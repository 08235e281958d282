"""Palmer scanner: a rotating mirror whose normal is tilted from the motor axis sweeps an oval.

Geometry (the model of the Palmer-scanner error analysis for airborne bathymetric lidar that
this module reproduces; the equations are restated here, nothing else is taken from it):

* the laser leaves horizontally; the motor axis makes the angle A (``palmer_axis_angle``,
  nominally 45°) with it, the mirror normal the angle B (``palmer_mirror_tilt``, 7.5°) with
  the axis;
* in the motor frame m (z_m = motor axis) the mirror normal at the true encoder angle β is
  M = R_z(β) · V_R with V_R = (sin B, 0, cos B);
* the beam is reflected, V = V_L − 2 (V_L·M) M, and rotated back into the scanner frame by
  the rotation about y that carries z_m onto the motor axis, R_y(90° − A) (= R_y(A) at
  A = 45°);
* structural errors: encoder eccentricity β_true = β + (ε/r) sin(β − C)
  (``eccentricity_ratio`` ε/r, ``eccentricity_phase`` C), δ_L (``delta_l``) in the angle
  between laser and motor axis, δ_R (``delta_r``) in the angle between mirror normal and axis.

Scanner frame s = the paper's X/Y/Z: x forward, y right, z down, with the laser travelling
along −x and the motor axis in the x–z plane, tilted forward-down: a = (cos A, 0, sin A).
The nominal beam (B = 0) then points to nadir, and β = 0 puts the beam at the forward end of
the oval. Mounted with zero boresight the oval is swept around nadir with its long axis
(258.8 m at 500 m range for A = 45°, B = 7.5°) along track (x) and its short axis (184.6 m)
across track (y); for a long axis across track mount it with boresight yaw = 90°.

**δ_L and the frame the laser defines.** The frame s is attached to the laser: V_L stays
(−1, 0, 0) and δ_L tilts the motor axis — and with it the whole rotating mirror — about y,
A → A + δ_L (both in V_L's motor-frame coordinates and in the rotation back). A mirror tilted
by δ_L deflects the reflected beam by 2 δ_L, so at 500 m δ_L = 0.02° moves points by up to
34.3 cm in X: the 35 cm quoted in the paper's text. Reading the paper's equation (13)
literally — δ_L only in the laser vector written in the motor frame, rotated back with the
nominal R_y(A) — keeps the motor fixed and tilts the laser instead; an incident ray tilted
by δ_L in the plane of incidence leaves the mirror tilted by δ_L only, hence 17.2 cm. The two
readings describe the same relative error and differ exactly by a rigid rotation of the whole
pattern, u_motor = R_y(δ_L) · u_laser (because R_y(90° − A) · R_y(90° − A − δ_L)ᵀ = R_y(δ_L)),
which a boresight (pitch) calibration absorbs. calidar uses the laser-fixed reading;
:func:`palmer_directions` with ``reference="motor"`` gives the literal one for comparison.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import ClassVar

import numpy as np

from calidar.frames import rot_y
from calidar.scanners.named import NamedParameters
from calidar.scanners.rotating import (as_encoder_angles, check_toml_keys, encoder_angle,
                                       refine_angles, toml_number, true_angle)

_LASER = np.array([-1.0, 0.0, 0.0])  #: laser direction in frame s


def _motor_to_scanner(axis_angle_rad: float) -> np.ndarray:
    """Rotation (3, 3) carrying the motor frame (z = motor axis) into frame s."""
    return rot_y(np.pi / 2 - axis_angle_rad)


def palmer_directions(beta_rad, axis_angle: float, mirror_tilt: float,
                      eccentricity_ratio: float = 0.0, eccentricity_phase: float = 0.0,
                      delta_l: float = 0.0, delta_r: float = 0.0,
                      reference: str = "laser") -> np.ndarray:
    """Unit beam vectors (N, 3) in frame s for encoder angles β (N,) rad; all angles rad.

    ``reference="laser"`` (calidar): the laser is fixed in s and δ_L tilts the motor axis.
    ``reference="motor"``: the literal reading of the paper's eq. (13) — δ_L only in the laser
    vector of the motor frame, rotated back with the nominal axis angle (see the module notes).
    """
    if reference not in ("laser", "motor"):
        raise ValueError(f"reference must be 'laser' or 'motor', got {reference!r}")
    b = true_angle(beta_rad, eccentricity_ratio, eccentricity_phase)
    r_sm = _motor_to_scanner(axis_angle + delta_l)
    v_l = r_sm.T @ _LASER  # laser in the motor frame: angle A + δ_L to the axis
    tilt = mirror_tilt + delta_r
    # mirror normal M = R_z(β) · V_R, V_R = (sin B, 0, cos B); reflection V = V_L − 2 (V_L·M) M
    m = np.stack([np.sin(tilt) * np.cos(b), np.sin(tilt) * np.sin(b),
                  np.full_like(b, np.cos(tilt))], axis=-1)
    v = v_l - 2.0 * (m @ v_l)[:, None] * m
    back = r_sm if reference == "laser" else _motor_to_scanner(axis_angle)
    return v @ back.T


@dataclass(frozen=True)
class PalmerScanner(NamedParameters):
    """Palmer (oval) scanner; observations are the encoder angle β (N,) in rad."""

    palmer_axis_angle: float = np.radians(45.0)  #: rad, A: motor axis to (reversed) laser
    palmer_mirror_tilt: float = np.radians(7.5)  #: rad, B: mirror normal to motor axis
    eccentricity_ratio: float = 0.0  #: ε/r, encoder eccentricity over grating radius (ratio)
    eccentricity_phase: float = 0.0  #: rad, C
    delta_l: float = 0.0  #: rad, error of the laser–axis angle (laser fixed, axis tilts)
    delta_r: float = 0.0  #: rad, error of the mirror-normal–axis angle
    model: str = "palmer"
    units: ClassVar[dict[str, str]] = {"palmer_axis_angle": "rad", "palmer_mirror_tilt": "rad",
                                       "eccentricity_ratio": "1", "eccentricity_phase": "rad",
                                       "delta_l": "rad", "delta_r": "rad"}

    def __post_init__(self):
        check_palmer(self.palmer_axis_angle, self.palmer_mirror_tilt, self.eccentricity_ratio)

    def directions(self, angles) -> np.ndarray:
        """Encoder angles β (N,) rad → unit beam vectors (N, 3) in frame s."""
        beta = as_encoder_angles(angles)
        return palmer_directions(beta, self.palmer_axis_angle, self.palmer_mirror_tilt,
                                 self.eccentricity_ratio, self.eccentricity_phase, self.delta_l,
                                 self.delta_r)

    def angles(self, directions) -> np.ndarray:
        """Unit vectors (N, 3) in frame s → encoder angles β (N,) in rad, in (−π, π].

        On the pattern the mirror normal is parallel to u − V_L, so its azimuth about the motor
        axis is the true angle exactly; the eccentricity is inverted by Newton's method. For u
        off the pattern (noise, a perturbed model) a few Gauss–Newton steps then return the β
        whose direction is closest to u.
        """
        u = np.asarray(directions, float)
        u = u / np.linalg.norm(u, axis=1, keepdims=True)
        r_sm = _motor_to_scanner(self.palmer_axis_angle + self.delta_l)
        m = (u - _LASER) @ r_sm  # mirror normal (unnormalised) in the motor frame
        b_true = np.arctan2(m[:, 1], m[:, 0])
        b = encoder_angle(b_true, self.eccentricity_ratio, self.eccentricity_phase)
        b = refine_angles(self.directions, u, b)
        return np.angle(np.exp(1j * b))

    def to_toml(self) -> dict:
        return {
            "model": self.model,
            "axis_angle_deg": float(np.degrees(self.palmer_axis_angle)),
            "mirror_tilt_deg": float(np.degrees(self.palmer_mirror_tilt)),
            "eccentricity_ratio": float(self.eccentricity_ratio),
            "eccentricity_phase_deg": float(np.degrees(self.eccentricity_phase)),
            "delta_l_deg": float(np.degrees(self.delta_l)),
            "delta_r_deg": float(np.degrees(self.delta_r)),
        }

    @classmethod
    def from_toml(cls, table: dict, source: str = "sensor.toml") -> "PalmerScanner":
        keys = {"model", "axis_angle_deg", "mirror_tilt_deg", "eccentricity_ratio",
                "eccentricity_phase_deg", "delta_l_deg", "delta_r_deg"}
        check_toml_keys(table, keys, source)

        def radians(key: str, default_deg: float) -> float:
            return np.radians(toml_number(table, key, default_deg, source))

        a, b = radians("axis_angle_deg", 45.0), radians("mirror_tilt_deg", 7.5)
        e = toml_number(table, "eccentricity_ratio", 0.0, source)
        check_palmer(a, b, e, source, prefix="scanner.")
        return cls(a, b, e, radians("eccentricity_phase_deg", 0.0), radians("delta_l_deg", 0.0),
                   radians("delta_r_deg", 0.0))


def check_palmer(axis_angle: float, mirror_tilt: float, eccentricity_ratio: float,
                 source: str | None = None, prefix: str = "") -> None:
    """Reject non-physical Palmer geometry (angles rad) with a clear :class:`InputError`."""
    from calidar.errors import InputError

    a_deg, b_deg = np.degrees(axis_angle), np.degrees(mirror_tilt)
    if not 0.0 < axis_angle < np.pi / 2:
        raise InputError(source, f"{prefix}axis_angle_deg", f"expected 0 < A < 90°, got {a_deg:g}°")
    if not 0.0 < mirror_tilt < axis_angle:
        raise InputError(source, f"{prefix}mirror_tilt_deg",
                         f"expected 0 < B < A = {a_deg:g}°, got {b_deg:g}°")
    if not abs(eccentricity_ratio) < 1.0:
        raise InputError(source, f"{prefix}eccentricity_ratio",
                         f"expected |ε/r| < 1, got {eccentricity_ratio:g}")
