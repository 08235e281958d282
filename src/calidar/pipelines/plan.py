"""Calibration flight planning (``calidar plan``): predicted σ of a planned flight, what it will
not determine and why, the line that helps most, optionally confirmed by simulating the plan.

:func:`run_plan` reads the flight lines (:mod:`calidar.io.flight_lines`), the sensor and the
terrain (flat, a DEM GeoTIFF, or the simulator's built-in scene), predicts
(:func:`calidar.planning.predict.predict`), tries candidate lines
(:func:`calidar.planning.suggest.suggest`), with ``simulate`` > 0 flies and calibrates the plan
that many times (:func:`calidar.planning.simulate.confirm`), and writes ``plan.json`` and
``report.html``.
"""

from __future__ import annotations

import json
from dataclasses import dataclass, field, fields
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np

from calidar.errors import InputError
from calidar.pipelines import Progress, no_progress
from calidar.strips.config import Estimate

if TYPE_CHECKING:  # the run's parts, by type (imported where used)
    from calidar.planning.predict import Prediction
    from calidar.verdict import Verdict

#: the most simulations ``--simulate`` runs (each is a whole survey simulated and calibrated)
MAX_SIMULATE = 200


@dataclass(frozen=True)
class TerrainChoice:
    """--terrain, parsed (:func:`calidar.cli.plan.parse_terrain`): flat ground at ``height_m``, the
    simulator's built-in scene (``preset``, ``seed``), or a DEM GeoTIFF at ``path``."""

    kind: str = "flat"  #: "flat" | "scene" | "dem"
    height_m: float = 0.0
    preset: str = "uav"
    seed: int = 0
    path: Path | None = None

    def __str__(self) -> str:
        """As a user gives it."""
        if self.kind == "flat":
            return f"flat:{self.height_m:g}" if self.height_m else "flat"
        return f"scene:{self.preset}:{self.seed}" if self.kind == "scene" else str(self.path)


@dataclass(frozen=True)
class PlanOptions:
    """What ``calidar plan`` takes besides its files (see its --help), typed: the CLI parses the
    option strings (:mod:`calidar.cli.plan`), this pipeline checks ranges only. SI inside."""

    terrain: TerrainChoice = field(default_factory=TerrainChoice)
    pulse_rate_hz: float = 20_000.0
    fov_deg: float = 70.0  #: full field of view
    range_sigma_m: float = 0.01
    angle_sigma_deg: float = 0.002
    estimate: Estimate = field(default_factory=lambda: Estimate.of("boresight"))
    #: the expected trajectory accuracy: position m, attitude rad
    trajectory_sigma: tuple[float, float] = (0.02, float(np.radians(0.002)))
    suggest: bool = True
    simulate: int = 0
    #: σ of the platform's attitude wobble along a line: roll and pitch, heading (rad)
    platform_motion: tuple[float, float] = (float(np.radians(1.5)), float(np.radians(1.0)))

    def to_dict(self) -> dict:
        """The options as a user gives them (degrees, names), for the run record."""
        pos, att = self.trajectory_sigma
        values = {f.name: getattr(self, f.name) for f in fields(self)}
        return {**values, "terrain": str(self.terrain),
                "estimate": self.estimate.names(),
                "trajectory_sigma": f"{pos:g},{np.degrees(att):g}",
                "platform_motion": ",".join(f"{np.degrees(v):g}" for v in self.platform_motion)}


@dataclass
class PlanRun:
    """What :func:`run_plan` produced."""

    prediction: Prediction
    suggestions: list
    simulation: dict | None
    verdict: Verdict
    doc: dict


def check_terrain(choice: TerrainChoice) -> None:
    """The terrain chosen: flat at a height in ±9 km, a known scene preset and seed, or a DEM's
    path."""
    from calidar.sim.survey import PRESETS

    if choice.kind == "flat" and (not np.isfinite(choice.height_m) or abs(choice.height_m) > 9000):
        raise InputError(None, "--terrain",
                         f"expected a height in [-9000, 9000] m, got {choice.height_m:g}")
    if choice.kind == "scene" and (choice.preset not in PRESETS or choice.seed < 0):
        raise InputError(None, "--terrain", "expected scene[:PRESET[:SEED]] with PRESET one of "
                         f"{', '.join(PRESETS)} and SEED an integer ≥ 0, got {choice}")
    path_mismatch = (choice.kind == "dem") != (choice.path is not None)
    if choice.kind not in ("flat", "scene", "dem") or path_mismatch:
        raise InputError(None, "--terrain", "expected flat, scene or dem (with a path, the DEM's "
                         f"alone), got {choice.kind!r}")


