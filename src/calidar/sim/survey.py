"""Simulate a lidar survey with a known truth and deliver it as a real system would.

The *true* sensor (nominal + the requested errors) shoots rays from the *true* trajectory (plus
range and beam-angle noise, and the beam's divergence: ``calidar.sim.shots``) into the scene; the
instrument records GPS time, measured range and encoder angle. The GNSS/INS delivers a *measured*
trajectory (true + smooth position/attitude errors, optionally per-strip biases and drifts), written
as the SBET. Delivered points are georeferenced from those records with the *nominal* sensor and the
measured trajectory (:func:`calidar.georef.forward`), so every error the user asks for shows in the
strips exactly as it would in real data. Example: :func:`simulate_survey`.
"""

from __future__ import annotations

import datetime
import json
from collections.abc import Callable
from dataclasses import dataclass, replace
from pathlib import Path

import numpy as np

from calidar import georef
from calidar.errors import InputError
from calidar.outputs import prepare_out_dir, write_text_atomic
from calidar.sensor import Sensor
from calidar.sim.flightplan import FlightLine, plan_lines
from calidar.sim.motion import accuracy_epochs, fly, measured_trajectory, trajectory_sigma
from calidar.sim.patterns import half_field_of_view
from calidar.sim.scene import Scene, build_scene, scene_seed
# SURFACE_VEGETATION and the settings (survey_config.py) are re-exported: this module is their
# historical home
from calidar.sim.shots import SURFACE_VEGETATION, line_shots, record  # noqa: F401
from calidar.sim.survey_config import (PRESETS, STRIP_ERRORS, SurveyConfig,  # noqa: F401
                                       check_config)
from calidar.trajectory import Trajectory
from calidar.trajectory_accuracy import TrajectoryAccuracy

#: LAS header creation date of simulated strips, fixed so that a seed always gives the same bytes.
SIMULATION_DATE = datetime.date(2026, 1, 1)

GPS_WEEK_START_S = 388800.0  #: simulated flights start on a Thursday, 12:00 GPS time
CHUNK_SHOTS = 400_000

#: pulses a simulation may hold (≈ 100 bytes each, several times over while casting): all of them,
#: or one strip's when the strips are handed over as simulated (``on_strip``)
MAX_PULSES = 3e7
#: truth.json units of the parameters it always lists (value converted from SI)
TRUTH_UNITS = {"boresight_roll": "deg", "boresight_pitch": "deg", "boresight_yaw": "deg",
               "lever_arm_x": "m", "lever_arm_y": "m", "lever_arm_z": "m", "range_offset": "m",
               "scan_angle_scale": "ratio"}


def survey_config(preset: str = "uav", **overrides) -> SurveyConfig:
    """A preset (``uav`` ≈ 80 m above ground over 300 m × 300 m; ``airborne`` ≈ 1000 m over
    2.5 km × 1.6 km) with fields replaced by ``overrides`` (see :class:`SurveyConfig`).

    ``vegetation=FRACTION`` is accepted as a shortcut for the scene's vegetation fraction.

    >>> import calidar
    >>> cfg = calidar.survey_config("airborne", seed=2, vegetation=0.3)
    >>> cfg.height_agl_m, cfg.scene.vegetation_fraction, cfg.seed
    (1000.0, 0.3, 2)
    """
    if preset not in PRESETS:
        raise InputError(None, "preset", f"expected one of {', '.join(PRESETS)}, got {preset!r}")
    cfg = PRESETS[preset]
    if "vegetation" in overrides:
        fraction = float(overrides.pop("vegetation"))
        cfg = replace(cfg, scene=replace(cfg.scene, vegetation_fraction=fraction))
    fields = SurveyConfig.__dataclass_fields__
    unknown = set(overrides) - set(fields)
    if unknown:
        raise InputError(None, sorted(unknown)[0],
                         f"unknown survey setting; expected one of {sorted(fields)}")
    return replace(cfg, **overrides)


def utm_crs(lat_deg: float, lon_deg: float) -> str:
    """EPSG code of the WGS 84 UTM zone holding (lat, lon) in degrees."""
    zone = int(np.floor((lon_deg + 180.0) / 6.0)) % 60 + 1
    return f"EPSG:{(32600 if lat_deg >= 0 else 32700) + zone}"


