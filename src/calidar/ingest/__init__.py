"""The streaming engine: LAS/LAZ strips read chunk by chunk in bounded memory, for the strip
calibration (:class:`calidar.ingest.strips.StripIngest`, one
:class:`~calidar.ingest.settings.IngestSettings`) and the overlap quality
(:mod:`calidar.ingest.stages`, :mod:`calidar.ingest.cell_counts`).

A layer of its own between the pipelines (which orchestrate: inputs, outputs, verdicts) and the
methods (``strips``: lines, overlaps, thinning, strips): it reads files through ``calidar.io`` and
hands the methods arrays. Modules: ``settings`` (how strips are read), ``times`` (points into the
trajectory's frame and time), ``plausibility`` (the geometry checks of each chunk), ``held`` (what a
first pass keeps for the next), ``source`` (the files behind the strips, streamed again),
``footprints`` (the first pass), ``strips`` (the two passes into strips), ``stages`` (the overlap
quality of streamed lines), ``measure`` (every stage of it in one read), ``cell_counts`` (``calidar
quality``'s first pass).
"""

from __future__ import annotations

from collections.abc import Callable

from calidar.memory import release_memory  # noqa: F401 - the streamed stages hand memory back

#: progress(description, done, total): what a long step reports as it goes
Progress = Callable[[str, int, int], None]


def no_progress(description: str, done: int, total: int) -> None:
    """The default ``progress``: report nothing."""
