"""Commands of the photon-lidar CCR calibration: ``denoise``, ``ccr``, ``simulate photons``."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import typer

from calidar.cli.common import console, parse_floats, print_warning
from calidar.errors import InputError
from calidar.pipelines.ccr import _existing, run_ccr
from calidar.outputs import atomic_path, check_writable, prepare_out_dir

BEAM = typer.Option("gt1l", "--beam", help="ATL03 beam (gt1l, gt1r, gt2l, gt2r, gt3l, gt3r).")
FORCE = typer.Option(False, "--force", help="Overwrite existing outputs.")


def register(app: typer.Typer, simulate: typer.Typer) -> None:
    @app.command()
    def ccr(
        atl03: list[Path] = typer.Argument(..., help="ATL03 file(s); several passes are solved jointly."),
        beam: str = BEAM,
        ccr_file: Path = typer.Option(..., "--ccr", help="CCR survey CSV: id,lat,lon,height (deg, deg, m) or, for one pass only, id,x,y,height (m)."),
        out: Path = typer.Option(..., "--out", help="Output folder (solution.json, report.html)."),
        dead_time_ns: float = typer.Option(3.2, "--dead-time-ns", help="Detector dead time t_d (ns)."),
        pulse_width_ns: float = typer.Option(1.0, "--pulse-width-ns", help="RMS pulse width σ (ns)."),
        shot_spacing: float = typer.Option(0.7, "--shot-spacing-m", help="Along-track shot spacing d_l (m)."),
        channels: int = typer.Option(16, "--channels", help="Detector channels of the beam (ATLAS: 16 strong, 4 weak)."),
        jitter: float = typer.Option(0.3, "--pointing-jitter-m", help="RMS shot-to-shot footprint jitter per axis (m)."),
        diameter_range: str = typer.Option("8,15", "--diameter-range", help="Footprint diameters searched MIN,MAX (m)."),
        diameter_step: float = typer.Option(0.1, "--diameter-step", help="Diameter step Δr (m)."),
        length_step: float = typer.Option(0.1, "--length-step", help="Segment-length step Δl (m)."),
        bootstrap: int = typer.Option(200, "--bootstrap", help="Bootstrap replicates for σ (0 = none)."),
        truth: Path = typer.Option(None, "--truth", help="truth.json of a simulation (adds errors to the outputs)."),
        force: bool = FORCE,
    ) -> None:
        """Solve along/cross-track geolocation bias and footprint diameter from CCR returns."""
        from calidar.photon.ccr import PARAMETERS, SearchSettings, SystemParameters

        dmin, dmax = parse_floats(diameter_range, 2, "--diameter-range")
        for name, v in (("--dead-time-ns", dead_time_ns), ("--pulse-width-ns", pulse_width_ns),
                        ("--shot-spacing-m", shot_spacing), ("--diameter-step", diameter_step),
                        ("--length-step", length_step)):
            if not v > 0:
                raise InputError(None, name, f"expected a positive number, got {v}")
        if not 0 < dmin < dmax:
            raise InputError(None, "--diameter-range", f"expected 0 < MIN < MAX, got {diameter_range}")
        if not jitter >= 0:
            raise InputError(None, "--pointing-jitter-m", f"expected a number ≥ 0, got {jitter}")
        if channels < 1:
            raise InputError(None, "--channels", f"expected a positive integer, got {channels}")
        system = SystemParameters(dead_time_ns * 1e-9, pulse_width_ns * 1e-9, shot_spacing, channels, jitter)
        settings = SearchSettings(dmin, dmax, diameter_step, length_step, bootstrap=bootstrap)
        result = run_ccr(atl03, beam, ccr_file, out, system=system, settings=settings, truth_path=truth, force=force)
        v, s = result.solution.values, result.solution.sigma
        for k in PARAMETERS:
            console.print(f"  {k:20s} {v[k]:8.3f} ± {s[k]:.3f} m", highlight=False)
        for w in result.warnings:
            print_warning(w)
        console.print(f"wrote {out / 'solution.json'} and {out / 'report.html'}", highlight=False)

    @simulate.command("photons")
    def simulate_photons(
        seed: int = typer.Option(0, "--seed", help="Random seed."),
        out: Path = typer.Option(..., "--out", help="Output folder (ATL03_sim.h5, ccr.csv, truth.json)."),
        n_ccr: int = typer.Option(8, "--n-ccr", help="CCRs within the footprints' reach."),
        n_unlit: int = typer.Option(0, "--n-unlit", help="Extra CCRs out of reach (no returns)."),
        dropout: float = typer.Option(0.0, "--ccr-dropout", help="Fraction of shots whose CCR returns are lost."),
        along_bias: float = typer.Option(None, "--along-bias", help="Along-track bias (m); default random ±3 m."),
        cross_bias: float = typer.Option(None, "--cross-bias", help="Cross-track bias (m, left +); default random ±3 m."),
        diameter: float = typer.Option(11.0, "--footprint-diameter", help="Footprint diameter (m)."),
        length: float = typer.Option(1200.0, "--length", help="Track length simulated (m)."),
        force: bool = FORCE,
    ) -> None:
        """Simulate an ATL03-layout pass over surveyed CCRs with a known geolocation bias."""
        from calidar.sim.photons import PhotonSimConfig, simulate_pass, write_pass

        if not 0 <= dropout < 1:
            raise InputError(None, "--ccr-dropout", f"expected a fraction in [0, 1), got {dropout}")
        cfg = PhotonSimConfig(seed=seed, n_ccr=n_ccr, n_unlit=n_unlit, ccr_dropout=dropout, along_bias=along_bias,
                              cross_bias=cross_bias, footprint_diameter=diameter, length=length,
                              ccr_spacing=min(60.0, 0.9 * length / max(n_ccr + n_unlit, 1)))
        out = prepare_out_dir(out, force)
        paths = write_pass(simulate_pass(cfg), out)
        t = json.loads(paths["truth"].read_text())
        console.print(f"wrote {', '.join(str(p) for p in paths.values())}; truth: along {t['along_track_bias']:+.3f} m, "
                      f"cross {t['cross_track_bias']:+.3f} m, diameter {t['footprint_diameter']:.2f} m", highlight=False)


