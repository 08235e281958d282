"""Safe output writing: runs as transactions, atomic files, no silent overwrite, inputs never
touched.

Every command that writes goes through two calls:

- :func:`guard_inputs` — an output may never be an input: not the same path, not a hard link
  to it, and no input may lie inside an output folder. ``--force`` does not change that.
- :func:`output_folder` (a folder of results) or :func:`atomic_path` (one file): the run writes
  into a hidden temporary folder/file beside the destination, and the complete result is moved
  into place only when the run succeeds. A failed or interrupted run (SIGINT, SIGTERM: the CLI
  turns both into exceptions) removes its temporaries and leaves the destination as it was —
  absent, or the previous result under ``--force``.

Error messages that name a temporary path are shown with the destination's path instead
(:func:`shown_path`).
"""

from __future__ import annotations

import contextlib
import errno
import os
import shutil
import sys
import tempfile
from collections.abc import Callable, Iterable, Iterator
from pathlib import Path

from calidar import interrupts, run_lock
from calidar.errors import CalidarError, OutputExistsError, OutputWriteError

_TEMPORARIES: dict[str, str] = {}  #: temporary path → the destination it stands for (for messages)
_DEPTH = [0]  #: transactions open in this process (the outermost one's commit is the run's)
_PathOrNone = str | os.PathLike | None


def shown_path(text: str) -> str:
    """``text`` with every live temporary path replaced by the destination it stands for."""
    for tmp, final in sorted(_TEMPORARIES.items(), key=lambda kv: -len(kv[0])):
        text = text.replace(tmp, final)
    return text


def show_destinations(e: BaseException) -> None:
    """Rewrite an error leaving a transaction so that it names destinations, not temporaries
    (called while they are still registered: the caller prints it after they are gone)."""
    if isinstance(e, OSError):
        for attr in ("filename", "filename2"):
            if isinstance(getattr(e, attr, None), str):
                setattr(e, attr, shown_path(getattr(e, attr)))
    elif e.args and isinstance(e.args[0], str):
        e.args = (shown_path(e.args[0]), *e.args[1:])
        if isinstance(getattr(e, "source", None), str):
            e.source = shown_path(e.source)


def _same(a: Path, b: Path) -> bool:
    try:
        return a.resolve() == b.resolve() or (a.exists() and b.exists() and a.samefile(b))
    except OSError:
        return False


def _inside(child: Path, folder: Path) -> bool:
    try:
        return child.resolve().is_relative_to(folder.resolve())
    except OSError:
        return False


def guard_inputs(outputs: Iterable[_PathOrNone], inputs: Iterable[_PathOrNone],
                 folders: Iterable[_PathOrNone] = ()) -> None:
    """Refuse, whatever ``--force`` says, an output file that is an input (same path or hard link)
    and an output folder that holds an input. ``outputs``: files; ``folders``: output folders."""
    ins = [Path(i) for i in inputs if i is not None]
    for o in (Path(p) for p in outputs if p is not None):
        for i in ins:
            if _same(o, i):
                raise OutputExistsError(f"{o}: is an input of this command ({i}); choose another "
                                        "output (inputs are never modified, even with --force)")
    for d in (Path(p) for p in folders if p is not None):
        for i in ins:
            if _same(d, i) or _inside(i, d):
                raise OutputExistsError(f"{d}: holds the input {i}; choose another output folder "
                                        "(inputs are never modified, even with --force)")


def check_writable(path: str | os.PathLike, force: bool = False) -> Path:
    """Refuse to overwrite an existing file unless ``force``; create parent folders."""
    path = Path(path)
    if path.exists() and not force:
        raise OutputExistsError(f"{path}: exists; pass --force to overwrite it")
    if path.is_dir():
        raise OutputExistsError(f"{path}: is a folder; expected a file name")
    path.parent.mkdir(parents=True, exist_ok=True)
    return path


