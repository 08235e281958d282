"""Surveyed checkpoints (CSV): id, x, y, z, land cover and an optional σ, checked on reading.

The file (docs/conventions.md, "Checkpoint file")::

    # lines starting with # are comments
    id,x,y,z,class,sigma
    CP01,500123.412,5200456.118,452.331,non-vegetated,0.02
    CP02,500311.090,5200512.774,449.020,vegetated,0.03

- Columns are found by name (case and ``_``/``-``/spaces ignored), in any order: ``id`` (name,
  point, label), ``x`` (easting, east), ``y`` (northing, north), ``z`` (elevation, height, h),
  the land cover ``class`` (cover, landcover, type) and optionally ``sigma`` (sigma_z, sd, std;
  metres, the survey's 1σ vertical uncertainty of that point). Commas, semicolons or tabs.
- Land cover, as ASPRS Edition 2 (2023) tests it: **non-vegetated** (NVA; also ``nva``,
  ``open``, ``bare``, ``non vegetated``) or **vegetated** (VVA; also ``vva``, ``veg``,
  ``vegetation``, ``forest``, ``trees``).
- x, y, z are in the CRS of the points unless the caller gives another (``--checkpoints-crs``).

Every error names the file, the line and the field: missing columns, values that are not
finite numbers, an unknown land cover, a negative σ, two checkpoints with one id; and, once in a
metric frame (:func:`check_places`), two at one place.
"""

from __future__ import annotations

import csv
import io
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from calidar.errors import InputError

MAX_COORDINATE = 1e9  #: |x|, |y|, |z| beyond this is not a place in any CRS calidar reads
MAX_SIGMA_M = 10.0  #: a survey σ beyond this is a unit mistake (mm given as m)
SAME_PLACE_M = 1e-3  #: two checkpoints closer than this (x, y) are one point surveyed twice
MAX_CHECKPOINTS = 100_000

#: column → accepted header names (normalised: lower case, without spaces, "_" and "-")
COLUMNS = {
    "id": ("id", "name", "point", "pointid", "pointname", "label", "pt"),
    "x": ("x", "easting", "east", "e"),
    "y": ("y", "northing", "north", "n"),
    "z": ("z", "elevation", "elev", "height", "h"),
    "class": ("class", "cover", "landcover", "landclass", "type", "category"),
    "sigma": ("sigma", "sigmaz", "sigmam", "sigmazm", "sd", "sdz", "std", "stdz", "stddev",
              "accuracy"),
}
REQUIRED = ("id", "x", "y", "z", "class")
NON_VEGETATED = ("nonvegetated", "nva", "open", "bare", "bareearth", "nonveg")
VEGETATED = ("vegetated", "vva", "veg", "vegetation", "forest", "trees", "undertrees")


EXPECTED_HEADER = ("id, x, y, z and class (land cover: non-vegetated or vegetated), optionally "
                   "sigma")


def _norm(text: str) -> str:
    """A header name or land cover as compared: lower case, without spaces, "_" and "-"."""
    return "".join(ch for ch in text.strip().lower() if ch not in " _-")


@dataclass(frozen=True, eq=False)
class Checkpoints:
    """Checkpoints of one file; arrays in file order."""

    path: Path
    ids: np.ndarray  #: (N,) str
    xyz: np.ndarray  #: (N, 3) float, in the CRS they were surveyed in
    vegetated: np.ndarray  #: (N,) bool: VVA (True) or NVA (False)
    sigma_m: np.ndarray | None  #: (N,) survey 1σ (m), None when the file has no σ column
    lines: np.ndarray  #: (N,) line number of each in the file (1-based)

    def __len__(self) -> int:
        return self.ids.size

    def cover(self) -> np.ndarray:
        """'non-vegetated' / 'vegetated' per checkpoint."""
        return np.where(self.vegetated, "vegetated", "non-vegetated")


def _columns(header: list[str], path: Path, line: int, required=REQUIRED, columns=None,
             expected: str = EXPECTED_HEADER) -> dict[str, int]:
    """Each known column's position in ``header`` (``columns``: key → accepted names, default the
    checkpoints'); one line naming the file and field when one is named twice or a ``required``
    one is missing (``expected``: what the header should name)."""
    names = [_norm(h) for h in header]
    found = {}
    for key, aliases in (COLUMNS if columns is None else columns).items():
        hits = [i for i, n in enumerate(names) if n in aliases]
        if len(hits) > 1:
            named = ", ".join(repr(header[i]) for i in hits)
            raise InputError(path, key, f"line {line}: columns {named} all name the {key} column; "
                             "expected one")
        if hits:
            found[key] = hits[0]
    missing = [k for k in required if k not in found]
    if missing:
        raise InputError(path, missing[0], f"line {line}: no {' / '.join(missing)} column in the "
                         f"header {','.join(header)!r}; expected a header naming {expected}")
    return found


def _number(text: str, path: Path, line: int, field: str, limit: float) -> float:
    """The number in ``text``: finite and within ±``limit``, else an error naming the line."""
    try:
        v = float(text)
    except ValueError:
        v = None
    if v is None or not np.isfinite(v) or abs(v) > limit:
        raise InputError(path, field, f"line {line}: expected a finite number "
                         f"(|value| ≤ {limit:g}), got {text.strip()!r}")
    return v


def _cover(text: str, path: Path, line: int) -> bool:
    """Whether the land cover in ``text`` is vegetated (VVA); an error for an unknown one."""
    v = _norm(text)
    if v in NON_VEGETATED:
        return False
    if v in VEGETATED:
        return True
    raise InputError(path, "class", f"line {line}: expected a land cover, non-vegetated (NVA, "
                     f"open, bare) or vegetated (VVA, forest, trees), got {text.strip()!r}")


