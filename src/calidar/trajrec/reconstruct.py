"""One flight line's trajectory from its kept points: local frame, starting values, segment fits,
epochs at a regular rate with their σ (see the package docstring)."""

from __future__ import annotations

from dataclasses import dataclass, field, replace

import numpy as np

from calidar.crs import from_crs
from calidar.errors import InputError
from calidar.trajrec import mounting
from calidar.trajrec.fit import FitSettings, Observations, channel_sigma, solve_segment
from calidar.trajrec.frame import LocalFrame
from calidar.trajrec.geometry import ray_basis
from calidar.trajrec.lines import LinePoints
from calidar.trajrec.scanlines import course, ground_track, ray_start, scan_angle_start
from calidar.trajrec.spline import Spline

MIN_SCAN_VALUES = 5  #: distinct scan angles a line needs for the scan-angle geometry ...
MIN_SCAN_SPAN_DEG = 4.0  #: ... spread over at least this many degrees
MIN_RAYS = 50  #: multi-return pulses a line needs when its scan angles are unusable
MIN_DURATION_S = 0.5  #: shorter lines are not reconstructed
START_KNOT_S = 1.0
#: the trajectory is written this far (s) beyond the first and last kept point of a line
EDGE_S = 0.1


@dataclass
class LineTrajectory:
    """A reconstructed line: epochs in its local frame, attitude about the frame's NED axes."""

    label: str
    frame: LocalFrame
    time: np.ndarray  #: (n,) s, as the points' times
    enu: np.ndarray  #: (n, 3) m
    attitude: np.ndarray  #: (n, 3) roll, pitch, heading (rad)
    sigma: np.ndarray  #: (n, 6) σ east, north, up (m), roll, pitch, heading (rad)
    info: dict = field(default_factory=dict)


def _scan_usable(scan_deg: np.ndarray) -> bool:
    s = scan_deg[np.isfinite(scan_deg)]
    return (s.size > 0 and np.unique(s).size >= MIN_SCAN_VALUES
            and float(np.ptp(s)) >= MIN_SCAN_SPAN_DEG)


def _start(line: LinePoints, p, scan_rad, rays, use_scan,
           path=None) -> tuple[Spline, np.ndarray, int, str]:
    """A smooth starting path (spline over E, N, U, heading), the scan-angle sign, and its
    source."""
    sp, coef = ground_track(line.t, p)
    sign, source, rows = 1, "", np.empty((0, 4))
    if use_scan:
        srows, sign, score = scan_angle_start(line.t, p, scan_rad, sp, coef)
        if srows.shape[0] >= 2 and np.isfinite(score):
            tr = sp.evaluate(coef, srows[:, 0])
            psi = course(sp, coef, srows[:, 0])
            across = srows[:, 1]  # right of the course: (cos ψ, −sin ψ) in east, north
            east, north = tr[:, 0] + across * np.cos(psi), tr[:, 1] - across * np.sin(psi)
            rows = np.stack([srows[:, 0], east, north, srows[:, 2]], axis=1)
            source = "scan angles"
    if rows.shape[0] < 2 and rays[0].size >= MIN_RAYS:
        rows, source = ray_start(rays[0], rays[1], rays[2]), "multi-return rays"
    if rows.shape[0] < 2:
        raise InputError(path, f"line {line.label}", "cannot place the sensor: the method needs a "
                         f"usable scan-angle field (≥ {MIN_SCAN_VALUES} distinct values over ≥ "
                         f"{MIN_SCAN_SPAN_DEG:g}°) or ≥ {MIN_RAYS} multi-return pulses (returns "
                         "sharing a GPS time)")
    st = Spline.covering(line.t[0], line.t[-1], START_KNOT_S)
    head = np.interp(rows[:, 0], line.t, course(sp, coef, line.t))
    return st, st.fit(rows[:, 0], np.c_[rows[:, 1:], head], smooth=1e-3), sign, source


