"""The TOML side of every method's typed configuration (``--config FILE``, ``config.toml`` beside
the results): reading a document, each value checked against the type of the field it fills, and
writing one back. Errors name the file and the key (``solver.max_outer``), and what was expected.

>>> typed([20, 3.5], tuple[float, float], "config.toml", "trajectory_model.correlation_s")
(20.0, 3.5)
>>> typed("one", float, "config.toml", "block_s")
Traceback (most recent call last):
calidar.errors.InputError: config.toml: block_s: expected float, got 'one'
>>> print(toml_document({"fix_scale": False, "noise": {"range_sigma_m": 0.01}}, "a comment"))
# a comment
<BLANKLINE>
fix_scale = false
<BLANKLINE>
[noise]
range_sigma_m = 0.01
<BLANKLINE>
"""

from __future__ import annotations

import tomllib
import types
import typing
from dataclasses import fields
from pathlib import Path

from calidar.errors import InputError


def read_document(path: Path) -> dict:
    """The TOML document of ``path`` (an error naming the file when it is not TOML or not UTF-8
    text)."""
    from calidar.validate import read_text

    path = Path(path)
    try:
        return tomllib.loads(read_text(path, "TOML file"))
    except tomllib.TOMLDecodeError as e:
        raise InputError(path, None, f"expected TOML ({e})") from None


def toml_document(doc: dict, comment: str) -> str:
    """A document's TOML text: ``comment`` on top, plain keys, then one ``[table]`` per dict
    value."""
    lines = [f"# {comment}"]
    plain = [f"{k} = {toml_value(v)}" for k, v in doc.items() if not isinstance(v, dict)]
    lines += ["", *plain] if plain else []
    for name, table in ((k, v) for k, v in doc.items() if isinstance(v, dict)):
        lines += ["", f"[{name}]", *(f"{k} = {toml_value(v)}" for k, v in table.items())]
    return "\n".join(lines) + "\n"


def write_document(path: Path, doc: dict, comment: str) -> Path:
    """Write :func:`toml_document` atomically; returns its path."""
    from calidar.outputs import write_text_atomic

    return write_text_atomic(Path(path), toml_document(doc, comment))


def table(doc: dict, key: str, path) -> dict:
    """The table ``[key]`` of a document ({} when absent)."""
    value = doc.get(key, {})
    if not isinstance(value, dict):
        raise InputError(path, key, f"expected a table [{key}], got {value!r}")
    return value


def known(doc: dict, keys: set[str], path, prefix: str = "") -> None:
    """An error naming the first key of ``doc`` not among ``keys``."""
    unknown = sorted(set(doc) - keys)
    if unknown:
        raise InputError(path, prefix + unknown[0],
                         f"unknown key; expected one of {', '.join(sorted(keys))}")


def section(cls: type, doc: dict, path, name: str, **built):
    """A dataclass ``cls`` from a TOML table: every key one of its fields (but those ``built``
    already), of the field's type."""
    hints = typing.get_type_hints(cls)
    prefix = f"{name}." if name else ""
    known(doc, {f.name for f in fields(cls)} - set(built), path, prefix)
    kw = {k: typed(v, hints[k], path, prefix + k) for k, v in doc.items()}
    return build(path, name, lambda: cls(**kw, **built))


def build(path, name: str, make):
    """``make()``, its complaints named by the file and the section or key (``name``; "" for the
    document's top level: the key the complaint names)."""
    try:
        return make()
    except InputError as e:
        inner = e.field or (e.source if e.source and e.source.startswith("--") else None)
        label = f"{name} ({inner})" if name and inner and inner != name else name or inner
        raise InputError(path, label, e.problem) from None
    except (ValueError, TypeError) as e:
        raise InputError(path, name or None, str(e)) from None


def typed(value, tp, path, key: str):
    """``value`` of a TOML document as the type ``tp`` (float, int, str, bool, X | None,
    tuple[X, ...], tuple[X, Y]), else an error naming the file and the key."""
    origin, args = typing.get_origin(tp), typing.get_args(tp)
    if origin in (typing.Union, types.UnionType):
        if value is None and type(None) in args:
            return None
        alternatives = [a for a in args if a is not type(None)]
        for a in alternatives[:-1]:  # the first that fits (str | tuple[str, ...]: "all" or a list)
            try:
                return typed(value, a, path, key)
            except InputError:
                pass
        return typed(value, alternatives[-1], path, key)
    if origin is tuple:
        n = None if len(args) == 2 and args[1] is Ellipsis else len(args)
        if not isinstance(value, list) or (n is not None and len(value) != n):
            raise InputError(path, key,
                             f"expected a list of {n or 'one or more'} values, got {value!r}")
        item_types = [args[0] if n is None else args[k] for k in range(len(value))]
        return tuple(typed(v, t, path, key) for v, t in zip(value, item_types))
    ok = {float: lambda v: isinstance(v, (int, float)) and not isinstance(v, bool),
          int: lambda v: isinstance(v, int) and not isinstance(v, bool),
          str: lambda v: isinstance(v, str),
          bool: lambda v: isinstance(v, bool)}
    if tp not in ok or not ok[tp](value):
        raise InputError(path, key, f"expected {getattr(tp, '__name__', tp)}, got {value!r}")
    return float(value) if tp is float else value


def inputs_table(owners: dict, keys: dict) -> dict:
    """The ``[inputs]`` table: each key of ``keys`` (key → (owner, field)) read from
    ``owners[owner]`` (None values left out; tuples as lists, CRS as their text)."""
    values = {k: getattr(owners[o], f) for k, (o, f) in keys.items()}
    return {k: list(v) if isinstance(v, tuple) else str(v) if k.endswith("crs") else v
            for k, v in values.items() if v is not None}


def plain(settings) -> dict:
    """A settings dataclass's fields as TOML values (None and nested settings left out, tuples as
    lists)."""
    values = {f.name: getattr(settings, f.name) for f in fields(settings)}
    return {k: list(v) if isinstance(v, tuple) else v for k, v in values.items()
            if v is not None and not hasattr(v, "__dataclass_fields__")}


def toml_value(value) -> str:
    """One TOML value (numbers, strings, booleans, lists of them)."""
    if isinstance(value, bool):
        return "true" if value else "false"
    if isinstance(value, (list, tuple)):
        return "[" + ", ".join(toml_value(v) for v in value) + "]"
    if isinstance(value, float):
        return repr(value)
    if isinstance(value, int):
        return str(value)
    return '"' + str(value).replace("\\", "\\\\").replace('"', '\\"') + '"'
