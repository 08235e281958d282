"""``calidar simulate photons``: an ATL03-layout pass over surveyed CCRs with a known geolocation
bias."""

from __future__ import annotations

import json
from pathlib import Path

import typer

from calidar.cli.common import FORCE_HELP, console


OUT = typer.Option(..., "--out", help="Output folder (ATL03_sim.h5, ccr.csv, truth.json).")
DROPOUT = typer.Option(0.0, "--ccr-dropout", help="Fraction of shots whose CCR returns are lost.")
ALONG_BIAS = typer.Option(None, "--along-bias", help="Along-track bias (m); default random ±3 m.")
CROSS_BIAS = typer.Option(None, "--cross-bias",
                          help="Cross-track bias (m, left +); default random ±3 m.")
STRENGTH = typer.Option("strong", "--strength",
                        help="Beam strength: strong (16 channels) or weak (4).")
CCR_PHOTONS = typer.Option(20.0, "--ccr-photons",
                           help="Mean photons of a CCR at the footprint centre.")
GROUND_PHOTONS = typer.Option(3.0, "--ground-photons", help="Mean signal photons a shot from the "
                              "ground (a weak beam carries about a quarter of a strong beam's: "
                              "0.75).")
BACKGROUND = typer.Option(3.0, "--background-mhz",
                          help="Solar background rate (MHz; daylight 1–10, night ≈ 0.01).")
WINDOW = typer.Option(30.0, "--window-m",
                      help="Telemetry height window (m, from 10 m below the ground).")
RELIEF_WAVELENGTH = typer.Option(300.0, "--relief-wavelength", help="Wavelength of the hills (m).")
CANOPY_COVER = typer.Option(0.0, "--canopy-cover",
                            help="Fraction of the track under trees (40 m stands).")
CANOPY_HEIGHT = typer.Option(15.0, "--canopy-height", help="Height of the tallest trees (m).")


def simulate_photons(
    out: Path = OUT,
    seed: int = typer.Option(0, "--seed", help="Random seed (≥ 0)."),
    n_ccr: int = typer.Option(8, "--n-ccr", help="CCRs within the footprints' reach (≥ 1)."),
    n_unlit: int = typer.Option(0, "--n-unlit", help="Extra CCRs out of reach (no returns)."),
    dropout: float = DROPOUT,
    along_bias: float | None = ALONG_BIAS,
    cross_bias: float | None = CROSS_BIAS,
    diameter: float = typer.Option(11.0, "--footprint-diameter", help="Footprint diameter (m)."),
    length: float = typer.Option(1200.0, "--length", help="Track length simulated (m)."),
    strength: str = STRENGTH,
    ccr_photons: float = CCR_PHOTONS,
    ground_photons: float = GROUND_PHOTONS,
    background: float = BACKGROUND,
    window: float = WINDOW,
    slope: float = typer.Option(0.02, "--slope", help="Along-track terrain slope (m/m)."),
    relief: float = typer.Option(2.0, "--relief", help="Amplitude of the terrain's hills (m)."),
    relief_wavelength: float = RELIEF_WAVELENGTH,
    roughness: float = typer.Option(0.05, "--roughness", help="RMS surface roughness (m)."),
    canopy_cover: float = CANOPY_COVER,
    canopy_height: float = CANOPY_HEIGHT,
    force: bool = typer.Option(False, "--force", help=FORCE_HELP),
) -> None:
    """Simulate an ATL03-layout pass over surveyed CCRs with a known geolocation bias."""
    from calidar.errors import InputError
    from calidar.outputs import output_folder
    from calidar.pipelines.ccr import simulate_photons as run
    from calidar.sim.photons import PhotonSimConfig
    from calidar.validate import SEED_MAX, integer, number

    if strength not in ("strong", "weak"):
        raise InputError(None, "--strength", f"expected strong or weak, got {strength!r}")
    n = integer(n_ccr, "--n-ccr", 1, 200)
    unlit = integer(n_unlit, "--n-unlit", 0, 200)
    length = number(length, "--length", 100.0, 5_000_000.0, "m")
    cfg = PhotonSimConfig(
        seed=integer(seed, "--seed", 0, SEED_MAX), n_ccr=n, n_unlit=unlit,
        ccr_dropout=number(dropout, "--ccr-dropout", 0.0, 0.95),
        along_bias=None if along_bias is None
        else number(along_bias, "--along-bias", -50.0, 50.0, "m"),
        cross_bias=None if cross_bias is None
        else number(cross_bias, "--cross-bias", -50.0, 50.0, "m"),
        footprint_diameter=number(diameter, "--footprint-diameter", 1.0, 100.0, "m"), length=length,
        strength=strength, ccr_photons=number(ccr_photons, "--ccr-photons", 1.0, 500.0),
        ccr_spacing=min(60.0, 0.9 * length / max(n + unlit, 1)),
        ground_photons=number(ground_photons, "--ground-photons", 0.0, 100.0),
        background_rate=number(background, "--background-mhz", 0.0, 50.0, "MHz") * 1e6,
        window=number(window, "--window-m", 5.0, 2000.0, "m"),
        slope_along=number(slope, "--slope", -2.0, 2.0),
        undulation=number(relief, "--relief", 0.0, 500.0, "m"),
        undulation_wavelength=number(relief_wavelength, "--relief-wavelength", 10.0, 100_000.0,
                                     "m"),
        roughness=number(roughness, "--roughness", 0.0, 10.0, "m"),
        canopy_cover=number(canopy_cover, "--canopy-cover", 0.0, 1.0),
        canopy_height=number(canopy_height, "--canopy-height", 0.0, 100.0, "m"))
    with output_folder(out, force) as tmp:
        paths = run(cfg, tmp)
        t = json.loads(paths["truth"].read_text())
    console.print(f"wrote {out}/ATL03_sim.h5 (each photon's truth in "
                  "<beam>/heights/sim_class_ph), ccr.csv, truth.json; truth: along "
                  f"{t['along_track_bias']:+.3f} m, cross {t['cross_track_bias']:+.3f} m, "
                  f"diameter {t['footprint_diameter']:.2f} m", highlight=False, markup=False)


def register(app: typer.Typer, simulate: typer.Typer) -> None:
    simulate.command("photons")(simulate_photons)
