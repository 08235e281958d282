"""The simulated survey the ground-control and checkpoint tests share (issue 28): a 200 m UAV survey
(seed 5, cross lines, no trees) delivered with a 5 cm range offset, which the overlaps cannot see,
and checkpoints surveyed on open ground (σ 1 cm)."""

from __future__ import annotations

from dataclasses import replace
from pathlib import Path

import numpy as np

from calidar.sim.checkpoints import CLASS_GROUND, TRUTH_RADIUS_M, SimulatedCheckpoints, simulate_checkpoints
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
    _, out, simulated = checkpoint_survey(folder, n_checkpoints)
    return out, simulated


def checkpoint_survey(folder: Path, n_checkpoints: int):
    """As :func:`range_offset_survey`, the simulation (its trajectory's truth) returned first."""
    res, out = simulated_survey(folder)
    simulated = simulate_checkpoints(res, n_checkpoints, 0.01, seed=5, vegetated_share=0.0)
    simulated.write(out)
    return res, out, simulated


def trajectory_height_error_at(res, points) -> np.ndarray:
    """Per point (``points``: (N, 3) in the survey's CRS, e.g. checkpoints' ``xyz_true``), the
    measured trajectory's mean height error (m, up) at the times of the ground points within
    TRUTH_RADIUS_M (x, y) of it: the part of ``data_dz_m`` (the mean error of those same points)
    that the trajectory's GNSS draw puts there. NaN where no ground point is near."""
    scene = res.scene
    xy = enu_xy(res, points)
    up = scene.r_e_enu[:, 2]
    err: list[list[np.ndarray]] = [[] for _ in xy]
    for s in res.strips:
        ground = s.classification == CLASS_GROUND
        pxy = scene.ecef_to_enu(s.ecef[ground])[:, :2]
        t = s.gps_time[ground]
        for k, c in enumerate(xy):
            near = t[np.hypot(*(pxy - c).T) < TRUTH_RADIUS_M]
            if near.size:
                d = res.trajectory.interpolate(near)[0] - res.trajectory_true.interpolate(near)[0]
                err[k].append(d @ up)
    return np.array([np.concatenate(e).mean() if e else np.nan for e in err])


def enu_xy(res, points) -> np.ndarray:
    """The scene's ENU x, y (N, 2) m of ``points`` ((N, 3) in the survey's CRS)."""
    from calidar.crs import from_crs

    return res.scene.ecef_to_enu(from_crs(points, res.crs))[:, :2]