def _segments(t0: float, t1: float, s: FitSettings) -> list[tuple[float, float, float, float]]:
    """(fit start, fit end, own start, own end) covering [t0, t1]; own ranges partition it."""
    n = max(int(np.ceil((t1 - t0) / s.segment_s)), 1)
    edges = np.linspace(t0, t1, n + 1)
    return [(max(a - s.overlap_s, t0), min(b + s.overlap_s, t1), a, b)
            for a, b in zip(edges[:-1], edges[1:])]


def coordinate_step(xyz: np.ndarray) -> float:
    """The heights' rounding step (the LAS scale, in the file's units): the smallest difference
    between distinct heights (0 with fewer than two)."""
    z = np.unique(xyz[:, 2]) if xyz.size else np.empty(0)
    return float(np.min(np.diff(z))) if z.size > 1 else 0.0


def height_unit_m(crs) -> float:
    """Metres per unit of the points' heights: a 2-D projected CRS in feet has its heights in feet
    too (LAS files carry one unit), which PROJ would pass through as metres."""
    axes = crs.axis_info
    if crs.is_projected and len(axes) == 2 and axes[0].unit_conversion_factor:
        return float(axes[0].unit_conversion_factor)
    return 1.0


def _ecef(xyz, crs, undulation, source):
    z_unit = height_unit_m(crs)
    if z_unit != 1.0:
        xyz = np.c_[xyz[:, :2], xyz[:, 2] * z_unit]
    return from_crs(xyz, crs, undulation, source=source)


def _select(obs: Observations, a: float, b: float) -> Observations:
    """The observations of times [a, b]."""
    pm = (obs.t >= a) & (obs.t <= b)
    rm = (obs.ray_t >= a) & (obs.ray_t <= b)
    return Observations(obs.points[pm], obs.t[pm], obs.scan[pm], obs.use_across, obs.use_along,
                        obs.ray_last[rm], obs.ray_u1[rm], obs.ray_u2[rm], obs.ray_t[rm],
                        obs.ray_sigma[rm], ray_floor=obs.ray_floor)


def _fit_segments(obs: Observations, st: Spline, sc: np.ndarray, settings: FitSettings,
                  out_t: np.ndarray):
    """Each segment fitted from the starting path (st, sc); values and σ at ``out_t`` from the
    segment owning each epoch."""
    enu, att, sig = np.empty((out_t.size, 3)), np.empty((out_t.size, 3)), np.empty((out_t.size, 6))
    fits = []
    t_last = obs.t[-1]
    for a, b, oa, ob in _segments(obs.t[0], t_last, settings):
        spline = Spline.covering(a, b, settings.knot_s)
        ts = np.linspace(a, b, 4 * spline.n_coef)
        start = st.evaluate(sc, ts)
        # the scan lines' trace is normal to the scan plane: the body's heading is κ less
        heading = start[:, 3] - settings.scan_plane_yaw
        coef0 = spline.fit(ts, np.c_[start[:, :3], np.zeros((ts.size, 2)), heading])
        fit = solve_segment(_select(obs, a, b), spline, coef0, settings)
        fits.append(fit)
        tc = np.clip(out_t, obs.t[0], t_last)
        own = (tc >= oa) & ((tc < ob) | (ob == t_last))
        val = spline.evaluate(fit.coef, out_t[own])
        enu[own], att[own], sig[own] = val[:, :3], val[:, 3:], channel_sigma(fit, out_t[own])
    return enu, att, sig, fits


