"""The ``calidar`` command (typer + rich).

Each command lives in its own module under ``calidar.cli`` as a module-level function over a
pipeline (``calidar.pipelines``), added to the app by the module's ``register(app, simulate)``;
``COMMAND_MODULES`` lists them. How a run ends:

- errors a user can fix (:class:`calidar.errors.CalidarError`, missing files, permissions, a full
  disk — any ``OSError``): one line naming the file (the ``--out`` destination, never a temporary), exit 1;
- usage errors (unknown command or option, a value of the wrong type, a missing argument):
  the usage line and the error, exit 2 — for click itself and for the click that newer typer
  releases bundle (both are recognised by their class names);
- Ctrl-C (SIGINT) and SIGTERM: one line "interrupted", exit 130 (143 for SIGTERM), after every
  temporary file and folder of the run has been removed (outputs are transactions, see
  :mod:`calidar.outputs`) — also when the interruption surfaces as another error (a native
  library's, raised from inside its callback);
- anything else is a bug: "internal error" and exit 2 (``CALIDAR_DEBUG=1`` shows the traceback).
"""

from __future__ import annotations

import importlib
import os
import signal
import sys

import typer

from calidar import __version__
from calidar.cli.common import print_error
from calidar.errors import CalidarError
from calidar.outputs import shown_path

COMMAND_MODULES: list[str] = [
    "info", "georef", "rangecal", "photon", "denoise", "ccr", "simulate_survey", "demo", "quality", "boresight",
    "scanner", "sensor",
    "trajectory",
]

app = typer.Typer(
    name="calidar",
    help="Open geometric calibration of laser scanning (LiDAR) systems.",
    no_args_is_help=True,
    add_completion=False,
    pretty_exceptions_enable=False,
)
simulate = typer.Typer(help="Simulate inputs with a known truth.", no_args_is_help=True)
app.add_typer(simulate, name="simulate")


def _version(value: bool) -> None:
    if value:
        print(f"calidar {__version__}")
        raise typer.Exit()


@app.callback()
def _root(version: bool = typer.Option(False, "--version", callback=_version, is_eager=True, help="Print the version.")) -> None:
    """Open geometric calibration of laser scanning (LiDAR) systems."""


for _name in COMMAND_MODULES:
    importlib.import_module(f"calidar.cli.{_name}").register(app, simulate)


class Interrupted(KeyboardInterrupt):
    """SIGTERM (or SIGINT) turned into an exception, so that every ``finally`` cleans up."""

    def __init__(self, signum: int):
        super().__init__(signum)
        self.signum = signum


_SIGNALS: list[int] = []  #: the signals that interrupted this run (typer turns the exception into exit 130)


def _raise_interrupted(signum, frame):
    """The first signal interrupts the run; later ones (Ctrl-C pressed twice) are only recorded, so
    that they cannot cut short the removal of the run's temporaries."""
    _SIGNALS.append(signum)
    if len(_SIGNALS) == 1:
        raise Interrupted(signum)


def _is(e: BaseException, *names: str) -> bool:
    """Whether ``e`` is an instance of a class of one of these names (click's, or the click typer bundles)."""
    return any(c.__name__ in names for c in type(e).__mro__)


def run(argv: list[str] | None = None) -> int:
    """Run the CLI with ``argv``; return the exit code (used by ``main`` and the tests)."""
    _SIGNALS.clear()
    try:
        # with standalone_mode=False click returns the code of a typer.Exit raised in a command
        code = app(args=argv, prog_name="calidar", standalone_mode=False)
        if _SIGNALS:  # typer caught the interruption and returns 130 silently
            raise Interrupted(_SIGNALS[-1])
        return code if isinstance(code, int) else 0
    except KeyboardInterrupt as e:
        return _interrupted(getattr(e, "signum", signal.SIGINT))
    except Exception as e:  # noqa: BLE001 - dispatched by kind in _report
        if _SIGNALS:  # an error the interruption caused (e.g. raised inside a native LAZ writer's callback)
            return _interrupted(_SIGNALS[-1])
        return _report(e)


def _interrupted(signum: int) -> int:
    print_error("interrupted" + (" (SIGTERM)" if signum == signal.SIGTERM else ""), prefix="")
    return 128 + int(signum)


def _report(e: Exception) -> int:
    """One line for an error a user can fix (exit 1), click's usage message (exit 2), else a bug."""
    if isinstance(e, CalidarError):
        print_error(shown_path(str(e)))
        return 1
    if isinstance(e, OSError):  # missing files, permissions, a full disk: the system's word, naming the file
        name = f"{shown_path(str(e.filename))}: " if e.filename is not None else ""
        print_error(f"{name}{e.strerror or e}")
        return 1
    if _is(e, "Exit"):
        return int(getattr(e, "exit_code", 0) or 0)
    if _is(e, "Abort"):
        return _interrupted(signal.SIGINT)
    if _is(e, "ClickException") and hasattr(e, "show"):
        e.show()
        return int(getattr(e, "exit_code", 2))
    if os.environ.get("CALIDAR_DEBUG"):
        raise e
    print_error(f"internal error: {type(e).__name__}: {e} (set CALIDAR_DEBUG=1 for the traceback)", prefix="")
    return 2


def main() -> None:
    signal.signal(signal.SIGTERM, _raise_interrupted)
    signal.signal(signal.SIGINT, _raise_interrupted)
    code = run(sys.argv[1:])
    for signum in (signal.SIGTERM, signal.SIGINT):  # a late signal must not kill the exit (Python's finalisation
        signal.signal(signum, signal.SIG_IGN)       # would restore the default action for our handler)
    sys.exit(code)
