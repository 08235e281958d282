"""Planned flight lines (``calidar plan``): a CSV or a GeoJSON file.

CSV (one line per row, a header naming the columns, any order, ``#`` comments)::

    line,start_x,start_y,end_x,end_y,height_agl_m,speed_mps
    1,-60,-80,-60,80,80,8

- ``line``: a positive integer, unique (optional: 1, 2, … in file order);
- ``start_x``, ``start_y``, ``end_x``, ``end_y``: where scanning starts and ends, projected metres
  (east, north) in the terrain's frame (the DEM's CRS; the built-in scene's and flat terrain's:
  metres east and north of the centre);
- ``height_agl_m``: height above ground (> 0 m, above the mean terrain height under the line);
- ``speed_mps``: ground speed (> 0 m/s).

GeoJSON: a FeatureCollection of LineString features (first and last vertex: start and end),
coordinates in the same projected metres, with ``height_agl_m``, ``speed_mps`` and optionally
``line`` in each feature's properties.
"""

from __future__ import annotations

import csv
import json
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from calidar.errors import InputError

COLUMNS = ("start_x", "start_y", "end_x", "end_y", "height_agl_m", "speed_mps")
MIN_LENGTH_M = 10.0  #: a shorter line is rather degrees than metres, or a typo
MAX_HEIGHT_M = 10_000.0
MAX_SPEED_MPS = 150.0
MAX_LINES = 200


@dataclass(frozen=True)
class PlanLine:
    """One planned scanning line in the terrain's projected frame (m)."""

    number: int
    start: np.ndarray  #: (2,) east, north m
    end: np.ndarray  #: (2,) east, north m
    height_agl_m: float
    speed_mps: float

    @property
    def length_m(self) -> float:
        return float(np.linalg.norm(self.end - self.start))

    @property
    def direction(self) -> np.ndarray:
        """Unit vector (2,) of the flight direction."""
        return (self.end - self.start) / self.length_m

    @property
    def azimuth(self) -> float:
        """Flight direction, rad clockwise from north."""
        d = self.direction
        return float(np.arctan2(d[0], d[1]))

    def to_json(self) -> str:
        """The line as a hashable key (its fields)."""
        ends = f"{self.start.tolist()},{self.end.tolist()}"
        return f"{self.number},{ends},{self.height_agl_m},{self.speed_mps}"

    def to_dict(self) -> dict:
        """plan.json's entry: number, start and end (m), height above ground (m), speed (m/s)."""
        return {"line": self.number, "start": [float(v) for v in self.start],
                "end": [float(v) for v in self.end], "height_agl_m": self.height_agl_m,
                "speed_mps": self.speed_mps}


def read_flight_lines(path: str | Path) -> list[PlanLine]:
    """Flight lines from a CSV or GeoJSON file (by content: a JSON object, else CSV)."""
    path = Path(path)
    try:
        text = path.read_text(encoding="utf-8-sig")
    except FileNotFoundError:
        raise InputError(path, "file",
                         "not found; expected a flight-line CSV or GeoJSON file") from None
    except (OSError, UnicodeDecodeError) as e:
        raise InputError(path, "file", f"cannot be read as text ({e.__class__.__name__}); "
                         "expected a CSV or GeoJSON") from None
    rows = _geojson_rows(path, text) if text.lstrip().startswith("{") else _csv_rows(path, text)
    if not rows:
        raise InputError(path, "lines", "no flight line found; expected at least one")
    if len(rows) > MAX_LINES:
        raise InputError(path, "lines", f"{len(rows)} lines; expected at most {MAX_LINES}")
    lines = [_line(path, where, k + 1, row) for k, (where, row) in enumerate(rows)]
    numbers = [ln.number for ln in lines]
    if len(set(numbers)) != len(numbers):
        dup = sorted({n for n in numbers if numbers.count(n) > 1})[0]
        raise InputError(path, "line", f"line number {dup} appears twice; expected unique numbers")
    return lines


def _csv_rows(path: Path, text: str) -> list[tuple[str, dict]]:
    """(where, {column: text}) of each line of a flight-line CSV."""
    body = [ln for ln in text.splitlines() if ln.strip() and not ln.lstrip().startswith("#")]
    if not body:
        raise InputError(path, "header",
                         f"empty; expected a header with columns {', '.join(COLUMNS)}")
    reader = csv.DictReader(body)
    header = [h.strip() for h in reader.fieldnames or []]
    missing = [c for c in COLUMNS if c not in header]
    if missing:
        raise InputError(path, "header", f"missing column(s) {', '.join(missing)}; expected "
                         f"{', '.join(COLUMNS)} (and optionally line), got "
                         f"{', '.join(header) or 'nothing'}")
    out = []
    for k, row in enumerate(reader):
        row = {(key or "").strip(): (v or "").strip() for key, v in row.items() if key is not None}
        out.append((f"row {k + 1}", row))
    return out


