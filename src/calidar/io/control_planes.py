"""Control surfaces (CSV): surveyed points on planar patches such as roof facets, checked on
reading.

A surveyor measures a few points on each plane (a roof facet's corners, or points inside it, by
GNSS RTK or total station); the file lists them, one line a point, grouped by the plane's id::

    # lines starting with # are comments
    plane,x,y,z,sigma
    R01,500123.412,5200456.118,462.331,0.01
    R01,500131.090,5200456.774,462.337,0.01
    R01,500130.877,5200464.402,466.020,0.01
    R01,500123.205,5200463.746,466.014,0.01

- Columns by name (case and ``_``/``-``/spaces ignored), in any order: ``plane`` (surface, patch,
  facet, roof), ``x`` (easting), ``y`` (northing), ``z`` (elevation, height) and ``sigma`` (sd, std:
  metres, each point's survey 1σ, taken as 3-D); a point ``id`` column may be there and is kept for
  messages. Commas, semicolons or tabs.
- Each plane needs ≥ 3 points that are not on one line (spread ≥ ``MIN_SPREAD_M`` across), lying
  on one plane (each within ``MAX_MISFIT_SIGMAS`` σ plus ``MISFIT_ALLOWANCE_M`` of the plane the
  others fit); the patch is the polygon they span (their convex hull), so survey its corners or
  points near its edges. Steeper than ``MAX_SLOPE_DEG``: a wall, not a surface a strip's points
  cover from above.
- x, y, z are in the CRS of the strips unless ``--control-crs`` names another.

Every error names the file, the line and the field.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np

from calidar.errors import InputError
from calidar.io.checkpoints import MAX_COORDINATE, MAX_SIGMA_M, _norm, _number, _rows
from calidar.io.checkpoints import _columns as _checkpoint_columns

MIN_POINTS = 3
MIN_SPREAD_M = 1.0  #: the points' smaller horizontal spread (2σ of their second principal axis)
MAX_MISFIT_SIGMAS = 4.0
MISFIT_ALLOWANCE_M = 0.02  #: a roof is planar to a couple of centimetres, not to the survey's σ
MAX_SLOPE_DEG = 60.0
MAX_PLANES = 10_000

COLUMNS = {
    "plane": ("plane", "planeid", "surface", "surfaceid", "patch", "facet", "roof", "roofid"),
    "id": ("id", "point", "pointid", "name", "label", "pt"),
    "x": ("x", "easting", "east", "e"),
    "y": ("y", "northing", "north", "n"),
    "z": ("z", "elevation", "elev", "height", "h"),
    "sigma": ("sigma", "sigmam", "sd", "std", "stddev", "accuracy"),
}
REQUIRED = ("plane", "x", "y", "z", "sigma")


@dataclass(frozen=True, eq=False)
class ControlPlaneFile:
    """The surveyed points of a control-surface file, in file order, and the plane each is on."""

    path: Path
    plane: np.ndarray  #: (N,) str, the plane's id of each point
    xyz: np.ndarray  #: (N, 3) in the CRS they were surveyed in
    sigma_m: np.ndarray  #: (N,) survey 1σ (m)
    lines: np.ndarray  #: (N,) line number of each (1-based)

    def planes(self) -> list[str]:
        """The planes' ids in the order they first appear."""
        return list(dict.fromkeys(self.plane.tolist()))


def is_plane_file(path: str | Path) -> bool:
    """Whether the CSV at ``path`` is a control-surface file (its header names a plane column)."""
    try:
        _, header = next(_rows(Path(path)))
    except StopIteration:
        return False
    return any(_norm(h) in COLUMNS["plane"] for h in header)


def _columns(header: list[str], path: Path, line: int) -> dict[str, int]:
    """The plane file's columns (:func:`calidar.io.checkpoints._columns` with this file's names)."""
    return _checkpoint_columns(header, path, line, REQUIRED, COLUMNS, "plane, x, y, z and sigma")


def read_control_planes(path: str | Path) -> ControlPlaneFile:
    """Read and check a control-surface CSV (see the module docstring)."""
    path = Path(path)
    rows = _rows(path)
    head_line, header = next(rows)
    cols = _columns(header, path, head_line)
    plane, xyz, sigma, lines = [], [], [], []
    for number, cells in rows:
        name, point, s = _point(cells, cols, header, path, number)
        plane.append(name)
        xyz.append(point)
        sigma.append(s)
        lines.append(number)
    if not plane:
        raise InputError(path, None, f"a header (line {head_line}) but no points; expected "
                         f"≥ {MIN_POINTS} surveyed points per plane")
    out = ControlPlaneFile(path, np.asarray(plane, str), np.asarray(xyz, float),
                           np.asarray(sigma, float), np.asarray(lines, np.int64))
    if len(out.planes()) > MAX_PLANES:
        raise InputError(path, "plane", f"{len(out.planes())} planes; expected ≤ {MAX_PLANES}")
    # the geometry is checked in a metric frame (check_plane), once placed
    for name in out.planes():
        k = np.flatnonzero(out.plane == name)
        if k.size < MIN_POINTS:
            raise InputError(path, "plane", f"line {int(out.lines[k[0]])}: plane {name!r} has "
                             f"{k.size} point(s); expected ≥ {MIN_POINTS} surveyed points on it")
    return out


