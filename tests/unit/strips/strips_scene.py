"""A small synthetic survey for the strip tests: tilted planar tiles flown by straight lines.

Points are made by casting the beams of a TRUE sensor onto the scene and delivered
georeferenced with a NOMINAL one, as a real survey with a mis-calibrated mounting.
"""

from __future__ import annotations

import numpy as np

from calidar import frames, georef
from calidar.sensor import Sensor
from calidar.strips.strip import LocalFrame, Strip
from calidar.trajectory import Trajectory

ORIGIN = (np.radians(45.0), np.radians(7.0), 300.0)  # lat, lon rad, ellipsoidal height m of the ground
TILE_M = 20.0


def frame() -> LocalFrame:
    o = frames.geodetic_to_ecef(*ORIGIN)
    return LocalFrame(o, frames.R_ENU_NED @ frames.r_en(ORIGIN[0], ORIGIN[1]).T)


class Scene:
    """Heights z(x, y) made of planar 20 m tiles with random slopes and steps (buildings)."""

    def __init__(self, seed: int = 1, n: int = 200):
        rng = np.random.default_rng(seed)
        self.n = n
        self.g = rng.normal(0.0, 0.35, (n, n, 2))
        self.c = np.where(rng.random((n, n)) < 0.3, rng.uniform(3, 12, (n, n)), 0.0)

    def tile(self, xy):
        ij = np.floor(xy / TILE_M).astype(int) + self.n // 2
        return np.clip(ij[:, 0], 0, self.n - 1), np.clip(ij[:, 1], 0, self.n - 1)

    def cast(self, o, d):
        """Intersect rays o + s·d (local m) with the tiles; returns points and a validity mask."""
        s = (0.0 - o[:, 2]) / d[:, 2]
        for _ in range(8):
            i, j = self.tile(o[:, :2] + s[:, None] * d[:, :2])
            gx, gy, c = self.g[i, j, 0], self.g[i, j, 1], self.c[i, j]
            centre = (np.stack([i, j], 1) - self.n // 2 + 0.5) * TILE_M
            # plane through the tile centre: z = c + g·(xy − centre)
            s = (c + gx * (o[:, 0] - centre[:, 0]) + gy * (o[:, 1] - centre[:, 1]) - o[:, 2]) / (
                d[:, 2] - gx * d[:, 0] - gy * d[:, 1])
        p = o + s[:, None] * d
        i2, j2 = self.tile(p[:, :2])
        return p, (i2 == i) & (j2 == j) & (s > 0)


def line(start_enu, heading_deg, length_m, altitude_m, t0, speed=60.0, rate=100.0, seed=0) -> Trajectory:
    """A straight line with small attitude wobble, as a Trajectory (true heading = ENU azimuth)."""
    rng = np.random.default_rng(seed)
    dur = length_m / speed
    t = t0 + np.arange(0.0, dur + 1.0 / rate, 1.0 / rate)
    h = np.radians(heading_deg)
    dirn = np.array([np.sin(h), np.cos(h), 0.0])
    enu = np.asarray(start_enu, float) + np.outer(t - t0, speed * dirn)
    enu[:, 2] = altitude_m
    lat, lon, hgt = frames.ecef_to_geodetic(frame().to_ecef(enu))
    ph = rng.uniform(0, 6, 3)
    roll = np.radians(1.5) * np.sin(0.5 * (t - t0) + ph[0])
    pitch = np.radians(2.0) + np.radians(0.8) * np.sin(0.3 * (t - t0) + ph[1])
    head = h + np.radians(1.0) * np.sin(0.2 * (t - t0) + ph[2])
    return Trajectory(t, lat, lon, hgt, roll, pitch, head)


def fly(scene: Scene, traj: Trajectory, truth: Sensor, nominal: Sensor, strip_id: int, *, n=40000,
        fov_deg=50.0, range_noise_m=0.03, vegetation=0.0, seed=0) -> tuple[np.ndarray, np.ndarray]:
    """Scan a trajectory: delivered ECEF points (nominal sensor) and their GPS times."""
    rng = np.random.default_rng(seed + 1000 * strip_id)
    t = np.sort(rng.uniform(traj.time[0] + 0.05, traj.time[-1] - 0.05, n))
    ang = rng.uniform(-np.radians(fov_deg / 2), np.radians(fov_deg / 2), n)
    f = frame()
    o = f.to_local(georef.forward(traj, truth, t, truth.measured_range(np.zeros(n)), ang))
    d = f.to_local(georef.forward(traj, truth, t, truth.measured_range(np.ones(n)), ang)) - o
    p, ok = scene.cast(o, d)
    rho = np.linalg.norm(p - o, axis=1)
    if vegetation:
        veg = rng.random(n) < vegetation
        rho[veg] -= rng.uniform(0.5, 15.0, veg.sum())  # canopy returns above the ground
    measured = truth.measured_range(rho) + rng.normal(0.0, range_noise_m, n)
    pts = georef.forward(traj, nominal, t[ok], measured[ok], ang[ok])
    return pts, t[ok]


def survey(truth: Sensor, nominal: Sensor, lines, *, n=40000, vegetation=0.0, noise=0.03, seed=1):
    """Strips for a list of (start_enu, heading_deg, length_m, altitude_m); shared trajectory per line."""
    scene = Scene(seed)
    strips = []
    for k, (start, heading, length, alt) in enumerate(lines):
        traj = line(start, heading, length, alt, t0=1000.0 + 200.0 * k, seed=seed + k)
        pts, t = fly(scene, traj, truth, nominal, k + 1, n=n, range_noise_m=noise, vegetation=vegetation, seed=seed)
        strips.append(Strip.from_ecef(k + 1, pts, t, traj, nominal, frame()))
    return strips
