"""Total-station observations for the range calibration of a circular-scan lidar (CSV).

The file is CSV (UTF-8, comma-separated) in three parts: ``#!`` directive lines, one
header row, data rows. Lines starting with ``#`` (and not ``#!``) and blank lines are
comments; CSV readers with ``comment='#'`` read the table unchanged. Example::

    #! calidar-total-station 1
    #! scanner_sigma_mm: 2.0
    #! setup: TS1 angle_arcsec=1.0 distance_mm=1.0 distance_ppm=1.5
    setup,group,point,hz_gon,zd_gon,slope_m,scanner_m
    TS1,,P,12.34567,98.76543,4.5210,
    TS1,G1,A,35.10000,99.10000,7.8123,5.1803
    ...
    TS1,,E1,60.00000,97.50000,21.0331,18.2290

Directives (each required once, ``setup`` once per total-station setup):

- ``#! calidar-total-station 1``: the format and its version;
- ``#! scanner_sigma_mm: S``: 1σ noise of one scanner range (mm);
- ``#! setup: ID angle_arcsec=a distance_mm=b distance_ppm=c``: a total-station setup
  and its stated precision: σ of a direction / vertical angle (arc-seconds) and of a
  slope distance, b mm + c ppm of the distance.

Columns (all required, any order, no others):

- ``setup``: id of a declared setup the observation was made from;
- ``group``: id of the scan-circle group for the feature points A–D, empty otherwise;
- ``point``: ``P`` (the scanner's mirror centre; one per setup), ``A`` ``B`` (on the scan
  circle, level with P), ``C`` ``D`` (plumb above / below P), or ``E…`` (step 2: the
  stopped beam's spot on an arbitrary target);
- ``hz_<u>``: horizontal direction, 0 ≤ hz < 360 deg (400 gon);
- ``va_<u>`` (vertical angle, −90…90 deg) *or* ``zd_<u>`` (zenith distance, 0…180 deg, face I);
- ``slope_m``: slope distance from the total station (m, > 0);
- ``scanner_m``: the scanner's range (m, > 0) for A–D and E points; empty for P.

``<u>`` is ``deg`` or ``gon`` and declares the angle unit; both angle columns must use the
same unit. Each group needs exactly one A, B, C and D, all from one setup. Every error
names the file, the line and what was expected. Inside, angles are radians (vertical
angles, zenith distances converted), distances metres, σ SI.
"""

from __future__ import annotations

import csv
import math
import re
from collections.abc import Iterable
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from calidar.errors import InputError
from calidar.outputs import write_text_atomic

FORMAT_LINE = "calidar-total-station 1"
ARCSEC = math.pi / (180.0 * 3600.0)  #: one arc-second in radians
ANGLE_UNITS = {"deg": math.pi / 180.0, "gon": math.pi / 200.0}  #: unit → radians per unit
FULL_CIRCLE = {"deg": 360.0, "gon": 400.0}
FEATURE_POINTS = ("A", "B", "C", "D")
BASE_COLUMNS = ("setup", "group", "point", "slope_m", "scanner_m")


@dataclass(frozen=True)
class Setup:
    """A total-station setup: its stated precision (SI) and its observation of P."""

    id: str
    angle_sigma: float  #: σ of one direction or vertical angle (rad)
    distance_sigma_m: float  #: constant part of the slope-distance σ (m)
    distance_sigma_ppm: float  #: distance-proportional part of the slope-distance σ (ppm)
    p_slope: float  #: slope distance O→P (m)
    p_va: float  #: vertical angle O→P (rad, up positive)
    p_hz: float  #: horizontal direction O→P (rad)
    line: int  #: line of the P observation

    def distance_sigma(self, slope_m: np.ndarray) -> np.ndarray:
        """σ (m) of slope distances ``slope_m`` (m): mm + ppm."""
        return self.distance_sigma_m + self.distance_sigma_ppm * 1e-6 * np.asarray(slope_m, float)


