"""Simulated total-station observations of a circular-scan (rotating-wedge) lidar.

Geometry per setup: the scanner stands level on a tripod (mirror centre P 1.3–1.7 m above
ground), its scan cone (half-angle 15° by default) about a horizontal axis; each group is
a target wall perpendicular to the axis at 3–15 m on which the beam is stopped at A/B
(level with P) and C/D (plumb above/below P); E points are spots of the stopped beam at
2–40 m. The total station stands 3–6 m from P, beside or behind the scanner, at its own
height, with an arbitrary zero of its horizontal circle. The scanner measures
(1 + scale)·true + offset + noise from P; the total station adds its stated noise
(angle σ, distance σ = a mm + b ppm) to every polar observation, P's included.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from calidar.io.total_station import ARCSEC, Setup, TotalStationObservations


@dataclass(frozen=True)
class TotalStationSimConfig:
    """Simulation settings (units in the names)."""

    n_setups: int = 2
    groups_per_setup: int = 3
    e_per_setup: int = 5
    outliers: int = 0  #: scanner ranges with a gross error of 10–25 σ
    scanner_sigma_mm: float = 2.0
    angle_arcsec: float = 1.0
    distance_mm: float = 1.0
    distance_ppm: float = 1.5
    cone_half_angle_deg: float = 15.0
    range_offset_m: float | None = None  #: None: drawn from U(−0.06, 0.06)
    range_scale_ppm: float | None = None  #: None: drawn from U(−200, 200)


def _observe(rng, o, omega, x, cfg) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Noisy polar observations (m, rad, rad) from the station at ``o`` (zero direction ``omega``)
    of points ``x``."""
    v = np.atleast_2d(x) - o
    s = np.linalg.norm(v, axis=1)
    va = np.arcsin(v[:, 2] / s)
    hz = np.arctan2(v[:, 0], v[:, 1]) - omega
    s = s + rng.normal(0.0, 1e-3 * cfg.distance_mm + 1e-6 * cfg.distance_ppm * s)
    va = va + rng.normal(0.0, cfg.angle_arcsec * ARCSEC, s.size)
    hz = np.mod(hz + rng.normal(0.0, cfg.angle_arcsec * ARCSEC, s.size), 2 * math.pi)
    return s, va, hz


def _setup(rng, i: int, cfg: TotalStationSimConfig, theta: float) -> tuple[Setup, list[tuple]]:
    """Setup ``i``: the station beside or behind the scanner, its observation of the scanner
    (P), of the groups' four points on walls at a cone of half-angle ``theta`` about the
    scanner's axis (A–D) and of the E points along the cone; rows (setup, group, point, kind,
    slope m, vertical angle rad, horizontal angle rad, true scanner range m)."""
    p = np.array([0.0, 0.0, rng.uniform(1.3, 1.7)])
    az = rng.uniform(0, 2 * math.pi)
    axis = np.array([math.sin(az), math.cos(az), 0.0])
    left = np.array([-math.cos(az), math.sin(az), 0.0])
    up = np.array([0.0, 0.0, 1.0])
    psi = az + math.radians(rng.uniform(100.0, 260.0))  # beside or behind the scanner
    r = rng.uniform(3.0, 6.0)
    o = np.array([r * math.sin(psi), r * math.cos(psi), rng.uniform(1.4, 1.7)])
    omega = rng.uniform(0, 2 * math.pi)
    ps, pva, phz = _observe(rng, o, omega, p, cfg)
    setup = Setup(f"TS{i + 1}", cfg.angle_arcsec * ARCSEC, cfg.distance_mm * 1e-3,
                  cfg.distance_ppm, float(ps[0]), float(pva[0]), float(phz[0]), 0)
    rows = []
    n_groups = cfg.groups_per_setup
    walls = np.linspace(3.0, 15.0, n_groups) + rng.uniform(-0.5, 0.5, n_groups)
    for g, wall in enumerate(walls):
        t = wall * math.tan(theta)
        pts = p + wall * axis + t * np.array([left, -left, up, -up])
        s, va, hz = _observe(rng, o, omega, pts, cfg)
        group = f"G{i * n_groups + g + 1}"
        for name, *ob in zip("ABCD", s, va, hz):
            rows.append((i, group, name, "feature", *ob, wall / math.cos(theta)))
    phase = rng.uniform(0, 2 * math.pi, cfg.e_per_setup)
    dist = rng.uniform(2.0, 40.0, cfg.e_per_setup)
    around = np.cos(phase)[:, None] * left + np.sin(phase)[:, None] * up
    dirs = (math.cos(theta) * axis + math.sin(theta) * around)
    s, va, hz = _observe(rng, o, omega, p + dist[:, None] * dirs, cfg)
    for j in range(cfg.e_per_setup):
        point = f"E{i * cfg.e_per_setup + j + 1}"
        rows.append((i, "", point, "E", s[j], va[j], hz[j], dist[j]))
    return setup, rows


def simulate_total_station(seed: int, cfg: TotalStationSimConfig = TotalStationSimConfig()
                           ) -> tuple[TotalStationObservations, dict]:
    """Observations and the truth (``range_offset_m``, ``range_scale_ppm``, noise levels,
    outliers)."""
    rng = np.random.default_rng(seed)
    c = rng.uniform(-0.06, 0.06) if cfg.range_offset_m is None else cfg.range_offset_m
    k_ppm = rng.uniform(-200.0, 200.0) if cfg.range_scale_ppm is None else cfg.range_scale_ppm
    k = k_ppm * 1e-6
    theta = math.radians(cfg.cone_half_angle_deg)
    setups, rows = [], []
    for i in range(cfg.n_setups):
        setup, setup_rows = _setup(rng, i, cfg, theta)
        setups.append(setup)
        rows += setup_rows
    cols = list(zip(*rows))
    true_range = np.array(cols[7])
    sigma = cfg.scanner_sigma_mm * 1e-3
    # the scanner's range: measured = (1 + k) · true + c + noise; gross errors of 10–25 σ
    scanner = (1.0 + k) * true_range + c + rng.normal(0.0, sigma, true_range.size)
    bad = np.zeros(0, int)
    if cfg.outliers:
        bad = rng.choice(true_range.size, cfg.outliers, replace=False)
    sign = rng.choice([-1.0, 1.0], bad.size)
    scanner[bad] += sign * rng.uniform(10, 25, bad.size) * cfg.scanner_sigma_mm * 1e-3
    obs = TotalStationObservations(
        source="simulated", setups=setups, scanner_sigma=sigma,
        setup=np.array(cols[0], int), group=np.array(cols[1]).astype(str),
        point=np.array(cols[2]).astype(str), kind=np.array(cols[3]).astype(str),
        slope=np.array(cols[4], float), va=np.array(cols[5], float),
        hz=np.array(cols[6], float), scanner=np.round(scanner, 4), line=np.zeros(len(rows), int),
    )
    outliers = [{"setup": setups[obs.setup[b]].id, "group": str(obs.group[b]),
                 "point": str(obs.point[b])} for b in sorted(bad)]
    truth = {
        "range_offset_m": float(c), "range_scale_ppm": float(k_ppm),
        "noise": {"scanner_sigma_mm": cfg.scanner_sigma_mm, "angle_arcsec": cfg.angle_arcsec,
                  "distance_mm": cfg.distance_mm, "distance_ppm": cfg.distance_ppm},
        "outliers": outliers,
        "seed": seed,
    }
    return obs, truth
