"""The surveyed CCRs: reading the survey CSV, and each CCR's position in a pass's track.

A CCR survey is ``id,lat,lon,height`` (deg, deg, m above ground) or ``id,x,y,height`` (m along
track, m cross-track left of ONE pass's reported track, m). A pass's track is not straight over
thousands of km, so each CCR is placed on a straight track line fitted to the photons within
``local_m`` of the photon nearest to it (over a few km a ground track is straight to millimetres).
"""

from __future__ import annotations

import csv
import io
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from calidar.errors import InputError
from calidar.frames import geodetic_to_ecef
from calidar.photon.track import TrackLine
from calidar.validate import number, read_text

CCR_COLUMNS = ({"id", "lat", "lon", "height"}, {"id", "x", "y", "height"})
EXPECTED = "id,lat,lon,height or id,x,y,height"
RANGES = {"lat": (-90.0, 90.0, "deg"), "lon": (-180.0, 360.0, "deg"), "height": (-5.0, 100.0, "m above ground"),
          "x": (-1e8, 1e8, "m"), "y": (-1e4, 1e4, "m")}


@dataclass
class CCRSurvey:
    """Surveyed CCRs: geodetic (rad) or track (m) positions, and pole heights above ground (m)."""

    ids: list[str]
    height: np.ndarray
    lat: np.ndarray | None = None
    lon: np.ndarray | None = None
    x: np.ndarray | None = None
    y: np.ndarray | None = None
    source: str | None = None

    def in_track(self, x_m: np.ndarray, lat_rad: np.ndarray, lon_rad: np.ndarray, local_m: float = 1000.0,
                 subsample: int = 20) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """(along-track x, cross-track y left positive, distance to the nearest photon) of every
        CCR (m) in the track of a pass whose photons are at along-track ``x_m`` and lat/lon (rad).
        The nearest photon is searched on every ``subsample``-th photon (a few m apart)."""
        if self.lat is None:
            return self.x, self.y, np.zeros(len(self.ids))
        step = max(1, int(subsample))
        pts = geodetic_to_ecef(lat_rad[::step], lon_rad[::step], 0.0)
        ccr = geodetic_to_ecef(self.lat, self.lon, 0.0)
        xk, yk, dist = (np.full(len(self.ids), np.nan) for _ in range(3))
        order = np.argsort(x_m, kind="stable") if np.any(np.diff(x_m) < 0) else None
        xs = x_m if order is None else x_m[order]
        for k in range(len(self.ids)):
            d2 = np.einsum("ij,ij->i", pts - ccr[k], pts - ccr[k])
            i = int(np.argmin(d2)) * step
            dist[k] = float(np.sqrt(d2.min()))
            lo, hi = np.searchsorted(xs, [x_m[i] - local_m, x_m[i] + local_m])
            near = slice(lo, hi) if order is None else order[lo:hi]
            if hi - lo < 10:
                continue
            line = TrackLine.fit(x_m[near], lat_rad[near], lon_rad[near])
            a, b = line.to_track(self.lat[k:k + 1], self.lon[k:k + 1])
            xk[k], yk[k] = a[0], b[0]
        return xk, yk, dist


def read_ccr_csv(path: str | Path) -> CCRSurvey:
    """Read a CCR survey CSV (see the module docstring); every value checked, errors name the
    file, the line and the column."""
    path = Path(path)
    rows = list(csv.reader(io.StringIO(read_text(path, "CCR survey CSV"))))
    if not rows:
        raise InputError(path, "header", f"empty file; expected {EXPECTED}")
    header = [c.strip().lower() for c in rows[0]]
    cols = set(header)
    unknown = sorted(cols - {"id", "lat", "lon", "x", "y", "height"})
    if unknown or cols not in CCR_COLUMNS or len(cols) != len(header):
        what = f"unknown column(s) {', '.join(unknown)}" if unknown else f"columns {','.join(header)}"
        raise InputError(path, "header", f"{what}; expected {EXPECTED}")
    data = [(n, r) for n, r in enumerate(rows[1:], start=2) if any(c.strip() for c in r)]
    if not data:
        raise InputError(path, "rows", "no CCRs listed")
    vals = {c: [] for c in header}
    for n, r in data:
        if len(r) != len(header):
            raise InputError(path, f"line {n}", f"expected {len(header)} values, got {len(r)}")
        for c, v in zip(header, r):
            if c == "id":
                vals[c].append(v.strip())
            else:
                vals[c].append(number(v.strip(), path, *RANGES[c][:2], RANGES[c][2], field=f"line {n}: {c}"))
    if len(set(vals["id"])) != len(vals["id"]) or "" in vals["id"]:
        raise InputError(path, "id", "expected a unique, non-empty id per CCR")
    height = np.asarray(vals["height"])
    if "lat" in cols:
        lat, lon = np.asarray(vals["lat"]), np.asarray(vals["lon"])
        return CCRSurvey(vals["id"], height, lat=np.radians(lat), lon=np.radians(lon), source=str(path))
    return CCRSurvey(vals["id"], height, x=np.asarray(vals["x"]), y=np.asarray(vals["y"]), source=str(path))
