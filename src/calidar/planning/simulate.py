"""A plan confirmed end to end: the simulator flies it, the strip calibrator calibrates it.

Each run simulates the planned lines over the plan's terrain
(:class:`~calidar.sim.survey.SurveyConfig` with ``lines``; the built-in scene, or flat ground), with
the plan's instrument, its noise and the stated trajectory accuracy, and true mounting errors drawn
per run; the strips go to :func:`calidar.strips.calibrate.calibrate_with_client` with the trajectory
model whose priors are the simulated trajectory's accuracy (as ``calidar boresight`` with its
smrmsg). The error of each estimated parameter against the truth, over N runs, gives the RMS error
to set against the predicted σ.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import replace

import numpy as np

from calidar.planning.geometry import Flown, Instrument
from calidar.planning.predict import PlanSettings
from calidar.sim.flightplan import FlightLine
from calidar.sim.survey import SurveyConfig, simulate_survey, survey_config

#: σ of the true mounting errors drawn per run (rad, m): a few times the σ the calibration reaches
TRUE_ERROR_SIGMA = {"boresight": np.radians(0.03), "lever_arm": 0.03, "range_offset": 0.03}
#: a scene without relief, buildings or trees: flat terrain
FLAT_SCENE = dict(relief_m=0.0, rough_sigma_m=0.0, building_density_per_km2=0.0,
                  vegetation_fraction=0.0)


def scan_rate_hz(flown: Flown, inst: Instrument) -> float:
    """The mirror frequency that spaces the points alike along and across track (oscillating: two
    sweeps a period): (2f)² = PRF · v / swath; a rotating scanner's turn also crosses the swath
    twice (ahead and back), so the same."""
    swath = 2.0 * flown.line.height_agl_m * np.tan(inst.half_fov_rad)
    return 0.5 * float(np.sqrt(inst.pulse_rate_hz * flown.line.speed_mps / swath))


def _trajectory_noise(model) -> tuple[float, float]:
    """The σ of the simulated trajectory's position (m) and attitude (rad) errors: the model's
    accuracy's means, else its own σ."""
    if model.accuracy is None:
        return model.position_sigma_m, model.attitude_sigma_rad
    return float(np.mean(model.accuracy.position)), float(np.mean(model.accuracy.attitude))


def plan_config(flown: list[Flown], inst: Instrument, settings: PlanSettings,
                base: SurveyConfig | None = None, seed: int = 0,
                errors: dict | None = None) -> SurveyConfig:
    """The simulator's configuration for one run of the plan (``base``: the scene's preset and
    seed; None: flat ground)."""
    if base is None:
        base = survey_config("uav", scene_seed=0)
        base = replace(base, scene=replace(base.scene, **FLAT_SCENE))
    pos, att = _trajectory_noise(settings.trajectory)
    speed = float(np.mean([f.line.speed_mps for f in flown]))
    lines = tuple(FlightLine(f.line.number, f.line.start.astype(float), f.line.end.astype(float),
                             f.altitude_m) for f in flown)
    motion = replace(base.motion, speed_mps=speed, attitude_sigma_rad=inst.motion_rad[0],
                     heading_sigma_rad=inst.motion_rad[1])
    scan_rate = float(np.mean([scan_rate_hz(f, inst) for f in flown]))
    scene_seed = base.scene_seed if base.scene_seed is not None else 0
    return replace(base, seed=seed, lines=lines, nominal=inst.nominal,
                   pulse_rate_hz=inst.pulse_rate_hz, density=1.0, scan_rate_hz=scan_rate,
                   half_fov_rad=inst.half_fov_rad, motion=motion, range_noise_m=inst.range_noise_m,
                   angle_noise_rad=inst.angle_noise_rad, gnss_noise_m=pos, attitude_noise_rad=att,
                   errors=errors or {}, scene_seed=scene_seed)


def true_errors(names: list[str], rng: np.random.Generator) -> dict[str, float]:
    """Mounting errors (SI) drawn for the estimated parameters."""
    out = {}
    for n in names:
        group = next((g for g in TRUE_ERROR_SIGMA if n.startswith(g)), None)
        if group is not None:
            out[n] = float(rng.normal(0.0, TRUE_ERROR_SIGMA[group]))
    return out


def simulate_and_calibrate(flown: list[Flown], inst: Instrument, settings: PlanSettings,
                           names: list[str], seed: int, base: SurveyConfig | None = None) -> dict:
    """One run: {"seed", "error": {name: SI}, "sigma": {name: SI}, "sigma0"}."""
    from calidar.strips.calibrate import calibrate_with_client
    from calidar.strips.config import CalibrationConfig, Estimate
    from calidar.strips.matchers import TiePlanes

    errors = true_errors(names, np.random.default_rng(seed + 7919))
    cfg = plan_config(flown, inst, settings, base, seed, errors)
    res = simulate_survey(cfg)
    strips = res.calibration_strips()
    model = replace(settings.trajectory, accuracy=res.accuracy)
    config = CalibrationConfig(Estimate.of(*settings.estimate), (TiePlanes(settings.planes),))
    result = calibrate_with_client(strips, res.nominal, config, trajectory=model)
    sol, truth = result.solution, res.truth.parameters()
    return {"seed": seed, "error": {n: float(sol.values[n] - truth[n]) for n in names},
            "sigma": {n: float(sol.sigma[n]) for n in names}, "sigma0": float(sol.sigma0),
            "points": int(res.n_points)}


def confirm(flown: list[Flown], inst: Instrument, settings: PlanSettings, names: list[str],
            runs: int, base: SurveyConfig | None = None, first_seed: int = 1,
            progress: Callable[[str, int, int], None] | None = None) -> dict:
    """``runs`` simulations of the plan: per parameter the RMS error (SI), the mean σ the
    calibration reported, and every run."""
    done = []
    for k in range(runs):
        done.append(simulate_and_calibrate(flown, inst, settings, names, first_seed + k, base))
        if progress:
            progress("simulating and calibrating the plan", k + 1, runs)
    err = np.array([[r["error"][n] for n in names] for r in done])
    sig = np.array([[r["sigma"][n] for n in names] for r in done])
    return {"runs": done, "rms_error": dict(zip(names, np.sqrt(np.mean(err**2, axis=0)).tolist())),
            "mean_sigma": dict(zip(names, sig.mean(axis=0).tolist()))}