@dataclass(eq=False)
class Strip:
    """One delivered flight line, points in time order (returns of one pulse together)."""

    line: FlightLine
    xyz: np.ndarray  #: delivered coordinates in the output CRS (N, 3), m
    ecef: np.ndarray  #: the same points in ECEF (N, 3), m
    gps_time: np.ndarray  #: GPS week seconds (N,)
    range_m: np.ndarray  #: measured range (N,), m
    angles: np.ndarray  #: encoder angles (N,) or (N, k), rad
    scan_angle_deg: np.ndarray  #: across-track beam angle of the nominal scanner (N,), deg
    return_number: np.ndarray
    number_of_returns: np.ndarray
    classification: np.ndarray  #: 2 ground, 6 building, 5 vegetation
    intensity: np.ndarray
    surface: np.ndarray  #: building plane id, -1 terrain, -3 vegetation (N,)
    #: the exact hit in the scene's ENU frame, before noise (N, 3), m: where the true beam met the
    #: scene (with beam divergence, the ray the return came from, off the nominal beam:
    #: ``calidar.sim.shots``)
    true_enu: np.ndarray

    def __len__(self) -> int:
        return self.gps_time.size

    @property
    def point_source_id(self) -> int:
        return self.line.number


@dataclass(eq=False)
class SurveyResult:
    """A simulated survey: scene, plan, trajectories, sensors and delivered strips."""

    config: SurveyConfig
    scene: Scene
    lines: list[FlightLine]
    trajectory_true: Trajectory
    trajectory: Trajectory  #: the measured trajectory (what sbet.out holds)
    nominal: Sensor  #: the sensor the strips were delivered with (sensor.toml)
    truth: Sensor  #: the sensor that shot them
    crs: str
    strips: list[Strip]
    #: per line, keyed by STRIP_ERRORS (NED m, m/s; roll/pitch/heading rad, rad/s)
    strip_errors: list[dict]
    #: the σ of the measured trajectory's errors (smrmsg.out)
    accuracy: TrajectoryAccuracy | None = None
    #: points of the strips handed to ``on_strip`` as simulated (not in ``strips``)
    streamed_points: int = 0

    @property
    def n_points(self) -> int:
        return sum(len(s) for s in self.strips) + self.streamed_points

    def truth_dict(self) -> dict:
        """The truth.json document (degrees, metres, ratios)."""
        c = self.config
        strips = [{"point_source_id": ln.number,
                   "position_bias_m": e["position_bias_m"].tolist(),
                   "position_drift_mps": e["position_drift_mps"].tolist(),
                   "attitude_bias_deg": np.degrees(e["attitude_bias_rad"]).tolist(),
                   "attitude_drift_deg_per_s": np.degrees(e["attitude_drift_radps"]).tolist()}
                  for ln, e in zip(self.lines, self.strip_errors)]
        simulation = {"preset": c.preset, "seed": c.seed, "density": c.density,
                      "directions": c.directions, "height_agl_m": c.height_agl_m, "crs": self.crs,
                      "points": self.n_points}
        return {"parameters": self._truth_parameters(), "noise": self._truth_noise(),
                "strips": strips, "simulation": simulation}

    def _truth_parameters(self) -> dict:
        """truth.json's parameters: each one's true and nominal value in its unit (angles in
        degrees)."""
        true, nominal = self.truth.parameters(), self.nominal.parameters()
        names = list(TRUTH_UNITS) + [k for k in self.config.errors if k not in TRUTH_UNITS]
        # other scanner parameters: units from the model's ``units`` table (rad → deg), else SI
        scanner_units = getattr(self.truth.scanner, "units", {})
        units = {**{k: {"1": "ratio"}.get(u, u) for k, u in scanner_units.items()},
                 "range_scale": "ratio", "scan_angle_offset": "deg", **TRUTH_UNITS}
        params = {}
        for k in names:
            if k not in true:
                continue
            unit = units.get(k, "SI")
            angle = unit in ("deg", "rad")
            conv = np.degrees if angle else float
            params[k] = {"value": float(conv(true[k])), "unit": "deg" if angle else unit,
                         "nominal": float(conv(nominal[k]))}
        return params

    def _truth_noise(self) -> dict:
        """truth.json's noise: the range, beam-angle and trajectory noise (m, degrees)."""
        c = self.config
        noise = {"range_m": c.range_noise_m, "angle_deg": float(np.degrees(c.angle_noise_rad)),
                 "gnss_position_m": c.gnss_noise_m,
                 "attitude_deg": float(np.degrees(c.attitude_noise_rad)),
                 "trajectory_sigma_scale": list(c.trajectory_sigma_scale),
                 "trajectory_sigma_variation": c.trajectory_sigma_variation}
        if c.beam_divergence_rad:
            noise["beam_divergence_mrad"] = c.beam_divergence_rad * 1e3
        return noise

    def calibration_strips(self) -> list:
        """The delivered lines as :class:`calidar.strips.strip.Strip` (what the strip calibrator
        takes; ids = point_source_id) in one local frame at the survey's centre, their scan
        observations from the measured trajectory and the nominal sensor."""
        from calidar.strips.strip import LocalFrame
        from calidar.strips.strip import Strip as CalibrationStrip

        frame = LocalFrame.at(np.concatenate([s.ecef[::50] for s in self.strips]))
        return [CalibrationStrip.from_ecef(s.point_source_id, s.ecef, s.gps_time, self.trajectory,
                                           self.nominal, frame) for s in self.strips]

    def las_points(self) -> list:
        """The strips as :class:`calidar.io.las.LasPoints` (what ``read_las`` of the written files
        gives, without the file's mm / 0.006° quantisation), for in-memory use."""
        import pyproj

        from calidar.io.las import LasPoints

        crs = pyproj.CRS.from_user_input(self.crs)
        return [LasPoints(s.xyz, s.gps_time, "gps_week_seconds", crs,
                          Path(f"<simulated line_{s.line.number:03d}>"), s.scan_angle_deg,
                          np.full(len(s), s.line.number, np.uint16), s.return_number,
                          s.number_of_returns, s.classification, s.intensity)
                for s in self.strips]

    def write(self, out_dir: str | Path, force: bool = False,
              progress: Callable[[str, int, int], None] | None = None) -> Path:
        """Write strips/line_NNN.laz, sbet.out, smrmsg.out (its accuracy), sensor.toml (nominal) and
        truth.json into ``out_dir``."""
        from calidar.io.sbet import write_sbet
        from calidar.io.smrmsg import write_smrmsg

        out = prepare_out_dir(out_dir, force)
        (out / "strips").mkdir(exist_ok=True)
        for k, s in enumerate(self.strips):
            write_strip(out, s, self.crs, force)
            if progress:
                progress("writing strips", k + 1, len(self.strips))
        write_sbet(out / "sbet.out", self.trajectory, force=force)
        if self.accuracy is not None:
            write_smrmsg(out / "smrmsg.out", self.accuracy, force=force)
        self.nominal.write(out / "sensor.toml", force=force)
        truth = json.dumps(self.truth_dict(), indent=2) + "\n"
        write_text_atomic(out / "truth.json", truth, force=force)
        return out


