"""Demo step: simulate the demo survey and add the simulation section."""

from __future__ import annotations

import time
from pathlib import Path

import numpy as np

from calidar.pipelines import no_progress
from calidar.report import Report

DEMO_SURVEY = "survey"  #: sub-folder of the demo output holding the simulated survey
DEMO_ERRORS = {  #: true − nominal mounting of the demo survey (SI)
    "boresight_roll": np.radians(0.05), "boresight_pitch": np.radians(-0.04), "boresight_yaw": np.radians(0.08),
    "lever_arm_x": 0.03, "lever_arm_y": -0.02, "lever_arm_z": 0.05,
}


def demo_config(seed: int = 0):
    """The demo survey: UAV preset, cross lines, mounting errors, light density (≈ 1 M points)."""
    from calidar.sim.survey import survey_config

    return survey_config("uav", seed=seed, directions="cross", density=0.3, errors=dict(DEMO_ERRORS))


def simulation_step(report: Report, out_dir: Path, seed: int, progress=no_progress) -> None:
    """Simulate the demo survey into out_dir/survey and add the simulation section."""
    from calidar.sim import plots
    from calidar.sim.survey import simulate_survey

    t0 = time.perf_counter()
    result = simulate_survey(demo_config(seed), progress=progress)
    result.write(out_dir / DEMO_SURVEY, force=True, progress=progress)
    add_simulation_section(report, result, out_dir / DEMO_SURVEY, time.perf_counter() - t0)
    sec = report.sections[-1]
    figures = [(plots.coverage_map, "Scene, strip coverage and flight lines (ENU at the scene origin)."),
               (plots.density_map, "Point density of all strips together, all returns."),
               (plots.overlap_differences, "Before calibration: the delivered strips disagree where they overlap "
                                           "(the mounting errors tilt and shift them)."),
               (plots.trajectory_plot, "True trajectory; GNSS/INS errors are added to it in sbet.out.")]
    for k, (plot, caption) in enumerate(figures):
        sec.figure(plot(result), caption)
        progress("report figures", k + 1, len(figures))


def add_simulation_section(report: Report, result, folder: Path, seconds: float) -> None:
    """Inputs summary, truth and per-strip table of a simulated survey."""
    c, sc = result.config, result.scene
    sec = report.section("Simulated survey")
    xmin, xmax, ymin, ymax = sc.extent
    area = (xmax - xmin) * (ymax - ymin)
    sec.text(f"A {c.preset} survey simulated with seed {c.seed} in {seconds:.1f} s and written to {folder}: "
             f"{result.n_points:,} points in {len(result.strips)} strips, delivered in {result.crs} with the nominal "
             "sensor while the true sensor (nominal + the errors below) shot them.")
    sec.table(["input", "value"], [
        ["scene", f"{xmax - xmin:.0f} m × {ymax - ymin:.0f} m, {len(sc.roof_type)} buildings "
                  f"({', '.join(f'{sc.roof_type.count(k)} {k}' for k in sorted(set(sc.roof_type)))}), "
                  f"{sc.tree_radius.size} trees"],
        ["flight", f"{len(result.lines)} lines ({c.directions}), {c.height_agl_m:.0f} m above ground, "
                   f"{c.motion.speed_mps:.0f} m/s, side overlap {c.side_overlap:.0%}"],
        ["scanner", f"{result.nominal.scanner.model} ({c.scan_pattern}), ±{np.degrees(c.half_fov_rad):.0f}°, "
                    f"{c.pulse_rate_hz * c.density / 1e3:.3g} kHz, {c.scan_rate_hz * np.sqrt(c.density):.3g} Hz"],
        ["mean density", f"{result.n_points / area:.3g} points/m²"],
        ["noise", f"range {c.range_noise_m * 100:.3g} cm, beam angle {np.degrees(c.angle_noise_rad) * 3600:.3g}″, "
                  f"GNSS {c.gnss_noise_m * 100:.3g} cm, attitude {np.degrees(c.attitude_noise_rad) * 3600:.3g}″"],
    ], caption="Inputs")
    truth = result.truth_dict()["parameters"]
    sec.table(["parameter", "nominal", "truth", "error", "unit"],
              [[k, p["nominal"], p["value"], p["value"] - p["nominal"], p["unit"]] for k, p in truth.items()],
              caption="Sensor: nominal (sensor.toml) vs truth (truth.json)")
    rows = []
    for s in result.strips:
        cls = np.bincount(s.classification, minlength=7)
        rows.append([s.line.number, len(s), f"{np.degrees(s.line.azimuth) % 360:.0f}°", int(cls[2]), int(cls[6]),
                     int(cls[5]), float(s.gps_time[-1] - s.gps_time[0]) if len(s) else 0.0])
    sec.table(["strip", "points", "azimuth", "ground", "building", "vegetation", "duration [s]"], rows,
              caption="Delivered strips")
