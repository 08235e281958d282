"""``calidar info FILE``: what a LAS/LAZ point file, a trajectory or an ATL03 photon file holds."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import typer

from calidar.cli.common import console
from calidar.cli.georef import TRAJ_ANGLES, TRAJ_HEADING, load_trajectory
from calidar.errors import InputError
from calidar.io.atl03 import atl03_summary
from calidar.io.las import gps_time_system, iter_las_chunks, las_crs, las_header
from calidar.trajectory import SECONDS_PER_WEEK

LAS_SUFFIXES = (".las", ".laz")
HDF5_SIGNATURE = b"\x89HDF\r\n\x1a\n"
READS = "calidar info reads LAS/LAZ, SBET, text trajectories and ICESat-2 ATL03 (HDF5)"


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
    """Per beam: photons, shots, segments, strength, along-track source, time/lat/lon/height spans."""
    return atl03_summary(path)


def las_info(path: Path, crs: str | None = None, chunk_points: int = 2_000_000) -> dict:
    """Point count, flight lines (point_source_id: count, GPS time range), CRS, bounds, scan angles."""
    header = las_header(path)
    lines: dict[int, list] = {}
    scan = [np.inf, -np.inf]
    time_system = gps_time_system(header, path)
    for c in iter_las_chunks(path, chunk_points, crs=crs, fields=("scan_angle_deg", "point_source_id")):
        if len(c) == 0:
            continue
        scan = [min(scan[0], float(c.scan_angle_deg.min())), max(scan[1], float(c.scan_angle_deg.max()))]
        order = np.argsort(c.point_source_id, kind="stable")
        ids, start, counts = np.unique(c.point_source_id[order], return_index=True, return_counts=True)
        for i, s, n in zip(ids.tolist(), start, counts):
            t = c.gps_time[order[s:s + n]]
            prev = lines.get(i, [0, np.inf, -np.inf])
            lines[i] = [prev[0] + int(n), min(prev[1], float(t.min())), max(prev[2], float(t.max()))]
    file_crs = las_crs(header)
    return {
        "file": str(path), "kind": "points",
        "las_version": f"{header.version.major}.{header.version.minor}", "point_format": header.point_format.id,
        "points": int(header.point_count),
        "crs": None if crs is None and file_crs is None else (crs or file_crs.name),
        "crs_epsg": None if file_crs is None or crs else file_crs.to_epsg(),
        "time_system": time_system,
        "bounds": {"min": [float(v) for v in header.mins], "max": [float(v) for v in header.maxs]},
        "scan_angle_deg": scan if np.isfinite(scan[0]) else None,
        "warning": ("GPS times exceed one week but the global-encoding bit says week seconds: "
                    "probably adjusted standard GPS time (check with the data provider)")
        if time_system == "gps_week_seconds" and lines and max(v[2] for v in lines.values()) > SECONDS_PER_WEEK else None,
        "flight_lines": [{"point_source_id": k, "points": v[0], "gps_time": [v[1], v[2]]} for k, v in sorted(lines.items())],
    }


def trajectory_info(path: Path, crs=None, angles="deg", heading="true") -> dict:
    """Records, rate, time span, position extents (lat/lon deg, height m) and attitude ranges."""
    try:
        tr = load_trajectory(path, crs, angles, heading)
    except InputError as e:
        if e.field != "columns":
            raise
        raise InputError(path, "columns", f"{e.problem}; not a trajectory? {READS}") from None
    deg = lambda a: [float(np.degrees(a.min())), float(np.degrees(a.max()))]  # noqa: E731
    return {
        "file": str(path), "kind": "trajectory", "records": len(tr), "rate_hz": tr.rate_hz,
        "time_system": tr.time_system, "time": [float(tr.time[0]), float(tr.time[-1])],
        "duration_s": float(tr.time[-1] - tr.time[0]),
        "lat_deg": deg(tr.lat), "lon_deg": deg(tr.lon), "height_m": [float(tr.height.min()), float(tr.height.max())],
        "roll_deg": deg(tr.roll), "pitch_deg": deg(tr.pitch), "heading_deg": deg(tr.heading),
        "path_length_m": float(np.sum(np.linalg.norm(np.diff(tr.ecef, axis=0), axis=1))),
        "has_velocity": tr.velocity_ned is not None,
    }


def _print(info: dict) -> None:
    console.print(f"[bold]{info['file']}[/]: {info['kind']}", highlight=False, soft_wrap=True)
    for k, v in info.items():
        if k in ("file", "kind", "flight_lines", "beams") or v is None and k == "warning":
            continue
        if isinstance(v, list) and len(v) == 2 and all(isinstance(x, float) for x in v):
            v = f"{v[0]:.6f} … {v[1]:.6f}" if "time" in k or "deg" in k else f"{v[0]:.3f} … {v[1]:.3f}"
        elif isinstance(v, dict):
            v = "  ".join(f"{kk} {', '.join(f'{x:.3f}' for x in vv)}" for kk, vv in v.items())
        elif isinstance(v, float):
            v = f"{v:.6g}"
        console.print(f"  {k:15s} {v}", highlight=False, soft_wrap=True)
    for fl in info.get("flight_lines", []):
        t0, t1 = fl["gps_time"]
        console.print(f"  flight line {fl['point_source_id']:>5}: {fl['points']:>12,} points, "
                      f"GPS time {t0:.6f} … {t1:.6f} ({t1 - t0:.1f} s)", highlight=False, soft_wrap=True)
    for b in info.get("beams", []):
        text = f"  beam {b['beam']}: {b['photons']:>10,} photons, {b['shots']:,} shots, {b['segments']:,} segments"
        if b["photons"]:
            (t0, t1), (la0, la1), (lo0, lo1), (h0, h1) = b["delta_time"], b["lat_deg"], b["lon_deg"], b["h_m"]
            text += (f", delta_time {t0:.6f} … {t1:.6f} ({t1 - t0:.1f} s), lat {la0:.6f} … {la1:.6f}, "
                     f"lon {lo0:.6f} … {lo1:.6f}, h {h0:.3f} … {h1:.3f} m")
        console.print(text, highlight=False, soft_wrap=True)


def register(app: typer.Typer, simulate: typer.Typer) -> None:
    @app.command()
    def info(
        file: Path = typer.Argument(..., help="LAS/LAZ points, SBET, or text trajectory."),
        as_json: bool = typer.Option(False, "--json", help="Print JSON instead of text."),
        crs: str = typer.Option(None, "--crs", help="CRS of the points or of a text trajectory's coordinates."),
        trajectory_angles: str = TRAJ_ANGLES, trajectory_heading: str = TRAJ_HEADING,
    ) -> None:
        """Summarise a point file (flight lines, times, CRS, bounds, scan angles), a trajectory or an
        ICESat-2 ATL03 photon file (beams, photons, time span)."""
        if not file.is_file():
            raise FileNotFoundError(2, "No such file", str(file))
        if is_las(file):
            d = las_info(file, crs)
        elif is_hdf5(file):
            d = atl03_info(file)
        else:
            d = trajectory_info(file, crs, trajectory_angles, trajectory_heading)
        if as_json:
            print(json.dumps(d, indent=2))
        else:
            _print(d)
