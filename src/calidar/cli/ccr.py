"""``calidar ccr``: photon-lidar geolocation calibration (along/cross-track bias, footprint diameter)
from the returns of surveyed corner-cube retroreflectors."""

from __future__ import annotations

from pathlib import Path

import typer

from calidar.cli.common import (
    FORCE_HELP, console, exit_with_verdict, print_verdict, print_warning, progress_bar, progress_callback,
)
from calidar.cli.denoise import BEAM_HELP, SHOT_SPACING_RANGE


def _settings(diameter_range, diameter_step, length_step, max_bias, bootstrap, seed, shared_bias):
    from calidar.errors import InputError
    from calidar.photon.search import SearchSettings
    from calidar.validate import SEED_MAX, integer, number, parse_floats

    dmin, dmax = parse_floats(diameter_range, 2, "--diameter-range")
    number(dmin, "--diameter-range", 0.5, 500.0, "m", field="MIN")
    number(dmax, "--diameter-range", 0.5, 500.0, "m", field="MAX")
    if not dmin < dmax:
        raise InputError(None, "--diameter-range", f"expected MIN < MAX, got {diameter_range}")
    return SearchSettings(dmin, dmax, number(diameter_step, "--diameter-step", 0.01, 2.0, "m"),
                          number(length_step, "--length-step", 0.01, 2.0, "m"),
                          max_bias=number(max_bias, "--max-bias", 0.5, 200.0, "m"),
                          bootstrap=integer(bootstrap, "--bootstrap", 0, 10_000),
                          seed=integer(seed, "--seed", 0, SEED_MAX), shared_bias=shared_bias)


def _system(dead_time_ns, pulse_width_ns, shot_spacing, channels, jitter):
    from calidar.photon.passes import SystemParameters
    from calidar.validate import integer, number

    return SystemParameters(number(dead_time_ns, "--dead-time-ns", 0.1, 100.0, "ns") * 1e-9,
                            number(pulse_width_ns, "--pulse-width-ns", 0.01, 50.0, "ns") * 1e-9,
                            number(shot_spacing, "--shot-spacing-m", *SHOT_SPACING_RANGE, "m"),
                            None if channels is None else integer(channels, "--channels", 1, 64),
                            number(jitter, "--pointing-jitter-m", 0.0, 5.0, "m"))


def ccr(
    atl03: list[Path] = typer.Argument(..., help="ATL03 file(s); several passes and beams are solved jointly."),
    ccr_file: Path = typer.Option(..., "--ccr", help="CCR survey CSV: id,lat,lon,height (deg, deg, m above ground) "
                                  "or, for one pass only, id,x,y,height (m)."),
    out: Path = typer.Option(..., "--out", help="Output folder (solution.json, report.html)."),
    beam: str = typer.Option("all", "--beam", help=BEAM_HELP),
    shared_bias: bool = typer.Option(False, "--shared-bias", help="One along/cross-track bias for every beam "
                                     "(default: one per beam; the footprint diameter is always per beam)."),
    dead_time_ns: float = typer.Option(3.2, "--dead-time-ns", help="Detector dead time t_d (ns)."),
    pulse_width_ns: float = typer.Option(1.0, "--pulse-width-ns", help="RMS pulse width σ (ns)."),
    shot_spacing: float = typer.Option(0.7, "--shot-spacing-m", help="Along-track shot spacing d_l (m)."),
    channels: int | None = typer.Option(None, "--channels", help="Detector channels per beam (default: 16 strong, "
                                        "4 weak, from the file)."),
    jitter: float = typer.Option(0.3, "--pointing-jitter-m", help="RMS shot-to-shot footprint jitter per axis (m)."),
    diameter_range: str = typer.Option("8,15", "--diameter-range", help="Footprint diameters searched MIN,MAX (m); "
                                       "also the estimate's bounds."),
    diameter_step: float = typer.Option(0.1, "--diameter-step", help="Diameter step Δr of the grid search (m)."),
    length_step: float = typer.Option(0.1, "--length-step", help="Segment-length step Δl of the grid search (m)."),
    max_bias: float = typer.Option(10.0, "--max-bias", help="Largest |bias| accepted (m)."),
    bootstrap: int = typer.Option(100, "--bootstrap", help="Parametric bootstrap replicates for σ (0 = none)."),
    seed: int = typer.Option(0, "--seed", help="Seed of the bootstrap."),
    truth: Path | None = typer.Option(None, "--truth", help="truth.json of a simulation (adds errors to the outputs)."),
    force: bool = typer.Option(False, "--force", help=FORCE_HELP),
) -> None:
    """Solve along/cross-track geolocation bias and footprint diameter from CCR returns (maximum likelihood)."""
    from calidar.outputs import check_out_dir, output_folder
    from calidar.pipelines.ccr import run_ccr
    from calidar.provenance import RunRecord

    settings = _settings(diameter_range, diameter_step, length_step, max_bias, bootstrap, seed, shared_bias)
    system = _system(dead_time_ns, pulse_width_ns, shot_spacing, channels, jitter)
    inputs = [*atl03, ccr_file, truth]
    check_out_dir(out, force)
    record = RunRecord.capture(None, inputs=inputs, options={
        "beam": beam, "shared_bias": shared_bias, "dead_time_ns": dead_time_ns, "pulse_width_ns": pulse_width_ns,
        "shot_spacing_m": shot_spacing, "channels": channels, "pointing_jitter_m": jitter,
        "diameter_range": diameter_range, "max_bias_m": max_bias, "bootstrap": bootstrap, "seed": seed})
    with output_folder(out, force, inputs=inputs) as tmp, progress_bar() as bar:
        result = run_ccr(atl03, beam, ccr_file, tmp, system=system, settings=settings, truth_path=truth,
                         record=record, progress=progress_callback(bar))
    sol = result.solution
    for n in sol.parameters.free_names:
        if n.split("[")[0] in ("along_track_bias", "cross_track_bias", "footprint_diameter"):
            console.print(f"  {n:34s} {sol.values[n]:8.3f} ± {sol.sigma[n]:.3f} m", highlight=False, markup=False)
    for w in result.warnings:
        print_warning(w)
    print_verdict(result.verdict, "CCR calibration")
    console.print(f"wrote {out / 'solution.json'} and {out / 'report.html'}", highlight=False, markup=False)
    exit_with_verdict(result.verdict)


def register(app: typer.Typer, simulate: typer.Typer) -> None:
    app.command("ccr")(ccr)
