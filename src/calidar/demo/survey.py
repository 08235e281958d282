"""Demo step: simulate the demo survey and add the simulation section."""

from __future__ import annotations

import time
from pathlib import Path

import numpy as np

from calidar.pipelines import Progress, no_progress
from calidar.report import Report

DEMO_SURVEY = "survey"  #: sub-folder of the demo output holding the simulated survey
#: true − nominal mounting of the demo survey (SI): a boresight to calibrate; the lever arm was
#: measured (its nominal value is right), so the calibration can hold it there
DEMO_ERRORS = {
    "boresight_roll": np.radians(0.05),
    "boresight_pitch": np.radians(-0.04),
    "boresight_yaw": np.radians(0.08),
}
#: the units of truth.json's parameters as the sensor table shows them
_UNIT_SHOWN = {"deg": "°", "m": " m", "ratio": ""}


def demo_config(seed: int = 0):
    """The demo survey: UAV preset, lines in alternate directions with 60 % side overlap (as a
    calibration flight is planned) and two cross lines, a boresight error, light density
    (≈ 1.5 M points)."""
    from calidar.sim.survey import survey_config

    return survey_config("uav", seed=seed, directions="cross", side_overlap=0.6, density=0.3,
                         errors=dict(DEMO_ERRORS))


def simulation_step(report: Report, out_dir: Path, seed: int,
                    progress: Progress = no_progress) -> None:
    """Simulate the demo survey into out_dir/survey and add the simulation section."""
    from calidar.sim import plots
    from calidar.sim.survey import simulate_survey

    t0 = time.perf_counter()
    result = simulate_survey(demo_config(seed), progress=progress)
    result.write(Path(out_dir) / DEMO_SURVEY, force=True, progress=progress)
    add_simulation_section(report, result, Path(out_dir) / DEMO_SURVEY, time.perf_counter() - t0)
    sec = report.sections[-1]
    figures = [
        (plots.coverage_map, "Scene, strip coverage and flight lines (ENU at the scene origin)."),
        (plots.density_map, "Point density of all strips together, all returns."),
        (plots.overlap_differences, "Before calibration: the delivered strips disagree where they "
                                    "overlap (the boresight error tilts and shifts them)."),
        (plots.trajectory_plot, "True trajectory; GNSS/INS errors are added to it in sbet.out."),
    ]
    for k, (plot, caption) in enumerate(figures):
        sec.figure(plot(result), caption)
        progress("report figures", k + 1, len(figures))


def add_simulation_section(report: Report, result, folder: Path, seconds: float) -> None:
    """Inputs summary, truth and per-strip table of a simulated survey."""
    c = result.config
    sec = report.section("Simulated survey")
    sec.text(f"A {c.preset} survey simulated with seed {c.seed} in {seconds:.1f} s and written to "
             f"{folder}: {result.n_points:,} points in {len(result.strips)} strips, delivered in "
             f"{result.crs} with the nominal sensor while the true sensor (nominal + the errors "
             "below) shot them. The trajectory's errors follow the accuracy written beside it "
             "(smrmsg.out, as POSPac writes one beside every SBET).")
    sec.table(["input", "value"], _input_rows(result), caption="Inputs")
    sec.table(["parameter", "nominal", "truth", "truth − nominal"], _sensor_rows(result),
              caption="Sensor: nominal (sensor.toml) and truth (truth.json)")
    strip_columns = ["strip", "points", "azimuth [°]", "ground", "building", "vegetation",
                     "duration [s]"]
    sec.table(strip_columns, _strip_rows(result), caption="Delivered strips (points per class)",
              formats=[None, ",d", ".0f", ",d", ",d", ",d", ".1f"])


def _input_rows(result) -> list[list[str]]:
    """The inputs table: scene, flight, scanner, density and noise, in user units."""
    c, sc = result.config, result.scene
    xmin, xmax, ymin, ymax = sc.extent
    area_m2 = (xmax - xmin) * (ymax - ymin)
    roofs = ", ".join(f"{sc.roof_type.count(k)} {k}" for k in sorted(set(sc.roof_type)))
    half_fov_deg = np.degrees(c.half_fov_rad)
    pulse_khz, scan_hz = c.pulse_rate_hz * c.density / 1e3, c.scan_rate_hz * np.sqrt(c.density)
    angle_noise_arcsec = np.degrees(c.angle_noise_rad) * 3600
    attitude_noise_arcsec = np.degrees(c.attitude_noise_rad) * 3600
    return [
        ["scene", f"{xmax - xmin:.0f} m × {ymax - ymin:.0f} m, {len(sc.roof_type)} buildings "
                  f"({roofs}), {sc.tree_radius.size} trees"],
        ["flight", f"{len(result.lines)} lines ({c.directions}), {c.height_agl_m:.0f} m above "
                   f"ground, {c.motion.speed_mps:.0f} m/s, side overlap {c.side_overlap:.0%}"],
        ["scanner", f"{result.nominal.scanner.model} ({c.scan_pattern}), ±{half_fov_deg:.0f}°, "
                    f"{pulse_khz:.3g} kHz, {scan_hz:.3g} Hz"],
        ["mean density", f"{result.n_points / area_m2:.3g} points/m²"],
        ["noise", f"range {c.range_noise_m * 100:.3g} cm, beam angle {angle_noise_arcsec:.3g}″, "
                  f"GNSS {c.gnss_noise_m * 100:.3g} cm, attitude {attitude_noise_arcsec:.3g}″"],
    ]


def _sensor_rows(result) -> list[list[str]]:
    """Each sensor parameter's nominal value, truth and their difference, in truth.json's units."""
    rows = []
    for name, p in result.truth_dict()["parameters"].items():
        unit = _UNIT_SHOWN.get(p["unit"], " " + p["unit"])
        nominal, truth = f"{p['nominal']:.4f}{unit}", f"{p['value']:.4f}{unit}"
        difference = f"{p['value'] - p['nominal']:+.4f}".replace("+0.0000", "0.0000")
        rows.append([name, nominal, truth, difference + unit])
    return rows


def _strip_rows(result) -> list[list]:
    """Per strip: number, points, azimuth (°), ground/building/vegetation points, duration (s)."""
    rows = []
    for s in result.strips:
        per_class = np.bincount(s.classification, minlength=7)
        duration_s = float(s.gps_time[-1] - s.gps_time[0]) if len(s) else 0.0
        rows.append([s.line.number, len(s), np.degrees(s.line.azimuth) % 360, int(per_class[2]),
                     int(per_class[6]), int(per_class[5]), duration_s])
    return rows