def load_terrain(choice: TerrainChoice):
    """The terrain chosen (--terrain) → (terrain, the simulator's base configuration for
    --simulate or None for a DEM)."""
    from dataclasses import replace

    from calidar.planning.simulate import FLAT_SCENE
    from calidar.planning.terrain import FlatTerrain, scene_terrain
    from calidar.sim.survey import survey_config

    check_terrain(choice)
    if choice.kind == "flat":
        base = survey_config("uav", scene_seed=0)
        return FlatTerrain(choice.height_m), replace(base, scene=replace(base.scene, **FLAT_SCENE),
                                                     origin_deg=(47.0, 8.0, choice.height_m))
    if choice.kind == "scene":
        base = survey_config(choice.preset, scene_seed=choice.seed)
        return scene_terrain(base), base
    from calidar.io.dem import read_dem
    from calidar.planning.terrain import GridTerrain

    heights, x0, y0, dx, dy = read_dem(choice.path)
    return GridTerrain(heights, x0, y0, dx, dy, f"DEM {choice.path.name}"), None


def check_numbers(options: PlanOptions) -> None:
    """The options' numbers in their ranges (an error naming the option)."""
    from calidar.validate import number

    if not 0 <= options.simulate <= MAX_SIMULATE:
        raise InputError(None, "--simulate",
                         f"expected 0 to {MAX_SIMULATE} simulated surveys, got {options.simulate}")
    number(options.pulse_rate_hz, "--pulse-rate", 100.0, 5e6, "Hz")
    number(options.fov_deg, "--fov", 1.0, 150.0, "deg")
    number(options.range_sigma_m, "--range-sigma", 1e-5, 1.0, "m")
    number(options.angle_sigma_deg, "--angle-sigma", 0.0, 1.0, "deg")
    for v in options.platform_motion:
        # 10° with a margin: the option comes back from radians
        number(float(np.degrees(v)), "--platform-motion", 0.0, 10.0 + 1e-12, "deg")


def instrument(sensor_path: Path, options: PlanOptions):
    from calidar.planning.geometry import Instrument
    from calidar.planning.sweep import pattern_half_fov
    from calidar.scanners.linear import LinearScanner
    from calidar.sensor import Sensor

    nominal = Sensor.read(sensor_path)
    # a linear scanner sweeps --fov; a rotating one (Palmer oval, wedge cone) its own pattern,
    # seen twice
    half_fov = (float(np.radians(options.fov_deg / 2)) if isinstance(nominal.scanner, LinearScanner)
                else pattern_half_fov(nominal))
    angle_sigma_rad = float(np.radians(options.angle_sigma_deg))
    motion = tuple(float(v) for v in options.platform_motion)
    return Instrument(nominal, options.pulse_rate_hz, half_fov, options.range_sigma_m,
                      angle_sigma_rad, motion)


#: what a plan does not predict: the scan-angle and Palmer parameters
NOT_PLANNED = frozenset({"scan_angle_scale", "scan_angle_offset", "eccentricity_ratio",
                         "eccentricity_phase", "delta_l", "delta_r"})


def plan_settings(options: PlanOptions):
    from calidar.planning.predict import PlanSettings
    from calidar.strips.config import TrajectorySettings

    check_estimate(options.estimate)
    trajectory = TrajectorySettings(sigma=options.trajectory_sigma).model()
    return PlanSettings(estimate=tuple(options.estimate.names()), trajectory=trajectory)


def check_estimate(est: Estimate) -> None:
    """What a plan predicts: sensor parameters, not the Palmer and scan-angle ones (an error
    naming --estimate)."""
    if "height_bias" in est.parameters:
        raise InputError(None, "--estimate", "height_bias needs ground control; expected sensor "
                         "parameters (boresight, lever_arm, range_offset, …)")
    if est.parameters & NOT_PLANNED:
        raise InputError(None, "--estimate", f"got {','.join(est.names())}; calidar plan predicts "
                         "boresight, lever_arm, range_offset and range_scale (and their single "
                         "parameters)")


def _verdict(pred, found):
    from calidar.planning.findings import findings, headline, shown
    from calidar.verdict import Finding, Verdict

    out = []
    for f in findings(pred):
        sigma = f"σ {f['sigma']}" if "sigma" in f else ""
        if f["determined"]:
            out.append(Finding("pass", f["parameter"], sigma))
        else:
            why = f"{sigma}: {f['why']}" if sigma else f["why"]
            out.append(Finding("fail", f["parameter"], why, f["action"]))
    if found and pred.poor:
        best = found[0]
        unit = pred.units[pred.names.index(best.parameter)]
        before = shown(best.parameter, unit, best.sigma_before)
        after = shown(best.parameter, unit, best.sigma_after)
        out.append(Finding("note", "suggested line",
                           f"{best.kind}: {best.parameter} σ {before} → {after}"))
    return Verdict(f"calibration flight plan: {headline(pred)}", out)


