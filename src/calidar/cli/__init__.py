"""The ``calidar`` command (typer + rich).

Each command lives in its own module under ``calidar.cli`` as a module-level function over a
pipeline (``calidar.pipelines``), added to the app by the module's ``register(app, simulate)``;
``COMMAND_MODULES`` lists them. A run imports only the module of the command it runs
(``COMMAND_NAMES``: which module registers each command; a name not there, ``--help`` or no
command: every module, so ``calidar --help`` lists them all); ``calidar.cli.app`` is the whole app.
How a run ends:

- the exit codes are one contract for every command (:mod:`calidar.cli.common`, README
  "Exit codes"): 0 pass or warn, 3 a FAIL verdict (:func:`calidar.cli.common.exit_with_verdict`),
  1 input error, 2 usage error, 130/143 interrupted;
- errors a user can fix (:class:`calidar.errors.CalidarError`, missing or unreadable files, a full
  disk — any ``OSError``): one line naming the file (the ``--out`` destination, never a
  temporary), exit 1;
- usage errors (unknown command or option, a value of the wrong type, a missing argument):
  the usage line and the error, exit 2 — for click itself and for the click that newer typer
  releases bundle (both are recognised by their class names);
- Ctrl-C (SIGINT) and SIGTERM (:mod:`calidar.cli.signals`): one line "interrupted", exit 130
  (143 for SIGTERM), after every temporary file and folder of the run has been removed (outputs
  are transactions, see :mod:`calidar.outputs`) — also when the interruption surfaces as another
  error (a native library's, raised from inside its callback) or was dropped by Python;
- anything else is a bug: "internal error" and exit 2 (``CALIDAR_DEBUG=1`` shows the traceback).
"""

from __future__ import annotations

import importlib
import os
import signal
import sys
import warnings

import typer

from calidar import __version__, interrupts, run_lock
from calidar.cli.common import (
    EXIT_CODES_HELP, EXIT_FAIL, EXIT_INPUT, EXIT_OK, EXIT_USAGE, print_error, print_warning,
)
from calidar.errors import CalidarError
from calidar.outputs import shown_path

COMMAND_MODULES: list[str] = [
    "info", "georef", "rangecal", "photon", "denoise", "ccr", "simulate_survey", "demo", "quality",
    "boresight", "scanner", "sensor", "tpu", "accuracy", "trajectory", "plan",
]
# the module registering each command ("simulate X" under SIMULATE_NAMES); a command missing here
# costs only time (every module is imported), tests/unit/test_cli_lazy.py checks both maps
COMMAND_NAMES: dict[str, str] = {
    "info": "info", "inverse": "georef", "regeoref": "georef", "georef": "georef",
    "range-cal": "rangecal", "denoise": "denoise", "ccr": "ccr", "demo": "demo",
    "quality": "quality", "boresight": "boresight", "scanner": "scanner", "sensor": "sensor",
    "tpu": "tpu", "accuracy": "accuracy", "trajectory": "trajectory", "plan": "plan",
}
SIMULATE_NAMES: dict[str, str] = {
    "total-station": "rangecal", "photons": "photon", "survey": "simulate_survey",
}


def _version(value: bool) -> None:
    if value:
        print(f"calidar {__version__}")
        raise typer.Exit()


def _root(version: bool = typer.Option(False, "--version", callback=_version, is_eager=True,
                                       help="Print the version.")) -> None:
    """Open geometric calibration of laser scanning (LiDAR) systems."""


def build_app(modules: list[str] | None = None) -> typer.Typer:
    """The ``calidar`` app with the commands of ``modules`` (default every one), registered in
    ``COMMAND_MODULES``' order whatever the order asked."""
    app = typer.Typer(
        name="calidar",
        help="Open geometric calibration of laser scanning (LiDAR) systems.",
        no_args_is_help=True,
        add_completion=False,
        pretty_exceptions_enable=False,
        epilog=EXIT_CODES_HELP,
    )
    simulate = typer.Typer(help="Simulate inputs with a known truth.", no_args_is_help=True)
    app.add_typer(simulate, name="simulate")
    app.callback()(_root)
    wanted = COMMAND_MODULES if modules is None else set(modules)
    for name in COMMAND_MODULES:
        if name in wanted:
            importlib.import_module(f"calidar.cli.{name}").register(app, simulate)
    _exit_codes_in_help(app)
    return app


