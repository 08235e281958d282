"""Per-line figures of plausibility (altitude, speed, heading steadiness, σ) of a reconstruction."""

from __future__ import annotations

import numpy as np

from calidar.trajrec.reconstruct import LineTrajectory
from calidar.trajrec.result import line_geodetic


def line_summary(ln: LineTrajectory) -> dict:
    """Duration, mean ellipsoidal height, speed, heading and its steadiness (RMS about a straight
    trend), roll and pitch, median σ; SI units (m, s, m/s, rad)."""
    g = line_geodetic(ln)
    dt = np.diff(ln.time)
    v = np.linalg.norm(np.diff(ln.enu, axis=0), axis=1) / np.where(dt > 0, dt, np.nan)
    head = np.unwrap(g["heading"])
    tc = ln.time - ln.time.mean()
    trend = np.polyval(np.polyfit(tc, head, 1), tc) if ln.time.size > 2 else head
    med = np.median(ln.sigma, axis=0)
    channels = ("east_m", "north_m", "up_m", "roll_rad", "pitch_rad", "heading_rad")
    return {"line": ln.label, "start_s": float(ln.time[0]),
            "duration_s": float(ln.time[-1] - ln.time[0]),
            "epochs": int(ln.time.size), "points": ln.info["points"], "rays": ln.info["rays"],
            "height_m": float(np.mean(g["height"])), "height_range_m": float(np.ptp(g["height"])),
            "speed_mps": float(np.nanmedian(v)),
            "heading_rad": float(np.angle(np.exp(1j * np.mean(head)))),
            "heading_rms_about_trend_rad": float(np.sqrt(np.mean((head - trend) ** 2))),
            "roll_mean_rad": float(np.mean(g["roll"])), "roll_std_rad": float(np.std(g["roll"])),
            "pitch_mean_rad": float(np.mean(g["pitch"])),
            "pitch_std_rad": float(np.std(g["pitch"])),
            "sigma_median": dict(zip(channels, med.tolist())),
            "scan_angles_used": bool(ln.info["scan_angles"]), "scan_sign": ln.info["scan_sign"],
            "started_from": ln.info["start_from"], "sigma0": ln.info["sigma0"],
            "misfit_rad": ln.info["scales"]}


def summary_rows(summaries: list[dict]) -> tuple[list[str], list[list], list]:
    """A table of line summaries (header, rows, formats) in user units (m, s, m/s, deg)."""
    d = np.degrees
    header = ["line", "duration [s]", "points kept", "rays", "height [m]", "speed [m/s]",
              "heading [°]", "heading RMS about trend [°]", "roll mean ± std [°]",
              "pitch mean ± std [°]", "σ E/N/U [m]", "σ roll/pitch/heading [°]"]
    rows = []
    for s in summaries:
        sg = s["sigma_median"]
        sigma_m = " / ".join(f"{sg[k]:.2g}" for k in ("east_m", "north_m", "up_m"))
        sigma_deg = " / ".join(f"{d(sg[k]):.2g}" for k in ("roll_rad", "pitch_rad", "heading_rad"))
        rows.append([s["line"], s["duration_s"], s["points"], s["rays"], s["height_m"],
                     s["speed_mps"], d(s["heading_rad"]), d(s["heading_rms_about_trend_rad"]),
                     f"{d(s['roll_mean_rad']):+.3f} ± {d(s['roll_std_rad']):.3f}",
                     f"{d(s['pitch_mean_rad']):+.3f} ± {d(s['pitch_std_rad']):.3f}",
                     sigma_m, sigma_deg])
    formats = [None, ".1f", "d", "d", ".1f", ".1f", ".2f", ".3f", None, None, None, None]
    return header, rows, formats
