"""Reading a total-station observation file (format: :mod:`calidar.io.total_station`): every
error names the file, the line, the field and what was expected."""

from __future__ import annotations

import csv
import math
import re
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from calidar.errors import InputError
from calidar.io.total_station.observations import (
    ANGLE_UNITS, ARCSEC, BASE_COLUMNS, FEATURE_POINTS, FORMAT_LINE, FULL_CIRCLE, MAX_DISTANCE_M,
    MAX_FILE_BYTES, MAX_SETUPS, MAX_TARGETS, Setup, TotalStationObservations,
)
from calidar.validate import existing_file, read_text


def _float(text: str, src: str, line: int, field: str, what: str) -> float:
    """The finite number in ``text``, else an error naming the line, the field and ``what``."""
    try:
        v = float(text)
    except ValueError:
        raise InputError(src, f"line {line}: {field}", f"expected {what}, got {text!r}") from None
    if not math.isfinite(v):
        raise InputError(src, f"line {line}: {field}", f"expected {what}, got {text!r}")
    return v


def _parse_setup(value: str, src: str, line: int) -> dict:
    """A ``#! setup:`` directive's id and σ (angle rad, distance m and ppm)."""
    parts = value.split()
    need = ("angle_arcsec", "distance_mm", "distance_ppm")
    expect = "'ID angle_arcsec=a distance_mm=b distance_ppm=c'"
    if not parts or "=" in parts[0]:
        raise InputError(src, f"line {line}: setup", f"expected {expect}, got {value!r}")
    kv = {}
    for p in parts[1:]:
        k, eq, v = p.partition("=")
        where = f"line {line}: setup {parts[0]}"
        if not eq or k not in need:
            raise InputError(src, where, f"unknown item {p!r}; expected {expect}")
        kv[k] = _float(v, src, line, f"setup {parts[0]}: {k}", "a number")
        if kv[k] < 0 or (k != "distance_ppm" and kv[k] == 0):
            raise InputError(src, f"{where}: {k}", f"expected a positive number, got {v}")
    missing = [k for k in need if k not in kv]
    if missing:
        raise InputError(src, f"line {line}: setup {parts[0]}",
                         f"missing {', '.join(missing)}; expected {expect}")
    return {"id": parts[0], "angle_sigma": kv["angle_arcsec"] * ARCSEC,
            "distance_sigma_m": kv["distance_mm"] * 1e-3,
            "distance_sigma_ppm": kv["distance_ppm"], "line": line}


EXPECTED_COLUMNS = ("setup, group, point, hz_<deg|gon>, va_<deg|gon> or zd_<deg|gon>, slope_m, "
                    "scanner_m")


def _angle_columns(cells: list[str], src: str, line: int) -> dict[str, tuple[str, str]]:
    """The header's angle columns: {"hz" | "va" | "zd": (column, unit)}; an error for an unknown
    column or unit, or a second hz or vertical column."""
    where = f"line {line}: header"
    angle = {}
    for c in cells:
        m = re.fullmatch(r"(hz|va|zd)_(\w+)", c)
        if c in BASE_COLUMNS:
            continue
        if m and m.group(2) in ANGLE_UNITS:
            kind = m.group(1)
            if kind in angle or (kind in ("va", "zd") and ({"va", "zd"} & angle.keys())):
                what = "hz" if kind == "hz" else "vertical (va_ or zd_)"
                raise InputError(src, where,
                                 f"more than one {what} column; expected {EXPECTED_COLUMNS}")
            angle[kind] = (c, m.group(2))
        elif m:
            raise InputError(src, f"{where}: {c}",
                             f"unknown angle unit {m.group(2)!r}; expected deg or gon")
        else:
            raise InputError(src, where, f"unknown column {c!r}; expected {EXPECTED_COLUMNS}")
    return angle


