"""The simulated survey the ground-control and checkpoint tests share (issue 28): a 200 m UAV survey
(seed 5, cross lines, no trees) delivered with a 5 cm range offset, which the overlaps cannot see,
and checkpoints surveyed on open ground (σ 1 cm)."""

from __future__ import annotations

from dataclasses import replace
from pathlib import Path

from calidar.sim.checkpoints import SimulatedCheckpoints, simulate_checkpoints
from calidar.sim.survey import simulate_survey, survey_config

RANGE_OFFSET = 0.05  #: m, the delivered strips' range offset


def simulated_survey(folder: Path):
    """Simulate the survey and write it into ``folder``/sim; return the simulation and that folder."""
    cfg = survey_config("uav", seed=5, density=0.2, directions="cross", errors={"range_offset": RANGE_OFFSET})
    res = simulate_survey(replace(cfg, scene=replace(cfg.scene, width_m=200.0, length_m=200.0, vegetation_fraction=0.0)))
    return res, res.write(Path(folder) / "sim")


def range_offset_survey(folder: Path, n_checkpoints: int) -> tuple[Path, SimulatedCheckpoints]:
    """Write the survey and its ``checkpoints.csv`` into ``folder``/sim; return that folder and the
    simulated checkpoints (their truth)."""
    res, out = simulated_survey(folder)
    simulated = simulate_checkpoints(res, n_checkpoints, 0.01, seed=5, vegetated_share=0.0)
    simulated.write(out)
    return out, simulated
