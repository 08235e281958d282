"""One mapping between a command's typed configuration and its TOML file, used by every
command's configuration: each :class:`Key` ties a TOML key (``cell_m``, ``inputs.crs``) to the
attribute it fills (``settings.cell_m``: a field of a nested settings dataclass, or an entry of a
dict field) and to the command-line option that sets it. From the keys alone a
:class:`FileConfig` writes its ``config.toml``, reads one back (each value checked against its
type; a key not among them an error), takes the options given on the command line over the file's
settings and names a bad value by the file, the key and the option::

    mine.toml: settings.radius_m (--radius): expected a finite number in (0, 1000] m, got -1.0

>>> from dataclasses import dataclass
>>> @dataclass(frozen=True)
... class Demo(FileConfig):
...     KEYS = (Key("cell_m", "cell_m", "--cell"), Key("grid.rows", "rows"))
...     COMMAND = "demo"
...     cell_m: float = 2.0
...     rows: int = 3
...     def check(self):
...         if self.cell_m <= 0:
...             raise InputError(None, "--cell", f"expected a length > 0 m, got {self.cell_m}")
>>> Demo(cell_m=1.0).to_dict()
{'cell_m': 1.0, 'grid': {'rows': 3}}
>>> Demo.from_document({"cell_m": -1.0}, "mine.toml")
Traceback (most recent call last):
calidar.errors.InputError: mine.toml: cell_m (--cell): expected a length > 0 m, got -1.0
>>> Demo.configure(None, {"cell_m": -1.0})
Traceback (most recent call last):
calidar.errors.InputError: --cell: expected a length > 0 m, got -1.0
"""

from __future__ import annotations

import dataclasses
import typing
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import Any, ClassVar

from calidar.errors import InputError
from calidar.pipelines.config_toml import known, read_document, table, typed, write_document


@dataclass(frozen=True)
class Key:
    """One setting: its TOML key (``section.name`` or ``name``), the config's attribute it fills
    (dotted through nested dataclasses and dicts), its command-line option, the TOML value's type
    (default: the attribute's annotation) and, where the file holds it otherwise than the
    attribute, ``encode`` (attribute → TOML) and ``decode`` (checked TOML value → attribute)."""

    key: str
    attr: str
    option: str | None = None
    tp: Any = None
    encode: Callable[[Any], Any] | None = None
    decode: Callable[[Any], Any] | None = None

    @property
    def label(self) -> str:
        """How an error names the key: ``section.name (--option)``."""
        return f"{self.key} ({self.option})" if self.option else self.key


def get(obj, attr: str):
    """The value at a dotted attribute path (dataclass fields, dict entries, a missing one None,
    tuple items by index)."""
    for part in attr.split("."):
        if isinstance(obj, dict):
            obj = obj.get(part)
        elif isinstance(obj, tuple):
            obj = obj[int(part)]
        else:
            obj = getattr(obj, part)
    return obj


def put(obj, values: dict):
    """A copy of ``obj`` with ``values`` ({dotted attribute path: value}) put in, each nested
    object made once with all of its changes (its checks see them together); None removes a dict
    entry."""
    direct: dict = {}
    nested: dict[str, dict] = {}
    for attr, value in values.items():
        head, _, rest = attr.partition(".")
        if rest:
            nested.setdefault(head, {})[rest] = value
        else:
            direct[head] = value
    changes = {**direct, **{h: put(get(obj, h), sub) for h, sub in nested.items()}}
    if isinstance(obj, dict):
        merged = {**obj, **changes}
        return {k: v for k, v in merged.items() if v is not None}
    if isinstance(obj, tuple):
        return tuple(changes.get(str(k), v) for k, v in enumerate(obj))
    return dataclasses.replace(obj, **changes)


def _toml(value):
    """A value as TOML holds it: tuples as lists, numpy scalars as Python numbers."""
    if isinstance(value, (tuple, list)):
        return [_toml(v) for v in value]
    return value.item() if hasattr(value, "item") and not isinstance(value, (str, bytes)) else value


def hint(cls: type, attr: str):
    """The annotation of a dotted attribute path of a dataclass type."""
    tp: Any = cls
    for part in attr.split("."):
        tp = typing.get_type_hints(tp)[part]
    return tp


