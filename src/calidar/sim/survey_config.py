"""The simulator's settings: :class:`SurveyConfig` (SI units), its presets and their checks.

:func:`check_config` rejects what no survey could fly, with a clear
:class:`~calidar.errors.InputError`. A preset with fields replaced:
:func:`calidar.sim.survey.survey_config`; the simulation itself:
:func:`calidar.sim.survey.simulate_survey`.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from calidar.errors import InputError
from calidar.sensor import Sensor
from calidar.sim.flightplan import FlightLine, check_plan_inputs
from calidar.sim.motion import MotionSpec
from calidar.sim.scene import SceneSpec
from calidar.validate import SEED_MAX, integer, number

#: per-strip trajectory errors (NED position, roll/pitch/heading attitude), drawn per line
STRIP_ERRORS = ("position_bias_m", "position_drift_mps", "attitude_bias_rad",
                "attitude_drift_radps")
#: largest σ of each of STRIP_ERRORS
STRIP_ERROR_MAX = (10.0, 1.0, np.radians(5.0), np.radians(1.0))
#: largest |true − nominal| of a sensor parameter simulated, by name prefix (rad, m, ratio)
ERROR_LIMITS = {
    "boresight": (np.radians(10.0), "rad"),
    "scan_angle_offset": (np.radians(10.0), "rad"),
    "lever_arm": (10.0, "m"),
    "range_offset": (10.0, "m"),
    "range_scale": (0.01, ""),
    "scan_angle_scale": (0.01, ""),
}


@dataclass(frozen=True)
class SurveyConfig:
    """Everything a simulation needs; SI units (m, s, rad, Hz)."""

    preset: str = "uav"
    seed: int = 0
    #: scene origin lat, lon (deg), h (m)
    origin_deg: tuple[float, float, float] = (47.0, 8.0, 450.0)
    scene: SceneSpec = field(default_factory=SceneSpec)
    motion: MotionSpec = field(default_factory=MotionSpec)
    height_agl_m: float = 80.0
    side_overlap: float = 0.5
    directions: str = "opposite"
    half_fov_rad: float = np.radians(35.0)  #: linear scanners; rotating ones have their own cone
    pulse_rate_hz: float = 20_000.0
    scan_rate_hz: float = 50.0  #: mirror/polygon/rotation frequency
    scan_pattern: str = "oscillating"  #: linear scanners: oscillating | polygon
    nominal: Sensor = field(default_factory=lambda: Sensor(lever_arm_x=0.05, lever_arm_z=0.12))
    errors: dict = field(default_factory=dict)  #: true − nominal per parameter name (SI)
    range_noise_m: float = 0.01
    angle_noise_rad: float = np.radians(0.002)
    gnss_noise_m: float = 0.02
    attitude_noise_rad: float = np.radians(0.002)
    #: per-axis factors on the trajectory errors' σ: north, east, down (× gnss_noise_m), roll,
    #: pitch, heading (× attitude_noise_rad)
    trajectory_sigma_scale: tuple[float, ...] = (1.0, 1.0, 1.0, 1.0, 1.0, 1.0)
    #: slow change of those σ over the flight (satellites come and go): σ(t) = σ · exp(v · g(t)),
    #: g smooth unit noise over ``calidar.sim.motion.SIGMA_VARIATION_S``; 0: constant
    trajectory_sigma_variation: float = 0.0
    #: σ of the per-strip trajectory errors, in the order of STRIP_ERRORS (m, m/s, rad, rad/s)
    strip_error_sigma: tuple[float, float, float, float] = (0.0, 0.0, 0.0, 0.0)
    density: float = 1.0  #: scales the pulse rate (and the scan rate by its square root)
    #: flown instead of the planned lines (``calidar plan``)
    lines: tuple[FlightLine, ...] | None = None
    #: the scene's own seed (None: from ``seed``): one scene, fresh noise
    scene_seed: int | None = None
    #: full angle (rad) of the beam's divergence: each return comes from a direction drawn from the
    #: Gaussian beam (σ = γ/4 per axis; ``calidar.sim.shots``); 0: one ray along the beam
    beam_divergence_rad: float = 0.0


PRESETS: dict[str, SurveyConfig] = {
    "uav": SurveyConfig(),
    "airborne": SurveyConfig(
        preset="airborne",
        scene=SceneSpec(width_m=2500.0, length_m=1600.0, cell_m=4.0, relief_m=40.0,
                        rough_sigma_m=0.6, building_density_per_km2=120.0,
                        building_size_m=(15.0, 50.0), building_height_m=(4.0, 20.0),
                        crown_radius_m=(2.0, 6.0)),
        motion=MotionSpec(speed_mps=60.0, run_in_m=300.0, turn_radius_m=400.0,
                          pitch_rad=np.radians(2.0), attitude_sigma_rad=np.radians(0.8),
                          heading_sigma_rad=np.radians(1.5), turbulence_tau_s=1.5,
                          along_sigma_m=4.0, across_sigma_m=3.0, vertical_sigma_m=2.0,
                          wander_tau_s=10.0),
        height_agl_m=1000.0, side_overlap=0.3, half_fov_rad=np.radians(20.0),
        pulse_rate_hz=20_000.0, scan_rate_hz=40.0,
        nominal=Sensor(lever_arm_x=0.25, lever_arm_y=-0.10, lever_arm_z=0.45),
        range_noise_m=0.02, gnss_noise_m=0.03,
    ),
}


def check_config(cfg: SurveyConfig) -> None:
    """Raise a clear :class:`InputError` for impossible settings."""
    check_plan_inputs(cfg.height_agl_m, cfg.motion.speed_mps, cfg.side_overlap, cfg.half_fov_rad,
                      cfg.directions)
    positive = {"density": cfg.density, "pulse_rate_hz": cfg.pulse_rate_hz,
                "scan_rate_hz": cfg.scan_rate_hz}
    for name, v in positive.items():
        if not np.isfinite(v) or v <= 0:
            raise InputError(None, name, f"expected a number > 0, got {v}")
    for name in ("range_noise_m", "angle_noise_rad", "gnss_noise_m", "attitude_noise_rad"):
        v = getattr(cfg, name)
        if not np.isfinite(v) or v < 0:
            raise InputError(None, name, f"expected a noise level >= 0, got {v}")
    _check_trajectory_errors(cfg)
    _check_sensor_errors(cfg)
    for name, v, hi in zip(STRIP_ERRORS, cfg.strip_error_sigma, STRIP_ERROR_MAX):
        number(v, "strip_errors", 0.0, hi, field=name)
    integer(cfg.seed, "seed", 0, SEED_MAX)
    number(cfg.range_noise_m, "range_noise_m", 0.0, 1.0, "m")
    number(cfg.beam_divergence_rad, "beam_divergence_rad", 0.0, 0.05, "rad")
    if cfg.pulse_rate_hz * cfg.density > 5e6:
        raise InputError(None, "density", f"pulse rate {cfg.pulse_rate_hz * cfg.density:.3g} Hz "
                         "is beyond any scanner (max 5 MHz)")
    if len(cfg.origin_deg) != 3 or not -80 <= cfg.origin_deg[0] <= 84:
        raise InputError(None, "origin_deg", "expected (lat, lon, h) with UTM latitude in "
                         f"[-80, 84], got {cfg.origin_deg}")


def _check_trajectory_errors(cfg: SurveyConfig) -> None:
    """The per-strip errors' σ, the per-axis factors and their variation over the flight; the
    vegetation fraction."""
    strip_sigma, scale = cfg.strip_error_sigma, cfg.trajectory_sigma_scale
    if len(strip_sigma) != len(STRIP_ERRORS) or not all(np.isfinite(v) and v >= 0
                                                        for v in strip_sigma):
        raise InputError(None, "strip_errors", f"expected {len(STRIP_ERRORS)} σ values >= 0 "
                         f"({', '.join(STRIP_ERRORS)}), got {strip_sigma}")
    if len(scale) != 6 or not all(np.isfinite(v) and v > 0 for v in scale):
        raise InputError(None, "trajectory_sigma_scale", "expected 6 factors > 0 (north, east, "
                         f"down, roll, pitch, heading), got {scale}")
    variation = cfg.trajectory_sigma_variation
    if not (np.isfinite(variation) and 0 <= variation <= 2):
        raise InputError(None, "trajectory_sigma_variation",
                         f"expected a number in [0, 2], got {variation}")
    if not 0 <= cfg.scene.vegetation_fraction <= 0.8:
        raise InputError(None, "vegetation", "expected a fraction of the area in [0, 0.8], got "
                         f"{cfg.scene.vegetation_fraction}")


def _check_sensor_errors(cfg: SurveyConfig) -> None:
    """Each true − nominal sensor error: a parameter of the sensor, within ERROR_LIMITS."""
    known = cfg.nominal.parameters()
    for name, v in cfg.errors.items():
        if name not in known:
            raise InputError(None, "errors",
                             f"unknown sensor parameter {name!r}; expected one of {sorted(known)}")
        limit, unit = next((lim for prefix, lim in ERROR_LIMITS.items()
                            if name.startswith(prefix)), (1.0, ""))
        if not (np.isfinite(v) and abs(v) <= limit):
            raise InputError(None, name, f"expected a finite error within ±{limit:.4g} {unit}, "
                             f"got {v:.6g} {unit}".rstrip())
