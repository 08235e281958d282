"""``calidar denoise``: classify every photon of an ATL03 file as signal or noise (a CSV)."""

from __future__ import annotations

from pathlib import Path

import typer

from calidar.cli.common import CONFIG_HELP, config_values, console, given_options, print_warning
from calidar.cli.options import parse_beams

BEAM_HELP = "ATL03 beam(s): gt1l … gt3r, several separated by commas, or all."
#: options → (DenoiseConfig attribute, parse)
OPTIONS = {"beam": ("beams", parse_beams), "shot_spacing": ("shot_spacing_m", None)}


OUT = typer.Option(..., "--out", help="CSV to write: beam, strength, delta_time, along_track_m, "
                   "dist_ph_along, lat, lon, h_ph, atl03_conf, signal.")
SHOT_SPACING = typer.Option(0.7, "--shot-spacing-m", help="Along-track shot spacing d_l (m).")
FORCE = typer.Option(False, "--force", help="Overwrite an existing CSV (never an input).")


#: the command's help (its line breaks are those --help shows)
DENOISE_HELP = ("Classify every photon as signal (1) or noise (0): slope-following neighbour "
                "counts against the\nmeasured solar background (ATL03 ATBD slant histograms, ATL08 "
                "DRAGANN); weak beams and daylight too.\nThe run's settings go beside the CSV as "
                "<name>.config.toml (for --config).")


def denoise(
    ctx: typer.Context,
    atl03: Path = typer.Argument(..., help="ATL03 HDF5 file."),
    beam: str = typer.Option("all", "--beam", help=BEAM_HELP),
    out: Path = OUT,
    shot_spacing: float = SHOT_SPACING,
    force: bool = FORCE,
    config: Path | None = typer.Option(None, "--config", help=CONFIG_HELP),
) -> None:
    """``calidar denoise`` (its help: DENOISE_HELP)."""
    from calidar.outputs import atomic_path, check_writable, guard_inputs
    from calidar.pipelines.config_file import config_beside
    from calidar.pipelines.denoise import DenoiseConfig, run_denoise
    from calidar.validate import existing_file

    cfg = DenoiseConfig.configure(config, config_values(given_options(ctx), OPTIONS))
    guard_inputs([out, config_beside(out)], [atl03, config])
    existing_file(atl03, "ATL03 file")
    check_writable(config_beside(out), force)
    with atomic_path(out, force) as tmp:
        result = run_denoise(atl03, tmp, cfg)
    cfg.write(config_beside(out))
    for b in result.beams:
        agree = ("" if b.atl03_agreement is None else f"; {b.atl03_agreement:.1%} of the "
                 f"{b.atl03_confident:,} ATL03 rates medium/high confidence")
        strength = b.strength or "strength unknown"
        console.print(f"  {b.beam} ({strength}): {b.photons:,} photons, {b.signal:,} signal "
                      f"({b.signal / b.photons:.1%}){agree}", highlight=False, markup=False)
        if b.along_track_from != "segments":
            print_warning(f"{b.beam}: along-track distance from the {b.along_track_from}")
    if result.skipped:
        print_warning(f"no photons in {', '.join(result.skipped)}; skipped")
    console.print(f"{out}: {result.photons:,} photons, {result.signal:,} signal", highlight=False,
                  markup=False)


def register(app: typer.Typer, simulate: typer.Typer) -> None:
    app.command("denoise", help=DENOISE_HELP)(denoise)
