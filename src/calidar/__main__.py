"""``python -m calidar`` and the ``calidar`` command: signals are recorded from the first moment,
before the CLI's imports (typer, rich, numpy: a second or more), so that a Ctrl-C while they load
ends the run cleanly instead of in a KeyboardInterrupt traceback (:mod:`calidar.cli.signals`)."""

import signal

from calidar import interrupts  # light: nothing but the standard library


def _record(signum, frame) -> None:
    interrupts.record(signum)


def main() -> None:
    """Record signals, import the CLI, run it."""
    for s in (signal.SIGINT, signal.SIGTERM):
        signal.signal(s, _record)
    from calidar.cli import main as run_cli

    run_cli()


if __name__ == "__main__":
    main()
