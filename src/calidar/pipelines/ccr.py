"""The CCR calibration pipeline (``calidar ccr`` and its demo step): read the passes and the
CCR survey, calibrate, write ``solution.json`` and the report."""

from __future__ import annotations

from pathlib import Path

from calidar.errors import InputError
from calidar.outputs import prepare_out_dir
from calidar.validate import read_json


def _existing(path: Path) -> Path:
    if not path.is_file():
        raise FileNotFoundError(2, "No such file", str(path))
    return path


def run_ccr(files: list[Path], beam: str, ccr: Path, out: Path, *, system, settings, truth_path: Path | None,
            force: bool, report=None):
    """Read, calibrate, write solution.json (+ report.html unless a report is passed in). Returns the result."""
    from calidar.io.atl03 import read_atl03
    from calidar.photon.ccr import PARAMETERS, calibrate, prepare_pass, read_ccr_csv
    from calidar.photon.report import add_section
    from calidar.report import Report

    survey = read_ccr_csv(_existing(ccr))
    truth = None
    if truth_path is not None:
        doc = read_json(truth_path)
        try:
            truth = {k: float(doc[k]) for k in PARAMETERS}
        except (KeyError, TypeError, ValueError):
            raise InputError(truth_path, None, f"expected JSON with numbers {', '.join(PARAMETERS)}") from None
    out = prepare_out_dir(out, force)
    passes = [prepare_pass(read_atl03(_existing(f), beam), system, name=str(f)) for f in files]
    result = calibrate(passes, survey, system, settings)
    result.solution.write_json(out / "solution.json", truth)
    own = report is None
    if own:
        report = Report("calidar: photon lidar CCR calibration")
    add_section(report, result, truth)
    if own:
        report.write(out / "report.html")
    return result
