"""Interruptions (SIGINT, SIGTERM) as one state every part of a run can check.

The CLI's signal handler (``calidar.cli.signals``) :func:`record`\\ s each signal and raises
:class:`Interrupted` from the main thread. Python cannot deliver that exception everywhere: raised
inside a garbage-collector callback, a ``__del__`` or a ctypes callback it is printed as
"Exception ignored" and dropped, and the run would go on. So the signal is also kept here, and the
places that make a run's result visible — the commit of an output folder or file
(:mod:`calidar.outputs`) — and the progress callbacks call :func:`check` first: a recorded signal
is never lost, and no result is committed after it.

Once a run has committed its result (:func:`mark_committed`) later signals are recorded but no
longer interrupt it: the result is complete and stays, and the run exits with its own code.
"""

from __future__ import annotations

import contextlib
import signal
import threading
from collections.abc import Callable, Iterator

_RECORDED: list[int] = []  #: signals received by this run, in order
_STATE = {"committed": False}
_DEFERRED = {"depth": 0}  #: how deep the main thread is in :func:`deferred` blocks
#: acts on signals held back by :func:`deferred` (set by the CLI)
_DELIVER: list[Callable[[], None]] = []


class Interrupted(KeyboardInterrupt):
    """SIGINT or SIGTERM turned into an exception, so that every ``finally`` cleans up.

    >>> Interrupted(signal.SIGTERM).exit_code
    143
    """

    def __init__(self, signum: int):
        super().__init__(signum)
        self.signum = int(signum)

    @property
    def exit_code(self) -> int:
        """128 + the signal's number, as a shell reports a process ended by it."""
        return 128 + self.signum


def reset() -> None:
    """Forget the signals and the commit of an earlier run (in-process runs of the tests)."""
    _RECORDED.clear()
    _DEFERRED.update(depth=0, seen=0)
    _STATE["committed"] = False


def record(signum: int) -> int:
    """Keep ``signum``; return how many signals this run has received."""
    _RECORDED.append(int(signum))
    return len(_RECORDED)


def received() -> int:
    """How many signals this run has received."""
    return len(_RECORDED)


def pending() -> int | None:
    """The first signal received and not yet acted upon by a committed run, or None."""
    return _RECORDED[0] if _RECORDED and not _STATE["committed"] else None


def check() -> None:
    """Raise :class:`Interrupted` when a signal was received (main thread only: worker threads must
    not raise it for the main thread's run)."""
    signum = pending()
    if signum is not None and threading.current_thread() is threading.main_thread():
        raise Interrupted(signum)


def committed() -> bool:
    """Whether this run has committed its result (later signals no longer interrupt it)."""
    return _STATE["committed"]


def mark_committed() -> None:
    """The run's result is in place: from now on a signal is recorded, not raised."""
    _STATE["committed"] = True


def is_deferred() -> bool:
    """Whether the main thread is inside a :func:`deferred` block (the handler only records)."""
    return _DEFERRED["depth"] > 0


def set_delivery(deliver: Callable[[], None]) -> None:
    """Install what acts on the signals held back by :func:`deferred` once the block ends (the CLI's
    handler logic: raise on the first, end the run on the second)."""
    _DELIVER[:] = [deliver]


@contextlib.contextmanager
def deferred() -> Iterator[None]:
    """Hold signals back for a short step that must not be cut in two (a lock file created and
    registered, or removed and forgotten): the handler records them, and they are acted upon when
    the outermost block ends. Main thread only; elsewhere the block does nothing."""
    if threading.current_thread() is not threading.main_thread():
        yield
        return
    if _DEFERRED["depth"] == 0:
        _DEFERRED["seen"] = len(_RECORDED)  # signals before the block were acted upon already
    _DEFERRED["depth"] += 1
    try:
        yield
    finally:
        _DEFERRED["depth"] -= 1
        held_back = len(_RECORDED) > _DEFERRED.get("seen", 0)
        if _DEFERRED["depth"] == 0 and held_back and not _STATE["committed"] and _DELIVER:
            _DELIVER[0]()


def signal_name(signum: int) -> str:
    """'SIGTERM' for 15 (for messages)."""
    try:
        return signal.Signals(signum).name
    except ValueError:
        return f"signal {signum}"
