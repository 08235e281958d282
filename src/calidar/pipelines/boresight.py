"""The strip-calibration pipeline (``calidar boresight``, its demo step and benchmarks):
load the strips and the trajectory, calibrate, write the outputs."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from calidar.errors import InputError
from calidar.validate import parse_floats


def load_strips(paths, trajectory, sensor):
    """Flight lines of the LAS/LAZ files as Strips in one local frame (times in the trajectory's system)."""
    from calidar.georef import from_crs
    from calidar.io.las import adjusted_standard_to_week_seconds
    from calidar.strips.lines import read_flight_lines
    from calidar.strips.strip import LocalFrame, Strip

    lines, _ = read_flight_lines(paths, crs=None)
    first = next(iter(lines.values()))
    crs = first.crs if first.crs is not None else sensor.crs
    if crs is None:
        raise InputError(first.path, "crs", "the file has no CRS and sensor.toml gives none; expected one of them")
    ecef = {i: from_crs(p.xyz, crs) for i, p in lines.items()}
    frame = LocalFrame.at(np.concatenate([e[:: max(1, len(e) // 20000)] for e in ecef.values()]))
    strips = []
    for i, p in lines.items():
        t = p.gps_time
        if p.time_system != trajectory.time_system:
            if p.time_system == "gps_adjusted_standard":
                t = adjusted_standard_to_week_seconds(t, p.path)[0]
            else:
                raise InputError(p.path, "gps_time", "holds GPS week seconds but the trajectory holds adjusted "
                                 "standard GPS time; expected the same time system")
        strips.append(Strip.from_ecef(i, ecef[i], t, trajectory, sensor, frame, str(p.path), las=p))
    return strips, crs


def write_strips(result, crs, out_dir: Path, force: bool) -> list[Path]:
    """Recalibrated strips as LAZ (one per flight line), attributes and GPS times as read."""
    from calidar.georef import to_crs
    from calidar.io.las import write_las

    paths = []
    for s in result.strips:
        las = s.extra["las"]
        xyz = to_crs(s.frame.to_ecef(result.georeference(s)), crs)
        paths.append(write_las(out_dir / f"strip_{s.id}.laz", xyz, crs, gps_time=las.gps_time,
                               scan_angle_deg=las.scan_angle_deg if las.scan_angle_deg is not None else np.zeros(len(s)),
                               point_source_id=s.id, return_number=las.return_number,
                               number_of_returns=las.number_of_returns, classification=las.classification,
                               intensity=las.intensity, time_system=las.time_system, force=force))
    return paths


def parse_methods(text: str) -> list[str]:
    """'planes', 'vgicp' or 'planes,vgicp' → the methods to run, in order."""
    from calidar.strips.calibrate import METHODS

    methods = [m.strip() for m in text.split(",") if m.strip()]
    if not methods or any(m not in METHODS for m in methods) or len(set(methods)) != len(methods):
        raise InputError(None, "--method", f"expected one or more of {', '.join(METHODS)} separated by commas, got {text!r}")
    return methods


def trajectory_model(sigma: str, block_s: float = 1.0, correlation: str = "20,3.5"):
    """--trajectory-sigma 'POSITION_M,ATTITUDE_DEG', --trajectory-block S and
    --trajectory-correlation 'POS_S,ATT_S' → a TrajectoryModel (defaults validated on the simulator)."""
    from calidar.strips.trajectory_errors import TrajectoryModel

    pos_m, att_deg = parse_floats(sigma, 2, "--trajectory-sigma (POSITION_M,ATTITUDE_DEG)")
    corr_pos, corr_att = parse_floats(correlation, 2, "--trajectory-correlation (POS_S,ATT_S)")
    for name, v in (("--trajectory-sigma", pos_m), ("--trajectory-sigma", att_deg), ("--trajectory-block", block_s),
                    ("--trajectory-correlation", corr_pos), ("--trajectory-correlation", corr_att)):
        if not (np.isfinite(v) and v > 0):
            raise InputError(None, name, f"expected numbers > 0, got {v}")
    return TrajectoryModel(block_s, pos_m, np.radians(att_deg), corr_pos, corr_att)