def _parse_header(cells: list[str], src: str, line: int) -> tuple[dict[str, int], str, str]:
    """Column positions, the angle unit and the vertical convention ("va" | "zd") from the
    header."""
    cells = [c.strip() for c in cells]
    where = f"line {line}: header"
    for sep in (";", "\t"):
        if len(cells) == 1 and sep in cells[0]:
            raise InputError(src, where, f"the columns are separated by {sep!r}; expected commas "
                             "(with a decimal point)")
    angle = _angle_columns(cells, src, line)
    missing = [c for c in BASE_COLUMNS if c not in cells]
    if "hz" not in angle:
        missing.append("hz_<deg|gon>")
    if not {"va", "zd"} & angle.keys():
        missing.append("va_<deg|gon> or zd_<deg|gon>")
    if missing:
        raise InputError(src, where,
                         f"missing column(s) {', '.join(missing)}; expected {EXPECTED_COLUMNS}")
    if len(set(cells)) != len(cells):
        raise InputError(src, where, f"a column appears twice; expected {EXPECTED_COLUMNS}")
    vertical = "va" if "va" in angle else "zd"
    units = {angle["hz"][1], angle[vertical][1]}
    if len(units) > 1:
        raise InputError(src, where, f"mixed angle units ({angle['hz'][0]} and "
                         f"{angle[vertical][0]}); expected both angle columns in deg or both in "
                         "gon")
    cols = {c: i for i, c in enumerate(cells)}
    cols["hz"] = cols[angle["hz"][0]]
    cols["v"] = cols[angle[vertical][0]]
    return cols, units.pop(), vertical


@dataclass
class _Parsed:
    """What the line scan found: directives (value, line), setups, the header and the data rows."""

    directives: dict = field(default_factory=dict)
    setups: dict = field(default_factory=dict)
    header: tuple | None = None
    header_line: int = 0
    rows: list = field(default_factory=list)


def _directive(parsed: _Parsed, text: str, src: str, no: int) -> None:
    """One ``#!`` line into ``parsed``."""
    if parsed.header is not None:
        raise InputError(src, f"line {no}", "expected directives (#!) before the header row")
    body = text[2:].strip()
    if body.startswith("calidar-total-station"):
        if body != FORMAT_LINE:
            raise InputError(src, f"line {no}", f"expected '#! {FORMAT_LINE}', got {text!r}")
        parsed.directives["format"] = (body, no)
        return
    key, colon, value = body.partition(":")
    key, value = key.strip(), value.strip()
    if not colon or key not in ("scanner_sigma_mm", "setup"):
        raise InputError(src, f"line {no}", "unknown directive; expected '#! calidar-total-station "
                         f"1', '#! scanner_sigma_mm: S' or '#! setup: ID ...', got {text!r}")
    if key == "setup":
        s = _parse_setup(value, src, no)
        if s["id"] in parsed.setups:
            first = parsed.setups[s["id"]]["line"]
            raise InputError(src, f"line {no}: setup {s['id']}",
                             f"declared twice (first on line {first})")
        if len(parsed.setups) >= MAX_SETUPS:
            raise InputError(src, f"line {no}: setup", f"more than {MAX_SETUPS} setups; expected "
                             f"at most {MAX_SETUPS} (the adjustment's memory grows with setups × "
                             "targets)")
        parsed.setups[s["id"]] = s
        return
    if key in parsed.directives:
        first = parsed.directives[key][1]
        raise InputError(src, f"line {no}: {key}", f"given twice (first on line {first})")
    parsed.directives[key] = (value, no)


def _scan(lines: list[str], src: str) -> _Parsed:
    """Directives, header and data rows of the file's lines (comments and blank lines skipped)."""
    parsed = _Parsed()
    for no, raw in enumerate(lines, start=1):
        text = raw.strip()
        if text.startswith("#!"):
            _directive(parsed, text, src, no)
        elif not text or text.startswith("#"):
            continue
        elif parsed.header is None:
            parsed.header = _parse_header(next(csv.reader([raw])), src, no)
            parsed.header_line = no
        else:
            parsed.rows.append((no, [c.strip() for c in next(csv.reader([raw]))]))
            if len(parsed.rows) > MAX_TARGETS + MAX_SETUPS:
                raise InputError(src, f"line {no}", f"more than {MAX_TARGETS} targets; expected at "
                                 f"most {MAX_TARGETS} (the adjustment's memory grows with them)")
    return parsed


def _scanner_sigma(parsed: _Parsed, src: str, n_lines: int) -> float:
    """The checked ``scanner_sigma_mm`` directive (m), after the format line and before the
    header."""
    end = parsed.header_line or n_lines + 1  # directives are missing before this line
    if "format" not in parsed.directives:
        raise InputError(src, "line 1", f"expected the directive '#! {FORMAT_LINE}' (not a "
                         "calidar total-station file?)")
    if "scanner_sigma_mm" not in parsed.directives:
        raise InputError(src, f"line {end}", "expected the directive '#! scanner_sigma_mm: S' (1σ "
                         "scanner range noise, mm) before this line")
    text, line = parsed.directives["scanner_sigma_mm"]
    sigma = _float(text, src, line, "scanner_sigma_mm", "a positive number (mm)") * 1e-3
    if not 0 < sigma <= 1.0:
        raise InputError(src, f"line {line}: scanner_sigma_mm",
                         f"expected a positive number up to 1000 (mm), got {text}")
    if not parsed.setups:
        raise InputError(src, f"line {end}", "expected at least one '#! setup: ID angle_arcsec=a "
                         "distance_mm=b distance_ppm=c' directive before this line")
    return sigma


