"""Shared CLI helpers: consoles, progress bars, option parsing, and the exit codes of every command.

Exit codes (one contract for every command; README.md "Exit codes"):

====  ==================================================================
0     done: the verdict (where there is one) is PASS or WARN
3     done, and the verdict is FAIL (the results are written: read them)
1     bad input, or the results cannot be written (one line names the file)
2     usage error (unknown option, a value of the wrong type), or a bug
130   interrupted by SIGINT (Ctrl-C); 143 by SIGTERM; nothing left behind
====  ==================================================================
"""

from __future__ import annotations

from contextlib import contextmanager

from rich.console import Console
from rich.markup import escape
from rich.progress import BarColumn, Progress, TextColumn, TimeElapsedColumn, TimeRemainingColumn

from calidar import interrupts
from calidar.validate import parse_floats, read_json  # noqa: F401 - the CLI's parsers

EXIT_OK = 0  #: done; the verdict, if any, is PASS or WARN
EXIT_INPUT = 1  #: bad input or unwritable results
EXIT_USAGE = 2  #: usage error
EXIT_FAIL = 3  #: done with a FAIL verdict
FORCE_HELP = ("Replace a non-empty output folder whole: its previous files go (an input inside it "
              "is refused).")
CONFIG_HELP = ("A configuration file (TOML, as the config.toml every run writes beside its "
               "results): its settings replace the defaults, options given on the command line "
               "replace its settings.")
EXIT_CODES_HELP = ("Exit codes: 0 pass or warn, 3 fail verdict, 1 input error (or results not "
                   "writable), 2 usage error, 130 interrupted (Ctrl-C), 143 terminated (SIGTERM).")


def given_options(ctx) -> dict:
    """The options given on the command line ({parameter name: value}) of a ``typer.Context``, not
    those left at their defaults (they replace a ``--config`` file's settings)."""
    return {k: v for k, v in ctx.params.items() if ctx.get_parameter_source(k).name != "DEFAULT"}


def config_values(given: dict, options: dict) -> dict:
    """The options ``given`` (:func:`given_options`) as a configuration's values ({attribute path:
    value}): ``options`` maps each parameter name to (attribute path, a parse of its text or None:
    as given)."""
    return {attr: given[p] if parse is None else parse(given[p])
            for p, (attr, parse) in options.items() if p in given}


def verdict_exit_code(*verdicts) -> int:
    """The exit code of a run that ended with these verdicts (:class:`calidar.verdict.Verdict`,
    or their status strings; None ignored): :data:`EXIT_FAIL` when one is FAIL, else
    :data:`EXIT_OK`.

    >>> verdict_exit_code("pass", "warn"), verdict_exit_code("warn", "fail")
    (0, 3)
    >>> verdict_exit_code(None)
    0
    """
    status = [getattr(v, "status", v) for v in verdicts if v is not None]
    return EXIT_FAIL if "fail" in status else EXIT_OK


def exit_with_verdict(*verdicts) -> None:
    """End a command with :func:`verdict_exit_code` (after its output is printed): exit 3 on
    FAIL."""
    import typer

    code = verdict_exit_code(*verdicts)
    if code != EXIT_OK:
        raise typer.Exit(code)

console = Console()
#: one error = one line, never wrapped (":moon:" as written)
err_console = Console(stderr=True, soft_wrap=True, emoji=False)


def print_error(message: str, prefix: str = "error: ") -> None:
    """One line on stderr: ``prefix`` in bold red, then ``message`` as written (brackets in file
    names and messages are not rich markup)."""
    text = f"[bold red]{escape(prefix)}[/]{escape(message)}" if prefix else escape(message)
    err_console.print(text, highlight=False, soft_wrap=True)


def print_warning(message: str) -> None:
    """One warning line on stderr (the message's brackets are kept)."""
    err_console.print(f"[yellow]warning:[/] {escape(message)}", highlight=False, soft_wrap=True)


@contextmanager
def progress_bar(transient: bool = True):
    """A rich progress bar on stderr (hidden when stderr is not a terminal: then not redrawn
    either — rich's refresh thread would lay its table out ten times a second for no one, a CPU
    cost that grows with the run's wall time)."""
    with Progress(
        TextColumn("[progress.description]{task.description}"), BarColumn(),
        TextColumn("{task.completed}/{task.total}"),
        TimeElapsedColumn(), TimeRemainingColumn(), console=err_console, transient=transient,
        auto_refresh=err_console.is_terminal,
    ) as p:
        yield p


_STATUS_STYLE = {"pass": "bold green", "warn": "bold yellow", "fail": "bold red",
                 "note": "bold blue"}


def print_verdict(verdict, title: str | None = None, brief: bool = False) -> None:
    """A verdict (:class:`calidar.verdict.Verdict`) on stdout: the status and summary, then each
    finding with its numbers and, when not a pass, what to do (``brief``: the findings that are not
    a pass)."""
    head = f"{escape(title)}: " if title else ""
    console.print(f"[{_STATUS_STYLE[verdict.status]}]{verdict.status.upper()}[/] "
                  f"{head}{escape(verdict.summary)}", highlight=False)
    for f in (f for f in verdict.findings if not (brief and f.status == "pass")):
        console.print(f"  [{_STATUS_STYLE[f.status]}]{f.status:4s}[/] {escape(f.check)}: "
                      f"{escape(f.detail)}", highlight=False)
        if f.action:
            console.print(f"       → {escape(f.action)}", highlight=False)


def progress_callback(progress):
    """A ``progress(description, done, total)`` function driving a rich progress bar."""
    tasks: dict[str, int] = {}

    def update(description: str, done: int, total: int) -> None:
        # a signal a native callback swallowed ends the run here, before its commit
        interrupts.check()
        if description not in tasks:
            tasks[description] = progress.add_task(description, total=total)
        progress.update(tasks[description], completed=done)

    return update
