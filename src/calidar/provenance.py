"""What produced a result: calidar's version, the command line, every input file (path, size,
sha256), the options and the time — recorded in ``solution.json`` and shown in the report, so
that a deliverable can be traced and reproduced.

>>> argv = ["calidar", "boresight", "a.laz"]
>>> rec = RunRecord.capture(argv, inputs=[], options={"method": "planes"})
>>> sorted(rec.to_dict())
['argv', 'calidar_version', 'finished_utc', 'inputs', 'options', 'python', 'started_utc']
"""

from __future__ import annotations

import hashlib
import os
import platform
import sys
from dataclasses import dataclass, field
from datetime import datetime, timezone
from pathlib import Path

from calidar import __version__


def sha256(path: str | os.PathLike, chunk: int = 1 << 22) -> str:
    """The file's SHA-256 (hex), read in chunks."""
    h = hashlib.sha256()
    with open(path, "rb") as f:
        while block := f.read(chunk):
            h.update(block)
    return h.hexdigest()


def _now() -> str:
    return datetime.now(timezone.utc).strftime("%Y-%m-%dT%H:%M:%SZ")


@dataclass
class RunRecord:
    """A run's provenance (see the module docstring)."""

    argv: list[str]
    inputs: list[dict] = field(default_factory=list)  #: per file: path, size_bytes, sha256
    options: dict = field(default_factory=dict)
    started_utc: str = field(default_factory=_now)
    finished_utc: str | None = None
    #: tasks run on Dask, by kind: how many, bytes sent back
    tasks: dict = field(default_factory=dict)

    @classmethod
    def capture(cls, argv: list[str] | None = None, inputs=(),
                options: dict | None = None) -> "RunRecord":
        """Record ``argv`` (default: this process's), the input files that exist and ``options``."""
        files = [_file_entry(Path(p)) for p in inputs if p is not None and Path(p).is_file()]
        return cls(list(sys.argv) if argv is None else [str(a) for a in argv], files,
                   {k: _plain(v) for k, v in (options or {}).items()})

    def finish(self) -> "RunRecord":
        self.finished_utc = _now()
        return self

    def to_dict(self) -> dict:
        doc = {"calidar_version": __version__, "python": platform.python_version(),
               "argv": self.argv, "inputs": self.inputs, "options": self.options,
               "started_utc": self.started_utc, "finished_utc": self.finished_utc}
        if self.tasks:
            doc["dask_tasks"] = self.tasks
        return doc


def _file_entry(path: Path) -> dict:
    """An input file's entry: its absolute path, size and SHA-256."""
    return {"path": str(path.resolve()), "size_bytes": path.stat().st_size, "sha256": sha256(path)}


def _plain(v):
    """An option value as JSON can hold it (paths as strings, tuples as lists)."""
    if isinstance(v, os.PathLike):
        return str(v)
    if isinstance(v, (list, tuple)):
        return [_plain(x) for x in v]
    if isinstance(v, dict):
        return {str(k): _plain(x) for k, x in v.items()}
    return v if v is None or isinstance(v, (bool, int, float, str)) else str(v)


def describe_tasks(tasks: dict) -> str:
    """One line for :attr:`RunRecord.tasks`: per kind, how many and what they sent back."""
    return "; ".join(f"{k}: {d['tasks']} tasks sent back {d['bytes_sent_back'] / 1e6:.3g} MB "
                     f"(largest {d['max_bytes_per_task'] / 1e6:.3g} MB)" for k, d in tasks.items())
