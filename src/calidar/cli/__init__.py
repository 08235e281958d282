"""The ``calidar`` command (typer + rich).

Each command lives in its own module under ``calidar.cli`` with a
``register(app, simulate)`` function; ``COMMAND_MODULES`` lists them. Errors a user can fix
(:class:`calidar.errors.CalidarError`, missing files) print one line and exit 1.
"""

from __future__ import annotations

import importlib
import os
import sys

import typer

from calidar import __version__
from calidar.cli.common import err_console
from calidar.errors import CalidarError

COMMAND_MODULES: list[str] = ["simulate_survey", "demo", "quality", "boresight"]

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


def run(argv: list[str] | None = None) -> int:
    """Run the CLI with ``argv``; return the exit code (used by ``main`` and the tests)."""
    try:
        app(args=argv, prog_name="calidar", standalone_mode=False)
    except CalidarError as e:
        err_console.print(f"[bold red]error:[/] {e}", highlight=False)
        return 1
    except (FileNotFoundError, IsADirectoryError, PermissionError) as e:
        err_console.print(f"[bold red]error:[/] {e.filename}: {e.strerror}", highlight=False)
        return 1
    except typer.Exit as e:
        return e.exit_code
    except (typer.Abort, KeyboardInterrupt):
        err_console.print("aborted")
        return 130
    except Exception as e:  # click usage errors and the like
        import click

        if isinstance(e, click.ClickException):
            e.show()
            return e.exit_code
        if os.environ.get("CALIDAR_DEBUG"):
            raise
        err_console.print(f"[bold red]internal error:[/] {type(e).__name__}: {e} (set CALIDAR_DEBUG=1 for the traceback)",
                          highlight=False)
        return 2
    return 0


def main() -> None:
    sys.exit(run(sys.argv[1:]))
