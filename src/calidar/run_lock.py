"""One run per output: a lock file beside the destination, held for the whole run.

``<parent>/.<name>.calidar-lock`` holds the owner's pid, command line and start time (JSON) and is
locked with ``flock``. The kernel releases an ``flock`` when its process ends, however it ends, so a
lock file left by a killed run is stale by construction: the next run takes it over. A second run
while the first is alive is refused with one line naming the first (pid, command, start time).
The lock is re-entrant within a process (a command may claim its ``--out`` before its work and the
output folder claims it again at the commit).
"""

from __future__ import annotations

import contextlib
import datetime as _dt
import fcntl
import json
import os
import sys
import time
from collections.abc import Iterator
from pathlib import Path

from calidar import interrupts
from calidar.errors import OutputExistsError, OutputWriteError

_HELD: dict[str, list] = {}  #: lock file → [fd, how many holders in this process]
COMMAND_CHARS = 160  #: characters of the other run's command line shown in the refusal


def lock_path(destination: str | os.PathLike) -> Path:
    """The lock file of ``destination`` (beside it, hidden)."""
    d = Path(os.path.abspath(destination))
    return d.parent / f".{d.name}.calidar-lock"


def _owner(fd: int) -> dict:
    try:
        os.lseek(fd, 0, os.SEEK_SET)
        doc = json.loads(os.read(fd, 65536).decode("utf-8") or "{}")
        return doc if isinstance(doc, dict) else {}
    except (OSError, ValueError):
        return {}


def _describe(owner: dict) -> str:
    command = str(owner.get("command", "?"))
    if len(command) > COMMAND_CHARS:
        command = command[: COMMAND_CHARS - 1] + "…"
    return f"pid {owner.get('pid', '?')}, started {owner.get('started', '?')}: {command}"


def _acquire(path: Path, shown: str) -> int:
    """Open and flock ``path`` (retrying when the file was replaced under us); write our details."""
    for _ in range(50):
        try:
            fd = os.open(path, os.O_RDWR | os.O_CREAT | os.O_CLOEXEC, 0o644)
        except OSError as e:  # a read-only or unwritable destination: named as given, not the lock
            raise OutputWriteError(f"{shown}: cannot write: {e.strerror or e}") from None
        try:
            fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
        except BlockingIOError:
            _refuse_busy(fd, shown)
        except BaseException:
            os.close(fd)
            raise
        try:
            same = os.fstat(fd).st_ino == os.stat(path).st_ino
        except FileNotFoundError:
            same = False
        if same:
            _write_details(fd)
            return fd
        os.close(fd)  # the previous owner removed the file after we opened it: take the new one
    raise OutputExistsError(f"{shown}: its lock file {path.name} keeps changing; "
                            "is another run starting?")


def _refuse_busy(fd: int, shown: str) -> None:
    """Close ``fd`` (a lock file another run holds) and raise the error naming that run."""
    owner = {}
    for _ in range(20):  # the owner may be writing its details this very moment
        owner = _owner(fd)
        if owner:
            break
        time.sleep(0.01)
    os.close(fd)
    raise OutputExistsError(f"{shown}: in use by another calidar run ({_describe(owner)}); "
                            "wait for it to end or choose another output") from None


def _write_details(fd: int) -> None:
    """Write this run's pid, command and start time into the lock file ``fd`` (best effort: the
    flock is the lock; the details only name us to another run)."""
    started = _dt.datetime.now(_dt.timezone.utc).strftime("%Y-%m-%d %H:%M:%S UTC")
    command = " ".join(["calidar", *sys.argv[1:]])
    doc = {"pid": os.getpid(), "command": command, "started": started}
    try:
        os.ftruncate(fd, 0)
        os.lseek(fd, 0, os.SEEK_SET)
        os.write(fd, json.dumps(doc).encode("utf-8"))
    except OSError:
        pass


@contextlib.contextmanager
def hold(destination: str | os.PathLike, shown: str | None = None) -> Iterator[Path]:
    """Hold the lock of ``destination`` for the block (re-entrant in this process); refuse with a
    one-line :class:`OutputExistsError` when another live run holds it."""
    path = lock_path(destination)
    taken = []
    try:
        with interrupts.deferred():  # a signal held back here is raised once the lock is registered
            _take(path, shown or str(destination))
            taken.append(path)
        yield path
    finally:
        if taken:
            _give_back(str(path))


def _take(path: Path, shown: str) -> None:
    """Take (or take again) the lock file ``path``. Callers hold signals back around it and their
    own record of it (:func:`calidar.interrupts.deferred`), so that a signal cannot fall between the
    file's creation and its registration: a second Ctrl-C always finds it (:func:`held_paths`)."""
    key = str(path)
    if key in _HELD:
        _HELD[key][1] += 1
        return
    path.parent.mkdir(parents=True, exist_ok=True)
    _HELD[key] = [_acquire(path, shown), 1]


def _give_back(key: str) -> None:
    """Release one hold of the lock file ``key``; the last one removes the file, then forgets it (a
    signal in between would leave a file no one removes)."""
    with interrupts.deferred():
        entry = _HELD.get(key)
        if entry is None:
            return
        entry[1] -= 1
        if entry[1] == 0:
            with contextlib.suppress(FileNotFoundError):
                Path(key).unlink()
            del _HELD[key]
            os.close(entry[0])


#: lock files claimed for the rest of the run (released by :func:`release_claims`)
_CLAIMS: list[str] = []


def claim(destination: str | os.PathLike, shown: str | None = None) -> None:
    """Take the lock of ``destination`` now and keep it until :func:`release_claims` (the CLI calls
    it when the run ends): for a command whose work precedes its output folder (``calidar
    quality``)."""
    path = lock_path(destination)
    with interrupts.deferred():
        _take(path, shown or str(destination))
        _CLAIMS.append(str(path))


def release_claims() -> None:
    """Release what :func:`claim` took (the lock files go when no one in this process holds
    them)."""
    while _CLAIMS:
        _give_back(_CLAIMS.pop())


def held_paths() -> list[Path]:
    """The lock files this process holds (removed at once by a second Ctrl-C)."""
    return [Path(k) for k in _HELD]
