"""Demo step: boresight and lever arm from the demo survey's strips."""

from __future__ import annotations


def boresight_step(report, out_dir, seed: int = 0, progress=None) -> None:
    """Demo step: boresight and horizontal lever arm from the demo survey's strips (tie planes).

    Reads ``out_dir/survey`` (written by the simulation step) and adds a section with the truth.
    """
    import json
    from pathlib import Path

    from calidar.pipelines.boresight import load_strips
    from calidar.io.trajectory import read_trajectory
    from calidar.sensor import Sensor
    from calidar.strips.calibrate import calibrate, truth_to_si
    from calidar.strips.report import add_report_section

    survey = Path(out_dir) / "survey"
    nominal = Sensor.read(survey / "sensor.toml")
    strips, _ = load_strips(sorted((survey / "strips").glob("*.laz")), read_trajectory(survey / "sbet.out"), nominal)
    result = calibrate(strips, nominal, estimate="boresight,lever_arm_x,lever_arm_y")
    truth = truth_to_si(json.loads((survey / "truth.json").read_text()), result.solution.parameters)
    sec = add_report_section(report, result, truth, title="Boresight and lever arm from tie planes (calidar boresight)")
    sec.text("lever_arm_z is kept at its nominal value: level flight lines shift up or down alike with it, so "
             "overlapping strips cannot measure it.")