def check_not_input(path: str | os.PathLike, inputs) -> None:
    """Refuse an output path that is one of the ``inputs`` (paths or None), even with --force."""
    guard_inputs([path], inputs)


def claim_output(path: str | os.PathLike) -> None:
    """Lock ``path`` for this run now, before work that precedes its :func:`output_folder`
    (:func:`calidar.run_lock.claim`; the CLI releases it when the run ends)."""
    run_lock.claim(path)


def check_out_dir(path: str | os.PathLike, force: bool = False) -> Path:
    """Refuse (before any work) an output folder that is a file, or exists non-empty without
    ``force``. Creates nothing."""
    path = Path(path)
    if path.exists() and not path.is_dir():
        raise OutputExistsError(f"{path}: exists and is not a folder")
    if path.is_dir() and any(path.iterdir()) and not force:
        raise OutputExistsError(f"{path}: folder exists and is not empty; "
                                "pass --force to write into it")
    return path


def prepare_out_dir(path: str | os.PathLike, force: bool = False) -> Path:
    """Create an output folder; refuse an existing non-empty one unless ``force``. For a sub-folder
    of a run's own (temporary) output; a command's ``--out`` goes through :func:`output_folder`."""
    path = check_out_dir(path, force)
    path.mkdir(parents=True, exist_ok=True)
    return path


@contextlib.contextmanager
def output_folder(path: str | os.PathLike, force: bool = False,
                  inputs: Iterable = ()) -> Iterator[Path]:
    """A run's output folder as a transaction: yields a fresh hidden folder beside ``path``; on
    success it replaces ``path`` whole (created when absent; under ``--force`` the previous folder
    goes whole, so no file of an earlier run stays); on any exception (interruptions included) it
    is removed and ``path`` is left as it was, byte for byte. The output is locked for the run
    (:mod:`calidar.run_lock`): a second run into it is refused.

    >>> with output_folder(tmp / "out") as d: (d / "a.json").write_text("{}")   # doctest: +SKIP
    """
    shown = str(path)
    path = check_out_dir(path, force)
    guard_inputs([], inputs, [path])
    if path.is_symlink():  # a link to a folder: the folder it points to is the output
        path = Path(os.path.realpath(path))
    with run_lock.hold(path, shown):
        # again under the lock: another run may have written it meanwhile
        check_out_dir(path, force)
        tmp = _temporary(lambda: _create_folder_beside(path, shown), shown)
        _DEPTH[0] += 1
        try:
            yield tmp
            _commit(tmp, path, shown)
        except BaseException as e:
            show_destinations(e)
            _raise_write_error(e, shown, tmp)
            raise
        finally:
            _DEPTH[0] -= 1
            with interrupts.deferred():  # the clean-up is not cut short
                shutil.rmtree(tmp, ignore_errors=True)
                _TEMPORARIES.pop(str(tmp), None)


def _create_folder_beside(path: Path, shown: str) -> Path:
    """A fresh hidden folder beside ``path`` (its parents created), or a one-line error."""
    try:
        path.parent.mkdir(parents=True, exist_ok=True)
        return Path(tempfile.mkdtemp(prefix=f".{path.name}.calidar-", dir=path.parent))
    except OSError as e:
        message = f"{shown}: cannot create the output folder: {e.strerror or e}"
        raise OutputWriteError(message) from None


def _commit(tmp: Path, path: Path, shown: str) -> None:
    """Put a finished run's folder in place of ``path``, whole: renamed when ``path`` is absent,
    else exchanged with the previous folder in one step (Linux ``renameat2(RENAME_EXCHANGE)``, or
    two renames undone on failure). The previous folder ends at ``tmp`` (removed by the caller).
    No commit after a signal (:func:`calidar.interrupts.check`)."""
    os.chmod(tmp, 0o777 & ~_umask())
    top = _DEPTH[0] == 1
    interrupts.check()
    if not os.path.lexists(path):
        os.rename(tmp, path)
    elif path.is_symlink() or not path.is_dir():
        now = "a link" if path.is_symlink() else "a file"
        raise OutputExistsError(f"{shown}: changed during the run (now {now}, not the folder it "
                                "was); left as it is, nothing written")
    else:
        try:
            _exchange(tmp, path)
        except OSError as e:
            raise OutputWriteError(f"{shown}: cannot replace the folder ({e.strerror or e}"
                                   f"{_why(e)}); the previous result is left as it was") from None
    if top:
        interrupts.mark_committed()


