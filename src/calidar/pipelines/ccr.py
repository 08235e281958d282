"""The CCR calibration pipeline (``calidar ccr``, its demo step and the benchmarks): read the
passes and the CCR survey, calibrate, write ``solution.json`` and ``report.html``; and the
photon simulation (``calidar simulate photons``)."""

from __future__ import annotations

from pathlib import Path

from calidar.errors import InputError
from calidar.io.json_file import write_json
from calidar.pipelines import Progress, no_progress
from calidar.pipelines.ccr_config import CCRConfig


def read_truth(path: Path) -> dict[str, float]:
    """The geolocation truth of a simulation's truth.json (m)."""
    from calidar.photon.parameters import GEOLOCATION
    from calidar.validate import read_json

    doc = read_json(path)
    try:
        return {k: float(doc[k]) for k in GEOLOCATION}
    except (KeyError, TypeError, ValueError):
        raise InputError(path, None,
                         f"expected JSON with numbers {', '.join(GEOLOCATION)}") from None


def read_ccr_csv(path: Path):
    """The CCR survey of a CSV file (:func:`calidar.io.ccr_survey.read_ccr_survey`) as the method
    takes it (:class:`calidar.photon.survey.CCRSurvey`)."""
    from calidar.io.ccr_survey import read_ccr_survey
    from calidar.photon.survey import CCRSurvey

    return CCRSurvey.from_rows(read_ccr_survey(path))


def load_passes(files: list[Path], beams: tuple[str, ...] | None, survey, system,
                progress: Progress = no_progress):
    """Every chosen beam (``beams``: ATL03 beam names; None: every beam) of every ATL03 file as a
    pass prepared near the CCRs (beams without photons skipped)."""
    from calidar.io.atl03 import read_atl03, select_beams
    from calidar.photon.passes import prepare_pass
    from calidar.validate import existing_file

    names = [Path(f).name for f in files]
    passes = []
    for i, f in enumerate(files):
        existing_file(f, "ATL03 file")
        label = names[i] if names.count(names[i]) == 1 else str(f)
        for b in select_beams(f, beams):
            beam = read_atl03(f, b)
            if len(beam):
                passes.append(prepare_pass(beam, survey, system, name=f"{label}:{b}"))
        progress("reading passes", i + 1, len(files))
    if not passes:
        chosen = "all" if beams is None else ",".join(beams)
        raise InputError(files[0], chosen, "no photons in the chosen beam(s)")
    return passes


def run_ccr(files: list[Path], ccr: Path, out_dir: Path, config: CCRConfig = CCRConfig(), *,
            truth_path: Path | None = None, record=None, report=None,
            progress: Progress = no_progress):
    """Read, calibrate with ``config`` (:class:`calidar.pipelines.ccr_config.CCRConfig`: the beams,
    the search's and the fit's settings, the instrument), write ``out_dir``/solution.json,
    config.toml and (unless a report is passed in, as the demo does) report.html
    (``calidar.calibrate_ccr``). ``record``: the run's :class:`calidar.provenance.RunRecord`.
    Returns the :class:`calidar.photon.ccr.CCRResult`.

    Quick (no bootstrap σ, no likelihood map in the report):

    >>> import tempfile, calidar
    >>> from calidar.photon.search import SearchSettings
    >>> from calidar.sim.photons import PhotonSimConfig
    >>> folder = Path(tempfile.mkdtemp())
    >>> truth = {"along_track_bias": 1.5, "cross_track_bias": -2.0}
    >>> sim_config = PhotonSimConfig(seed=1, n_ccr=8, along_bias=1.5, cross_bias=-2.0)
    >>> sim = simulate_photons(sim_config, folder)
    >>> quick = calidar.CCRConfig(search=SearchSettings(bootstrap=0, surface_points=0))
    >>> result = calidar.calibrate_ccr([sim["atl03"]], sim["ccr"], folder, quick)
    >>> v, s = result.solution.values, result.solution.sigma
    >>> [bool(abs(v[k] - t) < 3 * s[k]) for k, t in truth.items()]
    [True, True]
    >>> sorted(p.name for p in folder.iterdir() if p.suffix in (".json", ".html", ".toml"))
    ['config.toml', 'report.html', 'solution.json', 'truth.json']
    """
    from calidar.photon.ccr import calibrate, describe
    from calidar.photon.report import add_section
    from calidar.report import Report

    survey = read_ccr_csv(ccr)
    truth = read_truth(truth_path) if truth_path is not None else None
    passes = load_passes(files, config.beams, survey, config.system, progress)
    result = calibrate(passes, survey, config.system, config.search, progress)
    result.solution.extra.update(describe(result))
    if record is not None:
        result.solution.extra["run"] = record.finish().to_dict()
    write_json(Path(out_dir) / "solution.json", result.solution.to_dict(truth))
    config.write(Path(out_dir) / "config.toml")
    own = report is None
    if own:
        report = Report("calidar: photon lidar CCR calibration")
        report.record = record
    add_section(report, result, truth)
    if own:
        report.write(Path(out_dir) / "report.html")
    return result


def simulate_photons(cfg, out_dir: Path) -> dict[str, Path]:
    """Simulate a pass (:class:`calidar.sim.photons.PhotonSimConfig`) into ``out_dir``:
    ATL03_sim.h5, ccr.csv, truth.json."""
    from calidar.sim.photons import simulate_pass, write_pass

    return write_pass(simulate_pass(cfg), Path(out_dir))
