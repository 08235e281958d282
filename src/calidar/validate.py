"""Checks at the edges: every number read from a file or an option is finite and within its
physical range, or a clear :class:`~calidar.errors.InputError` names the file (or option), the
field and the expected range. (The examples' long messages are wrapped: run them with doctest's
NORMALIZE_WHITESPACE, as tests/unit/test_doctests.py does.)

>>> number(5.0, "--cell", 0.01, 1000.0, "m")
5.0
>>> number(float("nan"), "--cell", 0.01, 1000.0, "m")
Traceback (most recent call last):
...
calidar.errors.InputError: --cell: expected a finite number in [0.01, 1000] m, got nan
>>> values(np.array([1.0, 2.0, np.inf]), "sbet.out", "height", -1000.0, 20000.0, "m")
Traceback (most recent call last):
...
calidar.errors.InputError: sbet.out: height: expected finite values in [-1000, 20000] m, got inf
(1 of 3 values, first at record 2)
"""

from __future__ import annotations

import json
import math
import os
import stat
from pathlib import Path

import numpy as np

from calidar.errors import InputError


def _g(v: float) -> str:
    """A bound as people write it: 1209600, 0.01, 3.14159, 1e+09 (an int exactly: 4294967295)."""
    if isinstance(v, (int, np.integer)) and not isinstance(v, bool):
        return str(v)
    return f"{v:.6g}" if abs(v) < 1e6 or v != int(v) or abs(v) >= 1e8 else f"{v:.0f}"


def _range_text(lo: float | None, hi: float | None, unit: str, open_lo: bool = False,
                open_hi: bool = False) -> str:
    """The range as an error states it: "in [lo, hi] unit", "≥ lo unit" or "≤ hi unit" (a round
    bracket or a strict sign for an open end), "" with neither bound."""
    u = f" {unit}" if unit else ""
    if lo is not None and hi is not None:
        left, right = "(" if open_lo else "[", ")" if open_hi else "]"
        return f"in {left}{_g(lo)}, {_g(hi)}{right}{u}"
    if lo is not None:
        return f"{'>' if open_lo else '≥'} {_g(lo)}{u}"
    if hi is not None:
        return f"{'<' if open_hi else '≤'} {_g(hi)}{u}"
    return ""


def number(value, where: str | os.PathLike | None, lo: float | None = None,
           hi: float | None = None, unit: str = "", field: str | None = None,
           open_lo: bool = False, open_hi: bool = False) -> float:
    """``value`` as a float when finite and within [lo, hi] (``open_lo`` / ``open_hi``: that end
    excluded), else an error naming ``where`` (an option such as "--cell", or a file with
    ``field``)."""
    try:
        v = float(value)
    except (TypeError, ValueError):
        v = math.nan
    bad = (not math.isfinite(v) or (lo is not None and (v <= lo if open_lo else v < lo))
           or (hi is not None and (v >= hi if open_hi else v > hi)))
    if bad:
        expected = f"a finite number {_range_text(lo, hi, unit, open_lo, open_hi)}".rstrip()
        raise InputError(where, field, f"expected {expected}, got {value}")
    return v


def integer(value, where: str | os.PathLike | None, lo: int | None = None, hi: int | None = None,
            unit: str = "", field: str | None = None, why: str = "") -> int:
    """``value`` as an int within [lo, hi], else an error naming ``where``; ``why`` says what the
    bounds protect (e.g. the memory a larger value would take).

    >>> integer(2_000_000, "--points", 8, 100_000, why="memory grows with it")
    Traceback (most recent call last):
    ...
    calidar.errors.InputError: --points: expected an integer in [8, 100000] (memory grows with it),
    got 2000000
    """
    ok = isinstance(value, (int, np.integer)) and not isinstance(value, bool)
    if ok and (lo is None or value >= lo) and (hi is None or value <= hi):
        return int(value)
    parts = ("an integer", _range_text(lo, hi, unit), f"({why})" if why else "")
    expected = " ".join(p for p in parts if p)
    raise InputError(where, field, f"expected {expected}, got {value}")


def positive(value, where, unit: str = "", field: str | None = None,
             hi: float | None = None) -> float:
    """A finite number > 0 (and ≤ ``hi``)."""
    return number(value, where, 0.0, hi, unit, field, open_lo=True)


def values(array, source: str | os.PathLike | None, field: str, lo: float | None = None,
           hi: float | None = None, unit: str = "", what: str = "record",
           labels=None) -> np.ndarray:
    """``array`` unchanged when every value is finite and within [lo, hi]; else an error naming
    the file, the field, the expected range, the first bad value, how many and where (its index,
    or ``labels[index]``, e.g. line numbers)."""
    a = np.asarray(array, dtype=float)
    bad = ~np.isfinite(a)
    if lo is not None:
        bad |= a < lo
    if hi is not None:
        bad |= a > hi
    if bad.any():
        flat = bad.ravel()
        first = int(np.argmax(flat))
        expected = f"finite values {_range_text(lo, hi, unit)}".rstrip()
        where = first if labels is None else labels[first]
        raise InputError(source, field, f"expected {expected}, got {a.ravel()[first]:g} "
                         f"({int(flat.sum())} of {flat.size} values, first at {what} {where})")
    return a


