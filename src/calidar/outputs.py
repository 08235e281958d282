"""Safe output writing: runs as transactions, atomic files, no silent overwrite, inputs never touched.

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
import os
import shutil
import tempfile
from collections.abc import Iterable, Iterator
from pathlib import Path

from calidar.errors import OutputExistsError

_TEMPORARIES: dict[str, str] = {}  #: temporary path → the destination it stands for (for messages)


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


def guard_inputs(outputs: Iterable[str | os.PathLike | None], inputs: Iterable[str | os.PathLike | None],
                 folders: Iterable[str | os.PathLike | None] = ()) -> None:
    """Refuse, whatever ``--force`` says, an output file that is an input (same path or hard link)
    and an output folder that holds an input. ``outputs``: files; ``folders``: output folders."""
    ins = [Path(i) for i in inputs if i is not None]
    for o in (Path(p) for p in outputs if p is not None):
        for i in ins:
            if _same(o, i):
                raise OutputExistsError(f"{o}: is an input of this command ({i}); choose another output "
                                        "(inputs are never modified, even with --force)")
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


def check_out_dir(path: str | os.PathLike, force: bool = False) -> Path:
    """Refuse (before any work) an output folder that is a file, or exists non-empty without ``force``.
    Creates nothing."""
    path = Path(path)
    if path.exists() and not path.is_dir():
        raise OutputExistsError(f"{path}: exists and is not a folder")
    if path.is_dir() and any(path.iterdir()) and not force:
        raise OutputExistsError(f"{path}: folder exists and is not empty; pass --force to write into it")
    return path


def prepare_out_dir(path: str | os.PathLike, force: bool = False) -> Path:
    """Create an output folder; refuse an existing non-empty one unless ``force``. For a sub-folder
    of a run's own (temporary) output; a command's ``--out`` goes through :func:`output_folder`."""
    path = check_out_dir(path, force)
    path.mkdir(parents=True, exist_ok=True)
    return path


@contextlib.contextmanager
def output_folder(path: str | os.PathLike, force: bool = False, inputs: Iterable = ()) -> Iterator[Path]:
    """A run's output folder as a transaction: yields a fresh hidden folder beside ``path``; on
    success its entries replace those of ``path`` (created when absent, renamed whole); on any
    exception (interruptions included) it is removed and ``path`` is left as it was.

    >>> with output_folder(tmp / "out") as d: (d / "a.json").write_text("{}")   # doctest: +SKIP
    """
    path = check_out_dir(path, force)
    guard_inputs([], inputs, [path])
    path.parent.mkdir(parents=True, exist_ok=True)
    tmp = Path(tempfile.mkdtemp(prefix=f".{path.name}.calidar-", dir=path.parent))
    _TEMPORARIES[str(tmp)] = str(path)
    try:
        yield tmp
        _commit(tmp, path)
    except BaseException as e:
        show_destinations(e)
        raise
    finally:
        _TEMPORARIES.pop(str(tmp), None)
        shutil.rmtree(tmp, ignore_errors=True)


def _commit(tmp: Path, path: Path) -> None:
    """Move a finished run's folder into place (whole when ``path`` is absent, else entry by entry)."""
    os.chmod(tmp, 0o777 & ~_umask())
    if not path.exists():
        os.rename(tmp, path)
        return
    for entry in tmp.iterdir():
        dest = path / entry.name
        if dest.is_dir() and not dest.is_symlink():
            shutil.rmtree(dest)
        os.replace(entry, dest)


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
    fd, tmp = tempfile.mkstemp(prefix=f".{path.name}.", suffix=path.suffix, dir=path.parent)
    os.close(fd)
    tmp = Path(tmp)
    _TEMPORARIES[str(tmp)] = str(path)
    try:
        yield tmp
        os.chmod(tmp, 0o666 & ~_umask())  # mkstemp makes 0600; give the usual permissions
        os.replace(tmp, path)
    except BaseException as e:
        show_destinations(e)
        raise
    finally:
        _TEMPORARIES.pop(str(tmp), None)
        if tmp.exists():
            tmp.unlink()


def write_text_atomic(path: str | os.PathLike, text: str, force: bool = True) -> Path:
    """Write text atomically (force=True: outputs inside a folder already checked)."""
    with atomic_path(path, force) as tmp:
        tmp.write_text(text, encoding="utf-8")
    return Path(path)