def read_observations(path: str | Path) -> TotalStationObservations:
    """Read and check an observation file (format in this module's docstring)."""
    src = str(path)
    size = existing_file(path, "total-station observation file").stat().st_size
    if size > MAX_FILE_BYTES:
        raise InputError(src, "size", f"expected at most {MAX_FILE_BYTES >> 20} MB "
                         f"(≤ {MAX_TARGETS} targets), got {size / 2**20:.0f} MB")
    lines = read_text(path, "total-station observation file").splitlines()
    parsed = _scan(lines, src)
    scanner_sigma = _scanner_sigma(parsed, src, len(lines))
    if parsed.header is None:
        raise InputError(src, f"line {len(lines) + 1}",
                         "expected a header row and observations; the file has none")
    if not parsed.rows:
        raise InputError(src, f"line {parsed.header_line}",
                         "expected observation rows after the header; there are none")
    return _parse_rows(src, parsed.rows, parsed.header, parsed.setups, scanner_sigma)


@dataclass(frozen=True)
class _Columns:
    """Where each value sits in a row, the angle unit and the vertical convention."""

    cols: dict[str, int]
    unit: str
    vertical: str  #: "va" | "zd"

    def angles(self, get: dict[str, str], src: str, no: int) -> tuple[float, float]:
        """(vertical angle, horizontal direction) in rad of a row, range-checked."""
        unit, full = self.unit, FULL_CIRCLE[self.unit]
        hz = _float(get["hz"], src, no, f"hz_{unit}", f"a horizontal direction in {unit}")
        if not 0.0 <= hz < full:
            raise InputError(src, f"line {no}: hz_{unit}", "angle out of range: expected "
                             f"0 ≤ hz < {full:g} {unit}, got {get['hz']}")
        vname = f"{self.vertical}_{unit}"
        lo, hi = (-full / 4, full / 4) if self.vertical == "va" else (0.0, full / 2)
        what = "vertical angle" if self.vertical == "va" else "zenith distance"
        v = _float(get["v"], src, no, vname, f"a {what} in {unit}")
        if not lo <= v <= hi:
            face = " (face I)" if self.vertical == "zd" else ""
            raise InputError(src, f"line {no}: {vname}", "angle out of range: expected "
                             f"{lo:g} ≤ {self.vertical} ≤ {hi:g} {unit}{face}, got {get['v']}")
        to_rad = ANGLE_UNITS[unit]
        return (v * to_rad if self.vertical == "va" else math.pi / 2 - v * to_rad), hz * to_rad


def _kind(pt: str, grp: str, src: str, no: int) -> str:
    """"feature" (A–D, in a group) or "E" (E…, no group) for a target row; anything else is an
    error."""
    if pt in FEATURE_POINTS:
        if not grp:
            raise InputError(src, f"line {no}: group", f"feature point {pt} needs a group id")
        return "feature"
    if pt.startswith("E") and len(pt) > 1:
        if grp:
            raise InputError(src, f"line {no}: group",
                             f"E point {pt} belongs to no group; expected an empty group")
        return "E"
    raise InputError(src, f"line {no}: point", f"expected P, A, B, C, D or E<name>, got {pt!r}")


