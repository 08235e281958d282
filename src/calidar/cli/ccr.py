"""``calidar ccr``: photon-lidar geolocation calibration (along/cross-track bias, footprint
diameter) from the returns of surveyed corner-cube retroreflectors."""

from __future__ import annotations

from pathlib import Path

import typer

from calidar.cli.common import (
    CONFIG_HELP, FORCE_HELP, console, exit_with_verdict, given_options, print_verdict,
    print_warning, progress_bar, progress_callback,
)
from calidar.cli.denoise import BEAM_HELP

#: options → the search settings' fields (calidar.photon.search.SearchSettings)
SEARCH_OPTIONS = {"diameter_step": "diameter_step", "length_step": "length_step",
                  "max_bias": "max_bias", "bootstrap": "bootstrap", "seed": "seed",
                  "shared_bias": "shared_bias"}
#: options → (the instrument's field, factor to SI; None: as given)
#: (calidar.photon.passes.SystemParameters)
SYSTEM_OPTIONS = {"dead_time_ns": ("dead_time", 1e-9), "pulse_width_ns": ("pulse_width", 1e-9),
                  "shot_spacing": ("shot_spacing", 1.0), "channels": ("channels", None),
                  "jitter": ("pointing_jitter", 1.0)}


def ccr_config(path: Path | None, given: dict):
    """The configuration: the ``--config`` file's (else the defaults), with the options ``given`` on
    the command line ({parameter name: value}) replacing its settings; checked."""
    from calidar.cli.common import config_values
    from calidar.cli.options import parse_beams
    from calidar.pipelines.ccr_config import CCRConfig
    from calidar.validate import parse_floats

    options = {k: (f"search.{f}", None) for k, f in SEARCH_OPTIONS.items()}
    options.update({k: (f"system.{f}", None if c is None else (lambda v, c=c: v * c))
                    for k, (f, c) in SYSTEM_OPTIONS.items()}, beam=("beams", parse_beams))
    values = config_values(given, options)
    if "diameter_range" in given:
        low, high = parse_floats(given["diameter_range"], 2, "--diameter-range")
        values["search.diameter_min"], values["search.diameter_max"] = low, high
    return CCRConfig.configure(path, values)


ATL03 = typer.Argument(..., help="ATL03 file(s); several passes and beams are solved jointly.")
CCR_FILE = typer.Option(..., "--ccr", help="CCR survey CSV: id,lat,lon,height (deg, deg, m above "
                        "ground) or, for one pass only, id,x,y,height (m).")
OUT = typer.Option(..., "--out", help="Output folder (solution.json, config.toml, report.html).")
SHARED_BIAS = typer.Option(False, "--shared-bias", help="One along/cross-track bias for every beam "
                           "(default: one per beam; the footprint diameter is always per beam).")
SHOT_SPACING = typer.Option(0.7, "--shot-spacing-m", help="Along-track shot spacing d_l (m).")
CHANNELS = typer.Option(None, "--channels", help="Detector channels per beam (default: 16 strong, "
                        "4 weak, from the file).")
JITTER = typer.Option(0.3, "--pointing-jitter-m",
                      help="RMS shot-to-shot footprint jitter per axis (m).")
DIAMETER_RANGE = typer.Option("8,15", "--diameter-range", help="Footprint diameters searched "
                              "MIN,MAX (m); also the estimate's bounds.")
DIAMETER_STEP = typer.Option(0.1, "--diameter-step",
                             help="Diameter step Δr of the grid search (m).")
LENGTH_STEP = typer.Option(0.1, "--length-step",
                           help="Segment-length step Δl of the grid search (m).")
BOOTSTRAP = typer.Option(100, "--bootstrap",
                         help="Parametric bootstrap replicates for σ (0 = none).")
TRUTH = typer.Option(None, "--truth",
                     help="truth.json of a simulation (adds errors to the outputs).")


#: the command's help (its line breaks are those --help shows)
CCR_HELP = ("Solve along/cross-track geolocation bias and footprint diameter from CCR returns "
            "(maximum likelihood);\nwrites solution.json, config.toml (this run's settings, for "
            "--config) and report.html.")


def ccr(
    ctx: typer.Context,
    atl03: list[Path] = ATL03,
    ccr_file: Path = CCR_FILE,
    out: Path = OUT,
    beam: str = typer.Option("all", "--beam", help=BEAM_HELP),
    shared_bias: bool = SHARED_BIAS,
    dead_time_ns: float = typer.Option(3.2, "--dead-time-ns", help="Detector dead time t_d (ns)."),
    pulse_width_ns: float = typer.Option(1.0, "--pulse-width-ns", help="RMS pulse width σ (ns)."),
    shot_spacing: float = SHOT_SPACING,
    channels: int | None = CHANNELS,
    jitter: float = JITTER,
    diameter_range: str = DIAMETER_RANGE,
    diameter_step: float = DIAMETER_STEP,
    length_step: float = LENGTH_STEP,
    max_bias: float = typer.Option(10.0, "--max-bias", help="Largest |bias| accepted (m)."),
    bootstrap: int = BOOTSTRAP,
    seed: int = typer.Option(0, "--seed", help="Seed of the bootstrap."),
    truth: Path | None = TRUTH,
    force: bool = typer.Option(False, "--force", help=FORCE_HELP),
    config: Path | None = typer.Option(None, "--config", help=CONFIG_HELP),
) -> None:
    """``calidar ccr`` (its help: CCR_HELP)."""
    from calidar.outputs import check_out_dir, output_folder
    from calidar.pipelines.ccr import run_ccr
    from calidar.provenance import RunRecord

    cfg = ccr_config(config, given_options(ctx))
    inputs = [*atl03, ccr_file, truth, config]
    check_out_dir(out, force)
    record = RunRecord.capture(None, inputs=inputs, options=cfg.to_dict())
    with output_folder(out, force, inputs=inputs) as tmp, progress_bar() as bar:
        result = run_ccr(atl03, ccr_file, tmp, cfg, truth_path=truth, record=record,
                         progress=progress_callback(bar))
    sol = result.solution
    for n in sol.parameters.free_names:
        if n.split("[")[0] in ("along_track_bias", "cross_track_bias", "footprint_diameter"):
            console.print(f"  {n:34s} {sol.values[n]:8.3f} ± {sol.sigma[n]:.3f} m",
                          highlight=False, markup=False)
    for w in result.warnings:
        print_warning(w)
    print_verdict(result.verdict, "CCR calibration")
    console.print(f"wrote {out / 'solution.json'}, {out / 'config.toml'} and "
                  f"{out / 'report.html'}", highlight=False, markup=False)
    exit_with_verdict(result.verdict)


def register(app: typer.Typer, simulate: typer.Typer) -> None:
    app.command("ccr", help=CCR_HELP)(ccr)