def modules_for(argv: list[str]) -> list[str] | None:
    """The modules a run of ``argv`` needs: its command's, or None (every module) for ``--help``,
    no command or a name not in ``COMMAND_NAMES`` (click then says what is wrong, as before)."""
    words = [a for a in argv if not a.startswith("-")]
    if not words or any(a in ("--help", "-h") for a in argv[:argv.index(words[0])]):
        return None
    if words[0] == "simulate":
        module = SIMULATE_NAMES.get(words[1]) if len(words) > 1 else None
    else:
        module = COMMAND_NAMES.get(words[0])
    return [module] if module else None


def _exit_codes_in_help(t: typer.Typer) -> None:
    """Every command's --help ends with the exit codes (unless it states its own)."""
    for c in t.registered_commands:
        c.epilog = c.epilog or EXIT_CODES_HELP
    for g in t.registered_groups:
        g.epilog = g.epilog or EXIT_CODES_HELP
        _exit_codes_in_help(g.typer_instance)


_whole: list[typer.Typer] = []


def __getattr__(name: str) -> typer.Typer:
    """``calidar.cli.app``: the app with every command (built once, on first use)."""
    if name != "app":
        raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
    if not _whole:
        _whole.append(build_app())
    return _whole[0]


def _is(e: BaseException, *names: str) -> bool:
    """Whether ``e`` is an instance of a class of one of these names (click's, or the click
    typer bundles)."""
    return any(c.__name__ in names for c in type(e).__mro__)


def run(argv: list[str] | None = None) -> int:
    """Run the CLI with ``argv``; return the exit code (used by ``main`` and the tests). Python
    warnings raised during the run are shown as one line each after a run that succeeds, dropped
    after a failure (its error is the one line that matters)."""
    interrupts.reset()
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("default")
        try:
            code = _run(argv)
        finally:
            run_lock.release_claims()
    if code in (EXIT_OK, EXIT_FAIL):
        for text in dict.fromkeys(f"{w.category.__name__}: {w.message}" for w in caught):
            print_warning(text)
    return code


def _run(argv: list[str] | None) -> int:
    app, args = None, []
    try:
        # with standalone_mode=False click returns the code of a typer.Exit raised in a command
        args = sys.argv[1:] if argv is None else list(argv)
        app = __getattr__("app") if modules_for(args) is None else build_app(modules_for(args))
        code = app(args=args, prog_name="calidar", standalone_mode=False)
        # a signal swallowed on the way (typer returns 130 silently, or a callback dropped it)
        interrupts.check()
        return code if isinstance(code, int) else 0
    except KeyboardInterrupt as e:
        return _interrupted(getattr(e, "signum", signal.SIGINT))
    except Exception as e:  # noqa: BLE001 - dispatched by kind in _report
        # an error the interruption caused (e.g. inside a native callback)
        if interrupts.pending() is not None:
            return _interrupted(interrupts.pending())
        _give_usage_context(e, app, args)
        return _report(e)


def _give_usage_context(e: Exception, app, args: list[str]) -> None:
    """click's parser raises some usage errors (``--force=1``: an option given a value it does
    not take) before any context exists, so they would print no usage line: give them the
    context of the command the arguments name (exit 2 with the usage line, as every other)."""
    if app is None or not _is(e, "UsageError") or getattr(e, "ctx", None) is not None:
        return
    command = typer.main.get_command(app)
    ctx = command.context_class(command, info_name="calidar")
    for word in args:
        sub = None if word.startswith("-") else getattr(command, "get_command", None)
        sub = sub and sub(ctx, word)
        if sub is None:
            break
        command, ctx = sub, sub.context_class(sub, info_name=word, parent=ctx)
    e.ctx = ctx


def _interrupted(signum: int) -> int:
    print_error("interrupted" + (" (SIGTERM)" if signum == signal.SIGTERM else ""), prefix="")
    return 128 + int(signum)