#: text inputs (sensor.toml, CSV, JSON): read at most this much (a device never ends)
MAX_TEXT_BYTES = 64 << 20
#: the kinds of file that are not regular, as an error names them
_KINDS = ((stat.S_ISFIFO, "a pipe"), (stat.S_ISCHR, "a character device"),
          (stat.S_ISBLK, "a block device"), (stat.S_ISSOCK, "a socket"))


def _kind(mode: int) -> str:
    for test, name in _KINDS:
        if test(mode):
            return name
    return "not a regular file"


def existing_file(path: str | os.PathLike, what: str = "file") -> Path:
    """``path`` when it is a regular file (links followed), else a clear error naming it: not found,
    a folder, unreadable, or a pipe or device (read on purpose by no reader: a device never ends and
    a pipe can be read once, while calidar reads inputs more than once)."""
    path = Path(path)
    try:
        st = path.stat()
    except (FileNotFoundError, NotADirectoryError):
        raise InputError(path, None, f"{what} not found") from None
    except OSError as e:
        raise InputError(path, None, f"cannot be read: {e.strerror or e}") from None
    if stat.S_ISDIR(st.st_mode):
        raise InputError(path, None, f"is a folder; expected a {what}")
    if not stat.S_ISREG(st.st_mode):
        article = "an" if what[:1].lower() in "aeio" else "a"
        raise InputError(path, None, f"is {_kind(st.st_mode)}, not a regular file; expected "
                         f"{article} {what} (save the stream to a file first)")
    if not os.access(path, os.R_OK):
        raise InputError(path, None, "cannot be read: permission denied")
    return path


def read_text(path: str | os.PathLike, what: str = "text file", limit: int = MAX_TEXT_BYTES) -> str:
    """A file's text as UTF-8, or a clear error (missing, a folder, a pipe or device, larger than
    ``limit`` bytes, not UTF-8 — with the byte offset). At most ``limit`` + 1 bytes are read."""
    path = existing_file(path, what)
    size = path.stat().st_size
    if size <= limit:
        with open(path, "rb") as f:
            data = f.read(limit + 1)
        size = len(data)
    if size > limit:
        raise InputError(path, "size", f"expected a {what} of at most {limit / 2**20:g} MiB, got "
                         f"{size / 2**20:.0f} MiB{'+' if size == limit + 1 else ''}")
    try:
        return data.decode("utf-8-sig")
    except UnicodeDecodeError as e:
        byte = e.object[e.start]
        raise InputError(path, "encoding", f"expected UTF-8 text, got byte 0x{byte:02x} "
                         f"at offset {e.start}") from None


def parse_floats(text: str, n: int, option: str) -> tuple[float, ...]:
    """Parse 'a,b,c' into n floats, or raise a clear error naming the option."""
    try:
        vals = tuple(float(v) for v in text.split(","))
    except ValueError:
        vals = ()
    if len(vals) != n or not all(math.isfinite(v) for v in vals):
        raise InputError(None, option, f"expected {n} comma-separated finite numbers, got {text!r}")
    return vals


def read_json(path: Path) -> dict:
    """A JSON object from ``path``, or a clear error naming the file (missing, not JSON, not an
    object)."""
    try:
        doc = json.loads(read_text(path, "JSON file"))
    except json.JSONDecodeError as e:
        raise InputError(path, f"line {e.lineno}", f"expected JSON: {e.msg}") from None
    if not isinstance(doc, dict):
        raise InputError(path, None, "expected a JSON object")
    return doc


SEED_MAX = 2**32 - 1  #: the largest random seed (numpy's seeds are 32-bit here)

_MISSING = object()


def table_number(table: dict, key: str, source, lo: float | None = None, hi: float | None = None,
                 unit: str = "", prefix: str = "", default=_MISSING) -> float:
    """``table[key]`` (a TOML/JSON table) as a float: a number (not a bool or a string), finite,
    within [lo, hi]; a missing key is an error unless a ``default`` is given (docs must name it)."""
    if key not in table:
        if default is _MISSING:
            expected = f"a number {_range_text(lo, hi, unit)}".rstrip()
            raise InputError(source, prefix + key, f"missing; expected {expected}")
        return float(default)
    v = table[key]
    if isinstance(v, bool) or not isinstance(v, (int, float)):
        message = f"expected a number {_range_text(lo, hi, unit)}, got {v!r}".replace("  ", " ")
        raise InputError(source, prefix + key, message)
    return number(v, source, lo, hi, unit, field=prefix + key)

