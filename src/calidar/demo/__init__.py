"""``calidar demo``: simulate a small survey, run every calibration, write one HTML report.

``DEMO_STEPS`` is the list of steps, run in order as ``step(report, out_dir, seed, progress)``.
The first one simulates the survey into ``out_dir / DEMO_SURVEY`` (``strips/*.laz``,
``sbet.out``, ``sensor.toml`` nominal, ``truth.json``) and adds the simulation section; the
calibration steps read that folder through their pipelines (``calidar.pipelines``), add their
own section and verdict, and report progress through ``progress(description, done, total)``.
"""

from __future__ import annotations

from collections.abc import Callable
from pathlib import Path

from calidar.demo.boresight import boresight_step
from calidar.demo.photon import photon_step
from calidar.demo.rangecal import range_calibration_step
from calidar.demo.scanner import scanner_analysis_step
from calidar.demo.survey import DEMO_ERRORS, DEMO_SURVEY, demo_config, simulation_step  # noqa: F401
from calidar.pipelines import Progress, no_progress
from calidar.report import Report

DEMO_STEPS: list[Callable[[Report, Path, int, Progress], None]] = [
    simulation_step,
    boresight_step,
    scanner_analysis_step,
    range_calibration_step,
    photon_step,
]


def run_demo(out_dir: str | Path, seed: int = 0, progress: Progress = no_progress) -> Report:
    """Run every step of ``DEMO_STEPS`` into the folder ``out_dir`` (created; the CLI hands it the
    temporary folder of an output transaction) and write out_dir/report.html; returns the report
    (its ``verdicts``: one per step, in order)."""
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    report = Report("calidar demo")
    for k, step in enumerate(DEMO_STEPS):
        step(report, out, seed, progress)
        progress("demo steps", k + 1, len(DEMO_STEPS))
    report.write(out / "report.html")
    return report
