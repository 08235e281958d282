"""The scanner pipelines: the structural-error analysis (``calidar scanner analyze``, its demo
step) and the Palmer strip self-calibration experiment (``benchmarks/palmer_selfcal.py``)."""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np

from calidar.pipelines import Progress, no_progress

if TYPE_CHECKING:  # the run's parts, by type (imported where used)
    from calidar.scanners.analysis import ScannerAnalysis
    from calidar.scanners.separability import Separability
    from calidar.verdict import Verdict


@dataclass
class ScannerRun:
    """What one analysis produced: the analysis, its separability, the verdict and summary.json's
    document."""

    analysis: ScannerAnalysis
    separability: Separability
    verdict: Verdict
    summary: dict


def run_scanner_analysis(settings, out_dir: Path, *, argv: list[str] | None = None,
                         report=None, title: str | None = None,
                         progress: Progress = no_progress) -> ScannerRun:
    """Analyse ``settings`` (:class:`calidar.scanners.settings.AnalysisSettings`) and write into the
    existing folder ``out_dir``: pattern and displacement CSV/PNG, summary.json (with the verdict
    and the run record) and report.html — or, when ``report`` is given, add the verdict and the
    section to it instead of writing report.html."""
    from calidar.pipelines.reports import report_for
    from calidar.provenance import RunRecord
    from calidar.scanners.analysis import analyze, pattern_angles
    from calidar.pipelines.scanner_files import separability_summary, write_curves, write_summary
    from calidar.scanners.report import add_section
    from calidar.scanners.separability import SEPARATION_SAMPLES, separability
    from calidar.scanners.sources import error_sources
    from calidar.scanners.verdict import analysis_verdict

    record = RunRecord.capture(argv, inputs=[], options=settings.options())
    a = analyze(settings, progress)
    phase, tilt_azimuth = np.radians(settings.phase_deg), np.radians(settings.axis_tilt_azimuth_deg)
    sources = error_sources(a.model, phase, tilt_azimuth)
    angles = pattern_angles(a.scanner, SEPARATION_SAMPLES, np.radians(settings.fov_deg))
    sep = separability(a.scanner, sources, angles, a.range_m)
    verdict = analysis_verdict(a, sep)
    progress("writing outputs", 0, 1)
    write_curves(a, out_dir)
    record.finish()
    doc = {**a.summary(), "separability": separability_summary(sep), "verdict": verdict.to_dict(),
           "run": record.to_dict()}
    write_summary(doc, Path(out_dir) / "summary.json")
    title_line = f"calidar scanner analysis: {a.model} at {a.range_m:g} m"
    with report_for(report, title_line, record, Path(out_dir) / "report.html", verdict,
                    "Scanner structural errors") as rep:
        add_section(rep, a, sep, title)
    progress("writing outputs", 1, 1)
    return ScannerRun(a, sep, verdict, doc)


#: true − nominal of the simulated Palmer survey (SI); the nominal ε/r is 1e-5 so that C is defined
SURVEY_ERRORS = {"boresight_roll": np.radians(0.05), "boresight_pitch": np.radians(-0.04),
                 "boresight_yaw": np.radians(0.08), "eccentricity_ratio": 5e-4,
                 "eccentricity_phase": np.radians(30.0),
                 "delta_l": np.radians(0.05), "delta_r": np.radians(0.05)}


def palmer_strip_selfcal(preset: str = "uav", *, density: float = 0.3,
                         height_agl_m: float | None = None, seed: int = 0,
                         errors: dict[str, float] | None = None,
                         estimates=(("boresight",), ("boresight", "palmer")),
                         progress: Progress = no_progress, **survey):
    """Self-calibration of a simulated Palmer survey from overlapping strips (tie planes).

    Simulates a ``preset`` survey (cross lines) shot by a Palmer sensor with ``errors`` (SI,
    default :data:`SURVEY_ERRORS`) and delivered with the nominal one, then runs the strip
    calibrator once per entry of ``estimates``. ``survey``: further
    :class:`calidar.sim.survey.SurveyConfig` fields (e.g. gnss_noise_m=0). Returns (truth
    parameters SI, {estimate tuple: CalibrationResult}).
    """
    from calidar.scanners import PalmerScanner
    from calidar.sensor import Sensor
    from calidar.sim.survey import simulate_survey, survey_config
    from calidar.strips.calibrate import calibrate
    from calidar.strips.config import CalibrationConfig, Estimate

    scanner = PalmerScanner(eccentricity_ratio=1e-5)
    nominal = Sensor(lever_arm_x=0.05, lever_arm_z=0.12, scanner=scanner)
    extra = dict(survey) if height_agl_m is None else {**survey, "height_agl_m": height_agl_m}
    cfg = survey_config(preset, seed=seed, directions="cross", density=density, nominal=nominal,
                        errors=dict(errors or SURVEY_ERRORS), **extra)
    res = simulate_survey(cfg)
    strips = res.calibration_strips()
    results = {}
    for k, est in enumerate(estimates):
        progress("strip calibrations", k, len(estimates))
        results[est] = calibrate(strips, res.nominal, CalibrationConfig(Estimate.of(*est)))
    progress("strip calibrations", len(estimates), len(estimates))
    return res.truth.parameters(), results
