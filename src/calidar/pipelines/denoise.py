"""The photon denoising pipeline (``calidar denoise``): read the beams of an ATL03 file, classify
every photon as signal or noise, write one CSV row per photon.

Columns: ``beam``, ``strength`` (strong/weak/unknown), ``delta_time`` (s since 2018-01-01),
``along_track_m`` (distance along the beam's track: ATL03 segment_dist_x + dist_ph_along),
``dist_ph_along`` (ATL03's own field: the distance within the photon's 20 m segment),
``lat``, ``lon`` (deg), ``h_ph`` (m, ellipsoidal), ``atl03_conf`` (ATL03's highest signal_conf_ph
over the surface types, −2…4) and ``signal`` (1 signal, 0 noise).
"""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from calidar.pipelines import Progress, no_progress
from calidar.pipelines.config_file import FileConfig, Key

COLUMNS = ("beam", "strength", "delta_time", "along_track_m", "dist_ph_along", "lat", "lon",
           "h_ph", "atl03_conf", "signal")


@dataclass(frozen=True)
class DenoiseConfig(FileConfig):
    """What ``calidar denoise`` takes besides its files: the beams (None: every beam of the file)
    and the along-track shot spacing (m); its TOML file is written beside the CSV
    (``<name>.config.toml``).

    >>> DenoiseConfig(beams=("gt1l",)).to_dict()
    {'beams': ['gt1l'], 'shot_spacing_m': 0.7}
    """

    KEYS = (Key("beams", "beams", "--beam"),
            Key("shot_spacing_m", "shot_spacing_m", "--shot-spacing-m"))
    COMMAND = "denoise"

    beams: tuple[str, ...] | None = None
    shot_spacing_m: float = 0.7

    def check(self) -> None:
        """Beam names of ATL03, each once; the shot spacing in its range."""
        from calidar.errors import InputError
        from calidar.io.atl03 import BEAMS
        from calidar.pipelines.ccr_config import SHOT_SPACING_RANGE
        from calidar.validate import number

        if self.beams is not None and (not self.beams or any(b not in BEAMS for b in self.beams)):
            raise InputError(None, "--beam", f"expected all, one of {', '.join(BEAMS)} or several "
                             f"separated by commas, got {','.join(self.beams)!r}")
        number(self.shot_spacing_m, "--shot-spacing-m", *SHOT_SPACING_RANGE, "m")


@dataclass
class BeamDenoised:
    """One beam's outcome: photons, signal photons, how its along-track distance was found."""

    beam: str
    strength: str | None
    photons: int
    signal: int
    along_track_from: str
    #: photons ATL03 rates medium or high confidence (signal_conf_ph ≥ 3 on any surface)
    atl03_confident: int = 0
    atl03_confident_kept: int = 0  #: of those, flagged signal here

    @property
    def atl03_agreement(self) -> float | None:
        """Fraction of ATL03's medium/high-confidence photons flagged signal (None: the file rates
        none)."""
        return self.atl03_confident_kept / self.atl03_confident if self.atl03_confident else None


@dataclass
class DenoiseResult:
    beams: list[BeamDenoised]
    skipped: list[str] = field(default_factory=list)  #: beams without photons

    @property
    def photons(self) -> int:
        return sum(b.photons for b in self.beams)

    @property
    def signal(self) -> int:
        return sum(b.signal for b in self.beams)


def run_denoise(atl03: Path, out_csv: Path, config: DenoiseConfig = DenoiseConfig(),
                progress: Progress = no_progress) -> DenoiseResult:
    """Denoise the chosen beams (``config.beams``; None: every beam) of ``atl03`` and write the CSV
    ``out_csv`` (a fresh path: the CLI hands in an atomic temporary)."""
    from calidar.io.atl03 import read_atl03, select_beams
    from calidar.photon.denoise import denoise

    names = select_beams(atl03, config.beams)
    result = DenoiseResult([])
    with open(out_csv, "w", encoding="utf-8", newline="") as fh:
        fh.write(",".join(COLUMNS) + "\n")
        for k, name in enumerate(names):
            b = read_atl03(atl03, name)
            progress("beams", k, len(names))
            if len(b) == 0:
                result.skipped.append(name)
                continue
            sig = denoise(b.x, b.h, config.shot_spacing_m)
            _write_rows(fh, b, sig)
            conf = b.signal_conf.max(axis=1) >= 3 if b.signal_conf.size else np.zeros(len(b), bool)
            result.beams.append(BeamDenoised(name, b.strength, len(b), int(sig.sum()),
                                             b.along_track_source, int(conf.sum()),
                                             int((conf & sig).sum())))
        progress("beams", len(names), len(names))
    if not result.beams:
        from calidar.errors import InputError

        raise InputError(atl03, f"{'/'.join(names)}/heights",
                         "no photons in the chosen beam(s); nothing to denoise")
    return result


def _write_rows(fh, b, signal: np.ndarray) -> None:
    """The beam's rows (see the module docstring), written in chunks of 200 000 photons."""
    conf = b.signal_conf.max(axis=1) if b.signal_conf.size else np.zeros(0, np.int8)
    lead = f"{b.beam},{b.strength or 'unknown'},"
    cols = (b.delta_time, b.x, b.dist_along, np.degrees(b.lat), np.degrees(b.lon), b.h, conf,
            signal.astype(int))
    fmt = lead + "%.9f,%.4f,%.4f,%.9f,%.9f,%.4f,%d,%d"
    for s in range(0, len(b), 200_000):
        np.savetxt(fh, np.column_stack([c[s:s + 200_000] for c in cols]), fmt=fmt)