def write_strip(out: Path, s: Strip, crs: str, force: bool = False) -> Path:
    """One simulated strip as ``out/strips/line_NNN.laz``."""
    from calidar.io.las import write_las

    path = out / "strips" / f"line_{s.line.number:03d}.laz"
    return write_las(path, s.xyz, crs, gps_time=s.gps_time, scan_angle_deg=s.scan_angle_deg,
                     point_source_id=s.line.number, return_number=s.return_number,
                     number_of_returns=s.number_of_returns, classification=s.classification,
                     intensity=s.intensity, creation_date=SIMULATION_DATE, force=force)


def simulate_survey(cfg: SurveyConfig,
                    progress: Callable[[str, int, int], None] | None = None,
                    on_strip: Callable[[Strip], None] | None = None) -> SurveyResult:
    """Run the simulation described by ``cfg`` in memory (see the module docstring).

    ``progress(description, done, total)`` is called as lines are simulated; ``on_strip(strip)``,
    when given, takes each strip as it is simulated instead of the result keeping it (large
    surveys: one strip in memory at a time).

    >>> import tempfile, numpy as np, calidar
    >>> cfg = calidar.survey_config("uav", seed=1, density=0.1, directions="cross",
    ...                             errors={"boresight_roll": 1e-3})
    >>> small = replace(cfg.scene, width_m=150.0, length_m=150.0)
    >>> res = calidar.simulate_survey(replace(cfg, scene=small))
    >>> # what a real system delivers, and the truth
    >>> folder = res.write(Path(tempfile.mkdtemp()) / "sim")
    >>> sorted(p.name for p in folder.iterdir()), res.truth.boresight_roll
    (['sbet.out', 'sensor.toml', 'smrmsg.out', 'strips', 'truth.json'], 0.001)
    """
    check_config(cfg)
    ss = np.random.SeedSequence(cfg.seed)
    rngs = [np.random.default_rng(s) for s in ss.spawn(6)]
    _, rng_motion, rng_nav, rng_strip, rng_shots, rng_sigma = rngs
    lat0, lon0, h0 = cfg.origin_deg
    crs = utm_crs(lat0, lon0)
    seed = scene_seed(cfg.seed, cfg.scene_seed)
    scene = build_scene(cfg.scene, seed, np.radians(lat0), np.radians(lon0), h0)
    nominal = replace(cfg.nominal, crs=crs)
    params = nominal.parameters()
    truth = nominal.with_parameters(**{k: params[k] + v for k, v in cfg.errors.items()})
    lines = survey_lines(cfg, scene, nominal)
    traj_true, windows = fly(scene, lines, cfg.motion, rng_motion, GPS_WEEK_START_S)
    _check_pulses(cfg, windows, one_strip=on_strip is not None)
    strip_errors = [{k: rng_strip.normal(0.0, sigma, 3)
                     for k, sigma in zip(STRIP_ERRORS, cfg.strip_error_sigma)} for _ in lines]
    sig_pos, sig_att = trajectory_sigma(cfg, traj_true.time, rng_sigma)
    per_strip = [(a, b, e) for (a, b), e in zip(windows, strip_errors)]
    traj = measured_trajectory(traj_true, rng_nav, sig_pos, sig_att, per_strip)

    strips, streamed = [], 0
    for k, (line, window) in enumerate(zip(lines, windows)):
        t_all, enc_all = line_shots(cfg, nominal, window, cfg.half_fov_rad)
        parts = [record(cfg, scene, traj_true, traj, truth, nominal, t_all[c0:c0 + CHUNK_SHOTS],
                        enc_all[c0:c0 + CHUNK_SHOTS], rng_shots)
                 for c0 in range(0, t_all.size, CHUNK_SHOTS)]
        cat = {key: np.concatenate([p[key] for p in parts]) for key in parts[0]}
        strip = Strip(line, georef.to_crs(cat["ecef"], crs), **cat)
        streamed += 0 if on_strip is None else len(strip)
        (on_strip or strips.append)(strip)
        if progress:
            progress("simulating lines", k + 1, len(lines))
    accuracy = accuracy_epochs(traj_true.time, sig_pos, sig_att)
    return SurveyResult(cfg, scene, lines, traj_true, traj, nominal, truth, crs, strips,
                        strip_errors, accuracy, streamed)