def _rows(path: Path):
    """(line number, cells) of the non-comment, non-blank lines."""
    from calidar.validate import read_text

    text = read_text(path, "checkpoint file")
    lines = [(k + 1, s) for k, s in enumerate(text.splitlines())
             if s.strip() and not s.lstrip().startswith("#")]
    if not lines:
        raise InputError(path, None, "no checkpoints: expected a header line "
                         "(id,x,y,z,class[,sigma]) and one line per checkpoint")
    head = lines[0][1]
    delimiter = "," if "," in head else (";" if ";" in head else ("\t" if "\t" in head else ","))
    for number, s in lines:
        yield number, next(csv.reader(io.StringIO(s), delimiter=delimiter))


def _check_ids(ids, lines, path: Path) -> None:
    """An error naming the first id used twice."""
    seen: dict[str, int] = {}
    for i, name in enumerate(ids):
        if name in seen:
            raise InputError(path, "id", f"line {lines[i]}: id {name!r} is used again (first on "
                             f"line {lines[seen[name]]}); expected one line per checkpoint")
        seen[name] = i


def check_places(cp: "Checkpoints", xy_m: np.ndarray) -> None:
    """An error naming two checkpoints within SAME_PLACE_M of each other (``xy_m``: their metric x,
    y)."""
    if len(xy_m) > 1:
        from scipy.spatial import cKDTree

        pairs = cKDTree(xy_m).query_pairs(SAME_PLACE_M, output_type="ndarray")
        if len(pairs):
            a, b = sorted(pairs[np.argmin(pairs.max(axis=1))])  # the first repeat in file order
            again, first = str(cp.ids[b]), str(cp.ids[a])
            raise InputError(cp.path, "x/y", f"line {cp.lines[b]}: checkpoint {again!r} is at the "
                             f"place of {first!r} (line {cp.lines[a]}, within "
                             f"{SAME_PLACE_M * 1e3:g} mm); expected each place once")


def read_checkpoints(path: str | Path, cover: bool = True) -> Checkpoints:
    """Read and check a checkpoint CSV (see the module docstring); ``cover`` False: the land-cover
    column is optional (ground control, ``calidar boresight --control``; without it every point
    counts as non-vegetated)."""
    path = Path(path)
    rows = _rows(path)
    head_line, header = next(rows)
    required = REQUIRED if cover else tuple(k for k in REQUIRED if k != "class")
    cols = _columns(header, path, head_line, required)
    ids, xyz, veg, sigma, lines = [], [], [], [], []
    for number, cells in rows:
        name, point, vegetated, s = _checkpoint(cells, cols, header, path, number)
        ids.append(name)
        xyz.append(point)
        veg.append(vegetated)
        if s is not None:
            sigma.append(s)
        lines.append(number)
        if len(ids) > MAX_CHECKPOINTS:
            raise InputError(path, None, f"more than {MAX_CHECKPOINTS} checkpoints; expected a "
                             "checkpoint survey")
    if not ids:
        raise InputError(path, None, f"a header (line {head_line}) but no checkpoints; expected "
                         "one line per checkpoint")
    xyz_a = np.asarray(xyz, float)
    _check_ids(ids, lines, path)
    sigma_a = np.asarray(sigma, float) if "sigma" in cols else None
    return Checkpoints(path, np.asarray(ids, dtype=str), xyz_a, np.asarray(veg, bool), sigma_a,
                       np.asarray(lines, np.int64))


def _checkpoint(cells: list[str], cols: dict[str, int], header: list[str], path: Path,
                number: int) -> tuple[str, list[float], bool, float | None]:
    """One line's checkpoint: id, [x, y, z], vegetated, σ (m; None without the column)."""
    if len(cells) < len(header):
        missing = [k for k, i in cols.items() if i >= len(cells)]
        raise InputError(path, missing[0] if missing else None,
                         f"line {number}: {len(cells)} values, expected {len(header)} (as the "
                         f"header {','.join(header)!r})")
    name = cells[cols["id"]].strip()
    if not name:
        raise InputError(path, "id", f"line {number}: expected a checkpoint id, got an empty value")
    point = [_number(cells[cols[k]], path, number, k, MAX_COORDINATE) for k in ("x", "y", "z")]
    vegetated = _cover(cells[cols["class"]], path, number) if "class" in cols else False
    s = None
    if "sigma" in cols:
        s = _number(cells[cols["sigma"]], path, number, "sigma", MAX_SIGMA_M)
        if s < 0:
            raise InputError(path, "sigma", f"line {number}: expected a σ ≥ 0 m, got {s:g}")
    return name, point, vegetated, s


def write_checkpoints(path: str | Path, ids, xyz, vegetated, sigma_m=None,
                      comment: str | None = None, force: bool = False) -> Path:
    """Write a checkpoint CSV that :func:`read_checkpoints` reads (mm resolution), atomically."""
    from calidar.outputs import write_text_atomic

    xyz = np.asarray(xyz, float)
    out = [f"# {c}" for c in (comment or "").splitlines()]
    out.append("id,x,y,z,class" + (",sigma" if sigma_m is not None else ""))
    for k, name in enumerate(ids):
        cover = "vegetated" if vegetated[k] else "non-vegetated"
        row = f"{name},{xyz[k, 0]:.3f},{xyz[k, 1]:.3f},{xyz[k, 2]:.3f},{cover}"
        out.append(row + (f",{float(np.asarray(sigma_m)[k]):.4f}" if sigma_m is not None else ""))
    return write_text_atomic(path, "\n".join(out) + "\n", force)