def reconstruct_line(line: LinePoints, crs, undulation, settings: FitSettings, rate_hz: float,
                     source=None) -> LineTrajectory:
    """The trajectory of one line (see the module docstring); ``source`` names the file in
    errors."""
    if line.duration_s < MIN_DURATION_S:
        raise InputError(source, f"line {line.label}", f"{line.duration_s:.2f} s of points; the "
                         f"method needs ≥ {MIN_DURATION_S:g} s of one flight line (several scan "
                         "lines)")
    ecef = _ecef(line.xyz, crs, undulation, source)
    frame = LocalFrame.at(ecef[:: max(1, ecef.shape[0] // 5000)])
    p = frame.to_local(ecef)
    last, d, sep = _rays(line, frame, crs, undulation, source)
    use_scan = settings.use_scan_angles and _scan_usable(line.scan)
    if not (use_scan or settings.planar_scanner or line.ray_t.size >= MIN_RAYS):
        raise InputError(source, f"line {line.label}", f"{line.ray_t.size} multi-return pulses "
                         "and no scan-angle or scan-plane geometry; the method needs ≥ "
                         f"{MIN_RAYS} pulses with several returns")
    scan = np.radians(line.scan) if use_scan else np.full(line.t.size, np.nan)
    settings = replace(settings, mount_sigma=_mount_sigma(settings, use_scan))
    st, sc, sign, start_from = _start(line, p, scan, (line.ray_t, last, d), use_scan, source)
    u1, u2 = ray_basis(d) if sep.size else (np.empty((0, 3)), np.empty((0, 3)))
    # the rays' floor: two heights rounded to the LAS scale (uniform, variance step²/12 each)
    ray_floor = np.sqrt(2.0 / 12.0) * coordinate_step(line.xyz) * height_unit_m(crs)
    obs = Observations(p, line.t, sign * scan, use_scan, settings.planar_scanner, last, u1, u2,
                       line.ray_t, 1.0 / np.maximum(sep, 0.1), ray_floor=ray_floor)
    # epochs reach EDGE_S past the kept points: the thinned-out points at a line's ends stay covered
    n_out = int(np.ceil((line.t[-1] - line.t[0] + 2 * EDGE_S) * rate_hz)) + 1
    out_t = line.t[0] - EDGE_S + np.arange(n_out) / rate_hz
    enu, att, sig, fits = _fit_segments(obs, st, sc, settings, out_t)
    info = {"points": int(line.t.size), "rays": int(line.ray_t.size), "scan_angles": use_scan,
            "scan_sign": sign, "planar": settings.planar_scanner, "start_from": start_from,
            **_fits_info(fits, settings)}
    return LineTrajectory(line.label, frame, out_t, enu, att, sig, info)


def _rays(line: LinePoints, frame: LocalFrame, crs, undulation, source):
    """The line's multi-return rays in its local frame: last returns (R, 3) m, unit directions
    towards the sensor (R, 3) and the first-to-last separations (R,) m."""
    if line.ray_t.size:
        first = frame.to_local(_ecef(line.ray_first, crs, undulation, source))
        last = frame.to_local(_ecef(line.ray_last, crs, undulation, source))
    else:
        first = last = np.empty((0, 3))
    d = first - last
    sep = np.linalg.norm(d, axis=1)
    return last, d / np.maximum(sep, 1e-9)[:, None], sep


def _mount_sigma(settings: FitSettings, use_scan: bool) -> tuple[float, ...]:
    """The scanner calibration's prior σ the line can use: the encoder's terms need the scan-angle
    field, the scan plane's the planar geometry (older 4-term settings: the others known)."""
    m = np.zeros(len(mounting.NAMES))
    m[:len(settings.mount_sigma)] = settings.mount_sigma
    m = m * np.where(mounting.OF_SCAN_ANGLES, use_scan, settings.planar_scanner)
    return tuple(float(v) for v in m)


def _fits_info(fits, settings: FitSettings) -> dict:
    """The segments' fits summed up: how many, iterations, median σ0, the scanner calibration's
    median value and σ (with its prior σ) and the residual types' median scales."""
    def median(values):
        return float(np.median(values))

    mount = {n: (median([f.mount[k] for f in fits]), median([f.mount_sigma[k] for f in fits]),
                 float(settings.mount_sigma[k]))
             for k, n in enumerate(mounting.NAMES) if settings.mount_sigma[k] > 0}
    kinds = {k for f in fits for k in f.scales}
    return {"segments": len(fits), "iterations": max(f.iterations for f in fits),
            "sigma0": median([f.sigma0 for f in fits]), "mount": mount,
            "scales": {k: median([f.scales[k] for f in fits if k in f.scales]) for k in kinds}}
