"""Demo step: the boresight from the demo survey's strips, by ``calidar boresight``'s pipeline.

Two cases on the same strips, each with its verdict: the calibration as it should be run
(boresight only, the lever arm held at its measured value, the trajectory's accuracy from the
smrmsg beside the SBET) — a pass; and the same strips asked for the lever arm too, which one
flying height cannot separate from the boresight — a warning that says why and what to do.
"""

from __future__ import annotations

from pathlib import Path

from calidar.pipelines import Progress, no_progress

BORESIGHT_ONLY = (
    "The lever arm was measured when the scanner was mounted, so it is held there; the boresight "
    "is what the overlaps determine. The trajectory's errors are estimated too, with the accuracy "
    "POSPac states for it (smrmsg.out beside sbet.out) as priors, so the σ include them."
)
WITH_LEVER_ARM = (
    "The same strips asked for the lever arm as well. The lines are flown at one height, where a "
    "vertical lever-arm error moves every strip up or down alike: only the platform's roll and "
    "pitch changes reveal it, and the verdict says lever_arm_z is not determined and what would "
    "determine it (hold it at its measured value, or fly lines at a second height). Its outputs "
    "are in boresight_lever_arm/."
)
#: the demo's two cases: (title, the parameters estimated, what the reader should take from it)
CASES = (
    ("Boresight from tie planes, lever arm held at its measured value (calidar boresight)",
     ("boresight",), BORESIGHT_ONLY),
    ("Second case, for contrast: boresight and lever arm from the same strips (a warning)",
     ("boresight", "lever_arm"), WITH_LEVER_ARM),
)


def boresight_step(report, out_dir, seed: int = 0, progress: Progress = no_progress) -> None:
    """Run both cases on out_dir/survey (written by the simulation step) with the truth, adding
    their verdicts and sections to ``report``; outputs in out_dir/boresight and
    out_dir/boresight_lever_arm."""
    from calidar.demo.survey import DEMO_SURVEY
    from calidar.pipelines.boresight import calibrate_strips
    from calidar.pipelines.boresight_outputs import write_run
    from calidar.pipelines.strip_config import StripConfig
    from calidar.strips.config import CalibrationConfig, Estimate

    survey = Path(out_dir) / DEMO_SURVEY
    strips = sorted((survey / "strips").glob("*.laz"))
    trajectory, sensor, truth = survey / "sbet.out", survey / "sensor.toml", survey / "truth.json"
    for k, (title, estimate, text) in enumerate(CASES):
        out = Path(out_dir) / ("boresight" if k == 0 else "boresight_lever_arm")
        out.mkdir(parents=True, exist_ok=True)
        config = StripConfig(CalibrationConfig(Estimate.of(*estimate)))
        run = calibrate_strips(strips, trajectory, sensor, config, truth=truth, progress=progress)
        write_run(run, out, report=report, verdict_title=title.split(" (")[0], section_title=title)
        report.sections[-1].blocks.insert(0, f"<p>{text}</p>")
        progress("boresight cases", k + 1, len(CASES))
        del run