@dataclass(frozen=True)
class TotalStationObservations:
    """All targets (feature points A–D and E points), one entry per row, as arrays.

    ``kind`` is "feature" or "E"; ``setup`` indexes ``setups``; angles rad, distances m.
    """

    source: str
    setups: list[Setup]
    scanner_sigma: float  #: σ of one scanner range (m)
    setup: np.ndarray  #: (n,) int
    group: np.ndarray  #: (n,) str, "" for E points
    point: np.ndarray  #: (n,) str
    kind: np.ndarray  #: (n,) "feature" | "E"
    slope: np.ndarray  #: (n,) slope distance O→X (m)
    va: np.ndarray  #: (n,) vertical angle O→X (rad)
    hz: np.ndarray  #: (n,) horizontal direction O→X (rad)
    scanner: np.ndarray  #: (n,) scanner range (m)
    line: np.ndarray  #: (n,) line numbers in the file

    def __len__(self) -> int:
        return int(self.slope.size)

    def subset(self, keep: np.ndarray) -> "TotalStationObservations":
        """The observations with the targets selected by the boolean/int index ``keep``."""
        arrays = {k: getattr(self, k)[keep] for k in ("setup", "group", "point", "kind", "slope", "va", "hz",
                                                      "scanner", "line")}
        return TotalStationObservations(self.source, self.setups, self.scanner_sigma, **arrays)

    @property
    def groups(self) -> list[str]:
        """Group ids in file order."""
        return list(dict.fromkeys(self.group[self.kind == "feature"]))


def _float(text: str, src: str, line: int, field: str, what: str) -> float:
    try:
        v = float(text)
    except ValueError:
        raise InputError(src, f"line {line}: {field}", f"expected {what}, got {text!r}") from None
    if not math.isfinite(v):
        raise InputError(src, f"line {line}: {field}", f"expected {what}, got {text!r}")
    return v


def _parse_setup(value: str, src: str, line: int) -> dict:
    parts = value.split()
    need = ("angle_arcsec", "distance_mm", "distance_ppm")
    expect = "'ID angle_arcsec=a distance_mm=b distance_ppm=c'"
    if not parts or "=" in parts[0]:
        raise InputError(src, f"line {line}: setup", f"expected {expect}, got {value!r}")
    kv = {}
    for p in parts[1:]:
        k, eq, v = p.partition("=")
        if not eq or k not in need:
            raise InputError(src, f"line {line}: setup {parts[0]}", f"unknown item {p!r}; expected {expect}")
        kv[k] = _float(v, src, line, f"setup {parts[0]}: {k}", "a number")
        if kv[k] < 0 or (k != "distance_ppm" and kv[k] == 0):
            raise InputError(src, f"line {line}: setup {parts[0]}: {k}", f"expected a positive number, got {v}")
    missing = [k for k in need if k not in kv]
    if missing:
        raise InputError(src, f"line {line}: setup {parts[0]}", f"missing {', '.join(missing)}; expected {expect}")
    return {"id": parts[0], "angle_sigma": kv["angle_arcsec"] * ARCSEC, "distance_sigma_m": kv["distance_mm"] * 1e-3,
            "distance_sigma_ppm": kv["distance_ppm"], "line": line}


