"""One pipeline per method: load the inputs, run the method, write the outputs.

The CLI (``calidar.cli``), the demo (``calidar.demo``) and the benchmarks call these and nothing
below them for a whole run, so that a command, its demo step and its benchmark do the same
thing. A pipeline takes plain values (paths, settings dataclasses), writes into the folder it
is given (the CLI hands it the temporary folder of an output transaction, see
:func:`calidar.outputs.output_folder`), reports progress through an optional
``progress(description, done, total)`` callable and returns its result; it never prints.

Layers, top to bottom (an import may only point down; ``tests/unit/test_architecture.py``):
``cli`` → ``demo`` → ``pipelines`` → methods (``strips``, ``photon``, ``rangecal``, the
``scanners`` analysis, ``sim``) → ``io`` (files in, core objects out) → core (``georef``,
``sensor`` and the scanner models, ``trajectory``, ``frames``, ``adjust``, ``report``) →
``errors``, ``validate``, ``outputs``.
"""

from __future__ import annotations

from calidar.ingest import Progress, no_progress  # the callback convention every long step shares

__all__ = ["Progress", "no_progress", "release_memory"]


def release_memory() -> None:
    """Hand the memory freed by a finished stage back to the system (glibc keeps freed pages of
    its arenas: after the calibration, half a GiB of an 8.75 M-point run); elsewhere nothing."""
    import ctypes
    import ctypes.util

    try:
        ctypes.CDLL(ctypes.util.find_library("c") or "libc.so.6").malloc_trim(0)
    except (OSError, AttributeError):  # not glibc
        pass
