"""SIGINT and SIGTERM, handled in one place for the ``calidar`` command.

- While Python imports the CLI (``calidar.__main__``) a signal is only recorded: ``main`` then ends
  the run before it begins (no KeyboardInterrupt traceback out of an import).
- During the run the first signal is recorded (:mod:`calidar.interrupts`) and raised as
  :class:`~calidar.interrupts.Interrupted`, so that every ``finally`` removes the run's temporaries.
  Where Python drops that exception (raised inside a garbage-collector, ``__del__`` or ctypes
  callback it becomes an "Exception ignored" message), the record stays: the next progress
  callback or the commit of the output raises it again — a run never commits after a signal.
  Those "Exception ignored" reports are not printed (``CALIDAR_DEBUG=1`` shows them).
- A second signal ends the run at once: the temporaries and locks are removed, child processes
  (a local Dask cluster's workers) killed, "interrupted" printed, and the process exits 130/143.
- Once the result is committed a signal no longer interrupts: the result is complete.
"""

from __future__ import annotations

import os
import signal
import sys

from calidar import interrupts

SIGNALS = (signal.SIGINT, signal.SIGTERM)


def _handler(signum, frame) -> None:
    interrupts.record(signum)
    if interrupts.committed() or interrupts.is_deferred():
        return  # the result is in place (the run ends normally), or acted upon when the step ends
    _act()


def _act() -> None:
    """The first signal raises :class:`Interrupted`; a second one ends the run now."""
    signum = interrupts.pending()
    if signum is None:
        return
    if interrupts.received() == 1:
        raise interrupts.Interrupted(signum)
    end_now(signum)


def end_now(signum: int) -> None:
    """Remove this run's temporaries and locks, kill its child processes, say so and exit now."""
    from calidar.outputs import remove_temporaries

    remove_temporaries()
    _kill_children()
    try:
        os.write(2, b"interrupted" + (b" (SIGTERM)" if signum == signal.SIGTERM else b"") + b"\n")
    finally:
        os._exit(128 + int(signum))


def _kill_children() -> None:
    try:
        import psutil
    except ImportError:
        return
    try:
        for child in psutil.Process().children(recursive=True):
            child.kill()
    except psutil.Error:
        pass


def _unraisable(hook_args) -> None:
    """Drop Python's "Exception ignored in ..." reports: an interruption raised where it could not
    propagate is recorded and acted on by :func:`calidar.interrupts.check`; other such reports
    (a library's ``__del__`` on a failed write) are noise after the run's own one-line error."""
    if os.environ.get("CALIDAR_DEBUG"):
        sys.__unraisablehook__(hook_args)


def install() -> None:
    """Install the run's handlers (main thread). Also: the libraries' log records (GDAL's and
    libtiff's through rasterio, Dask's) are not printed — without a handler Python would print
    every warning of theirs, e.g. one "_tiffSeekProc: No space left on device." line per failed
    write before the run's own one-line error (``CALIDAR_DEBUG=1`` shows them)."""
    import logging

    interrupts.set_delivery(_act)
    sys.unraisablehook = _unraisable
    if not os.environ.get("CALIDAR_DEBUG"):
        logging.getLogger().addHandler(logging.NullHandler())
    for s in SIGNALS:  # last: from here a signal raises (``calidar.cli.main`` catches it)
        signal.signal(s, _handler)


def finish() -> None:
    """After the run: a late signal must not turn the exit into a traceback (Python's finalisation
    would restore the default action for our handler)."""
    for s in SIGNALS:
        signal.signal(s, signal.SIG_IGN)
