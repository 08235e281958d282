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

from calidar.ingest import Progress, no_progress, release_memory  # shared with the streaming engine

__all__ = ["Progress", "no_progress", "release_memory"]