def survey_lines(cfg: SurveyConfig, scene: Scene, nominal: Sensor) -> list[FlightLine]:
    """The lines to fly: ``cfg.lines``, else the plan over the scene at the configured height,
    overlap and directions (the swath from the scanner's half field of view)."""
    if cfg.lines:
        return list(cfg.lines)
    half_fov = half_field_of_view(nominal.scanner, cfg.scan_rate_hz, cfg.half_fov_rad,
                                  cfg.scan_pattern)
    return list(plan_lines(scene.extent, float(np.mean(scene.heights)), cfg.height_agl_m, half_fov,
                           cfg.side_overlap, cfg.directions, cfg.motion.speed_mps))


def _check_pulses(cfg: SurveyConfig, windows: list, one_strip: bool) -> None:
    """Memory grows with the pulses held: all the strips', or one strip's when they are handed
    over as simulated (``one_strip``); beyond MAX_PULSES, an error."""
    per_line = [cfg.pulse_rate_hz * cfg.density * (b - a) for a, b in windows]
    pulses = max(per_line) if one_strip else sum(per_line)
    if pulses > MAX_PULSES:
        where = " in one strip" if one_strip else ""
        raise InputError(None, "density", f"{pulses:.3g} pulses to simulate{where}; expected "
                         f"≤ {MAX_PULSES:.3g} (a smaller --density)")
