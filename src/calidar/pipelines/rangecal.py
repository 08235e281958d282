"""The range-calibration pipelines: ``calidar range-cal`` (read the observations, calibrate,
write solution.json and report.html with the verdict and the run record) and ``calidar simulate
total-station`` (simulate, write observations.csv and truth.json); the demo step and the
benchmark call the same functions."""

from __future__ import annotations

import json
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING

from calidar.errors import InputError
from calidar.io.json_file import write_json
from calidar.pipelines import Progress, no_progress
from calidar.pipelines.rangecal_config import RangeCalConfig
from calidar.validate import SEED_MAX, integer, number, read_json

# the run's parts, by type (imported when used: the demo imports this module first)
if TYPE_CHECKING:
    from calidar.provenance import RunRecord
    from calidar.rangecal import RangeCalibration
    from calidar.verdict import Verdict

ANGLE_UNITS = ("deg", "gon")
VERTICALS = ("zd", "va")


@dataclass
class RangeCalRun:
    """What one range calibration produced."""

    result: RangeCalibration
    verdict: Verdict
    record: RunRecord
    truth: dict | None  #: SI truth by parameter name, when a truth.json was given


def read_truth(path: Path) -> dict[str, float]:
    """SI truth by parameter name from a simulator's truth.json, or a clear error naming the
    file."""
    from calidar.rangecal import truth_parameters

    doc = read_json(path)
    try:
        truth = truth_parameters(doc)
    except (KeyError, TypeError, ValueError, AttributeError):
        raise InputError(path, None, "expected a truth.json with numbers range_offset_m and "
                         "range_scale_ppm") from None
    number(truth["range_offset"], path, -10.0, 10.0, "m", field="range_offset_m")
    number(truth["range_scale"] * 1e6, path, -1e5, 1e5, "ppm", field="range_scale_ppm")
    return truth


def calibrate_file(observations: Path, config: RangeCalConfig = RangeCalConfig(), *,
                   truth: Path | None = None) -> tuple[object, object, dict | None]:
    """Read and calibrate ``observations`` with ``config`` (and ``truth``, a simulator's
    truth.json): returns the :class:`calidar.rangecal.RangeCalibration`, its verdict and the SI
    truth (None without)."""
    from calidar.io.total_station import read_observations
    from calidar.rangecal import calibrate
    from calidar.rangecal.verdict import range_verdict

    obs = read_observations(observations)
    truth_si = read_truth(truth) if truth is not None else None
    result = calibrate(obs, config.tolerance_m, config.fix_scale)
    return result, range_verdict(result, truth_si), truth_si


def run_range_cal(observations: Path, out_dir: Path, config: RangeCalConfig = RangeCalConfig(),
                  *, truth: Path | None = None, argv: list[str] | None = None, report=None,
                  title: str | None = None, progress: Progress = no_progress) -> RangeCalRun:
    """:func:`calibrate_file`, then write solution.json (with the verdict and the run record, key
    "run"), config.toml (``config``, for ``--config``) and report.html into the existing folder
    ``out_dir`` — or, when ``report`` is given, add the verdict and the section to it instead of
    writing report.html (``calidar.calibrate_range``).

    The simulation of seed 0 has a range offset of 16 mm and a scale of −92 ppm; the run passes
    (the raw error stays within 5 cm):

    >>> import tempfile, calidar
    >>> folder = Path(tempfile.mkdtemp())
    >>> obs, truth, csv = run_simulate_total_station(folder, 0, simulation_config())
    >>> config = calidar.RangeCalConfig(tolerance_m=0.05)
    >>> run = calidar.calibrate_range(csv, folder, config, truth=folder / "truth.json")
    >>> sol = run.result.solution
    >>> [bool(abs(sol.values[k] - run.truth[k]) < 3 * sol.sigma[k])
    ...  for k in ("range_offset", "range_scale")]
    [True, True]
    >>> run.verdict.status, sorted(p.name for p in folder.iterdir())
    ('pass', ['config.toml', 'observations.csv', 'report.html', 'solution.json', 'truth.json'])
    """
    from calidar.provenance import RunRecord
    from calidar.pipelines.reports import report_for
    from calidar.rangecal.report import add_section

    record = RunRecord.capture(argv, inputs=[observations, truth], options=config.to_dict())
    progress("range calibration", 0, 2)
    result, verdict, truth_si = calibrate_file(observations, config, truth=truth)
    progress("range calibration", 1, 2)
    record.finish()
    result.solution.extra.update(verdict=verdict.to_dict(), run=record.to_dict())
    write_json(Path(out_dir) / "solution.json", result.solution.to_dict(truth_si))
    config.write(Path(out_dir) / "config.toml")
    with report_for(report, "calidar range calibration", record, Path(out_dir) / "report.html",
                    verdict, "Range calibration") as rep:
        add_section(rep, result, truth_si, title)
    progress("range calibration", 2, 2)
    return RangeCalRun(result, verdict, record, truth_si)


def simulation_config(setups: int = 2, groups: int = 3, e_points: int = 5, outliers: int = 0):
    """A checked :class:`calidar.sim.total_station.TotalStationSimConfig` (option names in the
    errors); the targets stay within what ``range-cal`` reads
    (:data:`calidar.io.total_station.MAX_TARGETS`)."""
    from calidar.io.total_station import MAX_SETUPS, MAX_TARGETS
    from calidar.sim.total_station import TotalStationSimConfig

    integer(setups, "--setups", 1, MAX_SETUPS, why="range-cal reads at most this many")
    integer(groups, "--groups", 1, MAX_TARGETS // 4)
    integer(e_points, "--e-points", 0, MAX_TARGETS)
    targets = setups * (4 * groups + e_points)
    if targets > MAX_TARGETS:
        raise InputError(None, "--setups × (4 × --groups + --e-points)",
                         f"expected at most {MAX_TARGETS} targets (what range-cal reads), got "
                         f"{targets}")
    integer(outliers, "--outliers", 0, targets, why="at most one per target")
    return TotalStationSimConfig(n_setups=setups, groups_per_setup=groups, e_per_setup=e_points,
                                 outliers=outliers)


def run_simulate_total_station(out_dir: Path, seed: int, config, *, angle_unit: str = "deg",
                               vertical: str = "zd") -> tuple[object, dict, Path]:
    """Simulate observations (``config``: :func:`simulation_config`) into the existing folder
    ``out_dir``: observations.csv and truth.json. Returns (observations, truth, path of the CSV)."""
    from calidar.io.total_station import write_observations
    from calidar.outputs import write_text_atomic
    from calidar.sim.total_station import simulate_total_station

    integer(seed, "--seed", 0, SEED_MAX)
    if angle_unit not in ANGLE_UNITS:
        raise InputError(None, "--angle-unit", f"expected deg or gon, got {angle_unit!r}")
    if vertical not in VERTICALS:
        raise InputError(None, "--vertical",
                         f"expected zd (zenith distance) or va (vertical angle), got {vertical!r}")
    obs, truth = simulate_total_station(seed, config)
    comment = f"simulated by calidar simulate total-station --seed {seed}"
    path = write_observations(Path(out_dir) / "observations.csv", obs, angle_unit, vertical,
                              force=True, comments=[comment])
    write_text_atomic(Path(out_dir) / "truth.json", json.dumps(truth, indent=2) + "\n")
    return obs, truth, path