def _parse_row(src: str, no: int, cells: list[str], columns: _Columns, setups: dict) -> tuple:
    """One data row → ("P", setup id, P observation) or ("target", target tuple)."""
    cols = columns.cols
    if len(cells) != len(cols) - 2:
        raise InputError(src, f"line {no}",
                         f"expected {len(cols) - 2} comma-separated values, got {len(cells)}")
    get = {k: cells[i] for k, i in cols.items()}
    sid, grp, pt = get["setup"], get["group"], get["point"]
    if sid not in setups:
        raise InputError(src, f"line {no}: setup",
                         f"{sid!r} is not declared; expected one of {', '.join(setups)}")
    va, hz = columns.angles(get, src, no)
    slope = _float(get["slope_m"], src, no, "slope_m", "a slope distance in m")
    if not 0 < slope <= MAX_DISTANCE_M:
        raise InputError(src, f"line {no}: slope_m", f"expected a distance in "
                         f"(0, {MAX_DISTANCE_M:g}] m, got {get['slope_m']}")
    if pt == "P":
        if grp or get["scanner_m"]:
            raise InputError(src, f"line {no}", "a P observation has no group and no scanner "
                             "range; expected both empty")
        return "P", sid, {"p_slope": slope, "p_va": va, "p_hz": hz, "line": no}
    kind = _kind(pt, grp, src, no)
    scan = _float(get["scanner_m"], src, no, "scanner_m", f"the scanner range of {pt} in m")
    if not 0 < scan <= MAX_DISTANCE_M:
        raise InputError(src, f"line {no}: scanner_m", f"expected a range in "
                         f"(0, {MAX_DISTANCE_M:g}] m, got {get['scanner_m']}")
    return "target", (list(setups).index(sid), grp, pt, kind, slope, va, hz, scan, no)


def _check_groups(src: str, group_rows: dict[str, list]) -> None:
    """Every group: one each of A, B, C, D, all from one setup."""
    for grp, members in group_rows.items():
        seen = {}
        for pt, sid, no in members:
            if pt in seen:
                raise InputError(src, f"line {no}: group {grp}", f"second point {pt} (first on "
                                 f"line {seen[pt]}); expected one each of A, B, C, D")
            seen[pt] = no
            if sid != members[0][1]:
                raise InputError(src, f"line {no}: group {grp}", f"setup {sid} differs from "
                                 f"{members[0][1]} on line {members[0][2]}; expected one setup "
                                 "per group")
        missing = [p for p in FEATURE_POINTS if p not in seen]
        if missing:
            raise InputError(src, f"line {members[-1][2]}: group {grp}",
                             f"missing point(s) {', '.join(missing)}; expected A, B, C and D")


def _check_setups(src: str, setups: dict, p_obs: dict, targets: list) -> None:
    """Every setup has its P observation and at least one target."""
    setup_ids = list(setups)
    used = {t[0] for t in targets}
    for sid, s in setups.items():
        if sid not in p_obs:
            rows_of = [t[8] for t in targets if setup_ids[t[0]] == sid]
            where = f"line {rows_of[0]}" if rows_of else f"line {s['line']}"
            raise InputError(src, f"{where}: setup {sid}", "missing its P observation (the mirror "
                             "centre); expected one row with point P")
        if setup_ids.index(sid) not in used:
            raise InputError(src, f"line {s['line']}: setup {sid}",
                             "has no targets; expected feature or E points observed from it")


def _parse_rows(src, rows, header, setups, scanner_sigma) -> TotalStationObservations:
    """The data rows → checked observations (groups complete, one P per setup, targets per
    setup)."""
    columns = _Columns(*header)
    p_obs: dict[str, dict] = {}
    targets, group_rows = [], {}
    for no, cells in rows:
        kind, *value = _parse_row(src, no, cells, columns, setups)
        if kind == "P":
            sid, p = value
            if sid in p_obs:
                first = p_obs[sid]["line"]
                raise InputError(src, f"line {no}: setup {sid}",
                                 f"second P observation (first on line {first}); expected one")
            p_obs[sid] = p
            continue
        t = value[0]
        targets.append(t)
        if t[3] == "feature":
            group_rows.setdefault(t[1], []).append((t[2], list(setups)[t[0]], no))
    _check_groups(src, group_rows)
    _check_setups(src, setups, p_obs, targets)
    if not group_rows:
        raise InputError(src, f"line {rows[-1][0]}", "no feature-point group in the file; expected "
                         "at least one group of A, B, C, D")
    built = [Setup(id=sid, angle_sigma=s["angle_sigma"], distance_sigma_m=s["distance_sigma_m"],
                   distance_sigma_ppm=s["distance_sigma_ppm"], **p_obs[sid])
             for sid, s in setups.items()]
    c = list(zip(*targets))
    return TotalStationObservations(
        source=src, setups=built, scanner_sigma=scanner_sigma, setup=np.array(c[0], int),
        group=np.array(c[1], dtype=object).astype(str), point=np.array(c[2]).astype(str),
        kind=np.array(c[3]).astype(str), slope=np.array(c[4], float), va=np.array(c[5], float),
        hz=np.array(c[6], float), scanner=np.array(c[7], float), line=np.array(c[8], int),
    )
