"""Shared CLI helpers: consoles, progress bars, option parsing."""

from __future__ import annotations

import json
from contextlib import contextmanager
from pathlib import Path

from rich.console import Console
from rich.progress import BarColumn, Progress, TextColumn, TimeElapsedColumn, TimeRemainingColumn

from calidar.errors import InputError

console = Console()
err_console = Console(stderr=True, soft_wrap=True)  # one error = one line, never wrapped


def parse_floats(text: str, n: int, option: str) -> tuple[float, ...]:
    """Parse 'a,b,c' into n floats, or raise a clear error naming the option."""
    try:
        vals = tuple(float(v) for v in text.split(","))
    except ValueError:
        vals = ()
    if len(vals) != n:
        raise InputError(None, option, f"expected {n} comma-separated numbers, got {text!r}")
    return vals


def read_json(path: Path) -> dict:
    """A JSON object from ``path``, or a clear error naming the file (missing, not JSON, not an object)."""
    try:
        doc = json.loads(Path(path).read_text(encoding="utf-8"))
    except FileNotFoundError:
        raise InputError(path, None, "file not found") from None
    except json.JSONDecodeError as e:
        raise InputError(path, f"line {e.lineno}", f"expected JSON: {e.msg}") from None
    if not isinstance(doc, dict):
        raise InputError(path, None, "expected a JSON object")
    return doc


@contextmanager
def progress_bar(transient: bool = True):
    """A rich progress bar on stderr (hidden when stderr is not a terminal)."""
    with Progress(
        TextColumn("[progress.description]{task.description}"), BarColumn(), TextColumn("{task.completed}/{task.total}"),
        TimeElapsedColumn(), TimeRemainingColumn(), console=err_console, transient=transient,
    ) as p:
        yield p
