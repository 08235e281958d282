"""Shared CLI helpers: consoles, progress bars, option parsing."""

from __future__ import annotations

from contextlib import contextmanager

from rich.console import Console
from rich.markup import escape
from rich.progress import BarColumn, Progress, TextColumn, TimeElapsedColumn, TimeRemainingColumn

from calidar.validate import parse_floats, read_json  # noqa: F401 - the CLI's parsers

console = Console()
err_console = Console(stderr=True, soft_wrap=True)  # one error = one line, never wrapped


def print_error(message: str, prefix: str = "error: ") -> None:
    """One line on stderr: ``prefix`` in bold red, then ``message`` as written (brackets in file
    names and messages are not rich markup)."""
    err_console.print(f"[bold red]{escape(prefix)}[/]{escape(message)}" if prefix else escape(message),
                      highlight=False, soft_wrap=True)


def print_warning(message: str) -> None:
    """One warning line on stderr (the message's brackets are kept)."""
    err_console.print(f"[yellow]warning:[/] {escape(message)}", highlight=False, soft_wrap=True)


@contextmanager
def progress_bar(transient: bool = True):
    """A rich progress bar on stderr (hidden when stderr is not a terminal)."""
    with Progress(
        TextColumn("[progress.description]{task.description}"), BarColumn(), TextColumn("{task.completed}/{task.total}"),
        TimeElapsedColumn(), TimeRemainingColumn(), console=err_console, transient=transient,
    ) as p:
        yield p


_STATUS_STYLE = {"pass": "bold green", "warn": "bold yellow", "fail": "bold red", "note": "bold blue"}


def print_verdict(verdict, title: str | None = None, brief: bool = False) -> None:
    """A verdict (:class:`calidar.verdict.Verdict`) on stdout: the status and summary, then each
    finding with its numbers and, when not a pass, what to do (``brief``: the findings that are not a pass)."""
    head = f"{escape(title)}: " if title else ""
    console.print(f"[{_STATUS_STYLE[verdict.status]}]{verdict.status.upper()}[/] {head}{escape(verdict.summary)}",
                  highlight=False)
    for f in (f for f in verdict.findings if not (brief and f.status == "pass")):
        console.print(f"  [{_STATUS_STYLE[f.status]}]{f.status:4s}[/] {escape(f.check)}: {escape(f.detail)}",
                      highlight=False)
        if f.action:
            console.print(f"       → {escape(f.action)}", highlight=False)


def progress_callback(progress):
    """A ``progress(description, done, total)`` function driving a rich progress bar."""
    tasks: dict[str, int] = {}

    def update(description: str, done: int, total: int) -> None:
        if description not in tasks:
            tasks[description] = progress.add_task(description, total=total)
        progress.update(tasks[description], completed=done)

    return update