def _parse_header(cells: list[str], src: str, line: int) -> tuple[dict[str, int], str, str]:
    """Column positions, the angle unit and the vertical convention ("va" | "zd") from the header."""
    cells = [c.strip() for c in cells]
    expected = "setup, group, point, hz_<deg|gon>, va_<deg|gon> or zd_<deg|gon>, slope_m, scanner_m"
    angle = {}
    for c in cells:
        m = re.fullmatch(r"(hz|va|zd)_(\w+)", c)
        if c in BASE_COLUMNS:
            continue
        if m and m.group(2) in ANGLE_UNITS:
            if m.group(1) in angle or (m.group(1) in ("va", "zd") and ({"va", "zd"} & angle.keys())):
                what = "hz" if m.group(1) == "hz" else "vertical (va_ or zd_)"
                raise InputError(src, f"line {line}: header", f"more than one {what} column; expected {expected}")
            angle[m.group(1)] = (c, m.group(2))
        elif m:
            raise InputError(src, f"line {line}: header: {c}", f"unknown angle unit {m.group(2)!r}; expected deg or gon")
        else:
            raise InputError(src, f"line {line}: header", f"unknown column {c!r}; expected {expected}")
    missing = [c for c in BASE_COLUMNS if c not in cells]
    if "hz" not in angle:
        missing.append("hz_<deg|gon>")
    if not {"va", "zd"} & angle.keys():
        missing.append("va_<deg|gon> or zd_<deg|gon>")
    if missing:
        raise InputError(src, f"line {line}: header", f"missing column(s) {', '.join(missing)}; expected {expected}")
    if len(set(cells)) != len(cells):
        raise InputError(src, f"line {line}: header", f"a column appears twice; expected {expected}")
    vertical = "va" if "va" in angle else "zd"
    units = {angle["hz"][1], angle[vertical][1]}
    if len(units) > 1:
        raise InputError(src, f"line {line}: header", f"mixed angle units ({angle['hz'][0]} and {angle[vertical][0]}); "
                         "expected both angle columns in deg or both in gon")
    cols = {c: i for i, c in enumerate(cells)}
    cols["hz"] = cols[angle["hz"][0]]
    cols["v"] = cols[angle[vertical][0]]
    return cols, units.pop(), vertical


def read_observations(path: str | Path) -> TotalStationObservations:
    """Read and check an observation file (format in this module's docstring)."""
    src = str(path)
    with open(path, encoding="utf-8", newline="") as f:
        lines = f.read().splitlines()
    directives: dict[str, tuple[str, int]] = {}
    setups: dict[str, dict] = {}
    header = None
    header_line = 0
    rows = []
    for no, raw in enumerate(lines, start=1):
        text = raw.strip()
        if text.startswith("#!"):
            if header is not None:
                raise InputError(src, f"line {no}", "expected directives (#!) before the header row")
            body = text[2:].strip()
            if body.startswith("calidar-total-station"):
                if body != FORMAT_LINE:
                    raise InputError(src, f"line {no}", f"expected '#! {FORMAT_LINE}', got {text!r}")
                directives["format"] = (body, no)
                continue
            key, colon, value = body.partition(":")
            key, value = key.strip(), value.strip()
            if not colon or key not in ("scanner_sigma_mm", "setup"):
                raise InputError(src, f"line {no}", "unknown directive; expected '#! calidar-total-station 1', "
                                 f"'#! scanner_sigma_mm: S' or '#! setup: ID ...', got {text!r}")
            if key == "setup":
                s = _parse_setup(value, src, no)
                if s["id"] in setups:
                    raise InputError(src, f"line {no}: setup {s['id']}",
                                     f"declared twice (first on line {setups[s['id']]['line']})")
                setups[s["id"]] = s
            else:
                if key in directives:
                    raise InputError(src, f"line {no}: {key}", f"given twice (first on line {directives[key][1]})")
                directives[key] = (value, no)
            continue
        if not text or text.startswith("#"):
            continue
        cells = next(csv.reader([raw]))
        if header is None:
            header, header_line = _parse_header(cells, src, no), no
            continue
        rows.append((no, [c.strip() for c in cells]))
    end = header_line or len(lines) + 1  # directives are missing before this line
    if "format" not in directives:
        raise InputError(src, "line 1", f"expected the directive '#! {FORMAT_LINE}' (not a calidar total-station file?)")
    if "scanner_sigma_mm" not in directives:
        raise InputError(src, f"line {end}", "expected the directive '#! scanner_sigma_mm: S' (1σ scanner range noise, mm) "
                         "before this line")
    ssig_text, ssig_line = directives["scanner_sigma_mm"]
    scanner_sigma = _float(ssig_text, src, ssig_line, "scanner_sigma_mm", "a positive number (mm)") * 1e-3
    if scanner_sigma <= 0:
        raise InputError(src, f"line {ssig_line}: scanner_sigma_mm", f"expected a positive number (mm), got {ssig_text}")
    if not setups:
        raise InputError(src, f"line {end}", "expected at least one '#! setup: ID angle_arcsec=a distance_mm=b "
                         "distance_ppm=c' directive before this line")
    if header is None:
        raise InputError(src, f"line {len(lines) + 1}", "expected a header row and observations; the file has none")
    if not rows:
        raise InputError(src, f"line {header_line}", "expected observation rows after the header; there are none")
    return _parse_rows(src, rows, header, setups, scanner_sigma)


