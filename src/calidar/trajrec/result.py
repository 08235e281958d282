"""Reconstructed lines as one :class:`calidar.trajectory.Trajectory` with σ columns, and their
comparison with a known trajectory (the simulator's, or a real SBET)."""

from __future__ import annotations

import numpy as np

from calidar import frames, georef
from calidar.trajectory import Trajectory
from calidar.trajrec.reconstruct import LineTrajectory

SIGMA_KEYS = ("sigma_north", "sigma_east", "sigma_down",
              "sigma_roll", "sigma_pitch", "sigma_heading")


def line_geodetic(line: LineTrajectory) -> dict:
    """lat, lon, height, roll, pitch, heading (rad, m) of a line's epochs about the local NED."""
    lat, lon, h, r, p, y = line.frame.attitude_to_ned(line.enu, *line.attitude.T)
    return {"lat": lat, "lon": lon, "height": h, "roll": r, "pitch": p, "heading": y}


def to_trajectory(lines: list[LineTrajectory], time_shift_s: float = 0.0,
                  time_system: str = "gps_week_seconds",
                  source: str = "<reconstructed>") -> Trajectory:
    """All lines in time order as one trajectory (times + ``time_shift_s``), σ in ``extra``
    (north, east, down in m; roll, pitch, heading in rad). Epochs of a line inside another's
    time span are dropped (lines do not fly at once)."""
    parts = sorted(lines, key=lambda ln: ln.time[0])
    names = ("time", "lat", "lon", "height", "roll", "pitch", "heading", *SIGMA_KEYS)
    cols = {k: [] for k in names}
    t_end = -np.inf
    for ln in parts:
        keep = ln.time > t_end
        g = line_geodetic(ln)
        cols["time"].append(ln.time[keep] + time_shift_s)
        for k, v in g.items():
            cols[k].append(v[keep])
        s = ln.sigma[keep]
        for k, v in zip(SIGMA_KEYS, (s[:, 1], s[:, 0], s[:, 2], s[:, 3], s[:, 4], s[:, 5])):
            cols[k].append(v)
        if keep.any():
            t_end = ln.time[keep][-1]
    a = {k: np.concatenate(v) for k, v in cols.items()}
    heading = np.angle(np.exp(1j * a["heading"]))  # wrapped to (−π, π]
    return Trajectory(time=a["time"], lat=a["lat"], lon=a["lon"], height=a["height"],
                      roll=a["roll"], pitch=a["pitch"], heading=heading, time_system=time_system,
                      source=source, extra={k: a[k] for k in SIGMA_KEYS})


def compare(rec: Trajectory, truth: Trajectory, lever_arm_m=(0.0, 0.0, 0.0)) -> dict:
    """Errors of ``rec`` against ``truth`` at rec's epochs within truth's span: position against the
    truth's point ``lever_arm_m`` (body frame; the scanner's origin) in its local NED (m), attitude
    (rad, rec − truth, each about the truth's local NED), and the same errors divided by rec's σ."""
    t = rec.time[truth.covers(rec.time)]
    sel = np.isin(rec.time, t)
    pos_t, r_eb_t = georef.poses(truth, t)
    pos_t = pos_t + np.einsum("nij,j->ni", r_eb_t, np.asarray(lever_arm_m, float))
    r_ne = np.swapaxes(frames.r_en(rec.lat[sel], rec.lon[sel]), -1, -2)
    d_ned = np.einsum("nij,nj->ni", r_ne, rec.ecef[sel] - pos_t)
    rt, pt, yt = frames.matrix_to_rpy(r_ne @ r_eb_t)
    d_heading = np.angle(np.exp(1j * (rec.heading[sel] - yt)))
    d_att = np.stack([rec.roll[sel] - rt, rec.pitch[sel] - pt, d_heading], 1)
    out = {"time": t, "d_ned": d_ned, "d_att": d_att}
    if all(k in rec.extra for k in SIGMA_KEYS):
        sig = np.stack([rec.extra[k][sel] for k in SIGMA_KEYS], axis=1)
        out["z"] = np.c_[d_ned, d_att] / np.maximum(sig, 1e-12)
    return out


def error_summary(c: dict) -> dict:
    """Median and 95th percentile of |error|: 3-D position, horizontal, height (m), roll, pitch,
    heading (deg), and the RMS of error/σ per channel (1 when the σ are honest)."""
    d, a = c["d_ned"], np.degrees(np.abs(c["d_att"]))
    series = {"position_3d_m": np.linalg.norm(d, axis=1),
              "horizontal_m": np.hypot(d[:, 0], d[:, 1]), "height_m": np.abs(d[:, 2]),
              "roll_deg": a[:, 0], "pitch_deg": a[:, 1], "heading_deg": a[:, 2]}
    out = {k: {"median": float(np.median(v)), "p95": float(np.percentile(v, 95))}
           for k, v in series.items()}
    out["mean_height_error_m"] = float(np.mean(-d[:, 2]))
    if "z" in c:
        rms = np.sqrt(np.mean(c["z"] ** 2, axis=0)).round(3).tolist()
        channels = ("north", "east", "down", "roll", "pitch", "heading")
        out["rms_error_over_sigma"] = dict(zip(channels, rms))
    return out