_WHY = {errno.EBUSY: ": a mount point or in use", errno.EXDEV: ": another file system"}


def _why(e: OSError) -> str:
    return _WHY.get(e.errno, "")


def _exchange(a: Path, b: Path) -> None:
    """Swap two folders' names: atomically where the kernel can, else two renames (undone on
    failure)."""
    if _renameat2(a, b):
        return
    aside = Path(tempfile.mkdtemp(prefix=f".{b.name}.calidar-old-", dir=b.parent))
    os.rmdir(aside)
    os.rename(b, aside)
    try:
        os.rename(a, b)
    except BaseException:
        os.rename(aside, b)
        raise
    os.rename(aside, a)


def _renameat2(a: Path, b: Path) -> bool:
    """``renameat2(a, b, RENAME_EXCHANGE)``; False where unsupported (not Linux, old kernel, a file
    system without it), an OSError for a real failure."""
    import ctypes

    if not sys.platform.startswith("linux"):
        return False
    try:  # the libc this process runs on (no ldconfig process, see memory.release_memory)
        fn = ctypes.CDLL(None, use_errno=True).renameat2
    except (OSError, AttributeError):
        return False
    at_fdcwd, rename_exchange = -100, 2
    if fn(at_fdcwd, os.fsencode(a), at_fdcwd, os.fsencode(b), rename_exchange) == 0:
        return True
    err = ctypes.get_errno()
    if err in (errno.ENOSYS, errno.EINVAL, errno.ENOTSUP):
        return False
    raise OSError(err, os.strerror(err), str(b))


_WRITE_ERRNOS = {errno.ENOSPC, errno.EFBIG, errno.EDQUOT, errno.EROFS, errno.EIO}
_WRITE_WORDS = ("No space left on device", "os error 28", "errno = 28", "File too large",
                "Disk quota exceeded", "Read-only file system")


def _raise_write_error(e: BaseException, shown: str, tmp: Path) -> None:
    """Turn an error of writing the results (a full disk, a file too large, a read-only file
    system), however a library reports it (an OSError, LazrsError, h5py's errors), into one line
    naming the destination and the cause; other errors pass unchanged."""
    if isinstance(e, (CalidarError, KeyboardInterrupt)) or not isinstance(e, Exception):
        return
    cause = _write_cause(e, tmp)
    if cause is not None:
        what, file = cause
        target = shown_path(file) if file else "the results"
        raise OutputWriteError(f"{shown}: cannot write {target}: {what}") from None


def _write_cause(e: BaseException, tmp: Path) -> tuple[str, str | None] | None:
    """(the cause, the file when known) of a failed write, or None when ``e`` is not one."""
    seen = set()
    while e is not None and id(e) not in seen:
        seen.add(id(e))
        if isinstance(e, OSError) and e.errno in _WRITE_ERRNOS:
            return os.strerror(e.errno), e.filename if isinstance(e.filename, str) else None
        text = str(e)
        for words in _WRITE_WORDS:
            if words in text:
                return ("No space left on device" if "28" in words else words), None
        e = e.__cause__ or e.__context__
    try:
        st = os.statvfs(tmp if tmp.exists() else tmp.parent)
    except OSError:
        return None
    return ("No space left on device", None) if st.f_bavail * st.f_frsize < FULL_BYTES else None


FULL_BYTES = 64 * 1024  #: free space below which a failed write is blamed on a full disk


