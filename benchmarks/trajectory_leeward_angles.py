"""leeward_sierra's scan angles against its true SBET (issue #30, docs/validation.md "#30's three lines"): with
the SBET's positions and attitude at each point's time (scan plane yawed 13.96° in the body), the across-track
angle minus the stored scan angle and the along-track angle, each fitted as a polynomial in the scan angle θ (rad),
and the one multi-return pulse's ray against the SBET's sensor.

    CALIDAR_REAL_DATA=/work/shared/data/real PYTHONPATH=src python benchmarks/trajectory_leeward_angles.py
"""

from __future__ import annotations

import os
from pathlib import Path

import laspy
import numpy as np
import pyproj

from calidar import frames
from calidar.crs import from_crs
from calidar.io.sbet import read_sbet
from calidar.trajrec.frame import LocalFrame
from calidar.trajrec.geometry import body_vectors

KAPPA = np.radians(13.96)


def main() -> None:
    root = Path(os.environ.get("CALIDAR_REAL_DATA", "../shared/data/real")) / "leeward_sierra"
    las = laspy.read(root / "points.las")
    o = np.argsort(np.asarray(las.gps_time))
    t = np.asarray(las.gps_time, float)[o]
    scan = np.radians(np.asarray(las.scan_angle_rank, float))[o]
    ecef = from_crs(np.c_[las.x, las.y, las.z][o], pyproj.CRS.from_epsg(32611), None)
    sb = read_sbet(root / "sbet.out")
    lat, lon, h = (np.interp(t, sb.time, v) for v in (sb.lat, sb.lon, sb.height))
    sensor = frames.geodetic_to_ecef(lat, lon, h)
    fr = LocalFrame.at(sensor)
    p, s = fr.to_local(ecef), fr.to_local(sensor)
    r_nb = frames.r_en(fr.lat0, fr.lon0).T @ frames.r_en(lat, lon) @ frames.rpy_to_matrix(
        np.interp(t, sb.time, sb.roll), np.interp(t, sb.time, sb.pitch), np.interp(t, sb.time, np.unwrap(sb.heading)))
    b = body_vectors(p, s, np.stack(frames.matrix_to_rpy(r_nb), axis=1))
    across = np.arctan2(b[:, 1], b[:, 2])
    s0 = np.cos(KAPPA) * b[:, 0] + np.sin(KAPPA) * b[:, 1]
    s1 = -np.sin(KAPPA) * b[:, 0] + np.cos(KAPPA) * b[:, 1]
    along = np.arctan2(s0, np.hypot(s1, b[:, 2]))
    for name, y in (("across-track angle − stored", across - scan), ("along-track angle", along)):
        a = np.stack([scan**j for j in range(3)], axis=1)
        c = np.linalg.lstsq(a, y, rcond=None)[0]
        rest = y - a @ c
        print(f"{name}: {np.degrees(c[0]):+.4f}° {np.degrees(c[1]):+.4f}°·θ {np.degrees(c[2]):+.4f}°·θ² "
              f"(at 30°: {np.degrees(c[2]) * np.radians(30) ** 2:+.3f}°); rest RMS {np.degrees(np.sqrt(np.mean(rest**2))):.4f}°, "
              f"MAD {np.degrees(1.4826 * np.median(np.abs(rest - np.median(rest)))):.4f}°")
    _, inv, count = np.unique(t, return_inverse=True, return_counts=True)
    for g in np.flatnonzero(count > 1):
        m = np.flatnonzero(inv == g)
        hi, lo = m[np.argmax(p[m, 2])], m[np.argmin(p[m, 2])]
        d = (p[hi] - p[lo]) / np.linalg.norm(p[hi] - p[lo])
        w = s[lo] - p[lo]
        print(f"pulse at +{t[lo] - t[0]:.2f} s: returns {np.linalg.norm(p[hi] - p[lo]):.2f} m apart, its ray passes "
              f"{np.linalg.norm(w - (w @ d) * d):.1f} m from the SBET's sensor at {np.linalg.norm(w):.0f} m")
    v = np.diff(fr.to_local(frames.geodetic_to_ecef(sb.lat, sb.lon, sb.height)), axis=0) / np.diff(sb.time)[:, None]
    print(f"SBET speed {np.median(np.linalg.norm(v, axis=1)):.1f} m/s, course {np.degrees(np.arctan2(*np.median(v[:, :2], axis=0))):.2f}°, "
          f"heading {np.degrees(np.median(sb.heading)):.2f}°")


if __name__ == "__main__":
    main()