def _report(e: Exception) -> int:
    """One line for an error a user can fix (exit 1), click's usage message (exit 2), else a bug."""
    if isinstance(e, CalidarError):
        print_error(shown_path(str(e)))
        return EXIT_INPUT
    # missing files, permissions, a full disk: the system's word, naming the file
    if isinstance(e, OSError):
        name = f"{shown_path(str(e.filename))}: " if e.filename is not None else ""
        print_error(f"{name}{e.strerror or e}")
        return EXIT_INPUT
    if _is(e, "Exit"):
        return int(getattr(e, "exit_code", 0) or 0)
    if _is(e, "Abort"):
        return _interrupted(signal.SIGINT)
    # click's "Path '…' is not readable.": an input error, as a missing file is
    if _unreadable(e):
        print_error(_unreadable(e))
        return EXIT_INPUT
    if _is(e, "ClickException") and hasattr(e, "show"):
        e.show()
        return int(getattr(e, "exit_code", EXIT_USAGE))
    if os.environ.get("CALIDAR_DEBUG"):
        raise e
    bug = f"{type(e).__name__}: {e}"
    print_error(f"internal error: {bug} (set CALIDAR_DEBUG=1 for the traceback)", prefix="")
    return EXIT_USAGE


def _unreadable(e: Exception) -> str:
    """click's message for an input file it cannot read (empty when ``e`` is not that)."""
    text = getattr(e, "message", "") or ""
    return text if _is(e, "BadParameter") and "is not readable" in text else ""


def main() -> None:
    """The ``calidar`` command: signals handled by :mod:`calidar.cli.signals` from here on (they
    were only recorded while the CLI was being imported, see ``calidar.__main__``)."""
    from calidar.cli import signals

    code = None
    try:
        signals.install()
        # Ctrl-C while Python was importing: end now, nothing begun
        if interrupts.pending() is not None:
            raise interrupts.Interrupted(interrupts.pending())
        code = run(sys.argv[1:])
        signals.finish()
    except KeyboardInterrupt as e:
        # also a signal outside run's own handling: between the handlers' install and run's
        # ``try``, or after run returned (its code stands: the run had ended)
        signals.finish()
        code = _interrupted(getattr(e, "signum", signal.SIGINT)) if code is None else code
    _exit(code)  # as every interrupted run ends: without the interpreter's finalisation


def _exit(code: int) -> None:
    """Exit with ``code``. When threads still run (a reader inside a native decoder, after an
    error or an interruption) the interpreter's finalisation would unwind them by force, which
    aborts the process ("FATAL: exception not rethrown", exit 134): then the streams are flushed
    and the process ends without it (the run's temporaries are already gone: every transaction
    cleaned up). An interrupted run always ends so: a worker thread that has just stopped may
    still be tearing down its thread state while the interpreter finalises, which aborted one
    run in fifty on CI ("PyThreadState_Get: ... the GIL is released", exit −6). Every run ends
    without it: a run whose threads all ended first waits for the temporaries being removed and
    runs the atexit functions (the finalisation would only free memory, 0.3–0.8 s at 64 M)."""
    import atexit
    import threading

    from calidar.outputs import finish_removals, remove_temporaries

    interrupted = code in (128 + signal.SIGINT, 128 + signal.SIGTERM)
    if not interrupted:
        finish_removals()  # the temporaries being removed beside the run's last work
    others = [t for t in threading.enumerate() if t is not threading.main_thread()]
    if interrupted or any(t.is_alive() for t in others):
        remove_temporaries()  # what threads still held (e.g. ingest.held): atexit will not run
    else:
        # every thread ended: the atexit functions (temporaries, logging) run as at a normal
        # exit, but not the interpreter's finalisation after them (freeing every object and
        # module one by one: 0.3–0.8 s after a 64 M point run, nothing left to write)
        atexit._run_exitfuncs()
    import logging

    logging.shutdown()
    for stream in (sys.stdout, sys.stderr):
        try:
            stream.flush()
        except (OSError, ValueError):
            pass
    os._exit(code)