def _point(cells: list[str], cols: dict[str, int], header: list[str], path: Path,
           number: int) -> tuple[str, list[float], float]:
    """One line's surveyed point: its plane's id, [x, y, z] and its σ (m, > 0)."""
    if len(cells) < len(header):
        raise InputError(path, None, f"line {number}: {len(cells)} values, expected {len(header)} "
                         f"(as the header {','.join(header)!r})")
    name = cells[cols["plane"]].strip()
    if not name:
        raise InputError(path, "plane",
                         f"line {number}: expected the plane's id, got an empty value")
    point = [_number(cells[cols[k]], path, number, k, MAX_COORDINATE) for k in ("x", "y", "z")]
    s = _number(cells[cols["sigma"]], path, number, "sigma", MAX_SIGMA_M)
    if s <= 0:
        raise InputError(path, "sigma", f"line {number}: expected a survey σ > 0 m, got {s:g}")
    return name, point, s


def fit_plane(xyz: np.ndarray, sigma: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The weighted least-squares plane z = a + b·dx + c·dy through points ``xyz`` (k, 3) of 3-D σ
    ``sigma`` (k,), dx, dy from their weighted centroid: the centroid (3,), (a, b, c) and their
    covariance (3, 3) m², the points' errors taken along the normal (a 3-D σ moves a point off a
    plane of slope s by σ along its normal, σ·√(1 + s²) in height: the first pass's slope used)."""
    w = 1.0 / np.asarray(sigma, float) ** 2
    c = np.sum(w[:, None] * xyz, axis=0) / w.sum()
    d = xyz - c
    X = np.c_[np.ones(len(d)), d[:, 0], d[:, 1]]
    for _ in range(2):  # the height σ depends on the slope: once with σ, once with σ·√(1 + s²)
        N = X.T @ (w[:, None] * X)
        coef = np.linalg.solve(N, X.T @ (w * xyz[:, 2]))
        w = 1.0 / (np.asarray(sigma, float) ** 2 * (1.0 + coef[1] ** 2 + coef[2] ** 2))
    N = X.T @ (w[:, None] * X)
    coef = np.linalg.solve(N, X.T @ (w * xyz[:, 2]))
    return c, coef, np.linalg.inv(N)


def check_plane(f: ControlPlaneFile, k: np.ndarray, xyz: np.ndarray) -> None:
    """An error naming the plane (and the line of its worst point) of ``f`` whose points ``k`` at
    ``xyz`` (metric: the file's or the strips' frame) do not make a plane as the module docstring
    asks."""
    name, first = f.plane[k[0]], int(f.lines[k[0]])
    d = xyz[:, :2] - xyz[:, :2].mean(axis=0)
    spread = 2.0 * float(np.sqrt(max(np.linalg.eigvalsh(d.T @ d / k.size)[0], 0.0)))
    if spread < MIN_SPREAD_M:
        raise InputError(f.path, "x/y", f"line {first}: the points of plane {str(name)!r} lie "
                         f"along a line (spread {spread:.2f} m across); expected points around "
                         f"the patch, ≥ {MIN_SPREAD_M:g} m apart both ways")
    _, coef, _ = fit_plane(xyz, f.sigma_m[k])
    slope = float(np.degrees(np.arctan(np.hypot(coef[1], coef[2]))))
    if slope > MAX_SLOPE_DEG:
        raise InputError(f.path, "z", f"line {first}: plane {str(name)!r} slopes {slope:.0f}°; "
                         f"expected a roof or ground plane ≤ {MAX_SLOPE_DEG:g}° (a wall is not "
                         "seen from above)")
    if k.size > MIN_POINTS:
        miss, sd = _leave_one_out(xyz, f.sigma_m[k])
        limit = MAX_MISFIT_SIGMAS * sd + MISFIT_ALLOWANCE_M
        worst = int(np.argmax(miss / limit))
        if miss[worst] > limit[worst]:
            line = int(f.lines[k[worst]])
            raise InputError(f.path, "z", f"line {line}: point {worst + 1} of plane {str(name)!r} "
                             f"is {miss[worst] * 100:.1f} cm off the plane the others make; "
                             f"expected ≤ {limit[worst] * 100:.1f} cm (points on one plane)")


def _leave_one_out(xyz: np.ndarray, sigma: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Each point's distance (m, along the normal) from the plane its k − 1 fellows fit, and that
    distance's σ: the point's own and the fellows' plane's there (a short ridge's two corners
    tell the plane's tilt across the facet poorly)."""
    miss, sd = np.zeros(len(xyz)), np.zeros(len(xyz))
    for j in range(len(xyz)):
        rest = np.delete(np.arange(len(xyz)), j)
        c, coef, cov = fit_plane(xyz[rest], sigma[rest])
        d = xyz[j] - c
        nz2 = 1.0 / (1.0 + coef[1] ** 2 + coef[2] ** 2)
        g = np.r_[1.0, d[0], d[1]]
        miss[j] = abs(d[2] - coef[1] * d[0] - coef[2] * d[1]) * np.sqrt(nz2)
        sd[j] = np.sqrt(sigma[j] ** 2 + nz2 * float(g @ cov @ g))
    return miss, sd


def write_control_planes(path: str | Path, plane, xyz, sigma_m, comment: str | None = None,
                         force: bool = False) -> Path:
    """Write a control-surface CSV that :func:`read_control_planes` reads (mm resolution),
    atomically."""
    from calidar.outputs import write_text_atomic

    xyz = np.asarray(xyz, float)
    out = [f"# {c}" for c in (comment or "").splitlines()]
    out.append("plane,x,y,z,sigma")
    sigma = np.asarray(sigma_m)
    out += [f"{name},{xyz[k, 0]:.3f},{xyz[k, 1]:.3f},{xyz[k, 2]:.3f},{float(sigma[k]):.4f}"
            for k, name in enumerate(plane)]
    return write_text_atomic(path, "\n".join(out) + "\n", force)