def _parse_rows(src, rows, header, setups, scanner_sigma) -> TotalStationObservations:
    cols, unit, vertical = header
    to_rad = ANGLE_UNITS[unit]
    full = FULL_CIRCLE[unit]
    vname = f"{vertical}_{unit}"
    vlim = (-full / 4, full / 4) if vertical == "va" else (0.0, full / 2)
    setup_ids = list(setups)
    p_obs: dict[str, dict] = {}
    targets = []
    group_rows: dict[str, list] = {}
    for no, cells in rows:
        if len(cells) != len(cols) - 2:
            raise InputError(src, f"line {no}", f"expected {len(cols) - 2} comma-separated values, got {len(cells)}")
        get = {k: cells[i] for k, i in cols.items()}
        sid, grp, pt = get["setup"], get["group"], get["point"]
        if sid not in setups:
            raise InputError(src, f"line {no}: setup", f"{sid!r} is not declared; expected one of {', '.join(setup_ids)}")
        hz = _float(get["hz"], src, no, f"hz_{unit}", f"a horizontal direction in {unit}")
        if not 0.0 <= hz < full:
            raise InputError(src, f"line {no}: hz_{unit}",
                             f"angle out of range: expected 0 ≤ hz < {full:g} {unit}, got {get['hz']}")
        v = _float(get["v"], src, no, vname, f"a {'vertical angle' if vertical == 'va' else 'zenith distance'} in {unit}")
        if not vlim[0] <= v <= vlim[1]:
            raise InputError(src, f"line {no}: {vname}",
                             f"angle out of range: expected {vlim[0]:g} ≤ {vertical} ≤ {vlim[1]:g} {unit}"
                             + (" (face I)" if vertical == "zd" else "") + f", got {get['v']}")
        slope = _float(get["slope_m"], src, no, "slope_m", "a slope distance in m")
        if slope <= 0:
            raise InputError(src, f"line {no}: slope_m", f"expected a positive distance in m, got {get['slope_m']}")
        va = v * to_rad if vertical == "va" else math.pi / 2 - v * to_rad
        if pt == "P":
            if grp or get["scanner_m"]:
                raise InputError(src, f"line {no}", "a P observation has no group and no scanner range; expected both empty")
            if sid in p_obs:
                raise InputError(src, f"line {no}: setup {sid}",
                                 f"second P observation (first on line {p_obs[sid]['line']}); expected one")
            p_obs[sid] = {"p_slope": slope, "p_va": va, "p_hz": hz * to_rad, "line": no}
            continue
        if pt in FEATURE_POINTS:
            if not grp:
                raise InputError(src, f"line {no}: group", f"feature point {pt} needs a group id")
            kind = "feature"
        elif pt.startswith("E") and len(pt) > 1:
            if grp:
                raise InputError(src, f"line {no}: group", f"E point {pt} belongs to no group; expected an empty group")
            kind = "E"
        else:
            raise InputError(src, f"line {no}: point", f"expected P, A, B, C, D or E<name>, got {pt!r}")
        scan = _float(get["scanner_m"], src, no, "scanner_m", f"the scanner range of {pt} in m")
        if scan <= 0:
            raise InputError(src, f"line {no}: scanner_m", f"expected a positive range in m, got {get['scanner_m']}")
        targets.append((setup_ids.index(sid), grp, pt, kind, slope, va, hz * to_rad, scan, no))
        if kind == "feature":
            group_rows.setdefault(grp, []).append((pt, sid, no))
    for grp, members in group_rows.items():
        seen = {}
        for pt, sid, no in members:
            if pt in seen:
                raise InputError(src, f"line {no}: group {grp}",
                                 f"second point {pt} (first on line {seen[pt]}); expected one each of A, B, C, D")
            seen[pt] = no
            if sid != members[0][1]:
                raise InputError(src, f"line {no}: group {grp}",
                                 f"setup {sid} differs from {members[0][1]} on line {members[0][2]}; "
                                 "expected one setup per group")
        missing = [p for p in FEATURE_POINTS if p not in seen]
        if missing:
            raise InputError(src, f"line {members[-1][2]}: group {grp}",
                             f"missing point(s) {', '.join(missing)}; expected A, B, C and D")
    used = {t[0] for t in targets}
    for sid, s in setups.items():
        if sid not in p_obs:
            rows_of = [t[8] for t in targets if setup_ids[t[0]] == sid]
            where = f"line {rows_of[0]}" if rows_of else f"line {s['line']}"
            raise InputError(src, f"{where}: setup {sid}",
                             "missing its P observation (the mirror centre); expected one row with point P")
        if setup_ids.index(sid) not in used:
            raise InputError(src, f"line {s['line']}: setup {sid}",
                             "has no targets; expected feature or E points observed from it")
    if not any(t[3] == "feature" for t in targets):
        raise InputError(src, f"line {rows[-1][0]}", "no feature-point group in the file; expected at least one group "
                         "of A, B, C, D")
    built = [Setup(id=sid, angle_sigma=s["angle_sigma"], distance_sigma_m=s["distance_sigma_m"],
                   distance_sigma_ppm=s["distance_sigma_ppm"], **p_obs[sid]) for sid, s in setups.items()]
    cols_t = list(zip(*targets))
    return TotalStationObservations(
        source=src, setups=built, scanner_sigma=scanner_sigma,
        setup=np.array(cols_t[0], int), group=np.array(cols_t[1], dtype=object).astype(str),
        point=np.array(cols_t[2]).astype(str), kind=np.array(cols_t[3]).astype(str),
        slope=np.array(cols_t[4], float), va=np.array(cols_t[5], float), hz=np.array(cols_t[6], float),
        scanner=np.array(cols_t[7], float), line=np.array(cols_t[8], int),
    )


