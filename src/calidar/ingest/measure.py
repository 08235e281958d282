"""The overlap quality of a survey's whole flight lines, streamed from their files (a
:class:`~calidar.ingest.source.StripSource`) as delivered and re-georeferenced
(:func:`calidar.ingest.source.line_chunks`), every stage in one read: each file read in tasks of
:data:`TASK_POINTS` points, each task's cell moments merged (:mod:`calidar.ingest.stages`)."""

from __future__ import annotations

from calidar.ingest import Progress, no_progress
from calidar.ingest.source import line_chunks
from calidar.ingest.stages import StagePass, lines_quality, stage_pass
from calidar.strips.quality import QualitySettings

#: points of a file read by one overlap-quality task: what a task sends back (its cells' moments)
#: stays small however large the files (≈ 40 MB at 20 points/m²)
TASK_POINTS = 4_000_000


def measure_lines(source, nominal, models, progress: Progress = no_progress, work=None,
                  settings: QualitySettings = QualitySettings()) -> list[list]:
    """Per model of :func:`calidar.ingest.source.line_chunks` (None: the lines of ``source`` as
    delivered, else a (sensor, trajectory) they are re-georeferenced with from the ``nominal``
    sensor), the :class:`calidar.strips.quality.PairQuality` of every overlapping pair of flight
    lines, by :func:`calidar.ingest.stages.lines_quality` on the plan of the ingest's counts: one
    read of the files (two when a stage's own plan differs), each file a task run by ``work`` (a
    :class:`calidar.strips.distribute.Workers`; None: one at a time here); memory holds cells, not
    points; ``settings``: the swath difference's
    (:class:`calidar.strips.quality.QualitySettings`)."""
    import tempfile

    from calidar.ingest import release_memory
    from calidar.ingest.cell_counts import Metric
    from calidar.io.las import las_file_crs, las_header
    from calidar.strips.distribute import Workers

    f = source.files[0]
    crs = las_file_crs(f.path, f.points.crs)
    frame = source.frame if crs is not None and crs.is_geographic else None
    # the ingest's grid: its counts make the plan
    metric = Metric(crs, frame, f.points.geoid_undulation_m, f.path)
    tasks = [(k, a, min(a + TASK_POINTS, n)) for k, f in enumerate(source.files)
             for n in [las_header(f.path).point_count] for a in range(0, max(n, 1), TASK_POINTS)]
    total = sum(b - a for _, a, b in tasks)

    def read(plans, chosen, count):
        out, done = StagePass.start(plans, settings.cell_m, count, spill), 0
        shared = (source, nominal, models, metric, plans, chosen, count, settings.cell_m)
        parts = (work or Workers()).run(_file_stages, tasks, shared, kind="overlap quality")
        for (_, a, b), part in zip(tasks, parts):
            out.merge(part)
            del part
            release_memory()  # each task's working arrays
            done += b - a
            progress("overlap quality: reading strips", done, total)
        return out

    # the cell moments beyond HOLD_BYTES spill into a temporary folder
    with tempfile.TemporaryDirectory(prefix="calidar-moments-") as spill:
        return lines_quality(read, source.quality, len(models), source.names, settings,
                             threads=work.local_threads if work else 1)


def _file_stages(source, nominal, models, metric, plans, chosen, count, cell_m, k: int,
                 start: int, stop: int):
    """:func:`calidar.ingest.stages.stage_pass` of the points [start, stop) of the ``k``-th file
    (a task)."""
    from calidar.ingest.stages import chosen_points
    from calidar.strips.selection import FIELDS, candidate_mask

    # only the points each line's selection keeps are re-georeferenced (the ground of a
    # classified line: 27 % of the points of line_002 of large_flight.py's 8.75 M flight)
    chunks = line_chunks(source, nominal, models, FIELDS, candidate_mask,
                         files=[source.files[k]], span=(start, stop),
                         select=chosen_points(chosen))
    return stage_pass(chunks, metric, plans, chosen, cell_m, count=count)
