"""Shared CLI helpers: consoles, progress bars, option parsing."""

from __future__ import annotations

from contextlib import contextmanager

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


@contextmanager
def progress_bar(transient: bool = True):
    """A rich progress bar on stderr (hidden when stderr is not a terminal)."""
    with Progress(
        TextColumn("[progress.description]{task.description}"), BarColumn(), TextColumn("{task.completed}/{task.total}"),
        TimeElapsedColumn(), TimeRemainingColumn(), console=err_console, transient=transient,
    ) as p:
        yield p