def _temporary(create: Callable[[], Path], shown: str) -> Path:
    """Create a temporary file or folder and register it in one step a signal cannot split: a
    signal held back meanwhile is raised after the registration, and the temporary goes with it."""
    made: list[Path] = []
    try:
        with interrupts.deferred():
            made.append(create())
            _TEMPORARIES[str(made[0])] = shown
    except interrupts.Interrupted:
        for tmp in made:
            _remove(str(tmp))
            _TEMPORARIES.pop(str(tmp), None)
        raise
    return made[0]


def _remove(tmp: str) -> None:
    """Remove a temporary file or folder (retried: a thread may still be writing into it)."""
    for _ in range(3):
        if os.path.isdir(tmp) and not os.path.islink(tmp):
            shutil.rmtree(tmp, ignore_errors=True)
        else:
            with contextlib.suppress(OSError):
                os.unlink(tmp)
        if not os.path.lexists(tmp):
            break


_REMOVALS: list = []  #: threads removing temporaries no longer needed (:func:`remove_soon`)


def remove_soon(tmp: str | os.PathLike) -> None:
    """Remove a registered temporary (e.g. the held points of a first pass, once the last pass has
    read them) in a thread, beside the work that follows: unlinking large files is the kernel's
    work, done while the run writes its report. It stays registered until it is gone (an
    interruption meanwhile removes it as every temporary); :func:`finish_removals` waits."""
    import threading

    def remove() -> None:
        _remove(str(tmp))
        _TEMPORARIES.pop(str(tmp), None)

    thread = threading.Thread(target=remove, name="calidar-remove")
    _REMOVALS[:] = [t for t in _REMOVALS if t.is_alive()] + [thread]
    thread.start()


def finish_removals() -> None:
    """Wait for the removals :func:`remove_soon` started."""
    while _REMOVALS:
        _REMOVALS.pop().join()


def remove_temporaries() -> None:
    """Remove every live temporary of this process and its output locks at once (a second Ctrl-C:
    the run ends now, without unwinding)."""
    for tmp in list(_TEMPORARIES):
        _remove(tmp)
    for lock in run_lock.held_paths():
        with contextlib.suppress(OSError):
            lock.unlink()


def _umask() -> int:
    mask = os.umask(0)
    os.umask(mask)
    return mask


@contextlib.contextmanager
def atomic_path(path: str | os.PathLike, force: bool = True) -> Iterator[Path]:
    """Yield a temporary path beside ``path``; rename it onto ``path`` only on success.

    >>> with atomic_path(tmp / "a.json") as p: p.write_text("{}")   # doctest: +SKIP
    """
    path = check_writable(path, force)
    def create() -> Path:
        try:
            fd, tmp = tempfile.mkstemp(prefix=f".{path.name}.", suffix=path.suffix, dir=path.parent)
        except OSError as e:
            message = f"{shown_path(str(path))}: cannot write: {e.strerror or e}"
            raise OutputWriteError(message) from None
        os.close(fd)
        return Path(tmp)

    tmp = _temporary(create, shown_path(str(path)))
    _DEPTH[0] += 1
    try:
        yield tmp
        os.chmod(tmp, 0o666 & ~_umask())  # mkstemp makes 0600; give the usual permissions
        top = _DEPTH[0] == 1
        interrupts.check()
        os.replace(tmp, path)
        if top:
            interrupts.mark_committed()
    except BaseException as e:
        show_destinations(e)
        if _DEPTH[0] == 1:  # inside a folder's transaction, the folder's names the destination
            _raise_write_error(e, shown_path(str(path)), tmp)
        raise
    finally:
        _DEPTH[0] -= 1
        with interrupts.deferred(), contextlib.suppress(FileNotFoundError):
            tmp.unlink()
        _TEMPORARIES.pop(str(tmp), None)


def write_text_atomic(path: str | os.PathLike, text: str, force: bool = True) -> Path:
    """Write text atomically (force=True: outputs inside a folder already checked)."""
    with atomic_path(path, force) as tmp:
        tmp.write_text(text, encoding="utf-8")
    return Path(path)

