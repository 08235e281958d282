"""``calidar demo``: simulate a small survey, run every calibration, write DIR/report.html."""

from __future__ import annotations

import time
from pathlib import Path

import typer

from calidar.cli.common import (
    FORCE_HELP, console, exit_with_verdict, print_verdict, progress_bar, progress_callback,
)


OUT = typer.Option(..., "--out", help="Output folder for report.html and the simulated survey.")


def demo(
    out: Path = OUT,
    seed: int = typer.Option(0, "--seed", min=0, help="Random seed of the simulated survey (≥ 0)."),
    force: bool = typer.Option(False, "--force", help=FORCE_HELP),
) -> None:
    """Simulate a small survey, run every calibration calidar has, and write DIR/report.html."""
    from calidar.demo import run_demo
    from calidar.outputs import output_folder

    t0 = time.perf_counter()
    with output_folder(out, force) as tmp, progress_bar() as bar:
        report = run_demo(tmp, seed=seed, progress=progress_callback(bar))
    for title, verdict in report.verdicts:
        print_verdict(verdict, title, brief=True)
    console.print(f"report: {out / 'report.html'} ({time.perf_counter() - t0:.0f} s)", markup=False)
    exit_with_verdict(*(v for _, v in report.verdicts))


def register(app: typer.Typer, simulate: typer.Typer) -> None:
    app.command("demo")(demo)
