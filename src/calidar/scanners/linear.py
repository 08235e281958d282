"""Linear (oscillating-mirror or polygon) scanner: one across-track scan angle per shot.

Beam in frame s (x forward, y right, z down) for scan angle θ (LAS: negative left of the
flight direction) and an optional along-track angle φ (forward-looking or nodding units):

    θ' = (1 + scan_angle_scale) · θ + scan_angle_offset
    u_s = (sin φ, cos φ · sin θ', cos φ · cos θ')

Observations are (N, 2) [θ, φ] in rad; (N,) means φ = 0.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import ClassVar

import numpy as np

from calidar.scanners.named import NamedParameters


@dataclass(frozen=True)
class LinearScanner(NamedParameters):
    scan_angle_offset: float = 0.0  #: rad, added to the scaled encoder angle
    scan_angle_scale: float = 0.0  #: ratio: true angle = (1 + scale) · encoder angle + offset
    model: str = "linear"
    units: ClassVar[dict[str, str]] = {"scan_angle_offset": "rad", "scan_angle_scale": "1"}

    def directions(self, angles) -> np.ndarray:
        a = np.asarray(angles, dtype=float)
        theta = a if a.ndim == 1 else a[:, 0]
        phi = 0.0 if a.ndim == 1 else a[:, 1]
        th = (1.0 + self.scan_angle_scale) * theta + self.scan_angle_offset
        cphi = np.cos(phi)
        # u_s = (sin φ, cos φ · sin θ', cos φ · cos θ') (docs/conventions.md)
        u = np.broadcast_arrays(np.sin(phi), cphi * np.sin(th), cphi * np.cos(th))
        return np.stack(u, axis=-1)

    def angles(self, directions) -> np.ndarray:
        u = np.asarray(directions, dtype=float)
        th = np.arctan2(u[:, 1], u[:, 2])
        phi = np.arctan2(u[:, 0], np.hypot(u[:, 1], u[:, 2]))
        theta = (th - self.scan_angle_offset) / (1.0 + self.scan_angle_scale)
        return np.stack([theta, phi], axis=-1)

    def to_toml(self) -> dict:
        return {
            "model": self.model,
            "scan_angle_offset_deg": float(np.degrees(self.scan_angle_offset)),
            "scan_angle_scale": float(self.scan_angle_scale),
        }

    @classmethod
    def from_toml(cls, table: dict, source: str = "sensor.toml") -> "LinearScanner":
        from calidar.errors import InputError

        known = {"model", "scan_angle_offset_deg", "scan_angle_scale"}
        unknown = set(table) - known
        if unknown:
            raise InputError(source, "scanner",
                             f"unknown key(s) {sorted(unknown)}; expected {sorted(known)}")
        return cls(
            scan_angle_offset=float(np.radians(table.get("scan_angle_offset_deg", 0.0))),
            scan_angle_scale=float(table.get("scan_angle_scale", 0.0)),
        )
