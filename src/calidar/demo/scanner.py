"""Demo step: structural errors of a Palmer scanner, their separability from the boresight, and
the boresight + Palmer parameters estimated from noisy control points."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from calidar.pipelines import Progress, no_progress

#: Palmer errors of the demo (user units): a well-built scanner, within a 10″ spec at 500 m
DEMO_SCANNER_ERRORS = {"eccentricity": 5e-6 / 0.075, "delta_l": 0.0005, "delta_r": 0.0005}
#: the control-point adjustment's truth (SI): larger errors, so that the estimates stand out of
#: the noise
CONTROL_TRUTH = {
    "boresight_roll": np.radians(0.05),
    "boresight_pitch": np.radians(-0.03),
    "boresight_yaw": np.radians(0.1),
    "eccentricity_ratio": 2e-4,
    "eccentricity_phase": np.radians(30.0),
    "delta_l": np.radians(0.02),
    "delta_r": np.radians(0.02),
}


def scanner_analysis_step(report, out_dir: Path, seed: int,
                          progress: Progress = no_progress) -> None:
    """Analyse a Palmer scanner at 500 m (``calidar scanner analyze``'s pipeline) into
    ``out_dir/scanner_analysis`` with its verdict and section, then add the control-point
    adjustment (noise drawn from ``seed``). A few seconds."""
    from calidar.outputs import prepare_out_dir
    from calidar.pipelines.scanner import run_scanner_analysis
    from calidar.scanners.report import add_control_section
    from calidar.scanners.separability import control_adjustment
    from calidar.scanners.settings import AnalysisSettings

    sub = prepare_out_dir(Path(out_dir) / "scanner_analysis", force=True)
    run_scanner_analysis(AnalysisSettings("palmer", 500.0, DEMO_SCANNER_ERRORS), sub, report=report,
                         title="Palmer scanner: structural errors at 500 m", progress=progress)
    add_control_section(report, control_adjustment(CONTROL_TRUTH, n=2000, seed=seed), CONTROL_TRUTH)