def _geojson_rows(path: Path, text: str) -> list[tuple[str, dict]]:
    """(where, {field: value}) of each LineString feature of a GeoJSON FeatureCollection: its
    first and last positions and its properties."""
    try:
        doc = json.loads(text)
    except json.JSONDecodeError as e:
        raise InputError(path, "json", f"not valid JSON ({e.msg} at line {e.lineno}); expected a "
                         "GeoJSON FeatureCollection") from None
    feats = doc.get("features") if isinstance(doc, dict) else None
    if not isinstance(feats, list):
        raise InputError(path, "features",
                         "missing; expected a GeoJSON FeatureCollection of LineString features")
    out = []
    for k, f in enumerate(feats):
        where = f"feature {k + 1}"
        geom = f.get("geometry") if isinstance(f, dict) else None
        coords = geom.get("coordinates") if isinstance(geom, dict) else None
        line_string = isinstance(geom, dict) and geom.get("type") == "LineString"
        if not line_string or not isinstance(coords, list) or len(coords) < 2:
            raise InputError(path, f"{where} geometry",
                             "expected a LineString with at least two positions")
        props = f.get("properties") or {}
        if not isinstance(props, dict):
            raise InputError(path, f"{where} properties",
                             "expected an object with height_agl_m and speed_mps")
        try:
            (sx, sy), (ex, ey) = coords[0][:2], coords[-1][:2]
        except (TypeError, ValueError):
            raise InputError(path, f"{where} coordinates",
                             "expected [x, y] positions in projected metres") from None
        row = {"start_x": sx, "start_y": sy, "end_x": ex, "end_y": ey, **props}
        out.append((where, row))
    return out


def _line(path: Path, where: str, default_number: int, row: dict) -> PlanLine:
    """The checked flight line of one row: numbers finite, the line number a LAS
    point_source_id, height and speed in range, the line long enough to be in metres."""
    vals = {}
    for c in COLUMNS:
        v = row.get(c)
        if v is None or v == "":
            raise InputError(path, f"{where} {c}", "missing; expected a number")
        try:
            vals[c] = float(v)
        except (TypeError, ValueError):
            raise InputError(path, f"{where} {c}", f"expected a number, got {v!r}") from None
        if not np.isfinite(vals[c]):
            raise InputError(path, f"{where} {c}", f"expected a finite number, got {v!r}")
    number = row.get("line", default_number)
    try:
        number = int(str(number))
    except ValueError:
        raise InputError(path, f"{where} line",
                         f"expected a positive integer, got {number!r}") from None
    if not 1 <= number <= 65535:
        raise InputError(path, f"{where} line", "expected a positive integer ≤ 65535 (a LAS "
                         f"point_source_id), got {number}")
    h, v = vals["height_agl_m"], vals["speed_mps"]
    if not 0 < h <= MAX_HEIGHT_M:
        raise InputError(path, f"{where} height_agl_m", "expected a height above ground in "
                         f"(0, {MAX_HEIGHT_M:g}] m, got {h:g}")
    if not 0 < v <= MAX_SPEED_MPS:
        raise InputError(path, f"{where} speed_mps",
                         f"expected a ground speed in (0, {MAX_SPEED_MPS:g}] m/s, got {v:g}")
    start = np.array([vals["start_x"], vals["start_y"]])
    end = np.array([vals["end_x"], vals["end_y"]])
    length_m = np.linalg.norm(end - start)
    if length_m < MIN_LENGTH_M:
        raise InputError(path, f"{where} end_x/end_y", f"the line is {length_m:.3g} m long; "
                         f"expected ≥ {MIN_LENGTH_M:g} m in projected metres (not degrees)")
    return PlanLine(number, start, end, h, v)


def flight_lines_csv(lines: list[PlanLine]) -> str:
    """The CSV text of ``lines`` (what :func:`read_flight_lines` reads back)."""
    out = ["line," + ",".join(COLUMNS)]
    for ln in lines:
        ends = f"{ln.start[0]:.2f},{ln.start[1]:.2f},{ln.end[0]:.2f},{ln.end[1]:.2f}"
        out.append(f"{ln.number},{ends},{ln.height_agl_m:g},{ln.speed_mps:g}")
    return "\n".join(out) + "\n"
