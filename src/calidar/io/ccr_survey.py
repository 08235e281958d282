"""The CCR survey CSV of ``calidar ccr``: the surveyed corner-cube retroreflectors, read, checked.

A CCR survey is ``id,lat,lon,height`` (deg, deg, m above ground) or ``id,x,y,height`` (m along
track, m cross-track left of ONE pass's reported track, m). Every value is range-checked; errors
name the file, the line and the column. The reader returns typed arrays (:class:`CCRSurveyRows`);
placing each CCR on a pass's track is the method's (:class:`calidar.photon.survey.CCRSurvey`).

>>> import tempfile
>>> path = Path(tempfile.mkdtemp()) / "ccr.csv"
>>> _ = path.write_text("id,lat,lon,height\\nA,32.4,-106.4,2.0\\nB,32.41,-106.4,2.5\\n")
>>> rows = read_ccr_survey(path)
>>> rows.ids, rows.height.tolist(), rows.x is None
(['A', 'B'], [2.0, 2.5], True)
"""

from __future__ import annotations

import csv
import io
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from calidar.errors import InputError
from calidar.validate import number, read_text

CCR_COLUMNS = ({"id", "lat", "lon", "height"}, {"id", "x", "y", "height"})
EXPECTED = "id,lat,lon,height or id,x,y,height"
#: each numeric column's (lowest, highest, unit) accepted
RANGES = {
    "lat": (-90.0, 90.0, "deg"),
    "lon": (-180.0, 360.0, "deg"),
    "height": (-5.0, 100.0, "m above ground"),
    "x": (-1e8, 1e8, "m"),
    "y": (-1e4, 1e4, "m"),
}


@dataclass(frozen=True)
class CCRSurveyRows:
    """A CCR survey file's rows: ids, pole heights above ground (m) and either geodetic positions
    (``lat``, ``lon``, rad) or track positions (``x`` along, ``y`` cross-track left, m)."""

    ids: list[str]
    height: np.ndarray
    lat: np.ndarray | None = None
    lon: np.ndarray | None = None
    x: np.ndarray | None = None
    y: np.ndarray | None = None
    source: str | None = None  #: the file's path


def _header(path: Path, rows: list[list[str]]) -> list[str]:
    if not rows:
        raise InputError(path, "header", f"empty file; expected {EXPECTED}")
    header = [c.strip().lower() for c in rows[0]]
    cols = set(header)
    unknown = sorted(cols - {"id", "lat", "lon", "x", "y", "height"})
    if unknown or cols not in CCR_COLUMNS or len(cols) != len(header):
        if unknown:
            what = f"unknown column(s) {', '.join(unknown)}"
        else:
            what = f"columns {','.join(header)}"
        raise InputError(path, "header", f"{what}; expected {EXPECTED}")
    return header


def _value(path: Path, line: int, column: str, text: str) -> float:
    """One numeric cell, checked against the column's range (errors name the line and column)."""
    low, high, unit = RANGES[column]
    return number(text.strip(), path, low, high, unit, field=f"line {line}: {column}")


def read_ccr_survey(path: str | Path) -> CCRSurveyRows:
    """Read a CCR survey CSV (see the module docstring); every value checked, errors name the
    file, the line and the column."""
    path = Path(path)
    rows = list(csv.reader(io.StringIO(read_text(path, "CCR survey CSV"))))
    header = _header(path, rows)
    data = [(n, r) for n, r in enumerate(rows[1:], start=2) if any(c.strip() for c in r)]
    if not data:
        raise InputError(path, "rows", "no CCRs listed")
    vals: dict[str, list] = {c: [] for c in header}
    for n, r in data:
        if len(r) != len(header):
            raise InputError(path, f"line {n}", f"expected {len(header)} values, got {len(r)}")
        for c, v in zip(header, r):
            vals[c].append(v.strip() if c == "id" else _value(path, n, c, v))
    if len(set(vals["id"])) != len(vals["id"]) or "" in vals["id"]:
        raise InputError(path, "id", "expected a unique, non-empty id per CCR")
    height = np.asarray(vals["height"])
    if "lat" in header:
        return CCRSurveyRows(vals["id"], height, lat=np.radians(np.asarray(vals["lat"])),
                             lon=np.radians(np.asarray(vals["lon"])), source=str(path))
    x, y = np.asarray(vals["x"]), np.asarray(vals["y"])
    return CCRSurveyRows(vals["id"], height, x=x, y=y, source=str(path))
