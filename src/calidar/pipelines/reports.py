"""Where a pipeline's report goes: its own report.html (with the run record), or a report it is
handed (the demo's), to which it adds its verdict and section."""

from __future__ import annotations

import contextlib
from collections.abc import Iterator
from pathlib import Path


@contextlib.contextmanager
def report_for(report, title: str, record, path: Path, verdict, method: str) -> Iterator:
    """Yield the report to add sections to — ``report`` when given, else a new one titled ``title``
    with ``record`` that is written to ``path`` on leaving — after adding ``verdict`` at its top
    (headed by the ``method``'s name in a shared report)."""
    from calidar.report import Report

    own = report is None
    if own:
        report = Report(title)
        report.record = record
    report.add_verdict(verdict, None if own else method)
    yield report
    if own:
        report.write(path)
