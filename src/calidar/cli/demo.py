"""``calidar demo``: simulate a small survey, run every calibration, write DIR/report.html."""

from __future__ import annotations

import time
from pathlib import Path

import typer

from calidar.cli.common import console, progress_bar
from calidar.cli.simulate_survey import progress_callback


def register(app: typer.Typer, simulate: typer.Typer) -> None:
    @app.command("demo")
    def demo(
        out: Path = typer.Option(..., "--out", help="Output folder for report.html and the simulated survey."),
        seed: int = typer.Option(0, "--seed", help="Random seed of the simulated survey."),
        force: bool = typer.Option(False, "--force", help="Write into an existing non-empty folder."),
    ) -> None:
        """Simulate a small survey, run every calibration calidar has, and write DIR/report.html."""
        from calidar.demo import run_demo
        from calidar.outputs import prepare_out_dir

        prepare_out_dir(out, force)
        t0 = time.perf_counter()
        with progress_bar() as bar:
            path = run_demo(out, seed=seed, force=True, progress_callback=progress_callback(bar))
        console.print(f"report: {path} ({time.perf_counter() - t0:.0f} s)")