class FileConfig:
    """A frozen dataclass configuration whose fields (with defaults) map to a TOML file by
    ``KEYS``. ``check`` raises an :class:`InputError` naming the option of a value out of its
    range."""

    KEYS: ClassVar[tuple[Key, ...]] = ()
    COMMAND: ClassVar[str] = ""

    def check(self) -> None:
        """Every value in its range (an error naming the option)."""

    def to_dict(self) -> dict:
        """The TOML file's document (None values left out, tuples as lists)."""
        doc: dict = {}
        for k in self.KEYS:
            value = get(self, k.attr)
            value = k.encode(value) if k.encode is not None else value
            if value is None:
                continue
            section, _, name = k.key.rpartition(".")
            (doc.setdefault(section, {}) if section else doc)[name] = _toml(value)
        return doc

    def write(self, path: Path) -> Path:
        """Write the TOML file (atomically); returns its path."""
        return write_document(path, self.to_dict(), f"calidar {self.COMMAND} configuration: give "
                              "it again with --config to repeat the run")

    @classmethod
    def from_document(cls, doc: dict, path) -> FileConfig:
        """The configuration of a TOML document (keys left out: their defaults), checked."""
        return cls.configure_values(_values(cls, doc, path), {}, path)

    @classmethod
    def read(cls, path: Path) -> FileConfig:
        """The configuration of a TOML file (keys left out: their defaults), checked."""
        return cls.from_document(read_document(Path(path)), Path(path))

    @classmethod
    def configure(cls, path: Path | None, given: dict) -> FileConfig:
        """The ``--config`` file's configuration (else the defaults) with ``given`` ({attribute
        path: value}, from the options on the command line) replacing its settings; checked
        once."""
        from_file = {} if path is None else _values(cls, read_document(Path(path)), Path(path))
        return cls.configure_values(from_file, given, path)

    @classmethod
    def configure_values(cls, from_file: dict, given: dict, path) -> FileConfig:
        """The defaults with ``from_file`` then ``given`` ({attribute path: value}) put in;
        checked. A bad value is named by its option when given on the command line, else by the
        file and the key."""
        try:
            config = put(cls(), {**from_file, **given})
            config.check()
        except InputError as e:
            raise _named(e, cls.KEYS, from_file, given, path) from None
        return config


def _named(e: InputError, keys: tuple[Key, ...], from_file: dict, given: dict,
           path) -> InputError:
    """The error of a value checked: as it is when a value given on the command line is at fault
    (it names the option), else named by the file and the key (with its option) it came from."""
    where = " ".join(p for p in (e.field, e.source) if p)
    # "key (--option)", "--option": the option named
    words = {w.strip("(),") for w in where.split()}
    hit = [k for k in keys if (k.option is not None and k.option in words) or k.key == e.field]
    if path is None or any(k.attr in given for k in hit) or not from_file:
        return e
    mine = [k for k in hit if k.attr in from_file]
    if not mine:
        return InputError(path, where or None, e.problem)
    option = mine[0].option
    if len(mine) == 1:
        label = mine[0].label
    else:
        label = ", ".join(k.key for k in mine) + (f" ({option})" if option else "")
    return InputError(path, label, e.problem)


def _values(cls: type, doc: dict, path) -> dict:
    """{attribute path: value} of a TOML document, each value of its key's type (errors naming the
    key)."""
    by_section: dict[str, dict[str, Key]] = {}
    for k in cls.KEYS:
        section, _, name = k.key.rpartition(".")
        by_section.setdefault(section, {})[name] = k
    known(doc, set(by_section.get("", {})) | (set(by_section) - {""}), path)
    values = {}
    for section, keys in by_section.items():
        part = table(doc, section, path) if section else doc
        if section:
            known(part, set(keys), path, f"{section}.")
        for name, k in ((n, k) for n, k in keys.items() if n in part):
            value = typed(part[name], k.tp if k.tp is not None else hint(cls, k.attr), path, k.key)
            try:
                values[k.attr] = k.decode(value) if k.decode is not None else value
            except InputError as e:
                raise InputError(path, k.label, e.problem) from None
    return values


def text(value) -> str | None:
    """A value as TOML text (a CRS, a path; None stays None)."""
    return None if value is None else str(value)


def crs_decoder(option: str) -> Callable[[str], str]:
    def decode(text: str) -> str:
        from calidar.sensor import validated_crs

        return validated_crs(text, None, option)

    return decode


def point_keys(owner: str = "points", section: str = "inputs") -> tuple[Key, ...]:
    """The keys of how points are read (:class:`calidar.io.las.PointOptions` at ``owner``: --crs,
    --time-system, --geoid-undulation) in the table ``[section]``."""
    return (Key(f"{section}.crs", f"{owner}.crs", "--crs", str | None, encode=text,
                decode=crs_decoder("--crs")),
            Key(f"{section}.time_system", f"{owner}.time_system", "--time-system"),
            Key(f"{section}.geoid_undulation_m", f"{owner}.geoid_undulation_m",
                "--geoid-undulation"))


def config_beside(out: Path) -> Path:
    """Where a command writing one file writes its configuration: <stem>.config.toml beside it."""
    return Path(out).with_name(Path(out).stem + ".config.toml")


def trajectory_keys(owner: str = "trajectory_input", section: str = "inputs") -> tuple[Key, ...]:
    """The keys of how a text trajectory is read
    (:class:`calidar.pipelines.inputs.TrajectoryOptions` at ``owner``: --trajectory-crs,
    --trajectory-angles, --trajectory-heading, --trajectory-columns)."""
    return (Key(f"{section}.trajectory_crs", f"{owner}.crs", "--trajectory-crs", str | None,
                encode=text, decode=crs_decoder("--trajectory-crs")),
            *(Key(f"{section}.trajectory_{k}", f"{owner}.{k}", f"--trajectory-{k}")
              for k in ("angles", "heading", "columns")))