def format_observations(obs: TotalStationObservations, angle_unit: str = "deg", vertical: str = "zd",
                        comments: Iterable[str] = ()) -> str:
    """The file text of ``obs`` with angles in ``angle_unit`` ("deg" | "gon") as vertical
    angles ("va") or zenith distances ("zd"); rows in the order of ``obs`` after each setup's P."""
    if angle_unit not in ANGLE_UNITS or vertical not in ("va", "zd"):
        raise ValueError(f"angle_unit must be deg|gon and vertical va|zd, got {angle_unit!r}, {vertical!r}")
    k = 1.0 / ANGLE_UNITS[angle_unit]
    full = FULL_CIRCLE[angle_unit]

    def angles(va, hz):
        v = va * k if vertical == "va" else (math.pi / 2 - va) * k
        return f"{(hz * k) % full:.7f}", f"{v:.7f}"

    out = [f"#! {FORMAT_LINE}"] + [f"# {c}" for c in comments]
    out.append(f"#! scanner_sigma_mm: {obs.scanner_sigma * 1e3:g}")
    for s in obs.setups:
        out.append(f"#! setup: {s.id} angle_arcsec={s.angle_sigma / ARCSEC:g} distance_mm={s.distance_sigma_m * 1e3:g} "
                   f"distance_ppm={s.distance_sigma_ppm:g}")
    out.append(f"setup,group,point,hz_{angle_unit},{vertical}_{angle_unit},slope_m,scanner_m")
    for i, s in enumerate(obs.setups):
        h, v = angles(s.p_va, s.p_hz)
        out.append(f"{s.id},,P,{h},{v},{s.p_slope:.4f},")
        for j in np.flatnonzero(obs.setup == i):
            h, v = angles(obs.va[j], obs.hz[j])
            out.append(f"{s.id},{obs.group[j]},{obs.point[j]},{h},{v},{obs.slope[j]:.4f},{obs.scanner[j]:.4f}")
    return "\n".join(out) + "\n"


def write_observations(path: str | Path, obs: TotalStationObservations, angle_unit: str = "deg",
                       vertical: str = "zd", comments: Iterable[str] = (), force: bool = False) -> Path:
    """Write ``obs`` atomically in the file format of this module."""
    return write_text_atomic(path, format_observations(obs, angle_unit, vertical, comments), force)