def run_plan(lines_path: Path, sensor_path: Path, out_dir: Path,
             options: PlanOptions = PlanOptions(), progress: Progress = no_progress,
             argv: list[str] | None = None) -> PlanRun:
    """The whole ``calidar plan`` run into the folder ``out_dir`` (see the module docstring)."""
    from calidar.io.flight_lines import read_flight_lines
    from calidar.outputs import write_text_atomic
    from calidar.planning.geometry import fly_plan
    from calidar.planning.predict import predict
    from calidar.planning.simulate import confirm
    from calidar.planning.suggest import suggest
    from calidar.provenance import RunRecord

    check_numbers(options)
    record = RunRecord.capture(argv, inputs=[lines_path, sensor_path], options=options.to_dict())
    lines = read_flight_lines(lines_path)
    inst = instrument(Path(sensor_path), options)
    settings = plan_settings(options)
    terrain, base = load_terrain(options.terrain)
    progress("predicting", 0, 1)
    cache: dict = {}
    pred = predict(lines, terrain, inst, settings, cache)
    found = []
    if options.suggest:
        found = suggest(lines, terrain, inst, settings, pred, progress, cache)
    simulation = None
    if options.simulate:
        if base is None:
            raise InputError(None, "--simulate", "simulates flat ground or the built-in scene; "
                             "expected --terrain flat or scene[:PRESET[:SEED]] with it (a DEM "
                             "cannot be simulated)")
        simulation = confirm(fly_plan(lines, terrain), inst, settings, pred.names,
                             options.simulate, base, progress=progress)
    verdict = _verdict(pred, found)
    record.finish()
    doc = plan_document(lines, inst, options, terrain, pred, found, simulation, verdict, record)
    out_dir = Path(out_dir)
    write_text_atomic(out_dir / "plan.json", json.dumps(doc, indent=2, allow_nan=False) + "\n")
    from calidar.planning.report import plan_report

    image = _terrain_image(terrain, lines)
    plan_report(doc, pred, image, verdict, record).write(out_dir / "report.html")
    return PlanRun(pred, found, simulation, verdict, doc)


def plan_document(lines, inst, options, terrain, pred, found, simulation, verdict, record) -> dict:
    """plan.json: inputs, predicted σ (SI and display), correlations, findings, suggestions,
    simulation."""
    from calidar.adjust.solution import json_ready
    from calidar.planning.findings import findings, headline

    corr = np.where(np.isfinite(pred.correlation), pred.correlation, np.nan)
    instrument_doc = {"pulse_rate_hz": inst.pulse_rate_hz,
                      "half_fov_deg": float(np.degrees(inst.half_fov_rad)),
                      "range_noise_m": inst.range_noise_m,
                      "angle_noise_deg": float(np.degrees(inst.angle_noise_rad))}
    suggestions = [{**s.to_dict(), "unit": pred.units[pred.names.index(s.parameter)]}
                   for s in found]
    doc = {"headline": headline(pred), "poor": pred.poor, "lines": [ln.to_dict() for ln in lines],
           "terrain": terrain.name, "estimate": list(pred.names),
           "instrument": instrument_doc,
           "trajectory": f"{options.to_dict()['trajectory_sigma']} (position m, attitude deg)",
           "median_range_m": pred.median_range_m, "pairs": pred.pairs, "observations": pred.n_rows,
           "parameters": _parameter_rows(pred),
           "correlation": {"names": pred.names, "matrix": corr.tolist()},
           "findings": findings(pred),
           "suggestions": suggestions,
           "simulation": None if simulation is None else {k: v for k, v in simulation.items()},
           "verdict": verdict.to_dict(), "run": record.to_dict()}
    if simulation is not None:
        doc["simulation"]["runs"] = len(simulation["runs"])
        doc["simulation"]["per_run"] = simulation["runs"]
    return json_ready(doc)


def _finite_or_none(value: float) -> float | None:
    """``value`` as a float, None when it is not finite (JSON has no inf or NaN)."""
    return float(value) if np.isfinite(value) else None


def _parameter_rows(pred) -> list[dict]:
    """plan.json's "parameters": each parameter's predicted σ (SI; reported and of its error),
    whether it is determined, its effect on the ground and its limit (m)."""
    rows = []
    for k, (n, u, s, r) in enumerate(zip(pred.names, pred.units, pred.sigma, pred.reported)):
        effect = pred.ground_effect(k)
        rows.append({"parameter": n, "unit": u, "sigma_reported_si": _finite_or_none(r),
                     "sigma_error_si": _finite_or_none(s), "determined": pred.determined(k),
                     "ground_effect_m": effect if np.isfinite(effect) else None,
                     "limit_m": pred.limit(k)})
    return rows


def _terrain_image(terrain, lines):
    """A height image (and its extent) of the terrain under the plan, for the map (None: flat)."""
    from calidar.planning.terrain import FlatTerrain

    if isinstance(terrain, FlatTerrain):
        return None
    ends = np.array([p for ln in lines for p in (ln.start, ln.end)])
    pad = max(ln.height_agl_m for ln in lines)
    lo, hi = ends.min(axis=0) - pad, ends.max(axis=0) + pad
    x, y = np.linspace(lo[0], hi[0], 240), np.linspace(lo[1], hi[1], 240)
    gx, gy = np.meshgrid(x, y)
    z, _ = terrain.sample(gx, gy)
    return z, (lo[0], hi[0], lo[1], hi[1])
