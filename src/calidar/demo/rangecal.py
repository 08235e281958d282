"""Demo step: range calibration against a simulated total station (with one gross error)."""

from __future__ import annotations

from pathlib import Path

from calidar.pipelines import Progress, no_progress


def range_calibration_step(report, out_dir: Path, seed: int,
                           progress: Progress = no_progress) -> None:
    """Simulate observations (one gross error) into ``out_dir/range_cal`` and calibrate them with
    ``calidar range-cal``'s pipeline against their truth: solution.json there, the verdict and the
    section in ``report``. Under a second."""
    from calidar.outputs import prepare_out_dir
    from calidar.pipelines.rangecal import (run_range_cal, run_simulate_total_station,
                                            simulation_config)

    folder = prepare_out_dir(Path(out_dir) / "range_cal", force=True)
    one_gross_error = simulation_config(outliers=1)
    _, _, path = run_simulate_total_station(folder, seed, one_gross_error, angle_unit="gon")
    run_range_cal(path, folder, truth=folder / "truth.json", report=report,
                  title="Range calibration against a total station (simulated)", progress=progress)
