"""A flight line's local east-north-up frame (tangent at its centre): points in, trajectory out."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from calidar import frames


@dataclass(frozen=True)
class LocalFrame:
    origin_ecef: np.ndarray  #: (3,) m
    r_e_enu: np.ndarray  #: (3, 3): v_ecef = r_e_enu @ v_enu
    lat0: float
    lon0: float

    @classmethod
    def at(cls, ecef: np.ndarray) -> "LocalFrame":
        c = np.median(ecef, axis=0)
        lat, lon, _ = frames.ecef_to_geodetic(c)
        r = frames.r_en(lat, lon)  # columns north, east, down
        return cls(c, np.stack([r[:, 1], r[:, 0], -r[:, 2]], axis=1), float(lat), float(lon))

    def to_local(self, ecef: np.ndarray) -> np.ndarray:
        return (np.asarray(ecef, float) - self.origin_ecef) @ self.r_e_enu

    def to_ecef(self, enu: np.ndarray) -> np.ndarray:
        return np.asarray(enu, float) @ self.r_e_enu.T + self.origin_ecef

    def attitude_to_ned(self, enu: np.ndarray, roll, pitch, heading):
        """(lat, lon, h, roll, pitch, heading) at local positions whose attitude is given about the
        frame's own north-east-down axes: re-expressed about each position's local NED (the
        tangent frame tilts by distance / Earth radius: 0.09° at 10 km)."""
        lat, lon, h = frames.ecef_to_geodetic(self.to_ecef(enu))
        r_e_n0 = frames.r_en(self.lat0, self.lon0)
        r_n_e = np.swapaxes(frames.r_en(lat, lon), -1, -2)
        r_nb = r_n_e @ r_e_n0 @ frames.rpy_to_matrix(roll, pitch, heading)
        r, p, y = frames.matrix_to_rpy(r_nb)
        return lat, lon, h, r, p, y
