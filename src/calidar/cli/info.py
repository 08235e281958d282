"""``calidar info FILE``: what a LAS/LAZ point file, a trajectory, an Optech CSD file or an ATL03
photon file holds."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import typer
from rich.markup import escape

from calidar.cli.common import console
from calidar.cli.options import (
    TIME_SYSTEM, TRAJECTORY_ANGLES, TRAJECTORY_COLUMNS, TRAJECTORY_CRS, TRAJECTORY_HEADING,
    point_options,
)
from calidar.cli.options import trajectory_options
from calidar.errors import InputError
from calidar.io.atl03 import atl03_summary
from calidar.crs import vertical_reference
from calidar.io.las import gps_time_system, iter_las_chunks, las_crs, las_header
from calidar.io.optech_csd import is_csd, read_csd
from calidar.io.smrmsg import is_smrmsg_name, smrmsg_info
from calidar.pipelines.inputs import PointOptions, TrajectoryOptions, load_trajectory
from calidar.sensor_import import from_optech_header
from calidar.trajectory import SECONDS_PER_WEEK
from calidar.validate import existing_file

LAS_SUFFIXES = (".las", ".laz")
HDF5_SIGNATURE = b"\x89HDF\r\n\x1a\n"
READS = "calidar info reads LAS/LAZ, SBET, text trajectories, Optech CSD and ICESat-2 ATL03 (HDF5)"


def is_las(path: Path) -> bool:
    """LAS/LAZ by suffix or by the "LASF" signature."""
    if path.suffix.lower() in LAS_SUFFIXES:
        return True
    with open(path, "rb") as f:
        return f.read(4) == b"LASF"


def is_hdf5(path: Path) -> bool:
    """HDF5 by its signature (superblock at offset 0)."""
    with open(path, "rb") as f:
        return f.read(8) == HDF5_SIGNATURE


def atl03_info(path: Path) -> dict:
    """Per beam: photons, shots, segments, strength, along-track source, time/lat/lon/height
    spans."""
    return atl03_summary(path)


def _span(lo: float, hi: float) -> list[float] | None:
    return [lo, hi] if np.isfinite(lo) else None


def las_info(path: Path, options: PointOptions = PointOptions(),
             chunk_points: int = 2_000_000) -> dict:
    """Point count, flight lines (point_source_id: count, GPS time range), CRS, bounds, scan angles,
    and how many points have no finite GPS time (their time ranges leave them out)."""
    header = las_header(path)
    lines: dict[int, list] = {}
    scan, lo, hi, not_finite = [np.inf, -np.inf], np.full(3, np.inf), np.full(3, -np.inf), 0
    time_system = gps_time_system(header, path, options.time_system)
    fields = ("scan_angle_deg", "point_source_id")
    for c in iter_las_chunks(path, chunk_points, fields=fields, options=options):
        if len(c) == 0:
            continue
        scan = [min(scan[0], float(c.scan_angle_deg.min())),
                max(scan[1], float(c.scan_angle_deg.max()))]
        lo, hi = np.minimum(lo, c.xyz.min(axis=0)), np.maximum(hi, c.xyz.max(axis=0))
        finite = np.isfinite(c.gps_time)
        not_finite += int(c.gps_time.size - finite.sum())
        order = np.argsort(c.point_source_id, kind="stable")
        ids, start, counts = np.unique(c.point_source_id[order], return_index=True,
                                       return_counts=True)
        for i, s, n in zip(ids.tolist(), start, counts):
            t = c.gps_time[order[s:s + n]]
            t = t[np.isfinite(t)]
            prev = lines.get(i, [0, np.inf, -np.inf])
            lines[i] = [prev[0] + int(n), min(prev[1], float(t.min(initial=np.inf))),
                        max(prev[2], float(t.max(initial=-np.inf)))]
    file_crs, crs = las_crs(header), options.crs
    warnings = []
    if not_finite:
        warnings.append(f"{not_finite} points have NaN/inf GPS times (left out of the time ranges)")
    last_time = max((v[2] for v in lines.values()), default=None)
    if time_system == "gps_week_seconds" and lines and last_time > SECONDS_PER_WEEK:
        warnings.append("GPS times exceed one week but the global-encoding bit says week seconds: "
                        "probably adjusted standard GPS time (check with the data provider; "
                        "--time-system adjusted overrides it)")
    return {
        "file": str(path), "kind": "points",
        "las_version": f"{header.version.major}.{header.version.minor}",
        "point_format": header.point_format.id,
        "points": int(header.point_count),
        "crs": None if crs is None and file_crs is None else (str(crs) if crs else file_crs.name),
        "crs_epsg": None if file_crs is None or crs else file_crs.to_epsg(),
        "heights": None if crs is None and file_crs is None
        else vertical_reference(crs or file_crs, options.geoid_undulation_m)[0],
        "time_system": time_system,
        "bounds": {"min": lo.tolist(), "max": hi.tolist()} if np.isfinite(lo[0]) else None,
        "scan_angle_deg": _span(*scan), "gps_time_not_finite": not_finite,
        "warning": "; ".join(warnings) or None,
        "flight_lines": [{"point_source_id": k, "points": v[0], "gps_time": _span(v[1], v[2])}
                         for k, v in sorted(lines.items())],
    }


def csd_info(path: Path) -> dict:
    """An Optech CSD file: header (vendor, software, format, GPS week, records, boresight as a
    calidar sensor), pulse time span, returns, ranges, scan angles and the aircraft's position and
    attitude."""
    p = read_csd(path)
    h, sensor = p.header, from_optech_header(p.header)
    deg = lambda a: [float(np.degrees(a.min())), float(np.degrees(a.max()))]  # noqa: E731
    used = p.range_m[:, 0][p.returns > 0]
    boresight = (sensor.boresight_roll, sensor.boresight_pitch, sensor.boresight_yaw)
    return {
        "file": str(path), "kind": "raw pulses (Optech CSD)", "vendor": h.vendor,
        "software": h.software,
        "format_version": h.format_version, "gps_week": h.gps_week, "pulses": len(p),
        "returns": int(np.minimum(p.returns, 4).sum()),
        "gps_time": [float(p.time[0]), float(p.time[-1])],
        "range_m": [float(used.min()), float(used.max())] if used.size else None,
        "scan_angle_deg": deg(p.scan_angle), "lat_deg": deg(p.lat), "lon_deg": deg(p.lon),
        "height_m": [float(p.height.min()), float(p.height.max())], "roll_deg": deg(p.roll),
        "pitch_deg": deg(p.pitch), "heading_deg": deg(p.heading),
        "boresight_deg": [float(np.degrees(v)) for v in boresight],
        "temperature_c": h.temperature_c, "pressure_mbar": h.pressure_mbar,
    }


def trajectory_info(path: Path, options: TrajectoryOptions = TrajectoryOptions()) -> dict:
    """Records, rate, time span, position extents (lat/lon deg, height m) and attitude ranges."""
    try:
        tr = load_trajectory(path, options)
    except InputError as e:
        if e.field != "columns":
            raise
        raise InputError(path, "columns", f"{e.problem}; not a trajectory? {READS}") from None
    deg = lambda a: [float(np.degrees(a.min())), float(np.degrees(a.max()))]  # noqa: E731
    return {
        "file": str(path), "kind": "trajectory", "records": len(tr), "rate_hz": tr.rate_hz,
        "time_system": tr.time_system, "time": [float(tr.time[0]), float(tr.time[-1])],
        "duration_s": float(tr.time[-1] - tr.time[0]),
        "lat_deg": deg(tr.lat), "lon_deg": deg(tr.lon),
        "height_m": [float(tr.height.min()), float(tr.height.max())],
        "roll_deg": deg(tr.roll), "pitch_deg": deg(tr.pitch), "heading_deg": deg(tr.heading),
        "path_length_m": float(np.sum(np.linalg.norm(np.diff(tr.ecef, axis=0), axis=1))),
        "has_velocity": tr.velocity_ned is not None,
    }


def _item(key: str, value) -> str:
    """One entry of a dict shown on one line: a list of values (3 decimals) or a number."""
    if isinstance(value, list):
        return f"{key} {', '.join(f'{x:.3f}' for x in value)}"
    return f"{key} {value:.4g}"


def _print(info: dict) -> None:
    console.print(f"[bold]{escape(info['file'])}[/]: {info['kind']}", highlight=False,
                  soft_wrap=True)
    for k, v in info.items():
        if k in ("file", "kind", "flight_lines", "beams") or v is None and k == "warning":
            continue
        if isinstance(v, list) and len(v) == 2 and all(isinstance(x, float) for x in v):
            digits = 6 if "time" in k or "deg" in k else 3
            v = f"{v[0]:.{digits}f} … {v[1]:.{digits}f}"
        elif isinstance(v, dict):
            v = "  ".join(_item(kk, vv) for kk, vv in v.items())
        elif isinstance(v, float):
            v = f"{v:.6g}"
        elif isinstance(v, list) and all(isinstance(x, float) for x in v):
            v = ", ".join(f"{x:.6f}" for x in v)
        console.print(f"  {k:15s} {escape(str(v))}", highlight=False, soft_wrap=True)
    for fl in info.get("flight_lines", []):
        times = "no finite GPS time"
        if fl["gps_time"] is not None:
            t0, t1 = fl["gps_time"]
            times = f"GPS time {t0:.6f} … {t1:.6f} ({t1 - t0:.1f} s)"
        console.print(f"  flight line {fl['point_source_id']:>5}: {fl['points']:>12,} points, "
                      f"{times}", highlight=False, soft_wrap=True, markup=False)
    for b in info.get("beams", []):
        text = (f"  beam {b['beam']}: {b['photons']:>10,} photons, {b['shots']:,} shots, "
                f"{b['segments']:,} segments")
        if b["photons"]:
            (t0, t1), (la0, la1) = b["delta_time"], b["lat_deg"]
            (lo0, lo1), (h0, h1) = b["lon_deg"], b["h_m"]
            text += (f", delta_time {t0:.6f} … {t1:.6f} ({t1 - t0:.1f} s), lat {la0:.6f} … "
                     f"{la1:.6f}, lon {lo0:.6f} … {lo1:.6f}, h {h0:.3f} … {h1:.3f} m")
        console.print(text, highlight=False, soft_wrap=True)


FILE = typer.Argument(..., help="LAS/LAZ points, SBET, POSPac smrmsg, text trajectory, Optech CSD "
                      "or ATL03 (HDF5).")
CRS_OPTION = typer.Option(None, "--crs",
                          help="CRS of the points or of a text trajectory's coordinates.")


def info(
    file: Path = FILE,
    as_json: bool = typer.Option(False, "--json", help="Print JSON instead of text."),
    crs: str = CRS_OPTION,
    time_system: str | None = TIME_SYSTEM, trajectory_crs: str | None = TRAJECTORY_CRS,
    trajectory_angles: str | None = TRAJECTORY_ANGLES,
    trajectory_heading: str | None = TRAJECTORY_HEADING,
    trajectory_columns: str | None = TRAJECTORY_COLUMNS,
) -> None:
    """Summarise a point file (flight lines, times, CRS, bounds, scan angles), a trajectory, an
    Optech CSD file (header, boresight, pulses) or an ICESat-2 ATL03 photon file (beams, photons,
    time span)."""
    existing_file(file)
    if is_las(file):
        d = las_info(file, point_options(crs, time_system))
    elif is_hdf5(file):
        d = atl03_info(file)
    elif is_csd(file) or file.suffix.lower() == ".csd":
        d = csd_info(file)
    elif is_smrmsg_name(file):
        d = smrmsg_info(file)
    else:
        if crs is not None and trajectory_crs is not None:
            raise InputError(None, "--trajectory-crs",
                             "give the trajectory's CRS once: --crs or --trajectory-crs")
        options = trajectory_options(trajectory_crs or crs, trajectory_angles, trajectory_heading,
                                     trajectory_columns)
        d = trajectory_info(file, options)
    if as_json:
        print(json.dumps(d, indent=2, allow_nan=False))
    else:
        _print(d)


def register(app: typer.Typer, simulate: typer.Typer) -> None:
    app.command("info")(info)
