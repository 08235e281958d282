"""A beam's ground track as a local straight line: geodetic ↔ local east/north, and
surveyed points → (along-track, cross-track) coordinates of that track.

Cross-track convention: positive to the LEFT of the direction of travel (the direction of
increasing along-track distance). Over the few kilometres around a CCR site the ground
track is straight to millimetres, so a line fitted to the photons' positions is exact enough.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from calidar.frames import ecef_to_geodetic, geodetic_to_ecef, r_en


def geodetic_to_en(lat_rad, lon_rad, lat0_rad: float,
                   lon0_rad: float) -> tuple[np.ndarray, np.ndarray]:
    """Geodetic (rad) → local east, north (m) in the tangent plane at (lat0, lon0), height 0."""
    d = geodetic_to_ecef(lat_rad, lon_rad, 0.0) - geodetic_to_ecef(lat0_rad, lon0_rad, 0.0)
    ned = d @ r_en(lat0_rad, lon0_rad)
    return ned[..., 1], ned[..., 0]


def en_to_geodetic(east_m, north_m, lat0_rad: float,
                   lon0_rad: float) -> tuple[np.ndarray, np.ndarray]:
    """Local east, north (m) in the tangent plane at (lat0, lon0) → geodetic lat, lon (rad)."""
    east, north = np.broadcast_arrays(np.asarray(east_m, float), np.asarray(north_m, float))
    ned = np.stack([north, east, np.zeros_like(east)], -1)
    xyz = geodetic_to_ecef(lat0_rad, lon0_rad, 0.0) + ned @ r_en(lat0_rad, lon0_rad).T
    lat, lon, _ = ecef_to_geodetic(xyz)
    return lat, lon


@dataclass(frozen=True)
class TrackLine:
    """Ground track: position(x) = origin + (x - x_ref)·direction in a local east/north plane."""

    lat0: float  #: rad, tangent-plane origin
    lon0: float  #: rad
    x_ref: float  #: m, along-track distance at the origin
    east0: float  #: m, track position at x_ref
    north0: float  #: m
    direction: tuple[float, float]  #: unit vector (east, north) of travel

    @classmethod
    def fit(cls, x_m: np.ndarray, lat_rad: np.ndarray, lon_rad: np.ndarray) -> "TrackLine":
        """Least-squares line east/north = a + b·(x - x_ref) through photon positions."""
        x_ref = float(np.median(x_m))
        i0 = int(np.argmin(np.abs(x_m - x_ref)))
        lat0, lon0 = float(lat_rad[i0]), float(lon_rad[i0])
        e, n = geodetic_to_en(lat_rad, lon_rad, lat0, lon0)
        a = np.column_stack([np.ones_like(x_m), x_m - x_ref])
        (e0, de), *_ = np.linalg.lstsq(a, e, rcond=None)
        (n0, dn), *_ = np.linalg.lstsq(a, n, rcond=None)
        norm = float(np.hypot(de, dn))
        return cls(lat0, lon0, x_ref, float(e0), float(n0), (float(de / norm), float(dn / norm)))

    def to_track(self, lat_rad, lon_rad) -> tuple[np.ndarray, np.ndarray]:
        """Geodetic (rad) → (along-track distance x [m], cross-track y [m], left positive)."""
        e, n = geodetic_to_en(lat_rad, lon_rad, self.lat0, self.lon0)
        de, dn = e - self.east0, n - self.north0
        ue, un = self.direction
        return self.x_ref + de * ue + dn * un, -de * un + dn * ue

    def to_geodetic(self, x_m, y_m) -> tuple[np.ndarray, np.ndarray]:
        """(along-track x, cross-track y left positive) [m] → geodetic lat, lon (rad)."""
        ue, un = self.direction
        dx = np.asarray(x_m, float) - self.x_ref
        y = np.asarray(y_m, float)
        # along the track's unit direction (ue, un), left of it along (−un, ue)
        east, north = self.east0 + dx * ue - y * un, self.north0 + dx * un + y * ue
        return en_to_geodetic(east, north, self.lat0, self.lon0)
